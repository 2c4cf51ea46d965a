// gs-gpu prelude, prepended to every kernel together with the generated `struct Pass` and the
// generated storage-binding declarations (slots 2..).

// Per-dispatch constants (a dynamic-offset slot of one uniform buffer, see `PassUniform`).
@group(0) @binding(1) var<uniform> pass_: Pass;

// Linear id of a 1D dispatch that was split into 2D (at most 65535 workgroups per dimension).
fn linear_group(wid: vec3<u32>, nwg: vec3<u32>) -> u32 {
    return wid.y * nwg.x + wid.x;
}

// The builtins of a 1D kernel: entry points take `ids: Ids`.
struct Ids {
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
}

// Workgroup index within a (possibly 2D-split) 1D dispatch.
fn group_1d(ids: Ids) -> u32 {
    return linear_group(ids.wid, ids.nwg);
}

// Global thread index of a 1D dispatch of 256-thread workgroups (`Dispatcher::dispatch_1d`).
fn thread_1d(ids: Ids) -> u32 {
    return group_1d(ids) * 256u + ids.li;
}

// One step of a compensated (Kahan) f32 sum in a fixed order: `s` is (sum, compensation), the
// result s + v. The loss kernels sum each image row with it before the host adds the rows in
// f64, so a row of many values stays close to the f64 sum. Each term is multiplied by
// `pass_.unit` (1.0, unknown to the compiler): without it an optimiser that reassociates
// floats (Mesa's does) cancels the compensation as algebra, leaving a plain f32 sum.
fn kahan_add(s: vec2<f32>, v: f32) -> vec2<f32> {
    let u = pass_.unit;
    let y = (v - s.y) * u;
    let t = (s.x + y) * u;
    return vec2<f32>(t, ((t - s.x) * u - y) * u);
}

// One step of a double-f32 sum in a fixed order: `s` is (hi, lo), the sum being hi + lo with
// |lo| below an ulp of hi; the result is s + v, the rounding error of each addition kept in
// the pair (Knuth's TwoSum, then the pair renormalised), with `pass_.unit` as in `kahan_add`.
// Per-image totals of row sums are made with it on the device and read as one f64 each
// (`gs_gpu::wide_value`).
fn wide_add(s: vec2<f32>, v: f32) -> vec2<f32> {
    let u = pass_.unit;
    let t = (s.x + v) * u;
    let z = (t - s.x) * u;
    let e = ((s.x - (t - z) * u) * u + (v - z) * u) * u;
    let lo = (s.y + e) * u;
    let hi = (t + lo) * u;
    return vec2<f32>(hi, (lo - (hi - t) * u) * u);
}
