//! Visibility υ_rs and occlusion weight ω (docs/method.md §Visibility), shared by L_p and L_f.
//!
//! For a reference pixel p_r with plane depth z_r: x_r = z_r·K_r⁻¹p̄_r, p_s' = π(K_s(R_rs x_r +
//! t_rs)). υ = 1 iff z_r > 0, the source-camera z is > 0 and 0 < p_s' < (W_s, H_s) (all strict).
//! Forward–backward: the source plane depth z_s is sampled bilinearly at p_s', lifted to x_s =
//! z_s·K_s⁻¹p̄_s', mapped back with R_rsᵀ(x_s − t_rs) and projected to p_r'; φ = ‖p_r − p_r'‖₂
//! and ω = exp(−φ) if φ < 1, else 0. ω is also 0 when υ = 0, when z_s ≤ 0 or when the mapped
//! point is behind the reference. Both are constants: no gradient flows through them.

use crate::error::{MvsError, Result};
use crate::geometry::{MapView, PairGeometry, sample_bilinear};
use crate::Real;
use gs_core::Camera;
use rayon::prelude::*;

/// υ and ω of one reference/source pair, one value per reference pixel (row-major).
#[derive(Debug, Clone, PartialEq)]
pub struct Visibility<T> {
    /// Reference width.
    pub width: usize,
    /// Reference height.
    pub height: usize,
    /// υ_rs: 1 where the reprojected point lands inside the source image, in front of it.
    pub upsilon: Vec<u8>,
    /// ω: occlusion weight exp(−φ) (0 where φ ≥ 1 or υ = 0).
    pub omega: Vec<T>,
}

/// Summary of a [`Visibility`]: counts over all reference pixels.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct VisibilityStats {
    /// Pixels with υ = 1.
    pub n_upsilon: usize,
    /// Pixels with ω > 0.
    pub n_omega_positive: usize,
    /// Mean of ω over the pixels with υ = 1 (0 when there are none).
    pub mean_omega_over_upsilon: f64,
}

impl VisibilityStats {
    /// The statistics of `n_upsilon` pixels with υ = 1 whose ω add up to `omega_sum` and
    /// `n_omega_positive` pixels with ω > 0.
    pub fn of_counts(n_upsilon: usize, n_omega_positive: usize, omega_sum: f64) -> Self {
        let mean_omega_over_upsilon = if n_upsilon > 0 { omega_sum / n_upsilon as f64 } else { 0.0 };
        Self { n_upsilon, n_omega_positive, mean_omega_over_upsilon }
    }
}

impl<T: Real> Visibility<T> {
    /// The weight υ·ω of pixel index `k` (row-major).
    #[inline]
    pub fn weight(&self, k: usize) -> T {
        if self.upsilon[k] != 0 {
            self.omega[k]
        } else {
            T::ZERO
        }
    }

    /// Counts of υ = 1 and ω > 0 and the mean ω over υ = 1 (summed in f64, row order).
    pub fn stats(&self) -> VisibilityStats {
        let (mut upsilon, mut positive, mut sum) = (0, 0, 0.0f64);
        for (u, w) in self.upsilon.iter().zip(&self.omega) {
            if *u != 0 {
                upsilon += 1;
                sum += w.to_f64();
            }
            if *w > T::ZERO {
                positive += 1;
            }
        }
        VisibilityStats::of_counts(upsilon, positive, sum)
    }

    /// A copy with every weight replaced by `f(weight)`; lets tests freeze or edit weights.
    pub fn map_omega(&self, f: impl Fn(T) -> T) -> Self {
        Self {
            omega: self.omega.iter().map(|&w| f(w)).collect(),
            ..self.clone()
        }
    }
}

