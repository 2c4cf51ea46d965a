//! Multi-view photometric alignment L_p (docs/method.md §L_p) with its exact backward pass.
//!
//! For every reference pixel p_r whose whole patch lies inside the reference image and whose
//! weight υ_rs·ω is positive, the patch of the grey GT reference image (exact pixel values) is
//! compared with the grey GT source image sampled bilinearly at the patch pixel centres warped
//! by the per-pixel homography H_rs = K_s (R_rs − t_rs Ñᵀ/D) K_r⁻¹ (Ñ unnormalised). The pixel
//! is excluded for that source if any warped sample has a third homogeneous component ≤ 0 or
//! falls outside the open rectangle (0, W_s) × (0, H_s).
//!
//! NCC ([`NccMode`]) works on patch **sums** with centred (two-pass) moments:
//! cov = Σ a·b, var_r = Σ a², var_s = Σ b² (a, b the mean-removed reference and source values).
//!
//! L_p,s = Σ_V υω·cost / |V| per source and L_p = Σ_s L_p,s (**summed** over sources, as the
//! paper says). The weight λ3 = 0.15 is applied by the caller. Gradients flow through the
//! bilinear sample positions and the homography into Ñ and D of the reference view; υ, ω, the
//! pixel set and the NCC mask are constants, so ∂L_p/∂z (plane depth) is zero by construction.
//!
//! **Grey images at a higher resolution** (PGSR's `ncc_scale`): a grey image may be an integer
//! multiple s ∈ 1..=4 of its camera's size (s·W × s·H, the same s on both axes; reference and
//! sources each their own). The patch of reference pixel (i, j) is then taken around the
//! high-resolution pixel (s·i + ⌊s/2⌋, s·j + ⌊s/2⌋) with one high-resolution pixel per step
//! (exact values, as PGSR's `pixels / ncc_scale + offsets`), and warped with the homography of
//! the cameras resized to the grey images. The plane (Ñ, D) is camera-space and resolution-free,
//! so only the patch footprint shrinks (finer texture, s× smaller baseline in pixels); for even
//! s the patch centre sits half a high-resolution pixel from the training pixel's centre, which
//! the per-pixel plane makes harmless.

use crate::error::{MvsError, Result};
use crate::geometry::{MapView, PairGeometry, dot3, sample_bilinear_grad};
use crate::Real;
use crate::visibility::{Visibility, VisibilityStats, check_weights, visibility_unchecked};
use gs_core::{Camera, Image, Rng};
use rayon::prelude::*;

/// The ε added to var_r·var_s in the NCC (relative to patch sums, as PGSR's `lncc`).
pub const NCC_EPS: f64 = 1e-8;
/// PGSR's mask: patches with cost ≥ this are dropped in [`NccMode::Pgsr`].
pub const NCC_MASK_THRESHOLD: f64 = 0.9;
/// Default cap on the pixels per source (PGSR's `sample_num`).
pub const DEFAULT_MAX_PIXELS_PER_SOURCE: usize = 102_400;
/// The largest accepted patch size.
pub const MAX_PATCH_SIZE: usize = 9;

/// Which NCC cost per patch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum NccMode {
    /// PGSR's `lncc` (default): cc = cov² / (var_r·var_s + 1e-8), cost = clamp(1 − cc, 0, 2),
    /// patches with cost ≥ 0.9 are masked out. Squared correlation: insensitive to the sign, so
    /// contrast inversions are not penalised, and low-texture patches drop out through the mask.
    #[default]
    Pgsr,
    /// The paper's formula read literally (`--ncc plain`): ρ = cov / √(var_r·var_s + 1e-8),
    /// cost = 1 − ρ ∈ [0, 2], no clamp and no mask: every pixel passing the border rules counts,
    /// anti-correlated patches cost up to 2 and flat patches cost 1 with zero gradient.
    Plain,
}

gs_core::named_choices!(NccMode, "NCC reading", { NccMode::Pgsr => "pgsr", NccMode::Plain => "plain" });

/// Options of [`photometric_loss`].
#[derive(Debug, Clone, PartialEq)]
pub struct PhotometricConfig {
    /// Patch side, odd, 3–9 (7).
    pub patch_size: usize,
    /// NCC cost ([`NccMode::Pgsr`]).
    pub ncc: NccMode,
    /// At most this many candidate pixels (patch inside the reference, υω > 0) per source are
    /// evaluated, drawn uniformly without replacement; `None` evaluates all (reference
    /// conformance). Default 102,400 (PGSR). Applied before the patch border and NCC mask
    /// rules, as PGSR does, so the cost is bounded.
    pub max_pixels_per_source: Option<usize>,
    /// Seed of the sampling cap (source k uses `Rng::new(seed).fork(k)`); vary it per iteration.
    pub seed: u64,
}

