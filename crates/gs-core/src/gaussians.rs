//! The Gaussian model as struct-of-arrays, with its activations.
//!
//! Parameters are stored raw (what the optimiser updates): means, log-scales, quaternions
//! `(w, x, y, z)` (not necessarily normalised), opacity logits and SH coefficients
//! `[N][16][3]` with the DC term first. Activations: `exp` for scales, `sigmoid` for opacity,
//! normalisation for quaternions (docs/architecture.md §Conventions).

use crate::error::{CoreError, Result};
use crate::sh::{MAX_SH_DEGREE, SH_C0, SH_COEFFS};
use glam::{Mat3, Quat, Vec3};

/// Largest accepted Gaussian count (a resource cap; training uses its own, smaller cap).
pub const MAX_GAUSSIANS: usize = 50_000_000;

/// Gaussian parameters, one entry per Gaussian in each array.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Gaussians {
    /// Centres μ in world coordinates.
    pub means: Vec<[f32; 3]>,
    /// Log-scales; scales s = exp(log_scales).
    pub log_scales: Vec<[f32; 3]>,
    /// Rotations as quaternions `(w, x, y, z)`, normalised when used.
    pub rotations: Vec<[f32; 4]>,
    /// Opacity logits; opacity o = sigmoid(logit).
    pub opacity_logits: Vec<f32>,
    /// SH coefficients per Gaussian, 16 × RGB, DC first.
    pub sh: Vec<[[f32; 3]; SH_COEFFS]>,
    /// Active SH degree (0..=3) used for rendering.
    pub sh_degree: u32,
}

/// Logistic sigmoid, stable for large |x|.
#[inline]
pub fn sigmoid(x: f32) -> f32 {
    if x >= 0.0 {
        1.0 / (1.0 + (-x).exp())
    } else {
        let e = x.exp();
        e / (1.0 + e)
    }
}

/// Inverse sigmoid `ln(p / (1 − p))`, with `p` clamped to `[1e-7, 1 − 1e-7]`.
#[inline]
pub fn inverse_sigmoid(p: f32) -> f32 {
    let p = p.clamp(1e-7, 1.0 - 1e-7);
    (p / (1.0 - p)).ln()
}

/// SH DC coefficient that renders colour `rgb` (`(rgb − 0.5)/C0`).
#[inline]
pub fn rgb_to_sh_dc(rgb: f32) -> f32 {
    (rgb - 0.5) / SH_C0
}

/// The quaternion `(w, x, y, z)` normalised; one whose norm is zero or not finite gives the
/// identity `(1, 0, 0, 0)` (a deterministic choice for a degenerate input). Every use of a
/// Gaussian's rotation (rendering, exports) goes through this one rule.
#[inline]
pub fn unit_quaternion(q: [f32; 4]) -> [f32; 4] {
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    if !(n > 1e-20) || !n.is_finite() {
        return [1.0, 0.0, 0.0, 0.0];
    }
    [q[0] / n, q[1] / n, q[2] / n, q[3] / n]
}

/// Rotation matrix of quaternion `(w, x, y, z)` after normalisation ([`unit_quaternion`]; a
/// degenerate quaternion gives the identity).
pub fn rotation_matrix(q: [f32; 4]) -> Mat3 {
    let [w, x, y, z] = unit_quaternion(q);
    Mat3::from_quat(Quat::from_xyzw(x, y, z, w))
}

/// Backward of [`rotation_matrix`]: `∂L/∂q` (through the normalisation) given `∂L/∂R`.
pub fn rotation_matrix_backward(q: [f32; 4], grad_r: Mat3) -> [f32; 4] {
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    if !(n > 1e-20) || !n.is_finite() {
        return [0.0; 4];
    }
    let (w, x, y, z) = (q[0] / n, q[1] / n, q[2] / n, q[3] / n);
    // R (row r, column c) written out; g(r, c) = ∂L/∂R[r][c].
    let g = |r: usize, c: usize| grad_r.col(c)[r];
    // R = [[1-2(y²+z²), 2(xy-wz), 2(xz+wy)],
    //      [2(xy+wz), 1-2(x²+z²), 2(yz-wx)],
    //      [2(xz-wy), 2(yz+wx), 1-2(x²+y²)]]
    let dw = 2.0 * (-z * g(0, 1) + y * g(0, 2) + z * g(1, 0) - x * g(1, 2) - y * g(2, 0) + x * g(2, 1));
    let dx = 2.0
        * (y * g(0, 1) + z * g(0, 2) + y * g(1, 0) - 2.0 * x * g(1, 1) - w * g(1, 2) + z * g(2, 0) + w * g(2, 1)
            - 2.0 * x * g(2, 2));
    let dy = 2.0
        * (-2.0 * y * g(0, 0) + x * g(0, 1) + w * g(0, 2) + x * g(1, 0) + z * g(1, 2) - w * g(2, 0) + z * g(2, 1)
            - 2.0 * y * g(2, 2));
    let dz = 2.0
        * (-2.0 * z * g(0, 0) - w * g(0, 1) + x * g(0, 2) + w * g(1, 0) - 2.0 * z * g(1, 1) + y * g(1, 2)
            + x * g(2, 0)
            + y * g(2, 1));
    // Through the normalisation q̂ = q/‖q‖.
    let gq = [dw, dx, dy, dz];
    let qh = [w, x, y, z];
    let dot: f32 = (0..4).map(|k| gq[k] * qh[k]).sum();
    [(gq[0] - qh[0] * dot) / n, (gq[1] - qh[1] * dot) / n, (gq[2] - qh[2] * dot) / n, (gq[3] - qh[3] * dot) / n]
}

