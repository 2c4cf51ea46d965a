//! Multi-view feature alignment L_f (docs/method.md §L_f): sampling, cosine and backward, against
//! the [`FeatureMaps`] trait (implemented here for gs-features' VGG maps and for
//! [`GridFeatureMaps`]; tests use synthetic ones).
//!
//! x_r = z_r·K_r⁻¹p̄_r from the reference plane depth, p_s' = π(K_s(R_rs x_r + t_rs));
//! L_f = (1/N) Σ_s (1/|V_s|) Σ_(p∈V_s) υω·|1 − cos(F_r(p_r), F_s(p_s'))| with
//! cos(a, b) = a·b / (max(‖a‖, 1e-8)·max(‖b‖, 1e-8)) and V_s = {υ = 1, ω > 0} over the whole
//! image (no patch border). **Averaged** over sources (unlike L_p). The gradient flows into z_r
//! through p_s' only; F_r(p_r), υ and ω are constants. λ4 is applied by the caller.

use crate::error::{MvsError, Result};
use crate::geometry::{MapView, PairGeometry, mat_vec};
use crate::Real;
use crate::visibility::{Visibility, VisibilityStats, check_weights, visibility_unchecked};
use gs_core::Camera;
use rayon::prelude::*;

/// The ε of the cosine's norms.
pub const COS_EPS: f64 = 1e-8;

/// Dense per-image feature maps sampled at continuous **image-pixel** coordinates (pixel
/// centres at `i + 0.5`). A strided map with stride s has feature pixel k centred at
/// `s·(k + 0.5)` image pixels, i.e. image coordinate c maps to feature coordinate c/s, and is
/// sampled bilinearly with the convention of [`crate::geometry::sample_bilinear_grad`].
pub trait FeatureMaps<T: Real = f32>: Sync {
    /// Number of channels C.
    fn channels(&self) -> usize;
    /// Writes the C feature values at image coordinates `(u_px, v_px)` into `out`, and when
    /// requested their derivatives with respect to `u_px` and `v_px`.
    fn sample(
        &self,
        u_px: T,
        v_px: T,
        out: &mut [T],
        grad_u: Option<&mut [T]>,
        grad_v: Option<&mut [T]>,
    );
}

/// A row-major `[H_f][W_f][C]` feature grid with an integer stride, sampled bilinearly
/// (clamped taps) in image-pixel coordinates — the reference [`FeatureMaps`] implementation.
#[derive(Debug, Clone, PartialEq)]
pub struct GridFeatureMaps<T> {
    width: usize,
    height: usize,
    channels: usize,
    stride: usize,
    data: Vec<T>,
}

impl<T: Real> GridFeatureMaps<T> {
    /// Wraps `[H_f][W_f][C]` data at `stride` image pixels per feature pixel.
    pub fn new(
        width: usize,
        height: usize,
        channels: usize,
        stride: usize,
        data: Vec<T>,
    ) -> Result<Self> {
        if width == 0 || height == 0 || channels == 0 || stride == 0 {
            return Err(MvsError::InvalidInput(format!(
                "feature grid {width}x{height}x{channels} with stride {stride} is empty"
            )));
        }
        if let Some(m) = gs_core::image::grid_len_mismatch(width, height, channels, data.len()) {
            return Err(MvsError::InvalidInput(format!("feature grid: {m}")));
        }
        Ok(Self {
            width,
            height,
            channels,
            stride,
            data,
        })
    }
}

impl<T: Real> FeatureMaps<T> for GridFeatureMaps<T> {
    fn channels(&self) -> usize {
        self.channels
    }

