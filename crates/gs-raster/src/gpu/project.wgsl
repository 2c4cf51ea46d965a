// Projection of one Gaussian per thread (chunked over Gaussians: the per-Gaussian arrays are
// bound from `pass_.base` on, keys/vals/counters whole).

// The tiles [first, end) along one axis of `tiles` whose pixels have centres within `half`
// of `c` (the twin of project.rs's `tile_span`).
fn tile_span(c: f32, half: f32, tiles: u32) -> vec2<u32> {
    let ts = f32(TILE);
    let first = u32(clamp(floor((c - half - 0.5) / ts), 0.0, f32(tiles)));
    let end = max(i32(clamp(floor((c + half - 0.5) / ts), -1.0, f32(tiles) - 1.0)) + 1, 0);
    return vec2<u32>(first, u32(end));
}

@compute @workgroup_size(256)
fn project(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= pass_.n) {
        return;
    }
    let gi = pass_.base + i;
    keys[gi] = INVISIBLE;
    vals[gi] = gi;
    proj[i] = TileRect();
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
    // Visible when the square of the radius reaches a tile; listed only in the tiles of the
    // α-threshold box one pixel wider (the twin of project.rs).
    let sx = tile_span(x, radius_f, cam.tiles_x);
    let sy = tile_span(y, radius_f, cam.tiles_y);
    if (sx.x >= sx.y || sy.x >= sy.y) {
        return;
    }
    let bx = tile_span(x, ext_x + 1.0, cam.tiles_x);
    let by = tile_span(y, ext_y + 1.0, cam.tiles_y);
    let tx0 = max(bx.x, sx.x);
    let tx1 = max(min(bx.y, sx.y), tx0);
    let ty0 = max(by.x, sy.x);
    let ty1 = max(min(by.y, sy.y), ty0);
    let channels = array<f32, 8>(
        it.color.x, it.color.y, it.color.z, it.n_c.x, it.n_c.y, it.n_c.z, it.dist, t.z,
    );
    splat[i] = Splat(x, y, it.conic.x, it.conic.y, it.conic.z, it.opacity, sigma_max, ext_x, ext_y, channels);
    let radius = u32(min(radius_f, 4294967040.0));
    proj[i] = TileRect(tx0, ty0, tx1, ty1, radius);
    radii[i] = radius;
    keys[gi] = bitcast<u32>(t.z);
    atomicAdd(&counters[0], 1u);
}
