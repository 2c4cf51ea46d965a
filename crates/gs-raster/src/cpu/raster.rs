//! Tile binning, the per-tile forward blend, the per-tile backward (reverse traversal), and the
//! naive per-pixel reference.

use super::project::{Features, Splat, SplatGrad};
use crate::{MAX_ALPHA, RasterError, T_STOP, TILE_SIZE};
use rayon::prelude::*;

const TS: usize = TILE_SIZE as usize;
const TP: usize = TS * TS;

/// `exp(−x)` for `x ≥ 0`, inlined (the libm call dominated the blend loop): 2^n·e^f with
/// n = round(−x·log2 e), Cody–Waite reduction |f| ≲ ln2/2 and a degree-6 Taylor polynomial
/// (relative error ≤ 3e-7, f32 rounding level). Arguments beyond 87 return 0. Every path (tiled forward,
/// backward, naive reference) calls this same function.
#[inline(always)]
pub(crate) fn exp_neg(x: f32) -> f32 {
    if !(x < 87.0) {
        return 0.0;
    }
    let t = -x * std::f32::consts::LOG2_E;
    let n = (t - 0.5) as i32; // round(t) for t ≤ 0 (truncation toward zero)
    let nf = n as f32;
    // Cody–Waite reduction f = −x − n·ln2 with ln2 split in two (Cephes): n·C1 is exact.
    let f = (-x - nf * 0.693_359_4) + nf * 2.121_944_4e-4; // |f| ≲ ln2 / 2
    let p = 1.0
        + f * (1.0
            + f * (0.5
                + f * (1.0 / 6.0 + f * (1.0 / 24.0 + f * (1.0 / 120.0 + f * (1.0 / 720.0))))));
    p * f32::from_bits(((n + 127) as u32) << 23)
}

/// Alpha of `s` at offset `(dx, dy)` = pixel centre − mean, and whether it hit the 0.99 cap.
/// `None` when α < alpha_threshold (tested first as σ > ln(o/threshold), so the decision is
/// identical in every path that calls this function).
#[inline(always)]
pub(crate) fn alpha_at(s: &Splat, dx: f32, dy: f32, threshold: f32) -> Option<(f32, bool)> {
    let sigma = 0.5 * (s.ca * dx * dx + s.cc * dy * dy) + s.cb * dx * dy;
    if !(sigma >= 0.0 && sigma <= s.sigma_max) {
        return None;
    }
    let a = s.opacity * exp_neg(sigma);
    if a < threshold {
        return None;
    }
    if a > MAX_ALPHA {
        Some((MAX_ALPHA, true))
    } else {
        Some((a, false))
    }
}

/// Gaussians binned into tiles: for tile `t`, `ids[offsets[t]..offsets[t + 1]]` are its
/// Gaussians sorted by (depth, index), as positions in the depth order (the splat arrays are
/// compacted in that order, so every tile reads them at increasing addresses).
#[derive(Clone, Default)]
pub(crate) struct Bins {
    pub offsets: Vec<u32>,
    pub ids: Vec<u32>,
}

impl Bins {
    #[inline]
    pub fn tile(&self, t: usize) -> &[u32] {
        &self.ids[self.offsets[t] as usize..self.offsets[t + 1] as usize]
    }
}