    fn sample(
        &self,
        u_px: T,
        v_px: T,
        out: &mut [T],
        grad_u: Option<&mut [T]>,
        grad_v: Option<&mut [T]>,
    ) {
        let s = T::from_usize(self.stride);
        let half = T::from_f64(0.5);
        let x = (u_px / s - half)
            .max(T::from_f64(-1.0))
            .min(T::from_usize(self.width));
        let y = (v_px / s - half)
            .max(T::from_f64(-1.0))
            .min(T::from_usize(self.height));
        let (x0f, y0f) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0f, y - y0f);
        let (x0, y0) = (x0f.to_f64() as isize, y0f.to_f64() as isize);
        let cx = |i: isize| i.clamp(0, self.width as isize - 1) as usize;
        let cy = |j: isize| j.clamp(0, self.height as isize - 1) as usize;
        let c = self.channels;
        let at = |xx: usize, yy: usize| {
            &self.data[(yy * self.width + xx) * c..(yy * self.width + xx + 1) * c]
        };
        let (p00, p10, p01, p11) = (
            at(cx(x0), cy(y0)),
            at(cx(x0 + 1), cy(y0)),
            at(cx(x0), cy(y0 + 1)),
            at(cx(x0 + 1), cy(y0 + 1)),
        );
        let inv_s = T::ONE / s;
        let mut gu = grad_u;
        let mut gv = grad_v;
        for k in 0..c {
            let top = p00[k] + (p10[k] - p00[k]) * fx;
            let bottom = p01[k] + (p11[k] - p01[k]) * fx;
            out[k] = top + (bottom - top) * fy;
            if let Some(g) = gu.as_deref_mut() {
                g[k] = ((p10[k] - p00[k]) * (T::ONE - fy) + (p11[k] - p01[k]) * fy) * inv_s;
            }
            if let Some(g) = gv.as_deref_mut() {
                g[k] = (bottom - top) * inv_s;
            }
        }
    }
}

/// gs-features' VGG maps are L_f's features as they are (f32, any stride; their bilinear
/// convention is this trait's: feature pixel k centred at `stride·(k + 0.5)`, clamped taps).
impl FeatureMaps<f32> for gs_features::FeatureMap {
    fn channels(&self) -> usize {
        gs_features::FeatureMap::channels(self)
    }

    fn sample(&self, u_px: f32, v_px: f32, out: &mut [f32], grad_u: Option<&mut [f32]>, grad_v: Option<&mut [f32]>) {
        match (grad_u, grad_v) {
            (Some(gu), Some(gv)) => {
                self.sample_bilinear_into(u_px, v_px, out, Some((gu, gv)));
            }
            (None, None) => {
                self.sample_bilinear_into(u_px, v_px, out, None);
            }
            (gu, gv) => {
                // One derivative only: compute both, keep the one asked for.
                let c = out.len();
                let (mut su, mut sv) = (vec![0.0; c], vec![0.0; c]);
                self.sample_bilinear_into(u_px, v_px, out, Some((&mut su, &mut sv)));
                if let Some(gu) = gu {
                    gu.copy_from_slice(&su);
                }
                if let Some(gv) = gv {
                    gv.copy_from_slice(&sv);
                }
            }
        }
    }
}

/// The reference view for L_f: camera, plane depth z_r (gradients flow into it), features.
#[derive(Clone, Copy)]
pub struct FeatureReference<'a, T: Real> {
    /// Reference camera.
    pub camera: &'a Camera,
    /// Rendered plane depth z_r, 1 channel.
    pub plane_depth: MapView<'a, T>,
    /// F_r.
    pub features: &'a dyn FeatureMaps<T>,
}

/// A source view for L_f: camera, rendered plane depth (for ω only), features.
#[derive(Clone, Copy)]
pub struct FeatureSource<'a, T: Real> {
    /// Source camera.
    pub camera: &'a Camera,
    /// Rendered plane depth of the source, 1 channel.
    pub plane_depth: MapView<'a, T>,
    /// F_s.
    pub features: &'a dyn FeatureMaps<T>,
}

/// One view of an L_f evaluation with gs-features' VGG maps: camera, rendered plane depth
/// (the reference's carries the gradient; a source's gives ω), its features and the key a
/// device executor keeps them under ([`crate::FeatureGpu`]; the same key must always name the
/// same maps).
#[derive(Clone, Copy)]
pub struct AlignView<'a> {
    /// The camera.
    pub camera: &'a Camera,
    /// Rendered plane depth, 1 channel.
    pub plane_depth: MapView<'a, f32>,
    /// The feature maps.
    pub features: &'a gs_features::FeatureMap,
    /// The key of `features` on a device.
    pub key: u64,
}

