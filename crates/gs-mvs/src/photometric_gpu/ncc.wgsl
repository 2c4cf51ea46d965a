// L_p on the device: the NCC cost of one reference pixel's patch against one source view and
// its gradient with respect to the rendered plane (Ñ, D), the twin of `photometric::patch_cost`
// (docs/method.md §L_p). One thread per (pixel, source) entry, one dispatch per source; the patch samples are computed
// three times (sums, centred moments, gradient) instead of being kept in per-thread arrays, with
// the same arithmetic each time, so every pass sees the same values.
//
// Generated before this file: `struct NccFrame` (binding 0), `struct NccPair`,
// `struct NccResult`, `struct SurfaceTexel`, and the storage bindings `pairs`, `entries`, `surface`
// (the reference's rendered Ñ and D per pixel, from the rasterizer's surface image or the host),
// `row_starts` (per source, the first entry of each row and one past its last), `greys` (the
// reference grey image at 0, then each source's at its pair's offset), `rays`
// (the x ray table of the reference grey image's columns, then the y table of its rows) and
// `results`, and `sampling.wgsl` (`finite`, `arena_sample`).

@group(0) @binding(0) var<uniform> frame: NccFrame;

const NCC_EPS: f32 = 1e-8;
const MASK_THRESHOLD: f32 = 0.9;
const OUTSIDE: u32 = 0u;
const MASKED: u32 = 1u;
const VALID: u32 = 2u;

// The homogeneous warp of reference ray q by the plane (n, 1/D): w = A q − (K_s t)·m with
// m = n·q / D (`PairGeometry::warp`). Returns (w, m).
fn warp(pr: NccPair, q: vec3<f32>, n: vec3<f32>, inv_d: f32) -> vec4<f32> {
    let m = (n.x * q.x + n.y * q.y + n.z * q.z) * inv_d;
    let a0 = pr.a0.x * q.x + pr.a0.y * q.y + pr.a0.z * q.z;
    let a1 = pr.a1.x * q.x + pr.a1.y * q.y + pr.a1.z * q.z;
    let a2 = pr.a2.x * q.x + pr.a2.y * q.y + pr.a2.z * q.z;
    return vec4<f32>(a0 - pr.kt.x * m, a1 - pr.kt.y * m, a2 - pr.kt.z * m, m);
}

// Bilinear sample of the source grey image with (value, ∂/∂u, ∂/∂v) (`arena_sample`).
fn sample(pr: NccPair, u: f32, v: f32) -> vec3<f32> {
    return arena_sample(pr.grey_offset, pr.grey_width, pr.grey_height, u, v);
}

// Sample k of the patch around reference grey pixel (ci, cj): its reference ray q = (x, y, 1)
// from the ray tables and the reference grey value there.
struct Tap {
    q: vec3<f32>,
    grey: f32,
}

fn patch_tap(k: u32, ci: u32, cj: u32) -> Tap {
    let half = frame.side / 2u;
    let px = ci - half + k % frame.side;
    let py = cj - half + k / frame.side;
    return Tap(vec3<f32>(rays[px], rays[frame.grey_width + py], 1.0), greys[frame.ref_offset + py * frame.grey_width + px]);
}

fn put_result(t: u32, status: u32, cost: f32, gn: vec3<f32>, gd: f32) {
    var r: NccResult;
    r.grad_n = vec4<f32>(gn, 0.0);
    r.status = status;
    r.cost = cost;
    r.grad_d = gd;
    results[t] = r;
}