/// The per-pixel forward–backward check. Returns `(υ, ω)`.
#[inline]
pub(crate) fn visibility_at<T: Real>(
    g: &PairGeometry<T>,
    src_depth: &MapView<'_, T>,
    u: T,
    v: T,
    z: T,
) -> (bool, T) {
    if !(z > T::ZERO) || !z.is_finite() {
        return (false, T::ZERO);
    }
    let ray = g.ref_ray(u, v);
    let xr = [ray[0] * z, ray[1] * z, ray[2] * z];
    let xs = g.map_to_source(xr);
    if !(xs[2] > T::ZERO) {
        return (false, T::ZERO);
    }
    let us = g.s_fx * xs[0] / xs[2] + g.s_cx;
    let vs = g.s_fy * xs[1] / xs[2] + g.s_cy;
    if !g.inside_source(us, vs) {
        return (false, T::ZERO);
    }
    let zs = sample_bilinear(src_depth.data, src_depth.width, src_depth.height, us, vs);
    if !(zs > T::ZERO) || !zs.is_finite() {
        return (true, T::ZERO);
    }
    let rs = g.src_ray(us, vs);
    let xr2 = g.map_to_reference([rs[0] * zs, rs[1] * zs, rs[2] * zs]);
    if !(xr2[2] > T::ZERO) {
        return (true, T::ZERO);
    }
    let ur = g.r_fx * xr2[0] / xr2[2] + g.r_cx;
    let vr = g.r_fy * xr2[1] / xr2[2] + g.r_cy;
    let (du, dv) = (u - ur, v - vr);
    let phi = (du * du + dv * dv).sqrt();
    if phi < T::ONE {
        (true, (-phi).exp())
    } else {
        (true, T::ZERO)
    }
}

/// Computes υ_rs and ω for every reference pixel from the reference plane depth `z_r` and the
/// source's rendered plane depth (docs/method.md §Visibility). Maps must match their cameras' sizes
/// (1 channel each). Deterministic and parallel over rows.
pub fn compute_visibility<T: Real>(
    reference: &Camera,
    reference_plane_depth: MapView<'_, T>,
    source: &Camera,
    source_plane_depth: MapView<'_, T>,
) -> Result<Visibility<T>> {
    reference_plane_depth.expect_size(reference, 1, "reference plane_depth")?;
    source_plane_depth.expect_size(source, 1, "source plane_depth")?;
    Ok(visibility_unchecked(
        &PairGeometry::new(reference, source),
        &reference_plane_depth,
        &source_plane_depth,
    ))
}

pub(crate) fn visibility_unchecked<T: Real>(
    g: &PairGeometry<T>,
    z_ref: &MapView<'_, T>,
    z_src: &MapView<'_, T>,
) -> Visibility<T> {
    let (w, h) = (z_ref.width, z_ref.height);
    let mut upsilon = vec![0u8; w * h];
    let mut omega = vec![T::ZERO; w * h];
    let half = T::from_f64(0.5);
    upsilon
        .par_chunks_mut(w)
        .zip(omega.par_chunks_mut(w))
        .enumerate()
        .for_each(|(j, (ups, oms))| {
            let v = T::from_usize(j) + half;
            for i in 0..w {
                let u = T::from_usize(i) + half;
                let (vis, om) = visibility_at(g, z_src, u, v, z_ref.data[j * w + i]);
                ups[i] = vis as u8;
                oms[i] = om;
            }
        });
    Visibility {
        width: w,
        height: h,
        upsilon,
        omega,
    }
}

/// Checks that a precomputed weight list matches the reference and source count.
pub(crate) fn check_weights<T>(
    weights: &[Visibility<T>],
    n_sources: usize,
    reference: &Camera,
) -> Result<()> {
    if weights.len() != n_sources {
        return Err(MvsError::InvalidInput(format!(
            "{} visibility maps given for {n_sources} source views",
            weights.len()
        )));
    }
    for (k, v) in weights.iter().enumerate() {
        let n = reference.width as usize * reference.height as usize;
        if v.width != reference.width as usize
            || v.height != reference.height as usize
            || v.upsilon.len() != n
            || v.omega.len() != n
        {
            return Err(MvsError::SizeMismatch {
                map: format!("visibility of source {k}"),
                expected: format!("{}x{}", reference.width, reference.height),
                got: format!(
                    "{}x{} ({} / {} values)",
                    v.width,
                    v.height,
                    v.upsilon.len(),
                    v.omega.len()
                ),
            });
        }
    }
    Ok(())
}
