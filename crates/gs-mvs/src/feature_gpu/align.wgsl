// L_f on the device: one (reference pixel, source) pair's term υω·|1 − cos(F_r(p_r), F_s(p_s'))|
// and its derivative with respect to the reference plane depth z_r, the twin of the loop body
// of `feature_alignment::feature_loss_with_weights` (docs/method.md §L_f), in the same f32
// operations in the same order. One thread per pair; the channel sums run over the channels in
// order, recomputing the bilinear samples in each pass instead of keeping per-thread arrays.
//
// Generated before this file: `struct AlignFrame` (binding 0), `struct AlignPair`,
// `struct AlignResult`, and the storage bindings `pairs`, `weights` (υω per pixel, source after
// source), `depth` (z_r), `maps` (the feature arena: `[H'][W'][C]` f32 maps at slot offsets)
// and `results`; then `pair_weight(e)` and `ref_depth(p)`, which read `weights` and `depth` as
// the variant binds them (f32 arrays from the host, or L_p's visibility records and the
// rendered surface on the device).

@group(0) @binding(0) var<uniform> frame: AlignFrame;

const NOT_IN_V: u32 = 0u;
const NO_TERM: u32 = 1u;
const TERM: u32 = 2u;

fn finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

// One axis of the clamped bilinear sample (`gs_features` map.rs `axis`): lower and upper tap,
// fraction, and 1 when the derivative across the axis is not zero.
struct Axis {
    i0: u32,
    i1: u32,
    t: f32,
    ok: f32,
}

fn axis(f: f32, n: u32) -> Axis {
    let top = f32(n - 1u);
    if (n == 1u || f <= 0.0) {
        return Axis(0u, 0u, 0.0, 0.0);
    }
    if (f >= top) {
        return Axis(n - 1u, n - 1u, 0.0, 0.0);
    }
    let i = floor(f);
    let i0 = u32(i);
    return Axis(i0, min(i0 + 1u, n - 1u), f - i, 1.0);
}

// The four taps (offsets of channel 0 in `maps`) and weights of a map at image point (u, v).
struct Taps {
    o00: u32,
    o10: u32,
    o01: u32,
    o11: u32,
    tx: f32,
    ty: f32,
    su: f32,
    sv: f32,
}

fn taps(offset: u32, w: u32, h: u32, c: u32, inv_stride: f32, u: f32, v: f32) -> Taps {
    let ax = axis(u * inv_stride - 0.5, w);
    let ay = axis(v * inv_stride - 0.5, h);
    return Taps(
        offset + (ay.i0 * w + ax.i0) * c,
        offset + (ay.i0 * w + ax.i1) * c,
        offset + (ay.i1 * w + ax.i0) * c,
        offset + (ay.i1 * w + ax.i1) * c,
        ax.t,
        ay.t,
        inv_stride * ax.ok,
        inv_stride * ay.ok,
    );
}

// Channel k of a bilinear sample: w00·p00 + w10·p10 + w01·p01 + w11·p11 (map.rs's order).
fn value(t: Taps, k: u32) -> f32 {
    let w00 = (1.0 - t.tx) * (1.0 - t.ty);
    let w10 = t.tx * (1.0 - t.ty);
    let w01 = (1.0 - t.tx) * t.ty;
    let w11 = t.tx * t.ty;
    return w00 * maps[t.o00 + k] + w10 * maps[t.o10 + k] + w01 * maps[t.o01 + k] + w11 * maps[t.o11 + k];
}

// ∂/∂u and ∂/∂v of channel k (per image pixel; 0 across a clamped border).
fn slope(t: Taps, k: u32) -> vec2<f32> {
    let p00 = maps[t.o00 + k];
    let p10 = maps[t.o10 + k];
    let p01 = maps[t.o01 + k];
    let p11 = maps[t.o11 + k];
    let gu = t.su * ((p10 - p00) * (1.0 - t.ty) + (p11 - p01) * t.ty);
    let gv = t.sv * ((p01 - p00) * (1.0 - t.tx) + (p11 - p10) * t.tx);
    return vec2<f32>(gu, gv);
}