@compute @workgroup_size(256)
fn ncc_patch(ids: Ids) {
    let t = thread_1d(ids);
    if (t >= pass_.n) {
        return;
    }
    // One dispatch per source: `base` its first entry, `p1` its pair; its entries end where
    // its last row's do (fewer than `n` when the device selected them).
    let e = pass_.base + t;
    if (e >= row_starts[pass_.p1 * (frame.height + 1u) + frame.height]) {
        return;
    }
    let pr = pairs[pass_.p1];
    let p = entries[e];
    let st = surface[p];
    let n = vec3<f32>(st.normal[0], st.normal[1], st.normal[2]);
    let inv_d = 1.0 / st.distance;
    if (!(finite(inv_d) && finite(n.x) && finite(n.y) && finite(n.z))) {
        put_result(e, OUTSIDE, 0.0, vec3<f32>(0.0), 0.0);
        return;
    }
    let s = frame.grey_scale;
    let ci = s * (p % frame.width) + s / 2u;
    let cj = s * (p / frame.width) + s / 2u;
    let count = frame.side * frame.side;
    // Pass 1: the border rules and the patch sums.
    var sr = 0.0;
    var ss = 0.0;
    for (var k = 0u; k < count; k++) {
        let tp = patch_tap(k, ci, cj);
        let w = warp(pr, tp.q, n, inv_d);
        if (!(w.z > 0.0)) {
            put_result(e, OUTSIDE, 0.0, vec3<f32>(0.0), 0.0);
            return;
        }
        let us = w.x / w.z;
        let vs = w.y / w.z;
        if (!(us > 0.0 && us < pr.src_w && vs > 0.0 && vs < pr.src_h)) {
            put_result(e, OUTSIDE, 0.0, vec3<f32>(0.0), 0.0);
            return;
        }
        sr += tp.grey;
        ss += sample(pr, us, vs).x;
    }
    let nf = f32(count);
    let mr = sr / nf;
    let ms = ss / nf;
    // Pass 2: centred moments.
    var cov = 0.0;
    var var_r = 0.0;
    var var_s = 0.0;
    for (var k = 0u; k < count; k++) {
        let tp = patch_tap(k, ci, cj);
        let w = warp(pr, tp.q, n, inv_d);
        let a = tp.grey - mr;
        let b = sample(pr, w.x / w.z, w.y / w.z).x - ms;
        cov += a * b;
        var_r += a * a;
        var_s += b * b;
    }
    // cost and ∂cost/∂s_k = ca·a_k + cb·b_k.
    var cost: f32;
    var ca = 0.0;
    var cb = 0.0;
    if (frame.mode == 0u) {
        let den = var_r * var_s + NCC_EPS;
        let cc = cov * cov / den;
        let raw = 1.0 - cc;
        cost = min(max(raw, 0.0), 2.0);
        if (!(cost < MASK_THRESHOLD) || !finite(cost)) {
            put_result(e, MASKED, 0.0, vec3<f32>(0.0), 0.0);
            return;
        }
        if (raw >= 0.0 && raw <= 2.0) {
            ca = -(2.0 * cov / den);
            cb = 2.0 * cov * cov * var_r / (den * den);
        }
    } else {
        let sq = sqrt(var_r * var_s + NCC_EPS);
        cost = 1.0 - cov / sq;
        if (!finite(cost)) {
            put_result(e, MASKED, 0.0, vec3<f32>(0.0), 0.0);
            return;
        }
        ca = -(1.0 / sq);
        cb = cov * var_r / (sq * sq * sq);
    }
    // Pass 3: back through the samples, the warp and the homography into (Ñ, D).
    var gn = vec3<f32>(0.0);
    var gd = 0.0;
    for (var k = 0u; k < count; k++) {
        let tp = patch_tap(k, ci, cj);
        let q = tp.q;
        let w = warp(pr, q, n, inv_d);
        let smp = sample(pr, w.x / w.z, w.y / w.z);
        let a = tp.grey - mr;
        let b = smp.x - ms;
        let dc_ds = ca * a + cb * b;
        let du = dc_ds * smp.y;
        let dv = dc_ds * smp.z;
        let iz = 1.0 / w.z;
        let dw = vec3<f32>(du * iz, dv * iz, -(du * w.x + dv * w.y) * iz * iz);
        let dm = -(dw.x * pr.kt.x + dw.y * pr.kt.y + dw.z * pr.kt.z);
        let f = dm * inv_d;
        gn += f * q;
        gd -= f * w.w;
    }
    put_result(e, VALID, cost, gn, gd);
}