/// Depth sort (key: depth bits, index) + stable counting sort over tiles. Returns the
/// visible Gaussians in depth order and the bins (holding positions in that order).
pub(crate) fn bin(
    visible: &[u32],
    depth: &[f32],
    rects: &[[u32; 4]],
    tiles_x: u32,
    tiles_y: u32,
    cap: usize,
) -> Result<(Vec<u32>, Bins), RasterError> {
    // Depths are > near > 0, so their bit patterns order like the values.
    let mut keys: Vec<u64> = visible
        .iter()
        .map(|&i| ((depth[i as usize].to_bits() as u64) << 32) | i as u64)
        .collect();
    keys.par_sort_unstable();
    let order: Vec<u32> = keys.iter().map(|&k| k as u32).collect();
    let n_tiles = (tiles_x * tiles_y) as usize;
    let mut counts = vec![0u32; n_tiles + 1];
    let mut total: u64 = 0;
    for &i in &order {
        let [x0, y0, x1, y1] = rects[i as usize];
        total += (x1 - x0) as u64 * (y1 - y0) as u64;
    }
    if total > cap as u64 || total > u32::MAX as u64 {
        return Err(RasterError::TooManyIntersections { count: total, cap });
    }
    for &i in &order {
        let [x0, y0, x1, y1] = rects[i as usize];
        for ty in y0..y1 {
            let row = (ty * tiles_x) as usize;
            for tx in x0..x1 {
                counts[row + tx as usize + 1] += 1;
            }
        }
    }
    for t in 0..n_tiles {
        counts[t + 1] += counts[t];
    }
    let mut cursor = counts.clone();
    let mut ids = vec![0u32; total as usize];
    for (k, &i) in order.iter().enumerate() {
        let [x0, y0, x1, y1] = rects[i as usize];
        for ty in y0..y1 {
            let row = (ty * tiles_x) as usize;
            for tx in x0..x1 {
                let c = &mut cursor[row + tx as usize];
                ids[*c as usize] = k as u32;
                *c += 1;
            }
        }
    }
    Ok((
        order,
        Bins {
            offsets: counts,
            ids,
        },
    ))
}

/// Which channels a pass blends (const-generic flags keep unused channels free).
pub(crate) struct Ctx<'a> {
    pub splats: &'a [Splat],
    pub features: &'a [Features],
    pub bins: &'a Bins,
    pub width: u32,
    pub height: u32,
    pub tiles_x: u32,
    pub threshold: f32,
    /// [`crate::RenderRequest::geometry_cut`] (0: blend every contribution).
    pub geometry_cut: f32,
}

/// Per-pixel results of one tile (tile-local row-major, `tw × th`).
pub(crate) struct TileOut {
    pub acc: Vec<[f32; 8]>,
    pub final_t: Vec<f32>,
    pub last: Vec<u32>,
    pub traversed: Vec<u32>,
    /// Per tile-list entry: pixels it reached while T > 0.5 (when requested).
    pub observed: Vec<u32>,
    /// Σ over entries of the pixel box area inside the tile (work estimate).
    pub box_pairs: u64,
}

#[inline(always)]
fn tile_geometry(ctx: &Ctx, tile: usize) -> (usize, usize, usize, usize) {
    let tx = tile % ctx.tiles_x as usize;
    let ty = tile / ctx.tiles_x as usize;
    let x0 = tx * TS;
    let y0 = ty * TS;
    let tw = (ctx.width as usize - x0).min(TS);
    let th = (ctx.height as usize - y0).min(TS);
    (x0, y0, tw, th)
}

/// Pixel box `[lx0, lx1) × [ly0, ly1)` (tile-local) that can hold pixels with α ≥ threshold.
#[inline(always)]
pub(crate) fn pixel_box(
    s: &Splat,
    x0: usize,
    y0: usize,
    tw: usize,
    th: usize,
) -> (usize, usize, usize, usize) {
    // Clamp first (to [-1, size]), then floor by truncation: no libm call, no overflow.
    #[inline(always)]
    fn floor_clamped(v: f32, hi: usize) -> i32 {
        let v = v.clamp(-1.0, hi as f32);
        let i = v as i32;
        if (i as f32) > v { i - 1 } else { i }
    }
    let fx0 = x0 as f32;
    let fy0 = y0 as f32;
    let lx0 = floor_clamped(s.x - s.ext_x - 0.5 - fx0, tw).max(0) as usize;
    let lx1 = (floor_clamped(s.x + s.ext_x - 0.5 - fx0, tw) + 1).clamp(0, tw as i32) as usize;
    let ly0 = floor_clamped(s.y - s.ext_y - 0.5 - fy0, th).max(0) as usize;
    let ly1 = (floor_clamped(s.y + s.ext_y - 0.5 - fy0, th) + 1).clamp(0, th as i32) as usize;
    (lx0, lx1, ly0, ly1)
}

