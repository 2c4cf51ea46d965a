// Projection of one Gaussian per thread (chunked over Gaussians: the per-Gaussian arrays are
// bound from `pass_.base` on, keys/vals/counters whole).

@compute @workgroup_size(256)
fn project(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= pass_.n) {
        return;
    }
    let gi = pass_.base + i;
    keys[gi] = INVISIBLE;
    vals[gi] = gi;
    for (var k = 0u; k < 5u; k++) {
        proj[i * 5u + k] = 0u;
    }
    radii[i] = 0u;
    let it = internals(i, read_param(i));
    if (!it.ok) {
        return;
    }
    let t = it.t;
    let x = cam.fx * t.x / t.z + cam.cx;
    let y = cam.fy * t.y / t.z + cam.cy;
    let sigma_max = log(it.opacity / cam.threshold);
    let level = sqrt(max(2.0 * sigma_max, 0.0));
    let a = it.cov.x;
    let c = it.cov.z;
    let mid = 0.5 * (a + c);
    let lambda_max = mid + sqrt(max(mid * mid - it.det, 0.0));
    let radius_f = ceil(level * sqrt(lambda_max));
    let ext_x = level * sqrt(a);
    let ext_y = level * sqrt(c);
    let finite = is_finite(x) && is_finite(y) && radius_f > 0.0 && is_finite(radius_f)
        && is_finite(ext_x) && is_finite(ext_y) && finite3(it.color) && finite3(it.n_c)
        && is_finite(it.dist) && finite3(it.conic);
    if (!finite) {
        return;
    }
    let ts = f32(TILE);
    let tx0 = u32(clamp(floor((x - radius_f - 0.5) / ts), 0.0, f32(cam.tiles_x)));
    let tx1 = max(i32(clamp(floor((x + radius_f - 0.5) / ts), -1.0, f32(cam.tiles_x) - 1.0)) + 1, 0);
    let ty0 = u32(clamp(floor((y - radius_f - 0.5) / ts), 0.0, f32(cam.tiles_y)));
    let ty1 = max(i32(clamp(floor((y + radius_f - 0.5) / ts), -1.0, f32(cam.tiles_y) - 1.0)) + 1, 0);
    if (tx0 >= u32(tx1) || ty0 >= u32(ty1)) {
        return;
    }
    let o = i * SPLAT_STRIDE;
    splat[o] = x;
    splat[o + 1u] = y;
    splat[o + 2u] = it.conic.x;
    splat[o + 3u] = it.conic.y;
    splat[o + 4u] = it.conic.z;
    splat[o + 5u] = it.opacity;
    splat[o + 6u] = sigma_max;
    splat[o + 7u] = ext_x;
    splat[o + 8u] = ext_y;
    splat[o + 9u] = it.color.x;
    splat[o + 10u] = it.color.y;
    splat[o + 11u] = it.color.z;
    splat[o + 12u] = it.n_c.x;
    splat[o + 13u] = it.n_c.y;
    splat[o + 14u] = it.n_c.z;
    splat[o + 15u] = it.dist;
    splat[o + 16u] = t.z;
    proj[i * 5u] = tx0;
    proj[i * 5u + 1u] = ty0;
    proj[i * 5u + 2u] = u32(tx1);
    proj[i * 5u + 3u] = u32(ty1);
    proj[i * 5u + 4u] = u32(min(radius_f, 4294967040.0));
    radii[i] = proj[i * 5u + 4u];
    keys[gi] = bitcast<u32>(t.z);
    atomicAdd(&counters[0], 1u);
}
