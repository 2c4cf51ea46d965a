// Shared declarations of every gs-raster kernel (composed after the gs-gpu prelude, which
// declares `Pass`, `pass_`, `Ids` and the 1D-dispatch helpers).

// Camera, config and frame constants (one per render / backward): `struct Cam` is generated
// from the Rust `CamUniform` (gpu/kernels.rs).
@group(0) @binding(0) var<uniform> cam: Cam;

const TILE: u32 = 16u;
const MAX_ALPHA: f32 = 0.99;
const T_STOP: f32 = 1e-4;
const MIN_COMPENSATION: f32 = 0.005;
const INVISIBLE: u32 = 0xffffffffu;

fn is_finite(v: f32) -> bool {
    return (bitcast<u32>(v) & 0x7f800000u) != 0x7f800000u;
}

fn finite3(v: vec3<f32>) -> bool {
    return is_finite(v.x) && is_finite(v.y) && is_finite(v.z);
}

// exp(-x) for x >= 0, bit-for-bit the CPU backend's `exp_neg` (Cody-Waite + degree-6 Taylor).
fn exp_neg(x: f32) -> f32 {
    if (!(x < 87.0)) {
        return 0.0;
    }
    let t = -x * 1.44269502;
    let n = i32(t - 0.5);
    let nf = f32(n);
    let f = (-x - nf * 0.6933594) + nf * 2.1219444e-4;
    let p = 1.0 + f * (1.0 + f * (0.5 + f * (0.166666672 + f * (0.0416666679
        + f * (0.00833333377 + f * 0.00138888892)))));
    return p * bitcast<f32>(u32(n + 127) << 23u);
}

fn rot_c() -> mat3x3<f32> {
    return mat3x3<f32>(cam.r0.xyz, cam.r1.xyz, cam.r2.xyz);
}

// The CPU backend's `pixel_box` test: is tile-local coordinate `l` inside the box of a splat
// centred at `c` with half extent `e`, in a tile starting at `o` of size `size`?
fn floor_clamped(v: f32, hi: u32) -> i32 {
    let c = clamp(v, -1.0, f32(hi));
    let i = i32(c);
    if (f32(i) > c) {
        return i - 1;
    }
    return i;
}

fn in_box(c: f32, e: f32, o: u32, size: u32, l: u32) -> bool {
    let fo = f32(o);
    let l0 = max(floor_clamped(c - e - 0.5 - fo, size), 0);
    let l1 = clamp(floor_clamped(c + e - 0.5 - fo, size) + 1, 0, i32(size));
    return i32(l) >= l0 && i32(l) < l1;
}
