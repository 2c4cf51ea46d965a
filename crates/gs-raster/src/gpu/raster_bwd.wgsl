// Backward blend: one workgroup of 128 threads per 16x16 tile, each thread owning pixels
// (x, y) and (x, y + 8). The tile list is walked back to front from the largest last
// contributor (3DGS reverse traversal from T_final); per Gaussian the 16 gradient components
// of the tile's pixels are reduced in workgroup memory (in a fixed order) and written as the
// `ScreenGrad` partial of that intersection, at its tile-list position; `grad_reduce` then
// sums each Gaussian's partials in a fixed order. No float atomics: the result repeats bit
// for bit. List positions at or beyond a tile's largest last contributor are never visited:
// their partials stay as cleared (zeros).
// Components: xy (0, 1), conic (2..5), opacity (5), features (6..14), |xy| (14, 15).
//
// Like the forward, the traversal runs in windows of list positions [pass_.shift, pass_.nb),
// last window first, with the per-pixel state (T, the 8 "behind" sums) kept in `bstate`
// between dispatches. A tile whose list ends below a window skips it; the first window that
// reaches into its list (window end >= its largest last contributor) starts from T_final.
// Bands of tile rows as in the forward (pass_.base = first tile row; per-pixel buffers bound
// from the band's first pixel).

var<workgroup> red: array<f32, 2048>;
var<workgroup> ml_atomic: atomic<u32>;
var<workgroup> ml_plain: u32;

@compute @workgroup_size(128)
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
    var lxs: array<u32, 2>;
    var lys: array<u32, 2>;
    var valid: array<bool, 2>;
    var tr: array<f32, 2>;
    var tf: array<f32, 2>;
    var lastq: array<u32, 2>;
    var gfin: array<f32, 2>;
    var behind = array<f32, 16>(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    var gch: array<f32, 16>;
    var my_max = 0u;
    for (var q = 0u; q < 2u; q++) {
        lxs[q] = li % 16u;
        lys[q] = li / 16u + 8u * q;
        valid[q] = lxs[q] < tw && lys[q] < th;
        if (valid[q]) {
            let p = (y0 - yb + lys[q]) * cam.width + x0 + lxs[q];
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
        for (var q = 0u; q < 2u; q++) {
            if (valid[q]) {
                let p = (y0 - yb + lys[q]) * cam.width + x0 + lxs[q];
                let bs = bstate[p];
                tr[q] = bs.t;
                for (var c = 0u; c < 8u; c++) {
                    behind[q * 8u + c] = bs.behind[c];
                }
            }
        }
    }
    for (var kk = lo; kk < hi; kk++) {
        let k = hi - 1u - (kk - lo);
        let gid = gids[start + k];
        let s = splat[gid];
        let sx = s.x;
        let sy = s.y;
        let ca = s.conic_a;
        let cb = s.conic_b;
        let cc = s.conic_c;
        let op = s.opacity;
        let smax = s.sigma_max;
        let ex = s.ext_x;
        let ey = s.ext_y;
        var f = s.channels;
        var g: array<f32, 16>;
        for (var c = 0u; c < 16u; c++) {
            g[c] = 0.0;
        }
        for (var q = 0u; q < 2u; q++) {
            if (!valid[q] || k >= lastq[q]) {
                continue;
            }
            if (!in_box(sx, ex, x0, tw, lxs[q]) || !in_box(sy, ey, y0, th, lys[q])) {
                continue;
            }
            let dx = f32(x0 + lxs[q]) + 0.5 - sx;
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
                    g[6u + c] += wgt * gc;
                }
            }
            dl_da = dl_da * t + tf[q] / one_minus * gfin[q];
            if (!capped) {
                let gexp = alpha / op;
                g[5] += gexp * dl_da;
                let dl_dsigma = -alpha * dl_da;
                g[2] += dl_dsigma * 0.5 * dx * dx;
                g[3] += dl_dsigma * dx * dy;
                g[4] += dl_dsigma * 0.5 * dy * dy;
                let gx = -dl_dsigma * (ca * dx + cb * dy);
                let gy = -dl_dsigma * (cb * dx + cc * dy);
                g[0] += gx;
                g[1] += gy;
                g[14] += abs(gx);
                g[15] += abs(gy);
            }
        }
        for (var c = 0u; c < 16u; c++) {
            red[c * 128u + li] = g[c];
        }
        workgroupBarrier();
        // Two-level reduction: 128 threads sum 16 values each (component li / 8, segment
        // li % 8), then 16 threads sum the 8 segment sums of their component.
        {
            let base = (li / 8u) * 128u + (li % 8u) * 16u;
            var s = 0.0;
            for (var j = 0u; j < 16u; j++) {
                s += red[base + j];
            }
            red[base] = s;
        }
        workgroupBarrier();
        if (li < 16u) {
            var s = 0.0;
            for (var j = 0u; j < 8u; j++) {
                s += red[li * 128u + j * 16u];
            }
            red[li * 128u] = s;
        }
        workgroupBarrier();
        // Only thread 0 writes red[c * 128] in the next iteration, so it may read the sums
        // after the barrier without another one.
        if (li == 0u) {
            partials[start + k] = ScreenGrad(
                vec2<f32>(red[0], red[128]),
                vec2<f32>(red[14u * 128u], red[15u * 128u]),
                red[2u * 128u],
                red[3u * 128u],
                red[4u * 128u],
                red[5u * 128u],
                vec4<f32>(red[6u * 128u], red[7u * 128u], red[8u * 128u], red[9u * 128u]),
                vec4<f32>(red[10u * 128u], red[11u * 128u], red[12u * 128u], red[13u * 128u]),
            );
        }
    }
    for (var q = 0u; q < 2u; q++) {
        if (valid[q]) {
            let p = (y0 - yb + lys[q]) * cam.width + x0 + lxs[q];
            var bs: BlendState;
            bs.t = tr[q];
            for (var c = 0u; c < 8u; c++) {
                bs.behind[c] = behind[q * 8u + c];
            }
            bstate[p] = bs;
        }
    }
}