/// Index of the smallest of three scales; ties go to the lowest axis index, so a Gaussian with
/// three equal scales deterministically uses its local x axis.
#[inline]
pub fn smallest_axis(scales: [f32; 3]) -> usize {
    let mut k = 0;
    for a in 1..3 {
        if scales[a] < scales[k] {
            k = a;
        }
    }
    k
}

impl Gaussians {
    /// Number of Gaussians.
    pub fn len(&self) -> usize {
        self.means.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.means.is_empty()
    }

    /// `n` Gaussians with zero means, unit scales, identity rotations, opacity 0.1, grey colour.
    pub fn with_len(n: usize) -> Result<Self> {
        if n > MAX_GAUSSIANS {
            return Err(CoreError::InvalidGaussians(format!("{n} Gaussians exceed the cap of {MAX_GAUSSIANS}")));
        }
        Ok(Self {
            means: vec![[0.0; 3]; n],
            log_scales: vec![[0.0; 3]; n],
            rotations: vec![[1.0, 0.0, 0.0, 0.0]; n],
            opacity_logits: vec![inverse_sigmoid(0.1); n],
            sh: vec![[[0.0; 3]; SH_COEFFS]; n],
            sh_degree: 0,
        })
    }

    /// Appends one Gaussian.
    pub fn push(&mut self, mean: [f32; 3], log_scale: [f32; 3], rotation: [f32; 4], opacity_logit: f32, sh: [[f32; 3]; SH_COEFFS]) {
        self.means.push(mean);
        self.log_scales.push(log_scale);
        self.rotations.push(rotation);
        self.opacity_logits.push(opacity_logit);
        self.sh.push(sh);
    }

    /// Checks that the arrays have equal lengths, the degree is ≤ 3 and every value is finite.
    pub fn validate(&self) -> Result<()> {
        let n = self.means.len();
        let lens = [self.log_scales.len(), self.rotations.len(), self.opacity_logits.len(), self.sh.len()];
        if lens.iter().any(|&l| l != n) {
            return Err(CoreError::InvalidGaussians(format!(
                "array lengths differ: means {n}, log_scales {}, rotations {}, opacity {}, sh {}",
                lens[0], lens[1], lens[2], lens[3]
            )));
        }
        if self.sh_degree > MAX_SH_DEGREE {
            return Err(CoreError::InvalidGaussians(format!("SH degree {} > {MAX_SH_DEGREE}", self.sh_degree)));
        }
        let bad = (0..n).find(|&i| {
            !(self.means[i].iter().all(|v| v.is_finite())
                && self.log_scales[i].iter().all(|v| v.is_finite())
                && self.rotations[i].iter().all(|v| v.is_finite())
                && self.opacity_logits[i].is_finite()
                && self.sh[i].iter().flatten().all(|v| v.is_finite()))
        });
        if let Some(i) = bad {
            return Err(CoreError::InvalidGaussians(format!("Gaussian {i} has a NaN or infinite parameter")));
        }
        Ok(())
    }

    /// Activated scales `exp(log_scales[i])`.
    #[inline]
    pub fn scale(&self, i: usize) -> [f32; 3] {
        self.log_scales[i].map(f32::exp)
    }

    /// Activated opacity `sigmoid(logit[i])`.
    #[inline]
    pub fn opacity(&self, i: usize) -> f32 {
        sigmoid(self.opacity_logits[i])
    }

    /// Rotation matrix of Gaussian `i` (identity for a zero quaternion).
    #[inline]
    pub fn rotation(&self, i: usize) -> Mat3 {
        rotation_matrix(self.rotations[i])
    }

    /// World covariance Σ = R S Sᵀ Rᵀ.
    pub fn covariance(&self, i: usize) -> Mat3 {
        let r = self.rotation(i);
        let s = Vec3::from(self.scale(i));
        let m = r * Mat3::from_diagonal(s);
        m * m.transpose()
    }

    /// Unoriented normal: the rotation axis of the smallest scale (docs/method.md §Rendering); the caller
    /// flips it to face the camera.
    pub fn normal(&self, i: usize) -> Vec3 {
        let k = smallest_axis(self.log_scales[i]);
        self.rotation(i).col(k)
    }

