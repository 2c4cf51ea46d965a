// Forward blend: one workgroup per 16x16 tile, one thread per pixel, front to back over the
// tile's list (the CPU backend's rule: pixel box, alpha = min(0.99, o G), skip alpha below
// the threshold, stop when T (1 - alpha) < 1e-4 without blending). The accumulators are
// written channel-planar (plane c at c * npix): colour 0..3, normal 3..6, distance 6, depth 7.
// A geometry cut (cam.geometry_cut > 0) blends normal and distance only while T exceeds it.
//
// The list is walked in windows of list positions [pass_.shift, pass_.nb), one dispatch per
// window, with the per-pixel state (accumulators, T, last) kept in the output buffers between
// windows and "done" stored as the sign of T (T > 0 always): software Vulkan (llvmpipe) caps
// the loop iterations of one invocation at 65535, and a bounded dispatch is also kinder to
// GPU watchdogs. pass_.mode: 1 = first window, 2 = last window.
//
// Images whose per-pixel buffers exceed one storage binding are processed in bands of tile
// rows: rows [pass_.base, ...) with the per-pixel buffers bound from the band's first pixel;
// pass_.n is the band's pixel count (the plane stride).

fn add64(i: u32, v: u32) {
    let old = atomicAdd(&counters[i], v);
    if (old + v < old) {
        atomicAdd(&counters[i + 1u], 1u);
    }
}

@compute @workgroup_size(16, 16)
fn raster_fwd(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>) {
    let px = wid.x * TILE + lid.x;
    let tile_y = wid.y + pass_.base;
    let py = tile_y * TILE + lid.y;
    if (px >= cam.width || py >= cam.height) {
        return;
    }
    let tile = tile_y * cam.tiles_x + wid.x;
    let x0 = wid.x * TILE;
    let y0 = tile_y * TILE;
    let tw = min(cam.width - x0, TILE);
    let th = min(cam.height - y0, TILE);
    let start = ranges[2u * tile];
    let len = ranges[2u * tile + 1u] - start;
    // The longest tile list (a render that guessed its window count checks it at readback).
    if ((pass_.mode & 1u) != 0u && lid.x == 0u && lid.y == 0u) {
        atomicMax(&counters[LONGEST_TILE_LIST], len);
    }
    let npix = pass_.n;
    let p = (py - pass_.base * TILE) * cam.width + px;
    let fx = f32(px) + 0.5;
    let fy = f32(py) + 0.5;
    let color = (cam.flags & 1u) != 0u;
    let geo = (cam.flags & 2u) != 0u;
    let depth = (cam.flags & 4u) != 0u;
    let obs = (cam.flags & 8u) != 0u;
    let lo = pass_.shift;
    let hi = min(pass_.nb, len);
    let first = (pass_.mode & 1u) != 0u;
    let final_window = (pass_.mode & 2u) != 0u;
    var a = array<f32, 8>(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    var t = 1.0;
    var last_k = 0u;
    var done = false;
    if (!first) {
        for (var c = 0u; c < 8u; c++) {
            a[c] = acc[c * npix + p];
        }
        t = final_t[p];
        done = t < 0.0;
        t = abs(t);
        last_k = last[p];
    }
    // Entries of this window the pixel went through (the forward pair count).
    var traversed = 0u;
    if (!done && hi > lo) {
        traversed = hi - lo;
    }
    for (var k = lo; k < hi && !done; k++) {
        let gid = gids[start + k];
        let s = splat[gid];
        let sx = s.x;
        let sy = s.y;
        if (!in_box(sx, s.ext_x, x0, tw, lid.x) || !in_box(sy, s.ext_y, y0, th, lid.y)) {
            continue;
        }
        let dx = fx - sx;
        let dy = fy - sy;
        let sigma = 0.5 * (s.conic_a * dx * dx + s.conic_c * dy * dy) + s.conic_b * dx * dy;
        if (!(sigma >= 0.0 && sigma <= s.sigma_max)) {
            continue;
        }
        var alpha = s.opacity * exp_neg(sigma);
        if (alpha < cam.threshold) {
            continue;
        }
        alpha = min(alpha, MAX_ALPHA);
        let next_t = t * (1.0 - alpha);
        if (next_t < T_STOP) {
            traversed = k + 1u - lo;
            done = true;
            break;
        }
        let w = alpha * t;
        if (color) {
            a[0] += w * s.channels[0];
            a[1] += w * s.channels[1];
            a[2] += w * s.channels[2];
        }
        if (geo) {
            // The geometry cut (RenderRequest::geometry_cut): blend only while T > cut.
            var wg = w;
            if (cam.geometry_cut > 0.0) {
                wg = max(t - max(next_t, cam.geometry_cut), 0.0);
            }
            a[3] += wg * s.channels[3];
            a[4] += wg * s.channels[4];
            a[5] += wg * s.channels[5];
            a[6] += wg * s.channels[6];
        }
        if (depth) {
            a[7] += w * s.channels[7];
        }
        if (obs && t > 0.5) {
            atomicAdd(&observed[gid], 1u);
        }
        t = next_t;
        last_k = k + 1u;
    }
    for (var c = 0u; c < 8u; c++) {
        acc[c * npix + p] = a[c];
    }
    if (done && !final_window) {
        final_t[p] = -t;
    } else {
        final_t[p] = t;
    }
    last[p] = last_k;
    add64(4u, traversed);
    if (final_window) {
        add64(6u, last_k);
        // The longest list position blended (the backward's window count): an integer
        // maximum, the same in any order.
        atomicMax(&counters[LONGEST_BLEND], last_k);
    }
}
