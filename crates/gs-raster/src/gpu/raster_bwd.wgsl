// Backward blend: one workgroup of BWD_THREADS threads per 16x16 tile; thread li owns the
// PIXELS pixels of column li % 16 in rows li / 16 + (BWD_THREADS / 16) q. The tile list is
// walked back to front from the largest last contributor (3DGS reverse traversal from
// T_final), GROUP Gaussians per round: each thread sums a Gaussian's 16 gradient components
// over its own pixels (in row order), the round's GROUP x 16 x BWD_THREADS values meet in
// workgroup memory, each of them is summed over the threads in thread order, and the sums
// are written as the `ScreenGrad` partials of those intersections at their tile-list
// positions; `grad_reduce` then sums each Gaussian's partials in a fixed order. No float
// atomics: the result repeats bit for bit. Two barriers per round of GROUP Gaussians (the
// first version reduced over 128 threads with three barriers per Gaussian; barriers are what
// software Vulkan emulates slowest, and what a long list pays for on any GPU). List
// positions at or beyond a tile's largest last contributor are never visited: their
// partials stay as cleared (zeros).
// Components: xy (0, 1), conic (2..5), opacity (5), features (6..14), |xy| (14, 15).
//
// Like the forward, the traversal runs in windows of list positions [pass_.shift, pass_.nb),
// last window first, with the per-pixel state (T, the 8 "behind" sums) kept in `bstate`
// between dispatches. A tile whose list ends below a window skips it; the first window that
// reaches into its list (window end >= its largest last contributor) starts from T_final.
// Bands of tile rows as in the forward (pass_.base = first tile row; per-pixel buffers bound
// from the band's first pixel).

// BWD_THREADS, PIXELS (= 256 / BWD_THREADS) and GROUP come from the host (gpu/split.rs).
const COMPONENTS: u32 = 16u;

// The round's values, [GROUP][COMPONENTS][BWD_THREADS], and their sums over the threads.
var<workgroup> red: array<f32, GROUP * COMPONENTS * BWD_THREADS>;
var<workgroup> sums: array<f32, GROUP * COMPONENTS>;
var<workgroup> ml_atomic: atomic<u32>;
var<workgroup> ml_plain: u32;

