// Forward blend: one workgroup of FWD_THREADS threads per 16x16 tile, thread li owning the
// FWD_PIXELS pixels of column li % 16 in rows li / 16 + (FWD_THREADS / 16) q (both constants
// from the host's tile split, gpu/split.rs; each Gaussian is read once for all of them),
// front to back over the tile's list (the CPU backend's rule: pixel box, alpha = min(0.99,
// o G), skip alpha below the threshold, stop when T (1 - alpha) < 1e-4 without blending).
// The accumulators are written channel-planar (plane c at c * npix): colour 0..3, normal
// 3..6, distance 6, depth 7.
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


@compute @workgroup_size(FWD_THREADS)
fn raster_fwd(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let lx = li % TILE;
    let px = wid.x * TILE + lx;
    let tile_y = wid.y + pass_.base;
    if (px >= cam.width) {
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
    if ((pass_.mode & 1u) != 0u && li == 0u) {
        atomicMax(&counters[LONGEST_TILE_LIST], len);
    }
    let npix = pass_.n;
    let fx = f32(px) + 0.5;
    let color = (cam.flags & 1u) != 0u;
    let geo = (cam.flags & 2u) != 0u;
    let depth = (cam.flags & 4u) != 0u;
    let obs = (cam.flags & 8u) != 0u;
    let lo = pass_.shift;
    let hi = min(pass_.nb, len);
    let first = (pass_.mode & 1u) != 0u;
    let final_window = (pass_.mode & 2u) != 0u;
    var ly: array<u32, FWD_PIXELS>;
    var pix: array<u32, FWD_PIXELS>;
    var a: array<f32, FWD_PIXELS * 8u>;
    var t: array<f32, FWD_PIXELS>;
    var last_k: array<u32, FWD_PIXELS>;
    var done: array<bool, FWD_PIXELS>;
    // Entries of this window each pixel went through (the forward pair count).
    var traversed: array<u32, FWD_PIXELS>;
    var open = 0u;
    for (var q = 0u; q < FWD_PIXELS; q++) {
        ly[q] = li / TILE + (FWD_THREADS / TILE) * q;
        pix[q] = (tile_y * TILE + ly[q] - pass_.base * TILE) * cam.width + px;
        t[q] = 1.0;
        last_k[q] = 0u;
        done[q] = ly[q] >= th;
        for (var c = 0u; c < 8u; c++) {
            a[q * 8u + c] = 0.0;
        }
        if (!done[q] && !first) {
            let p = pix[q];
            for (var c = 0u; c < 8u; c++) {
                a[q * 8u + c] = acc[c * npix + p];
            }
            t[q] = abs(final_t[p]);
            done[q] = final_t[p] < 0.0;
            last_k[q] = last[p];
        }
        traversed[q] = 0u;
        if (!done[q]) {
            open += 1u;
            if (hi > lo) {
                traversed[q] = hi - lo;
            }
        }
    }
    for (var k = lo; k < hi && open > 0u; k++) {
        let gid = gids[start + k];
        let s = splat[gid];
        let sx = s.x;
        let sy = s.y;
        if (!in_box(sx, s.ext_x, x0, tw, lx)) {
            continue;
        }
        let dx = fx - sx;
        for (var q = 0u; q < FWD_PIXELS; q++) {
            if (done[q] || !in_box(sy, s.ext_y, y0, th, ly[q])) {
                continue;
            }
            let dy = f32(y0 + ly[q]) + 0.5 - sy;
            let sigma = 0.5 * (s.conic_a * dx * dx + s.conic_c * dy * dy) + s.conic_b * dx * dy;
            if (!(sigma >= 0.0 && sigma <= s.sigma_max)) {
                continue;
            }
            var alpha = s.opacity * exp_neg(sigma);
            if (alpha < cam.threshold) {
                continue;
            }
            alpha = min(alpha, MAX_ALPHA);
            let tq = t[q];
            let next_t = tq * (1.0 - alpha);
            if (next_t < T_STOP) {
                traversed[q] = k + 1u - lo;
                done[q] = true;
                open -= 1u;
                continue;
            }
            let w = alpha * tq;
            let o = q * 8u;
            if (color) {
                a[o] += w * s.channels[0];
                a[o + 1u] += w * s.channels[1];
                a[o + 2u] += w * s.channels[2];
            }
            if (geo) {
                // The geometry cut (RenderRequest::geometry_cut): blend only while T > cut.
                var wg = w;
                if (cam.geometry_cut > 0.0) {
                    wg = max(tq - max(next_t, cam.geometry_cut), 0.0);
                }
                a[o + 3u] += wg * s.channels[3];
                a[o + 4u] += wg * s.channels[4];
                a[o + 5u] += wg * s.channels[5];
                a[o + 6u] += wg * s.channels[6];
            }
            if (depth) {
                a[o + 7u] += w * s.channels[7];
            }
            if (obs && tq > 0.5) {
                atomicAdd(&observed[gid], 1u);
            }
            t[q] = next_t;
            last_k[q] = k + 1u;
        }
    }
    for (var q = 0u; q < FWD_PIXELS; q++) {
        if (ly[q] >= th) {
            continue;
        }
        let p = pix[q];
        for (var c = 0u; c < 8u; c++) {
            acc[c * npix + p] = a[q * 8u + c];
        }
        if (done[q] && !final_window) {
            final_t[p] = -t[q];
        } else {
            final_t[p] = t[q];
        }
        last[p] = last_k[q];
        add64(4u, traversed[q]);
        if (final_window) {
            add64(6u, last_k[q]);
            // The longest list position blended (the backward's window count): an integer
            // maximum, the same in any order.
            atomicMax(&counters[LONGEST_BLEND], last_k[q]);
        }
    }
}