impl Default for PhotometricConfig {
    fn default() -> Self {
        Self {
            patch_size: 7,
            ncc: NccMode::Pgsr,
            max_pixels_per_source: Some(DEFAULT_MAX_PIXELS_PER_SOURCE),
            seed: 0,
        }
    }
}

impl PhotometricConfig {
    /// Checks the patch size (odd, 3–9) and the cap (> 0).
    pub fn validate(&self) -> Result<()> {
        if self.patch_size % 2 == 0 || !(3..=MAX_PATCH_SIZE).contains(&self.patch_size) {
            return Err(MvsError::InvalidConfig(format!(
                "patch_size must be odd in 3..=9, got {}",
                self.patch_size
            )));
        }
        if self.max_pixels_per_source == Some(0) {
            return Err(MvsError::InvalidConfig(
                "max_pixels_per_source must be positive (or None)".into(),
            ));
        }
        Ok(())
    }
}

/// The reference view's rendered maps (gradients flow into `normal` and `distance`) and its
/// grey GT image. All maps are `W×H` of `camera`, except `grey`, which may be `s·W × s·H` for an
/// integer s in 1..=4 (see the module docs).
#[derive(Debug, Clone, Copy)]
pub struct PhotometricReference<'a, T> {
    /// Reference camera.
    pub camera: &'a Camera,
    /// Rendered normal Ñ, camera space, unnormalised, 3 channels.
    pub normal: MapView<'a, T>,
    /// Rendered distance D, 1 channel.
    pub distance: MapView<'a, T>,
    /// Plane depth z = D / (−Ñ·r + 1e-8), 1 channel (used for υ, ω only).
    pub plane_depth: MapView<'a, T>,
    /// Grey GT reference image (0.299R + 0.587G + 0.114B), 1 channel, W×H or s·W × s·H.
    pub grey: MapView<'a, T>,
}

/// One source view: its camera, its rendered plane depth (no gradient) and grey GT image.
#[derive(Debug, Clone, Copy)]
pub struct PhotometricSource<'a, T> {
    /// Source camera.
    pub camera: &'a Camera,
    /// Rendered plane depth of the source view, 1 channel (for ω only).
    pub plane_depth: MapView<'a, T>,
    /// Grey GT source image, 1 channel, W_s×H_s or s·W_s × s·H_s.
    pub grey: MapView<'a, T>,
}

/// Statistics of one source view.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SourceStats {
    /// υ/ω counts over all reference pixels.
    pub visibility: VisibilityStats,
    /// Pixels whose patch lies inside the reference and whose υω > 0.
    pub n_candidates: usize,
    /// Candidates evaluated after the sampling cap.
    pub n_sampled: usize,
    /// Evaluated pixels whose warped samples all lie inside the source (w_z > 0).
    pub n_inside_source: usize,
    /// |V|: pixels that count (inside, finite cost, and cost < 0.9 for [`NccMode::Pgsr`]).
    pub n_valid: usize,
    /// Σ_V υω·cost (the numerator).
    pub weighted_cost_sum: f64,
    /// Σ_V cost (unweighted).
    pub cost_sum: f64,
    /// L_p,s = weighted_cost_sum / |V| (0 when V is empty).
    pub loss: f64,
}

/// L_p and its gradients with respect to the reference's rendered maps.
#[derive(Debug, Clone, PartialEq)]
pub struct PhotometricOutput<T> {
    /// L_p = Σ_s L_p,s (not multiplied by λ3).
    pub loss: f64,
    /// One entry per source view, in input order.
    pub per_source: Vec<SourceStats>,
    /// ∂L_p/∂Ñ, `[H][W][3]`.
    pub grad_normal: Vec<T>,
    /// ∂L_p/∂D, `[H][W]`.
    pub grad_distance: Vec<T>,
    /// Reference width.
    pub width: usize,
    /// Reference height.
    pub height: usize,
}