impl<'a> AlignView<'a> {
    /// The view as the host reference's reference view.
    pub fn as_reference(&self) -> FeatureReference<'a, f32> {
        FeatureReference { camera: self.camera, plane_depth: self.plane_depth, features: self.features }
    }

    /// The view as one of the host reference's source views.
    pub fn as_source(&self) -> FeatureSource<'a, f32> {
        FeatureSource { camera: self.camera, plane_depth: self.plane_depth, features: self.features }
    }
}

/// Statistics of one source view for L_f.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FeatureSourceStats {
    /// υ/ω counts.
    pub visibility: VisibilityStats,
    /// |V| = pixels with υ = 1 and ω > 0.
    pub n_valid: usize,
    /// Σ_V υω·|1 − cos|.
    pub weighted_sum: f64,
    /// Σ_V cos (unweighted), for diagnostics.
    pub cos_sum: f64,
    /// L_f,s = weighted_sum / |V| (0 when V is empty).
    pub loss: f64,
}

/// L_f and ∂L_f/∂z_r.
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureOutput<T> {
    /// L_f = mean over sources of L_f,s (0 without sources); not multiplied by λ4.
    pub loss: f64,
    /// One entry per source, in input order.
    pub per_source: Vec<FeatureSourceStats>,
    /// ∂L_f/∂z_r, `[H][W]`.
    pub grad_plane_depth: Vec<T>,
    /// Reference width.
    pub width: usize,
    /// Reference height.
    pub height: usize,
}

