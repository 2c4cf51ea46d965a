// L_p's visibility on the device (docs/method.md §Visibility), the twin of
// `visibility::visibility_at` and of the candidate rule of `photometric::select_pixels`:
// - `visibility_pixels`, one thread per (source, reference pixel): υ and ω from the reference's plane
//   depth (the rendered surface's z) and the source's plane depth (bilinear, in the arena), the
//   host's arithmetic in the host's order; the pixel is a candidate when it lies a half patch
//   inside the image and υω > 0.
// - `visibility_rows`, one thread per (source, row): the row's counts of υ, ω > 0 and candidates and its
//   sum of ω over υ (compensated f32, in order), which the totals (totals.wgsl) or, under the
//   sampling cap, the host add up, and which the selection reads.
//
// Generated before this file: `struct NccFrame` (binding 0), `struct VisPair`,
// `struct SurfaceTexel`, `struct VisTexel`, `struct VisRow`, the storage bindings `vis_pairs`,
// `surface`, `greys` (the arena: each source's plane depth at its pair's offset), `vis` and
// `vis_rows`, then `sampling.wgsl`.

@group(0) @binding(0) var<uniform> frame: NccFrame;

const UPSILON: u32 = 1u;
const OMEGA: u32 = 2u;
const CANDIDATE: u32 = 4u;

// R_rs x (`geometry::mat_vec`).
fn rotate(pr: VisPair, x: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(
        pr.r0.x * x.x + pr.r0.y * x.y + pr.r0.z * x.z,
        pr.r1.x * x.x + pr.r1.y * x.y + pr.r1.z * x.z,
        pr.r2.x * x.x + pr.r2.y * x.y + pr.r2.z * x.z,
    );
}

// R_rsᵀ x (`geometry::mat_t_vec`).
fn rotate_back(pr: VisPair, x: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(
        pr.r0.x * x.x + pr.r1.x * x.y + pr.r2.x * x.z,
        pr.r0.y * x.x + pr.r1.y * x.y + pr.r2.y * x.z,
        pr.r0.z * x.x + pr.r1.z * x.y + pr.r2.z * x.z,
    );
}

// (υ, ω) of reference pixel centre (u, v) with plane depth z (`visibility_at`).
fn visibility(pr: VisPair, u: f32, v: f32, z: f32) -> vec2<f32> {
    if (!(z > 0.0) || !finite(z)) {
        return vec2<f32>(0.0, 0.0);
    }
    let ray = vec3<f32>((u - pr.ref_k.z) / pr.ref_k.x, (v - pr.ref_k.w) / pr.ref_k.y, 1.0);
    let y = rotate(pr, vec3<f32>(ray.x * z, ray.y * z, ray.z * z));
    let xs = vec3<f32>(y.x + pr.t.x, y.y + pr.t.y, y.z + pr.t.z);
    if (!(xs.z > 0.0)) {
        return vec2<f32>(0.0, 0.0);
    }
    let us = pr.src_k.x * xs.x / xs.z + pr.src_k.z;
    let vs = pr.src_k.y * xs.y / xs.z + pr.src_k.w;
    if (!(us > 0.0 && us < pr.src_w && vs > 0.0 && vs < pr.src_h)) {
        return vec2<f32>(0.0, 0.0);
    }
    let zs = arena_sample(pr.depth_offset, pr.depth_width, pr.depth_height, us, vs).x;
    if (!(zs > 0.0) || !finite(zs)) {
        return vec2<f32>(1.0, 0.0);
    }
    let rs = vec3<f32>((us - pr.src_k.z) / pr.src_k.x, (vs - pr.src_k.w) / pr.src_k.y, 1.0);
    let xr = rotate_back(pr, vec3<f32>(rs.x * zs - pr.t.x, rs.y * zs - pr.t.y, rs.z * zs - pr.t.z));
    if (!(xr.z > 0.0)) {
        return vec2<f32>(1.0, 0.0);
    }
    let ur = pr.ref_k.x * xr.x / xr.z + pr.ref_k.z;
    let vr = pr.ref_k.y * xr.y / xr.z + pr.ref_k.w;
    let du = u - ur;
    let dv = v - vr;
    let phi = sqrt(du * du + dv * dv);
    if (phi < 1.0) {
        return vec2<f32>(1.0, exp(-phi));
    }
    return vec2<f32>(1.0, 0.0);
}

@compute @workgroup_size(256)
fn visibility_pixels(ids: Ids) {
    let t = thread_1d(ids);
    if (t >= frame.sources * frame.pixels) {
        return;
    }
    let k = t / frame.pixels;
    let p = t % frame.pixels;
    let x = p % frame.width;
    let y = p / frame.width;
    let r = visibility(vis_pairs[k], f32(x) + 0.5, f32(y) + 0.5, surface[p].z);
    let weight = select(0.0, r.y, r.x > 0.0);
    var flags = select(0u, UPSILON, r.x > 0.0) | select(0u, OMEGA, r.y > 0.0);
    let half = frame.side / 2u;
    let inner = frame.width > 2u * half && frame.height > 2u * half
        && x >= half && x < frame.width - half && y >= half && y < frame.height - half;
    if (inner && weight > 0.0) {
        flags |= CANDIDATE;
    }
    vis[t] = VisTexel(weight, flags);
}

@compute @workgroup_size(256)
fn visibility_rows(ids: Ids) {
    let t = thread_1d(ids);
    if (t >= frame.sources * frame.height) {
        return;
    }
    let k = t / frame.height;
    let y = t % frame.height;
    let first = k * frame.pixels + y * frame.width;
    var row = VisRow(0u, 0u, 0u, 0.0);
    var omega = vec2<f32>(0.0);
    for (var x = 0u; x < frame.width; x++) {
        let v = vis[first + x];
        if ((v.flags & UPSILON) != 0u) {
            row.upsilon += 1u;
            omega = kahan_add(omega, v.weight);
        }
        if ((v.flags & OMEGA) != 0u) {
            row.omega_positive += 1u;
        }
        if ((v.flags & CANDIDATE) != 0u) {
            row.candidates += 1u;
        }
    }
    row.omega_sum = omega.x;
    vis_rows[t] = row;
}