/// The weight of a contribution in the geometry channels: its blend weight `w` = αT, or under a
/// transmittance cut `cut` > 0 ([`crate::RenderRequest::geometry_cut`]) the part of T → T′
/// above the cut (the twin of raster_fwd.wgsl's).
#[inline(always)]
pub(crate) fn geometry_weight(w: f32, t: f32, next_t: f32, cut: f32) -> f32 {
    if cut > 0.0 { (t - next_t.max(cut)).max(0.0) } else { w }
}

/// Front-to-back blend of one tile.
pub(crate) fn forward_tile<
    const COLOR: bool,
    const GEO: bool,
    const DEPTH: bool,
    const OBS: bool,
>(
    ctx: &Ctx,
    tile: usize,
) -> TileOut {
    let (x0, y0, tw, th) = tile_geometry(ctx, tile);
    let list = ctx.bins.tile(tile);
    let npix = tw * th;
    let mut acc = [[0.0f32; 8]; TP];
    let mut tr = [1.0f32; TP];
    let mut last = [0u32; TP];
    let mut traversed = [list.len() as u32; TP];
    let mut done = [false; TP];
    let mut n_done = 0usize;
    let mut observed = if OBS {
        vec![0u32; list.len()]
    } else {
        Vec::new()
    };
    let mut box_pairs = 0u64;
    let thr = ctx.threshold;
    let cut = ctx.geometry_cut;
    for (k, &gid) in list.iter().enumerate() {
        if n_done == npix {
            break;
        }
        let s = &ctx.splats[gid as usize];
        let f = &ctx.features[gid as usize];
        let (lx0, lx1, ly0, ly1) = pixel_box(s, x0, y0, tw, th);
        if lx0 >= lx1 || ly0 >= ly1 {
            continue;
        }
        box_pairs += ((lx1 - lx0) * (ly1 - ly0)) as u64;
        let mut obs = 0u32;
        for ly in ly0..ly1 {
            let dy = (y0 + ly) as f32 + 0.5 - s.y;
            let row = ly * TS;
            for lx in lx0..lx1 {
                let p = row + lx;
                if done[p] {
                    continue;
                }
                let dx = (x0 + lx) as f32 + 0.5 - s.x;
                let Some((alpha, _)) = alpha_at(s, dx, dy, thr) else {
                    continue;
                };
                let t = tr[p];
                let next_t = t * (1.0 - alpha);
                if next_t < T_STOP {
                    done[p] = true;
                    n_done += 1;
                    traversed[p] = k as u32 + 1;
                    continue;
                }
                let w = alpha * t;
                let a = &mut acc[p];
                if COLOR {
                    a[0] += w * f[0];
                    a[1] += w * f[1];
                    a[2] += w * f[2];
                }
                if GEO {
                    let wg = geometry_weight(w, t, next_t, cut);
                    a[3] += wg * f[3];
                    a[4] += wg * f[4];
                    a[5] += wg * f[5];
                    a[6] += wg * f[6];
                }
                if DEPTH {
                    a[7] += w * f[7];
                }
                if OBS && t > 0.5 {
                    obs += 1;
                }
                tr[p] = next_t;
                last[p] = k as u32 + 1;
            }
        }
        if OBS {
            observed[k] = obs;
        }
    }
    // Compact to tile-local `tw × th`.
    let mut out = TileOut {
        acc: Vec::with_capacity(npix),
        final_t: Vec::with_capacity(npix),
        last: Vec::with_capacity(npix),
        traversed: Vec::with_capacity(npix),
        observed,
        box_pairs,
    };
    for ly in 0..th {
        for lx in 0..tw {
            let p = ly * TS + lx;
            out.acc.push(acc[p]);
            out.final_t.push(tr[p]);
            out.last.push(last[p]);
            out.traversed.push(traversed[p]);
        }
    }
    out
}

/// Per-pixel inputs of the backward for one tile (tile-local `tw × th`, row-major).
pub(crate) struct TileGradIn {
    /// ∂L/∂(blended channel) per pixel (colour, Ñ, D, Σ w t_z), already folded with plane and
    /// expected depth.
    pub g_ch: Vec<[f32; 8]>,
    /// ∂L/∂T_final-term coefficient: g_A_eff − bg·g_C.
    pub g_final: Vec<f32>,
}

/// Per-pixel data the backward reads from the forward (image-sized).
pub(crate) struct PixelState<'a> {
    pub final_t: &'a [f32],
    pub last: &'a [u32],
}