pub(crate) fn check_inputs<T: Real>(
    reference: &FeatureReference<'_, T>,
    sources: &[FeatureSource<'_, T>],
) -> Result<()> {
    reference
        .plane_depth
        .expect_size(reference.camera, 1, "reference plane_depth")?;
    let c = reference.features.channels();
    if c == 0 {
        return Err(MvsError::InvalidInput(
            "reference feature maps have no channels".into(),
        ));
    }
    for (k, s) in sources.iter().enumerate() {
        s.plane_depth
            .expect_size(s.camera, 1, &format!("source {k} plane_depth"))?;
        if s.features.channels() != c {
            return Err(MvsError::InvalidInput(format!(
                "source {k} features have {} channels, the reference's have {c}",
                s.features.channels()
            )));
        }
    }
    Ok(())
}

/// L_f over `sources` with υ and ω computed from the plane depths (docs/method.md §L_f, §Visibility).
pub fn feature_loss<T: Real>(
    reference: &FeatureReference<'_, T>,
    sources: &[FeatureSource<'_, T>],
) -> Result<FeatureOutput<T>> {
    check_inputs(reference, sources)?;
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
    feature_loss_with_weights(reference, sources, &weights)
}

/// L_f with precomputed (e.g. frozen) υ/ω maps. With supplied weights a pixel of V may reproject
/// outside the source image under the evaluated depth: its features are then sampled with
/// border-clamped taps (as the synth-bunny reference does); one that lands behind the source
/// camera still counts in |V| and contributes 0.
pub fn feature_loss_with_weights<T: Real>(
    reference: &FeatureReference<'_, T>,
    sources: &[FeatureSource<'_, T>],
    weights: &[Visibility<T>],
) -> Result<FeatureOutput<T>> {
    check_inputs(reference, sources)?;
    check_weights(weights, sources.len(), reference.camera)?;
    let (w, h) = (
        reference.camera.width as usize,
        reference.camera.height as usize,
    );
    let c = reference.features.channels();
    let mut out = FeatureOutput {
        loss: 0.0,
        per_source: Vec::new(),
        grad_plane_depth: vec![T::ZERO; w * h],
        width: w,
        height: h,
    };
    let mut scratch = vec![T::ZERO; w * h];
    let n_src = sources.len();
    for (source, vis) in sources.iter().zip(weights) {
        let g = PairGeometry::<T>::new(reference.camera, source.camera);
        let eps = T::from_f64(COS_EPS);
        let rows: Vec<(usize, f64, f64)> = scratch
            .par_chunks_mut(w)
            .enumerate()
            .map(|(j, grow)| {
                grow.fill(T::ZERO);
                let (mut a, mut b, mut bu, mut bv) = (
                    vec![T::ZERO; c],
                    vec![T::ZERO; c],
                    vec![T::ZERO; c],
                    vec![T::ZERO; c],
                );
                let (mut valid, mut wsum, mut csum) = (0usize, 0.0f64, 0.0f64);
                let half = T::from_f64(0.5);
                let v = T::from_usize(j) + half;
                #[allow(clippy::needless_range_loop)]
                for i in 0..w {
                    let p = j * w + i;
                    let wt = vis.weight(p);
                    if !(wt > T::ZERO) {
                        continue;
                    }
                    valid += 1;
                    let u = T::from_usize(i) + half;
                    let z = reference.plane_depth.data[p];
                    let ray = g.ref_ray(u, v);
                    let xs = g.map_to_source([ray[0] * z, ray[1] * z, ray[2] * z]);
                    if !(xs[2] > T::ZERO) {
                        continue;
                    }
                    let us = g.s_fx * xs[0] / xs[2] + g.s_cx;
                    let vs = g.s_fy * xs[1] / xs[2] + g.s_cy;
                    // Outside the source image (possible only with supplied weights) the
                    // features are sampled with border-clamped taps, as the reference does.
                    reference.features.sample(u, v, &mut a, None, None);
                    source
                        .features
                        .sample(us, vs, &mut b, Some(&mut bu), Some(&mut bv));
                    let na = dot_slice(&a, &a).sqrt();
                    let nb = dot_slice(&b, &b).sqrt();
                    let (ma, mb) = (na.max(eps), nb.max(eps));
                    let ab = dot_slice(&a, &b);
                    let cos = ab / (ma * mb);
                    let one_minus = T::ONE - cos;
                    if !one_minus.is_finite() {
                        continue;
                    }
                    wsum += (wt * one_minus.abs()).to_f64();
                    csum += cos.to_f64();
                    let sign = if one_minus > T::ZERO {
                        T::ONE
                    } else if one_minus < T::ZERO {
                        -T::ONE
                    } else {
                        T::ZERO
                    };
                    // ∂|1 − cos|/∂cos = −sign; ∂cos/∂b = a/(m_a m_b) − cos·b/‖b‖² (when ‖b‖ > ε).
                    let inv = T::ONE / (ma * mb);
                    let kb = if nb > eps { cos / (nb * nb) } else { T::ZERO };
                    let (mut dcos_du, mut dcos_dv) = (T::ZERO, T::ZERO);
                    for k in 0..c {
                        let dk = a[k] * inv - kb * b[k];
                        dcos_du += dk * bu[k];
                        dcos_dv += dk * bv[k];
                    }
                    // p_s'(z): x_s = z·R r + t ⇒ ∂x_s/∂z = R r.
                    let dx = mat_vec(&g.rot, ray);
                    let iz2 = T::ONE / (xs[2] * xs[2]);
                    let du_dz = g.s_fx * (dx[0] * xs[2] - xs[0] * dx[2]) * iz2;
                    let dv_dz = g.s_fy * (dx[1] * xs[2] - xs[1] * dx[2]) * iz2;
                    grow[i] = -sign * wt * (dcos_du * du_dz + dcos_dv * dv_dz);
                }
                (valid, wsum, csum)
            })
            .collect();
        add_source(&mut out, vis, rows, &scratch, n_src);
    }
    Ok(out)
}

/// Adds one source to `out`: its rows' (|V|, Σ υω·|1 − cos|, Σ cos), summed in row order, give
/// L_f,s = Σ / |V|, averaged over the `n_src` sources, and its per-pixel gradient `grad` is
/// added scaled by 1 / (|V|·n_src).
pub(crate) fn add_source<T: Real>(
    out: &mut FeatureOutput<T>,
    vis: &Visibility<T>,
    rows: impl IntoIterator<Item = (usize, f64, f64)>,
    grad: &[T],
    n_src: usize,
) {
    if let Some(scale) = add_source_sums((&mut out.loss, &mut out.per_source), vis.stats(), rows, n_src) {
        let scale = T::from_f64(scale);
        out.grad_plane_depth
            .par_iter_mut()
            .zip(grad.par_iter())
            .for_each(|(o, s)| *o += *s * scale);
    }
}

/// [`add_source`] but the gradient: one source's statistics from its υ/ω counts and its rows
/// (pairs in V, the sums of υω·|1 − cos| and of cos), pushed onto `per_source`, its share
/// L_f,s / N added to `loss`; returns the scale of its gradient, 1 / (|V|·N), or `None`
/// without pairs in V. Shared by the host and the device evaluations.
pub(crate) fn add_source_sums(
    (loss, per_source): (&mut f64, &mut Vec<FeatureSourceStats>),
    visibility: VisibilityStats,
    rows: impl IntoIterator<Item = (usize, f64, f64)>,
    n_src: usize,
) -> Option<f64> {
    let mut st = FeatureSourceStats { visibility, ..Default::default() };
    for (v, ws, cs) in rows {
        st.n_valid += v;
        st.weighted_sum += ws;
        st.cos_sum += cs;
    }
    let scale = (st.n_valid > 0).then(|| {
        st.loss = st.weighted_sum / st.n_valid as f64;
        1.0 / (st.n_valid as f64 * n_src as f64)
    });
    *loss += st.loss / n_src as f64;
    per_source.push(st);
    scale
}

#[inline]
fn dot_slice<T: Real>(a: &[T], b: &[T]) -> T {
    let mut s = T::ZERO;
    for (x, y) in a.iter().zip(b) {
        s += *x * *y;
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::{small_scene, to_f64};
    use crate::visibility::compute_visibility;
    use gs_core::Rng;
    use gs_core::gradcheck::{GradCheck, check_gradient, numeric_gradient};

    /// A smooth random feature grid at stride 2 for a `w×h` image.
    fn grid(w: usize, h: usize, c: usize, seed: u64) -> GridFeatureMaps<f64> {
        let (fw, fh) = (w.div_ceil(2), h.div_ceil(2));
        let mut rng = Rng::new(seed);
        let data = (0..fw * fh * c).map(|_| rng.uniform_f64() - 0.3).collect();
        GridFeatureMaps::new(fw, fh, c, 2, data).unwrap()
    }

    #[test]
    fn grid_sampling_convention_and_gradient() {
        let g = grid(12, 10, 3, 4);
        let mut out = [0.0; 3];
        // Feature pixel (k, l) is centred at image pixel (2k + 1, 2l + 1).
        g.sample(2.0 * 3.0 + 1.0, 2.0 * 2.0 + 1.0, &mut out, None, None);
        assert_eq!(
            out.to_vec(),
            g.data[(2 * 6 + 3) * 3..(2 * 6 + 3) * 3 + 3].to_vec()
        );
        let (mut gu, mut gv) = ([0.0; 3], [0.0; 3]);
        let (u, v) = (5.3, 6.1);
        g.sample(u, v, &mut out, Some(&mut gu), Some(&mut gv));
        for c in 0..3 {
            let f = |x: &[f64]| {
                let mut o = [0.0; 3];
                g.sample(x[0], x[1], &mut o, None, None);
                o[c]
            };
            let n = numeric_gradient(f, &[u, v], 1e-6, &[0, 1]);
            assert!((n[0] - gu[c]).abs() < 1e-7 && (n[1] - gv[c]).abs() < 1e-7);
        }
        assert!(GridFeatureMaps::<f64>::new(2, 2, 3, 2, vec![0.0; 5]).is_err());
    }

    /// Finite-difference check of ∂L_f/∂z (υω frozen).
    #[test]
    fn gradient_matches_finite_differences() {
        let s = small_scene(40, 30, 3);
        let (w, h) = (40usize, 30usize);
        let z = to_f64(&s.maps[0].plane_depth);
        let src_z: Vec<Vec<f64>> = s.maps[1..].iter().map(|m| to_f64(&m.plane_depth)).collect();
        let feats: Vec<GridFeatureMaps<f64>> = (0..3).map(|k| grid(w, h, 6, 10 + k)).collect();
        fn mk<'a>(
            s: &'a crate::testutil::SmallScene,
            z: &'a [f64],
            src_z: &'a [Vec<f64>],
            feats: &'a [GridFeatureMaps<f64>],
        ) -> (FeatureReference<'a, f64>, Vec<FeatureSource<'a, f64>>) {
            let (w, h) = (40, 30);
            let r = FeatureReference {
                camera: &s.cams[0],
                plane_depth: MapView::new(w, h, 1, z).unwrap(),
                features: &feats[0],
            };
            let src: Vec<FeatureSource<f64>> = (0..2)
                .map(|k| FeatureSource {
                    camera: &s.cams[k + 1],
                    plane_depth: MapView::new(w, h, 1, &src_z[k]).unwrap(),
                    features: &feats[k + 1],
                })
                .collect();
            (r, src)
        }
        let (r, src) = mk(&s, &z, &src_z, &feats);
        let weights: Vec<Visibility<f64>> = src
            .iter()
            .map(|x| compute_visibility(r.camera, r.plane_depth, x.camera, x.plane_depth).unwrap())
            .collect();
        let out = feature_loss_with_weights(&r, &src, &weights).unwrap();
        let again = feature_loss(&r, &src).unwrap();
        assert_eq!(out, again);
        assert!(
            out.per_source.iter().all(|s| s.n_valid > 100),
            "{:?}",
            out.per_source
        );
        assert!(
            (out.loss - (out.per_source[0].loss + out.per_source[1].loss) / 2.0).abs() < 1e-15,
            "averaged over sources"
        );
        let nz: Vec<usize> = (0..z.len())
            .filter(|&k| out.grad_plane_depth[k] != 0.0)
            .collect();
        assert!(nz.len() > 100);
        let idx: Vec<usize> = nz.iter().step_by(nz.len() / 80).copied().collect();
        let loss = |x: &[f64]| {
            let (r, src) = mk(&s, x, &src_z, &feats);
            feature_loss_with_weights(&r, &src, &weights).unwrap().loss
        };
        let rep = check_gradient(
            loss,
            &z,
            &out.grad_plane_depth,
            &GradCheck {
                eps: 1e-6,
                rtol: 1e-4,
                atol: 1e-10,
                indices: Some(idx),
            },
        );
        assert!(rep.is_ok(), "{rep:?}");
    }

    /// Zero feature vectors, NaN/zero/huge depths and no sources: finite values, no panic.
    #[test]
    fn extremes_are_finite() {
        let s = small_scene(24, 18, 2);
        let (w, h) = (24usize, 18usize);
        let mut z = to_f64(&s.maps[0].plane_depth);
        z[0] = f64::NAN;
        z[1] = 0.0;
        z[2] = 1e30;
        z[3] = -1.0;
        z[40] = f64::INFINITY;
        let src_z = to_f64(&s.maps[1].plane_depth);
        let zero = GridFeatureMaps::new(12, 9, 4, 2, vec![0.0; 12 * 9 * 4]).unwrap();
        let rand = grid(w, h, 4, 3);
        for (fr, fs) in [
            (
                &zero as &dyn FeatureMaps<f64>,
                &rand as &dyn FeatureMaps<f64>,
            ),
            (&rand, &zero),
            (&zero, &zero),
        ] {
            let r = FeatureReference {
                camera: &s.cams[0],
                plane_depth: MapView::new(w, h, 1, &z).unwrap(),
                features: fr,
            };
            let src = [FeatureSource {
                camera: &s.cams[1],
                plane_depth: MapView::new(w, h, 1, &src_z).unwrap(),
                features: fs,
            }];
            let out = feature_loss(&r, &src).unwrap();
            assert!(out.loss.is_finite() && out.grad_plane_depth.iter().all(|g| g.is_finite()));
            let none = feature_loss(&r, &[]).unwrap();
            assert_eq!(none.loss, 0.0);
            assert!(none.grad_plane_depth.iter().all(|&g| g == 0.0));
        }
        let three = grid(w, h, 3, 1);
        let r = FeatureReference {
            camera: &s.cams[0],
            plane_depth: MapView::new(w, h, 1, &z).unwrap(),
            features: &three,
        };
        let src = [FeatureSource {
            camera: &s.cams[1],
            plane_depth: MapView::new(w, h, 1, &src_z).unwrap(),
            features: &rand,
        }];
        assert!(feature_loss(&r, &src).is_err(), "channel mismatch");
    }
}