impl<T: Real> PhotometricOutput<T> {
    /// The gradients as f32 images `(∂L_p/∂Ñ [3 ch], ∂L_p/∂D [1 ch])`.
    pub fn grad_images(&self) -> (Image, Image) {
        let conv = |v: &[T]| v.iter().map(|x| x.to_f64() as f32).collect::<Vec<f32>>();
        (
            Image::from_vec(self.width, self.height, 3, conv(&self.grad_normal))
                .expect("sizes set by construction"),
            Image::from_vec(self.width, self.height, 1, conv(&self.grad_distance))
                .expect("sizes set by construction"),
        )
    }
}

pub(crate) fn check_inputs<T>(
    reference: &PhotometricReference<'_, T>,
    sources: &[PhotometricSource<'_, T>],
    config: &PhotometricConfig,
) -> Result<()> {
    let cam = reference.camera;
    reference.normal.expect_size(cam, 3, "reference normal")?;
    reference
        .distance
        .expect_size(cam, 1, "reference distance")?;
    check_views((cam, &reference.plane_depth, &reference.grey), sources, config)
}

/// The checks of L_p's inputs besides the reference's rendered plane (shared with the device
/// twin's reference on the device): the configuration, the reference's plane depth and grey
/// image, and each source's.
pub(crate) fn check_views<T>(
    (cam, plane_depth, grey): (&Camera, &MapView<'_, T>, &MapView<'_, T>),
    sources: &[PhotometricSource<'_, T>],
    config: &PhotometricConfig,
) -> Result<()> {
    config.validate()?;
    plane_depth.expect_size(cam, 1, "reference plane_depth")?;
    grey_scale(grey, cam, "reference grey image")?;
    for (k, s) in sources.iter().enumerate() {
        s.plane_depth
            .expect_size(s.camera, 1, &format!("source {k} plane_depth"))?;
        grey_scale(&s.grey, s.camera, &format!("source {k} grey image"))?;
    }
    Ok(())
}

/// Largest accepted grey-image resolution multiple.
pub const MAX_GREY_SCALE: usize = 4;

/// The integer multiple s (1..=4) of the camera's size that a grey image has.
fn grey_scale<T>(grey: &MapView<'_, T>, camera: &Camera, name: &str) -> Result<usize> {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let s = grey.width / w.max(1);
    if grey.channels != 1 || s == 0 || s > MAX_GREY_SCALE || grey.width != s * w || grey.height != s * h {
        return Err(MvsError::SizeMismatch {
            map: name.to_string(),
            expected: format!("{w}x{h}x1 or an integer multiple s·{w} x s·{h} x 1 with s in 1..={MAX_GREY_SCALE}"),
            got: format!("{}x{}x{}", grey.width, grey.height, grey.channels),
        });
    }
    Ok(s)
}

/// The cameras whose pixels are the grey images' pixels, and the reference grey scale, of the
/// reference `camera` with its `grey` image and a source.
pub(crate) fn patch_geometry<T: Real>(
    (camera, grey): (&Camera, &MapView<'_, T>),
    source: &PhotometricSource<'_, T>,
) -> Result<(PairGeometry<T>, usize)> {
    let sr = grey_scale(grey, camera, "reference grey image")?;
    let ss = grey_scale(&source.grey, source.camera, "source grey image")?;
    if sr == 1 && ss == 1 {
        return Ok((PairGeometry::new(camera, source.camera), 1));
    }
    let up = |c: &Camera, s: usize| c.resized(c.width * s as u32, c.height * s as u32).map_err(|e| MvsError::InvalidInput(e.to_string()));
    Ok((PairGeometry::new(&up(camera, sr)?, &up(source.camera, ss)?), sr))
}

/// L_p over `sources` with υ and ω computed from the plane depths (docs/method.md §L_p, §Visibility).
/// An empty source list gives L_p = 0 and zero gradients (views with no neighbours).
pub fn photometric_loss<T: Real>(
    reference: &PhotometricReference<'_, T>,
    sources: &[PhotometricSource<'_, T>],
    config: &PhotometricConfig,
) -> Result<PhotometricOutput<T>> {
    check_inputs(reference, sources, config)?;
    let weights: Vec<Visibility<T>> = sources
        .iter()
        .map(|s| {
            visibility_unchecked(
                &PairGeometry::new(reference.camera, s.camera),
                &reference.plane_depth,
                &s.plane_depth,
            )
        })
        .collect();
    photometric_loss_with_weights(reference, sources, &weights, config)
}

/// L_p with precomputed (e.g. frozen) υ/ω maps, one per source. The sources' plane depths are
/// not read.
pub fn photometric_loss_with_weights<T: Real>(
    reference: &PhotometricReference<'_, T>,
    sources: &[PhotometricSource<'_, T>],
    weights: &[Visibility<T>],
    config: &PhotometricConfig,
) -> Result<PhotometricOutput<T>> {
    check_inputs(reference, sources, config)?;
    check_weights(weights, sources.len(), reference.camera)?;
    let (w, h) = (
        reference.camera.width as usize,
        reference.camera.height as usize,
    );
    let mut out = PhotometricOutput {
        loss: 0.0,
        per_source: Vec::with_capacity(sources.len()),
        grad_normal: vec![T::ZERO; w * h * 3],
        grad_distance: vec![T::ZERO; w * h],
        width: w,
        height: h,
    };
    let mut scratch_n = vec![T::ZERO; w * h * 3];
    let mut scratch_d = vec![T::ZERO; w * h];
    for (k, (source, vis)) in sources.iter().zip(weights).enumerate() {
        let (g, grey_scale) = patch_geometry((reference.camera, &reference.grey), source)?;
        let selected = select_pixels(vis, config, k, w, h);
        let (stats, any) = source_pass(
            reference,
            source,
            &g,
            grey_scale,
            vis,
            &selected,
            config,
            &mut scratch_n,
            &mut scratch_d,
        );
        let mut stats = SourceStats {
            visibility: vis.stats(),
            ..stats
        };
        if stats.n_valid > 0 {
            stats.loss = stats.weighted_cost_sum / stats.n_valid as f64;
            out.loss += stats.loss;
            if any {
                let scale = T::from_f64(1.0 / stats.n_valid as f64);
                out.grad_normal
                    .par_iter_mut()
                    .zip(scratch_n.par_iter())
                    .for_each(|(o, s)| *o += *s * scale);
                out.grad_distance
                    .par_iter_mut()
                    .zip(scratch_d.par_iter())
                    .for_each(|(o, s)| *o += *s * scale);
            }
        }
        out.per_source.push(stats);
    }
    Ok(out)
}

/// Marks the candidate pixels (patch inside the reference, υω > 0), applying the sampling cap.
/// Returns one byte per pixel: 0 = not a candidate, 1 = candidate not sampled, 2 = evaluated.
pub(crate) fn select_pixels<T: Real>(
    vis: &Visibility<T>,
    config: &PhotometricConfig,
    k: usize,
    w: usize,
    h: usize,
) -> Vec<u8> {
    let half = config.patch_size / 2;
    let mut sel = vec![0u8; w * h];
    let mut candidates = Vec::new();
    if w > 2 * half && h > 2 * half {
        for j in half..h - half {
            for i in half..w - half {
                let p = j * w + i;
                if vis.weight(p) > T::ZERO {
                    candidates.push(p);
                }
            }
        }
    }
    match drawn_candidates(candidates.len(), config, k) {
        Some(drawn) => {
            for &p in &candidates {
                sel[p] = 1;
            }
            for c in drawn {
                sel[candidates[c]] = 2;
            }
        }
        None => {
            for &p in &candidates {
                sel[p] = 2;
            }
        }
    }
    sel
}

/// Which of source `k`'s `n` candidates (ranks in row-major order) are evaluated: `None` for all
/// of them (within the cap), else the cap's number drawn without replacement with the seed
/// (`Rng::new(seed).fork(k)`). The host's selection and the device's (which draws here from
/// the device's candidate counts) share it, so both evaluate the same patches.
pub(crate) fn drawn_candidates(n: usize, config: &PhotometricConfig, k: usize) -> Option<Vec<usize>> {
    match config.max_pixels_per_source {
        Some(cap) if n > cap => Some(Rng::new(config.seed).fork(k as u64).choose_distinct(n, cap)),
        _ => None,
    }
}

/// Result of one patch.
pub(crate) enum PatchResult<T> {
    /// A warped sample left the source image (or w_z ≤ 0, or non-finite input).
    Outside,
    /// Inside, but masked (cost ≥ 0.9 in PGSR mode, or a non-finite cost).
    Masked,
    /// Counted: cost and ∂cost/∂Ñ, ∂cost/∂D.
    Valid { cost: T, grad_n: [T; 3], grad_d: T },
}

const M: usize = MAX_PATCH_SIZE * MAX_PATCH_SIZE;

/// Per-sample arrays of [`patch_cost`], allocated once per image row rather than zeroed per
/// patch (each call writes the `patch²` entries it reads).
pub(crate) struct PatchScratch<T> {
    rv: [T; M],
    sv: [T; M],
    gu: [T; M],
    gv: [T; M],
    wv: [[T; 3]; M],
    mv: [T; M],
}

impl<T: Real> PatchScratch<T> {
    pub(crate) fn new() -> Self {
        Self {
            rv: [T::ZERO; M],
            sv: [T::ZERO; M],
            gu: [T::ZERO; M],
            gv: [T::ZERO; M],
            wv: [[T::ZERO; 3]; M],
            mv: [T::ZERO; M],
        }
    }
}

/// The NCC cost of one reference pixel's patch and its gradient with respect to (Ñ, D).
#[inline]
#[allow(clippy::too_many_arguments)]
pub(crate) fn patch_cost<T: Real>(
    g: &PairGeometry<T>,
    rays: &(Vec<T>, Vec<T>),
    ref_grey: &MapView<'_, T>,
    src_grey: &MapView<'_, T>,
    n: [T; 3],
    d: T,
    i: usize,
    j: usize,
    patch: usize,
    mode: NccMode,
    scratch: &mut PatchScratch<T>,
) -> PatchResult<T> {
    let inv_d = T::ONE / d;
    if !(inv_d.is_finite() && n[0].is_finite() && n[1].is_finite() && n[2].is_finite()) {
        return PatchResult::Outside;
    }
    let half = patch / 2;
    let count = patch * patch;
    let PatchScratch { rv, sv, gu, gv, wv, mv } = scratch;
    let mut k = 0;
    for py in j - half..=j + half {
        let qy = rays.1[py];
        for px in i - half..=i + half {
            let q = [rays.0[px], qy, T::ONE];
            let (wh, m) = g.warp(q, n, inv_d);
            if !(wh[2] > T::ZERO) {
                return PatchResult::Outside;
            }
            let us = wh[0] / wh[2];
            let vs = wh[1] / wh[2];
            if !g.inside_source(us, vs) {
                return PatchResult::Outside;
            }
            let (s, du, dv) =
                sample_bilinear_grad(src_grey.data, src_grey.width, src_grey.height, us, vs);
            rv[k] = ref_grey.data[py * ref_grey.width + px];
            sv[k] = s;
            gu[k] = du;
            gv[k] = dv;
            wv[k] = wh;
            mv[k] = m;
            k += 1;
        }
    }
    // Centred (two-pass) moments on patch sums.
    let nf = T::from_usize(count);
    let (mut sr, mut ss) = (T::ZERO, T::ZERO);
    for k in 0..count {
        sr += rv[k];
        ss += sv[k];
    }
    let (mr, ms) = (sr / nf, ss / nf);
    let (mut cov, mut var_r, mut var_s) = (T::ZERO, T::ZERO, T::ZERO);
    for k in 0..count {
        let a = rv[k] - mr;
        let b = sv[k] - ms;
        rv[k] = a;
        sv[k] = b;
        cov += a * b;
        var_r += a * a;
        var_s += b * b;
    }
    let eps = T::from_f64(NCC_EPS);
    // cost and ∂cost/∂s_k = ca·a_k + cb·b_k (using Σa = Σb = 0: ∂cov/∂s_k = a_k, ∂var_s/∂s_k = 2b_k).
    let (cost, ca, cb) = match mode {
        NccMode::Pgsr => {
            let den = var_r * var_s + eps;
            let cc = cov * cov / den;
            let raw = T::ONE - cc;
            let cost = raw.max(T::ZERO).min(T::from_f64(2.0));
            if !(cost < T::from_f64(NCC_MASK_THRESHOLD)) || !cost.is_finite() {
                return PatchResult::Masked;
            }
            if raw >= T::ZERO && raw <= T::from_f64(2.0) {
                let two = T::from_f64(2.0);
                (
                    cost,
                    -(two * cov / den),
                    two * cov * cov * var_r / (den * den),
                )
            } else {
                (cost, T::ZERO, T::ZERO)
            }
        }
        NccMode::Plain => {
            let sq = (var_r * var_s + eps).sqrt();
            let rho = cov / sq;
            let cost = T::ONE - rho;
            if !cost.is_finite() {
                return PatchResult::Masked;
            }
            (cost, -(T::ONE / sq), cov * var_r / (sq * sq * sq))
        }
    };
    let mut grad_n = [T::ZERO; 3];
    let mut grad_d = T::ZERO;
    for k in 0..count {
        let dc_ds = ca * rv[k] + cb * sv[k];
        let du = dc_ds * gu[k];
        let dv = dc_ds * gv[k];
        let wh = wv[k];
        let iz = T::ONE / wh[2];
        // ∂cost/∂w for u = w0/w2, v = w1/w2.
        let dw = [du * iz, dv * iz, -(du * wh[0] + dv * wh[1]) * iz * iz];
        // w = A q − (K_s t) m  ⇒  ∂cost/∂m = −dw·(K_s t).
        let dm = -dot3(dw, g.kt);
        // m = Ñ·q / D  ⇒  ∂m/∂Ñ = q / D, ∂m/∂D = −m / D.
        let f = dm * inv_d;
        // The sample's reference ray q = (x, y, 1), read again from the tables.
        let q = [rays.0[i - half + k % patch], rays.1[j - half + k / patch], T::ONE];
        grad_n[0] += f * q[0];
        grad_n[1] += f * q[1];
        grad_n[2] += f * q[2];
        grad_d -= f * mv[k];
    }
    PatchResult::Valid {
        cost,
        grad_n,
        grad_d,
    }
}

#[derive(Default, Clone, Copy)]
struct RowStats {
    sampled: usize,
    inside: usize,
    valid: usize,
    weighted: f64,
    cost: f64,
}

/// One source: evaluates the selected pixels row-parallel, writing υω-weighted per-pixel
/// gradients into the scratch buffers (zero elsewhere). Returns the stats and whether any
/// pixel counted.
#[allow(clippy::too_many_arguments)]
fn source_pass<T: Real>(
    reference: &PhotometricReference<'_, T>,
    source: &PhotometricSource<'_, T>,
    g: &PairGeometry<T>,
    grey_scale: usize,
    vis: &Visibility<T>,
    selected: &[u8],
    config: &PhotometricConfig,
    scratch_n: &mut [T],
    scratch_d: &mut [T],
) -> (SourceStats, bool) {
    let w = reference.camera.width as usize;
    let rays = g.ref_ray_tables(reference.grey.width, reference.grey.height);
    let rays = &rays;
    let rows: Vec<RowStats> = scratch_n
        .par_chunks_mut(3 * w)
        .zip(scratch_d.par_chunks_mut(w))
        .enumerate()
        .map(|(j, (gn_row, gd_row))| {
            gn_row.fill(T::ZERO);
            gd_row.fill(T::ZERO);
            let mut st = RowStats::default();
            let mut scratch = PatchScratch::new();
            for i in 0..w {
                let p = j * w + i;
                if selected[p] != 2 {
                    continue;
                }
                st.sampled += 1;
                let n = [
                    reference.normal.data[3 * p],
                    reference.normal.data[3 * p + 1],
                    reference.normal.data[3 * p + 2],
                ];
                let d = reference.distance.data[p];
                match patch_cost(
                    g,
                    rays,
                    &reference.grey,
                    &source.grey,
                    n,
                    d,
                    grey_scale * i + grey_scale / 2,
                    grey_scale * j + grey_scale / 2,
                    config.patch_size,
                    config.ncc,
                    &mut scratch,
                ) {
                    PatchResult::Outside => {}
                    PatchResult::Masked => st.inside += 1,
                    PatchResult::Valid {
                        cost,
                        grad_n,
                        grad_d,
                    } => {
                        st.inside += 1;
                        st.valid += 1;
                        let wt = vis.weight(p);
                        st.weighted += (wt * cost).to_f64();
                        st.cost += cost.to_f64();
                        gn_row[3 * i] = wt * grad_n[0];
                        gn_row[3 * i + 1] = wt * grad_n[1];
                        gn_row[3 * i + 2] = wt * grad_n[2];
                        gd_row[i] = wt * grad_d;
                    }
                }
            }
            st
        })
        .collect();
    let mut stats = SourceStats {
        n_candidates: selected.iter().filter(|&&s| s != 0).count(),
        ..Default::default()
    };
    for r in &rows {
        stats.n_sampled += r.sampled;
        stats.n_inside_source += r.inside;
        stats.n_valid += r.valid;
        stats.weighted_cost_sum += r.weighted;
        stats.cost_sum += r.cost;
    }
    (stats, stats.n_valid > 0)
}

#[cfg(test)]
mod tests;