/// Reverse traversal of one tile: returns one gradient record per contributing Gaussian.
pub(crate) fn backward_tile<const COLOR: bool, const GEO: bool, const DEPTH: bool>(
    ctx: &Ctx,
    tile: usize,
    px: &PixelState,
    gin: &TileGradIn,
) -> Vec<(u32, SplatGrad)> {
    let (x0, y0, tw, th) = tile_geometry(ctx, tile);
    let list = ctx.bins.tile(tile);
    let w = ctx.width as usize;
    let mut tr = [0.0f32; TP];
    let mut tf = [0.0f32; TP];
    let mut last = [0u32; TP];
    let mut behind = [[0.0f32; 8]; TP];
    let mut gch = [[0.0f32; 8]; TP];
    let mut gfin = [0.0f32; TP];
    let mut max_last = 0u32;
    for ly in 0..th {
        for lx in 0..tw {
            let gp = (y0 + ly) * w + x0 + lx;
            let lp = ly * tw + lx;
            let p = ly * TS + lx;
            tr[p] = px.final_t[gp];
            tf[p] = px.final_t[gp];
            last[p] = px.last[gp];
            max_last = max_last.max(last[p]);
            gch[p] = gin.g_ch[lp];
            gfin[p] = gin.g_final[lp];
        }
    }
    let thr = ctx.threshold;
    let mut out = Vec::new();
    for k in (0..max_last as usize).rev() {
        let gid = list[k];
        let s = &ctx.splats[gid as usize];
        let f = &ctx.features[gid as usize];
        let (lx0, lx1, ly0, ly1) = pixel_box(s, x0, y0, tw, th);
        if lx0 >= lx1 || ly0 >= ly1 {
            continue;
        }
        let mut g = SplatGrad::default();
        let mut any = false;
        for ly in ly0..ly1 {
            let dy = (y0 + ly) as f32 + 0.5 - s.y;
            let row = ly * TS;
            for lx in lx0..lx1 {
                let p = row + lx;
                if k as u32 >= last[p] {
                    continue;
                }
                let dx = (x0 + lx) as f32 + 0.5 - s.x;
                let Some((alpha, capped)) = alpha_at(s, dx, dy, thr) else {
                    continue;
                };
                any = true;
                let one_minus = 1.0 - alpha;
                let t = tr[p] / one_minus;
                tr[p] = t;
                let wgt = alpha * t;
                let b = &mut behind[p];
                let gc = &gch[p];
                let mut dl_da = 0.0f32;
                if COLOR {
                    for ch in 0..3 {
                        dl_da += (f[ch] - b[ch]) * gc[ch];
                        b[ch] = alpha * f[ch] + one_minus * b[ch];
                        g.features[ch] += wgt * gc[ch];
                    }
                }
                if GEO {
                    for ch in 3..7 {
                        dl_da += (f[ch] - b[ch]) * gc[ch];
                        b[ch] = alpha * f[ch] + one_minus * b[ch];
                        g.features[ch] += wgt * gc[ch];
                    }
                }
                if DEPTH {
                    dl_da += (f[7] - b[7]) * gc[7];
                    b[7] = alpha * f[7] + one_minus * b[7];
                    g.features[7] += wgt * gc[7];
                }
                dl_da = dl_da * t + tf[p] / one_minus * gfin[p];
                if !capped {
                    let gexp = alpha / s.opacity; // exp(−σ)
                    g.opacity += gexp * dl_da;
                    let dl_dsigma = -alpha * dl_da;
                    g.conic[0] += dl_dsigma * 0.5 * dx * dx;
                    g.conic[1] += dl_dsigma * dx * dy;
                    g.conic[2] += dl_dsigma * 0.5 * dy * dy;
                    // dx = pixel − mean, so ∂σ/∂mean = −(Q d).
                    let gx = -dl_dsigma * (s.ca * dx + s.cb * dy);
                    let gy = -dl_dsigma * (s.cb * dx + s.cc * dy);
                    g.xy[0] += gx;
                    g.xy[1] += gy;
                    g.abs_xy[0] += gx.abs();
                    g.abs_xy[1] += gy.abs();
                }
            }
        }
        if any {
            out.push((gid, g));
        }
    }
    out
}