@compute @workgroup_size(BWD_THREADS)
fn raster_bwd(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let tile_y = wid.y + pass_.base;
    let tile = tile_y * cam.tiles_x + wid.x;
    let x0 = wid.x * TILE;
    let y0 = tile_y * TILE;
    let yb = pass_.base * TILE;
    let tw = min(cam.width - x0, TILE);
    let th = min(cam.height - y0, TILE);
    let start = ranges[2u * tile];
    let color = (cam.flags & 1u) != 0u;
    let geo = (cam.flags & 2u) != 0u;
    let depth = (cam.flags & 4u) != 0u;
    let lx = li % TILE;
    var lys: array<u32, PIXELS>;
    var valid: array<bool, PIXELS>;
    var tr: array<f32, PIXELS>;
    var tf: array<f32, PIXELS>;
    var lastq: array<u32, PIXELS>;
    var gfin: array<f32, PIXELS>;
    var behind: array<f32, PIXELS * 8u>;
    var gch: array<f32, PIXELS * 8u>;
    var my_max = 0u;
    for (var q = 0u; q < PIXELS; q++) {
        lys[q] = li / TILE + (BWD_THREADS / TILE) * q;
        valid[q] = lx < tw && lys[q] < th;
        for (var c = 0u; c < 8u; c++) {
            behind[q * 8u + c] = 0.0;
            gch[q * 8u + c] = 0.0;
        }
        if (valid[q]) {
            let p = (y0 - yb + lys[q]) * cam.width + x0 + lx;
            tr[q] = final_t[p];
            tf[q] = final_t[p];
            lastq[q] = last[p];
            let pg = pixel_grad(p);
            for (var c = 0u; c < 8u; c++) {
                gch[q * 8u + c] = pg.channels[c];
            }
            gfin[q] = pg.final_t;
            my_max = max(my_max, lastq[q]);
        }
    }
    atomicMax(&ml_atomic, my_max);
    workgroupBarrier();
    if (li == 0u) {
        ml_plain = atomicLoad(&ml_atomic);
    }
    let ml = workgroupUniformLoad(&ml_plain);
    let lo = pass_.shift;
    if (lo >= ml) {
        return;
    }
    let hi = min(pass_.nb, ml);
    if (pass_.nb < ml) {
        for (var q = 0u; q < PIXELS; q++) {
            if (valid[q]) {
                let p = (y0 - yb + lys[q]) * cam.width + x0 + lx;
                let bs = bstate[p];
                tr[q] = bs.t;
                for (var c = 0u; c < 8u; c++) {
                    behind[q * 8u + c] = bs.behind[c];
                }
            }
        }
    }
    var top = hi;
    while (top > lo) {
        let n_round = min(GROUP, top - lo);
        var g: array<f32, GROUP * COMPONENTS>;
        for (var i = 0u; i < GROUP * COMPONENTS; i++) {
            g[i] = 0.0;
        }
        for (var b = 0u; b < n_round; b++) {
            let k = top - 1u - b;
            let s = splat[gids[start + k]];
            let sx = s.x;
            let sy = s.y;
            let ca = s.conic_a;
            let cb = s.conic_b;
            let cc = s.conic_c;
            let op = s.opacity;
            let smax = s.sigma_max;
            let ex = s.ext_x;
            let ey = s.ext_y;
            let f = s.channels;
            let o = b * COMPONENTS;
            // The thread's pixels share a column: outside its box in x, none is touched.
            if (!in_box(sx, ex, x0, tw, lx)) {
                continue;
            }
            let dx = f32(x0 + lx) + 0.5 - sx;
            for (var q = 0u; q < PIXELS; q++) {
                if (!valid[q] || k >= lastq[q] || !in_box(sy, ey, y0, th, lys[q])) {
                    continue;
                }
                let dy = f32(y0 + lys[q]) + 0.5 - sy;
                let sigma = 0.5 * (ca * dx * dx + cc * dy * dy) + cb * dx * dy;
                if (!(sigma >= 0.0 && sigma <= smax)) {
                    continue;
                }
                var alpha = op * exp_neg(sigma);
                if (alpha < cam.threshold) {
                    continue;
                }
                let capped = alpha > MAX_ALPHA;
                alpha = min(alpha, MAX_ALPHA);
                let one_minus = 1.0 - alpha;
                let t = tr[q] / one_minus;
                tr[q] = t;
                let wgt = alpha * t;
                var dl_da = 0.0;
                for (var c = 0u; c < 8u; c++) {
                    let on = (c < 3u && color) || (c >= 3u && c < 7u && geo) || (c == 7u && depth);
                    if (on) {
                        let bi = q * 8u + c;
                        let gc = gch[bi];
                        dl_da += (f[c] - behind[bi]) * gc;
                        behind[bi] = alpha * f[c] + one_minus * behind[bi];
                        g[o + 6u + c] += wgt * gc;
                    }
                }
                dl_da = dl_da * t + tf[q] / one_minus * gfin[q];
                if (!capped) {
                    let gexp = alpha / op;
                    g[o + 5u] += gexp * dl_da;
                    let dl_dsigma = -alpha * dl_da;
                    g[o + 2u] += dl_dsigma * 0.5 * dx * dx;
                    g[o + 3u] += dl_dsigma * dx * dy;
                    g[o + 4u] += dl_dsigma * 0.5 * dy * dy;
                    let gx = -dl_dsigma * (ca * dx + cb * dy);
                    let gy = -dl_dsigma * (cb * dx + cc * dy);
                    g[o] += gx;
                    g[o + 1u] += gy;
                    g[o + 14u] += abs(gx);
                    g[o + 15u] += abs(gy);
                }
            }
        }
        for (var i = 0u; i < GROUP * COMPONENTS; i++) {
            red[i * BWD_THREADS + li] = g[i];
        }
        workgroupBarrier();
        // Each (Gaussian, component) of the round summed over the threads in thread order.
        for (var i = li; i < GROUP * COMPONENTS; i += BWD_THREADS) {
            var sum = 0.0;
            for (var j = 0u; j < BWD_THREADS; j++) {
                sum += red[i * BWD_THREADS + j];
            }
            sums[i] = sum;
        }
        workgroupBarrier();
        // The next round writes `sums` only after its first barrier, which every thread
        // reaches after these reads.
        if (li < n_round) {
            let o = li * COMPONENTS;
            partials[start + top - 1u - li] = ScreenGrad(
                vec2<f32>(sums[o], sums[o + 1u]),
                vec2<f32>(sums[o + 14u], sums[o + 15u]),
                sums[o + 2u],
                sums[o + 3u],
                sums[o + 4u],
                sums[o + 5u],
                vec4<f32>(sums[o + 6u], sums[o + 7u], sums[o + 8u], sums[o + 9u]),
                vec4<f32>(sums[o + 10u], sums[o + 11u], sums[o + 12u], sums[o + 13u]),
            );
        }
        top -= n_round;
    }
    for (var q = 0u; q < PIXELS; q++) {
        if (valid[q]) {
            let p = (y0 - yb + lys[q]) * cam.width + x0 + lx;
            var bs: BlendState;
            bs.t = tr[q];
            for (var c = 0u; c < 8u; c++) {
                bs.behind[c] = behind[q * 8u + c];
            }
            bstate[p] = bs;
        }
    }
}