    /// Keeps the Gaussians whose `keep` flag is true (densification and pruning).
    pub fn retain(&mut self, keep: &[bool]) -> Result<()> {
        if keep.len() != self.len() {
            return Err(CoreError::InvalidGaussians(format!("retain mask has {} entries for {} Gaussians", keep.len(), self.len())));
        }
        fn filter<T: Copy>(v: &mut Vec<T>, keep: &[bool]) {
            let mut k = keep.iter();
            v.retain(|_| *k.next().unwrap_or(&false));
        }
        filter(&mut self.means, keep);
        filter(&mut self.log_scales, keep);
        filter(&mut self.rotations, keep);
        filter(&mut self.opacity_logits, keep);
        filter(&mut self.sh, keep);
        Ok(())
    }

    /// Appends all Gaussians of `other`.
    pub fn extend_from(&mut self, other: &Gaussians) {
        self.means.extend_from_slice(&other.means);
        self.log_scales.extend_from_slice(&other.log_scales);
        self.rotations.extend_from_slice(&other.rotations);
        self.opacity_logits.extend_from_slice(&other.opacity_logits);
        self.sh.extend_from_slice(&other.sh);
    }

    /// Flat view of the SH coefficients, `[N × 16 × 3]`.
    pub fn sh_flat(&self) -> &[f32] {
        self.sh.as_flattened().as_flattened()
    }

    /// Mutable flat view of the SH coefficients.
    pub fn sh_flat_mut(&mut self) -> &mut [f32] {
        self.sh.as_flattened_mut().as_flattened_mut()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gradcheck::{GradCheck, check_gradient};
    use crate::rng::Rng;

    #[test]
    fn rotation_backward_matches_finite_differences() {
        let mut rng = Rng::new(2);
        for _ in 0..10 {
            let q = [rng.normal(), rng.normal(), rng.normal(), rng.normal()];
            let w: [f32; 9] = std::array::from_fn(|_| rng.normal());
            let g = Mat3::from_cols_array(&w);
            let analytic: Vec<f64> = rotation_matrix_backward(q, g).iter().map(|&v| v as f64).collect();
            let x: Vec<f64> = q.iter().map(|&v| v as f64).collect();
            // f64 loss: Σ G ⊙ R(q) with the same formula in f64.
            let loss = |x: &[f64]| -> f64 {
                let n = (x.iter().map(|v| v * v).sum::<f64>()).sqrt();
                let (w0, x0, y0, z0) = (x[0] / n, x[1] / n, x[2] / n, x[3] / n);
                let r = glam::DMat3::from_quat(glam::DQuat::from_xyzw(x0, y0, z0, w0));
                let gd = g.as_dmat3();
                (0..3).map(|c| r.col(c).dot(gd.col(c))).sum()
            };
            check_gradient(loss, &x, &analytic, &GradCheck { eps: 1e-6, rtol: 1e-3, atol: 1e-5, ..Default::default() }).unwrap();
        }
    }

    #[test]
    fn degenerate_quaternion_is_identity() {
        assert_eq!(rotation_matrix([0.0; 4]), Mat3::IDENTITY);
        assert_eq!(rotation_matrix([f32::NAN, 0.0, 0.0, 0.0]), Mat3::IDENTITY);
        assert_eq!(rotation_matrix_backward([0.0; 4], Mat3::IDENTITY), [0.0; 4]);
        // Non-normalised quaternions are normalised.
        let a = rotation_matrix([2.0, 0.0, 0.0, 2.0]);
        assert!((a.col(0) - Vec3::Y).length() < 1e-6);
    }

    #[test]
    fn normal_is_smallest_axis_and_ties_are_deterministic() {
        let mut g = Gaussians::with_len(2).unwrap();
        g.log_scales[0] = [0.0, -3.0, 0.0];
        g.log_scales[1] = [1.0, 1.0, 1.0];
        assert_eq!(g.normal(0), Vec3::Y);
        assert_eq!(g.normal(1), Vec3::X);
        g.log_scales[0] = [-20.0, 10.0, 10.0];
        let c = g.covariance(0);
        assert!(c.is_finite());
    }

    #[test]
    fn activations_are_stable_at_extremes() {
        assert_eq!(sigmoid(30.0), 1.0 / (1.0 + (-30.0f32).exp()));
        assert!(sigmoid(-30.0) > 0.0 && sigmoid(-30.0) < 1e-12);
        assert!(sigmoid(-1000.0).is_finite() && sigmoid(1000.0) == 1.0);
        assert!((inverse_sigmoid(sigmoid(2.0)) - 2.0).abs() < 1e-5);
        assert!(inverse_sigmoid(0.0).is_finite() && inverse_sigmoid(1.0).is_finite());
    }

    #[test]
    fn retain_and_validate() {
        let mut g = Gaussians::with_len(3).unwrap();
        g.means[1] = [1.0, 2.0, 3.0];
        g.retain(&[false, true, false]).unwrap();
        assert_eq!(g.len(), 1);
        assert_eq!(g.means[0], [1.0, 2.0, 3.0]);
        assert!(g.validate().is_ok());
        g.opacity_logits[0] = f32::NAN;
        assert!(g.validate().is_err());
        g.opacity_logits.push(0.0);
        assert!(g.validate().is_err());
        assert!(g.retain(&[true, true]).is_err());
        assert_eq!(g.sh_flat().len(), 48);
    }
}