/// Naive reference blend of one pixel: every Gaussian of `order` (depth-sorted), no tiles.
/// Returns (acc, final T, observed ids).
#[allow(clippy::too_many_arguments)]
pub(crate) fn naive_pixel(
    splats: &[Splat],
    features: &[Features],
    order: &[u32],
    px: f32,
    py: f32,
    threshold: f32,
    geometry_cut: f32,
    observed: &mut [u32],
) -> ([f32; 8], f32) {
    let mut acc = [0.0f32; 8];
    let mut t = 1.0f32;
    for &gid in order {
        let s = &splats[gid as usize];
        let Some((alpha, _)) = alpha_at(s, px - s.x, py - s.y, threshold) else {
            continue;
        };
        let next_t = t * (1.0 - alpha);
        if next_t < T_STOP {
            break;
        }
        let f = &features[gid as usize];
        let w = alpha * t;
        let wg = geometry_weight(w, t, next_t, geometry_cut);
        for ch in 0..8 {
            acc[ch] += if (3..7).contains(&ch) { wg } else { w } * f[ch];
        }
        if t > 0.5 {
            observed[gid as usize] += 1;
        }
        t = next_t;
    }
    (acc, t)
}

/// Runs the forward over all tiles in parallel with the right monomorphisation.
pub(crate) fn forward_tiles(
    ctx: &Ctx,
    color: bool,
    geo: bool,
    depth: bool,
    obs: bool,
) -> Vec<TileOut> {
    let n_tiles = ctx.bins.offsets.len() - 1;
    macro_rules! run {
        ($c:literal, $g:literal, $d:literal, $o:literal) => {
            (0..n_tiles)
                .into_par_iter()
                .map(|t| forward_tile::<$c, $g, $d, $o>(ctx, t))
                .collect()
        };
    }
    match (color, geo, depth, obs) {
        (true, false, false, false) => run!(true, false, false, false),
        (true, true, false, false) => run!(true, true, false, false),
        (true, true, true, false) => run!(true, true, true, false),
        (true, false, true, false) => run!(true, false, true, false),
        (false, false, false, false) => run!(false, false, false, false),
        (false, true, false, false) => run!(false, true, false, false),
        (false, true, true, false) => run!(false, true, true, false),
        (false, false, true, false) => run!(false, false, true, false),
        (true, false, false, true) => run!(true, false, false, true),
        (true, true, false, true) => run!(true, true, false, true),
        (true, true, true, true) => run!(true, true, true, true),
        (true, false, true, true) => run!(true, false, true, true),
        (false, false, false, true) => run!(false, false, false, true),
        (false, true, false, true) => run!(false, true, false, true),
        (false, true, true, true) => run!(false, true, true, true),
        (false, false, true, true) => run!(false, false, true, true),
    }
}

/// Runs the backward over all tiles in parallel; `gin(tile)` builds a tile's gradient inputs.
pub(crate) fn backward_tiles(
    ctx: &Ctx,
    px: &PixelState,
    gin: &(dyn Fn(usize) -> TileGradIn + Sync),
    color: bool,
    geo: bool,
    depth: bool,
) -> Vec<Vec<(u32, SplatGrad)>> {
    let n_tiles = ctx.bins.offsets.len() - 1;
    macro_rules! run {
        ($c:literal, $g:literal, $d:literal) => {
            (0..n_tiles)
                .into_par_iter()
                .map(|t| {
                    if ctx.bins.offsets[t] == ctx.bins.offsets[t + 1] {
                        return Vec::new();
                    }
                    backward_tile::<$c, $g, $d>(ctx, t, px, &gin(t))
                })
                .collect()
        };
    }
    match (color, geo, depth) {
        (true, false, false) => run!(true, false, false),
        (true, true, false) => run!(true, true, false),
        (true, true, true) => run!(true, true, true),
        (true, false, true) => run!(true, false, true),
        (false, false, false) => run!(false, false, false),
        (false, true, false) => run!(false, true, false),
        (false, true, true) => run!(false, true, true),
        (false, false, true) => run!(false, false, true),
    }
}