@compute @workgroup_size(256)
fn align_pair(ids: Ids) {
    let t = thread_1d(ids);
    if (t >= pass_.n) {
        return;
    }
    let e = pass_.base + t;
    let npix = frame.width * frame.height;
    let k = e / npix;
    let p = e % npix;
    var r = AlignResult(0.0, 0.0, 0.0, NOT_IN_V);
    let wt = pair_weight(e);
    if (!(wt > 0.0)) {
        results[t] = r;
        return;
    }
    r.status = NO_TERM;
    let pr = pairs[k];
    let u = f32(p % frame.width) + 0.5;
    let v = f32(p / frame.width) + 0.5;
    let z = ref_depth(p);
    let ray = vec3<f32>((u - frame.r_cx) / frame.r_fx, (v - frame.r_cy) / frame.r_fy, 1.0);
    let x = vec3<f32>(ray.x * z, ray.y * z, ray.z * z);
    let xs = vec3<f32>(
        pr.r0.x * x.x + pr.r0.y * x.y + pr.r0.z * x.z + pr.t.x,
        pr.r1.x * x.x + pr.r1.y * x.y + pr.r1.z * x.z + pr.t.y,
        pr.r2.x * x.x + pr.r2.y * x.y + pr.r2.z * x.z + pr.t.z,
    );
    if (!(xs.z > 0.0)) {
        results[t] = r;
        return;
    }
    let us = pr.s_fx * xs.x / xs.z + pr.s_cx;
    let vs = pr.s_fy * xs.y / xs.z + pr.s_cy;
    // A point the source cannot sample reads zero features there (map.rs does the same).
    let blind = !(finite(us) && finite(vs));
    let c = frame.channels;
    let ta = taps(frame.ref_offset, frame.ref_w, frame.ref_h, c, frame.ref_inv_stride, u, v);
    let tb = taps(pr.map_offset, pr.map_w, pr.map_h, c, pr.inv_stride, us, vs);
    var aa = 0.0;
    var bb = 0.0;
    var ab = 0.0;
    for (var i = 0u; i < c; i++) {
        let a = value(ta, i);
        let b = select(value(tb, i), 0.0, blind);
        aa = aa + a * a;
        bb = bb + b * b;
        ab = ab + a * b;
    }
    let na = sqrt(aa);
    let nb = sqrt(bb);
    let ma = max(na, frame.eps);
    let mb = max(nb, frame.eps);
    let cosv = ab / (ma * mb);
    let one_minus = 1.0 - cosv;
    if (!finite(one_minus)) {
        results[t] = r;
        return;
    }
    var sign = 0.0;
    if (one_minus > 0.0) {
        sign = 1.0;
    } else if (one_minus < 0.0) {
        sign = -1.0;
    }
    let inv = 1.0 / (ma * mb);
    var kb = 0.0;
    if (nb > frame.eps) {
        kb = cosv / (nb * nb);
    }
    var dcos_du = 0.0;
    var dcos_dv = 0.0;
    for (var i = 0u; i < c; i++) {
        let a = value(ta, i);
        let b = select(value(tb, i), 0.0, blind);
        let s = select(slope(tb, i), vec2<f32>(0.0), blind);
        let dk = a * inv - kb * b;
        dcos_du = dcos_du + dk * s.x;
        dcos_dv = dcos_dv + dk * s.y;
    }
    let dx = vec3<f32>(
        pr.r0.x * ray.x + pr.r0.y * ray.y + pr.r0.z * ray.z,
        pr.r1.x * ray.x + pr.r1.y * ray.y + pr.r1.z * ray.z,
        pr.r2.x * ray.x + pr.r2.y * ray.y + pr.r2.z * ray.z,
    );
    let iz2 = 1.0 / (xs.z * xs.z);
    let du_dz = pr.s_fx * (dx.x * xs.z - xs.x * dx.z) * iz2;
    let dv_dz = pr.s_fy * (dx.y * xs.z - xs.y * dx.z) * iz2;
    r.term = wt * abs(one_minus);
    r.cos = cosv;
    r.grad = -sign * wt * (dcos_du * du_dz + dcos_dv * dv_dz);
    r.status = TERM;
    results[t] = r;
}
