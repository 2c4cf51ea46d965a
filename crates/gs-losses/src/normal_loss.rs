//! Edge-aware normal consistency L_nc (docs/method.md §L_nc) and normal smoothing L_ns (§L_ns), with
//! gradients into the rendered normal Ñ and, through the depth normal N̂, into the plane depth z.

use crate::error::{LossError, Result};
use crate::image_loss::EdgeGuide;
use crate::normal::{depth_normal, depth_normal_backward};
use crate::Real;
use crate::dims::ordered_sum;
use gs_core::{Image, Intrinsics};
use rayon::prelude::*;

/// Direction of the L_ns gate on the rendered normals, `[‖Ñ_k − Ñ_p‖₁ ? τ]`.
///
/// The paper writes the Iverson bracket without a comparison. [`NsGate::Above`] (the default,
/// docs/method.md §L_ns) acts where the rendered normals jump by more than τ; [`NsGate::Below`]
/// (`--ns-gate below`) acts where they are already smooth (difference below τ).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum NsGate {
    /// `[‖Ñ_k − Ñ_p‖₁ > τ]` (default).
    #[default]
    Above,
    /// `[‖Ñ_k − Ñ_p‖₁ < τ]`.
    Below,
}

gs_core::named_choices!(NsGate, "L_ns gate", { NsGate::Above => "above", NsGate::Below => "below" });

/// Which neighbour pairs L_ns sums over.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum NsPairs {
    /// Only pairs with both pixels off the image border (default, docs/method.md §L_ns: N̂ is 0 on
    /// the border by construction, so border pairs would add a spurious ‖N̂_k‖₁).
    #[default]
    Interior,
    /// Every pair (the formula read literally; for comparison with the reference only).
    All,
}

/// L_nc = mean over pixels of δ·‖N̂ − Ñ‖₁. Returns the value; adds `weight·∂/∂N̂` and
/// `weight·∂/∂Ñ` to the given buffers (`[H][W][3]`).
pub fn normal_consistency<T: Real>(
    nhat: &[T],
    ntilde: &[T],
    delta: &[T],
    weight: f64,
    grad_nhat: Option<&mut [T]>,
    grad_ntilde: Option<&mut [T]>,
) -> f64 {
    let n = delta.len();
    assert_eq!(nhat.len(), n * 3, "normal_consistency: N̂ length");
    assert_eq!(ntilde.len(), n * 3, "normal_consistency: Ñ length");
    if n == 0 {
        return 0.0;
    }
    let sum = consistency_sum(n, |p| {
        let d = (nhat[3 * p] - ntilde[3 * p]).abs()
            + (nhat[3 * p + 1] - ntilde[3 * p + 1]).abs()
            + (nhat[3 * p + 2] - ntilde[3 * p + 2]).abs();
        (delta[p] * d).to_f64()
    });
    let s = T::from_f64(weight / n as f64);
    if let Some(g) = grad_nhat {
        g.par_iter_mut()
            .enumerate()
            .for_each(|(i, gi)| *gi += s * delta[i / 3] * (nhat[i] - ntilde[i]).sign0());
    }
    if let Some(g) = grad_ntilde {
        g.par_iter_mut()
            .enumerate()
            .for_each(|(i, gi)| *gi -= s * delta[i / 3] * (nhat[i] - ntilde[i]).sign0());
    }
    sum / n as f64
}

/// The fixed-order sum of L_nc's per-pixel values `value(p)` over `n` pixels: in chunks of 4096
/// pixels, the chunks in order (the device twin sums its per-pixel values the same way).
pub(crate) fn consistency_sum(n: usize, value: impl Fn(usize) -> f64 + Sync + Send) -> f64 {
    const CH: usize = 4096;
    ordered_sum(n.div_ceil(CH), |b| (b * CH..((b + 1) * CH).min(n)).map(&value).sum())
}

/// The fixed-order sum of L_ns's per-row values and active-pair counts: the rows in order.
pub(crate) fn smoothing_sum(rows: Vec<(f64, usize)>) -> (f64, usize) {
    (rows.iter().map(|r| r.0).sum(), rows.iter().map(|r| r.1).sum())
}

#[inline]
fn l1_3<T: Real>(v: &[T], p: usize, q: usize) -> T {
    (v[3 * q] - v[3 * p]).abs()
        + (v[3 * q + 1] - v[3 * p + 1]).abs()
        + (v[3 * q + 2] - v[3 * p + 2]).abs()
}

/// L_ns = (1/HW) Σ_p Σ_{k ∈ right, down} δ_k·ReLU(‖N̂_k − N̂_p‖₁ − τ²)·[‖Ñ_k − Ñ_p‖₁ gate τ].
/// Returns the value and the number of pairs that pass the gate; adds `weight·∂/∂N̂` to
/// `grad_nhat` when given (the gate is a constant mask, so Ñ gets no gradient).
#[allow(clippy::too_many_arguments)]
pub fn normal_smoothing<T: Real>(
    nhat: &[T],
    ntilde: &[T],
    delta: &[T],
    width: usize,
    height: usize,
    tau: f64,
    gate: NsGate,
    pairs: NsPairs,
    weight: f64,
    grad_nhat: Option<&mut [T]>,
) -> (f64, usize) {
    let (w, h) = (width, height);
    assert_eq!(delta.len(), w * h, "normal_smoothing: δ length");
    assert_eq!(nhat.len(), w * h * 3, "normal_smoothing: N̂ length");
    assert_eq!(ntilde.len(), w * h * 3, "normal_smoothing: Ñ length");
    if w * h == 0 {
        return (0.0, 0);
    }
    let tau_t = T::from_f64(tau);
    let tau2 = T::from_f64(tau * tau);
    let border = |i: usize, j: usize| i == 0 || j == 0 || i + 1 == w || j + 1 == h;
    // Whether pair (p, k) counts (pair rule and gate).
    let active = |pi: usize, pj: usize, ki: usize, kj: usize| -> bool {
        if pairs == NsPairs::Interior && (border(pi, pj) || border(ki, kj)) {
            return false;
        }
        let dt = l1_3(ntilde, pj * w + pi, kj * w + ki);
        match gate {
            NsGate::Above => dt > tau_t,
            NsGate::Below => dt < tau_t,
        }
    };
    let rows: Vec<(f64, usize)> = (0..h)
        .into_par_iter()
        .map(|j| {
            let mut s = 0.0;
            let mut cnt = 0;
            for i in 0..w {
                let p = j * w + i;
                for (ki, kj) in [(i + 1, j), (i, j + 1)] {
                    if ki >= w || kj >= h || !active(i, j, ki, kj) {
                        continue;
                    }
                    cnt += 1;
                    let k = kj * w + ki;
                    let r = l1_3(nhat, p, k) - tau2;
                    if r > T::ZERO {
                        s += (delta[k] * r).to_f64();
                    }
                }
            }
            (s, cnt)
        })
        .collect();
    let (total, count) = smoothing_sum(rows);
    let hw = (w * h) as f64;
    if let Some(g) = grad_nhat {
        let s = T::from_f64(weight / hw);
        // ∂/∂N̂_k of pair (p, k): coef·sign(N̂_k − N̂_p); ∂/∂N̂_p: the negative.
        let coef = |pi: usize, pj: usize, ki: usize, kj: usize| -> T {
            if !active(pi, pj, ki, kj) {
                return T::ZERO;
            }
            let (p, k) = (pj * w + pi, kj * w + ki);
            if l1_3(nhat, p, k) - tau2 > T::ZERO {
                s * delta[k]
            } else {
                T::ZERO
            }
        };
        g.par_chunks_mut(w * 3).enumerate().for_each(|(j, row)| {
            for i in 0..w {
                let p = j * w + i;
                let mut acc = [T::ZERO; 3];
                let mut add = |c: T, from: usize, to: usize, sign: T| {
                    if c != T::ZERO {
                        for d in 0..3 {
                            acc[d] += sign * c * (nhat[3 * to + d] - nhat[3 * from + d]).sign0();
                        }
                    }
                };
                // p as the first pixel of (p, right) and (p, down).
                if i + 1 < w {
                    add(coef(i, j, i + 1, j), p, p + 1, -T::ONE);
                }
                if j + 1 < h {
                    add(coef(i, j, i, j + 1), p, p + w, -T::ONE);
                }
                // p as the neighbour k of (left, p) and (up, p).
                if i >= 1 {
                    add(coef(i - 1, j, i, j), p - 1, p, T::ONE);
                }
                if j >= 1 {
                    add(coef(i, j - 1, i, j), p - w, p, T::ONE);
                }
                for d in 0..3 {
                    row[3 * i + d] += acc[d];
                }
            }
        });
    }
    (total / hw, count)
}

/// λ1 of the paper: weight of L_nc.
pub const LAMBDA_NC: f32 = 0.015;
/// λ2 of the paper: weight of L_ns.
pub const LAMBDA_NS: f32 = 0.3;
/// τ of L_ns: the normal-difference threshold of its gate.
pub const TAU: f32 = 0.01;

/// Weights and options of the normal terms. The weights λ1, λ2 are applied here: the returned
/// gradients are those of `lambda_nc·L_nc + lambda_ns·L_ns`, the returned values are unweighted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalLossConfig {
    /// λ1, weight of L_nc (paper: 0.015). 0 turns the term off.
    pub lambda_nc: f32,
    /// λ2, weight of L_ns (paper: 0.3). 0 turns the term off.
    pub lambda_ns: f32,
    /// τ of L_ns (paper: 0.01).
    pub tau: f32,
    /// Gate direction of L_ns.
    pub gate: NsGate,
    /// Pair rule of L_ns.
    pub pairs: NsPairs,
}

impl Default for NormalLossConfig {
    fn default() -> Self {
        Self {
            lambda_nc: LAMBDA_NC,
            lambda_ns: LAMBDA_NS,
            tau: TAU,
            gate: NsGate::Above,
            pairs: NsPairs::Interior,
        }
    }
}

/// Values and gradients of the normal terms: host images, or (`NormalLossOutput<
/// gs_gpu::DeviceImage>`, the device twin's `finish_on_device`) images kept on the device.
#[derive(Debug, Clone)]
pub struct NormalLossOutput<G = Image> {
    /// L_nc (unweighted).
    pub l_nc: f64,
    /// L_ns (unweighted).
    pub l_ns: f64,
    /// Number of L_ns pairs that pass the gate.
    pub ns_active_pairs: usize,
    /// λ1·L_nc + λ2·L_ns.
    pub total: f64,
    /// The depth normal N̂ (`[H][W][3]`).
    pub depth_normal: G,
    /// ∂total/∂z, plane depth (`[H][W]`, 1 channel).
    pub grad_plane_depth: G,
    /// ∂total/∂Ñ, rendered normal (`[H][W][3]`).
    pub grad_normal: G,
}

/// L_nc and L_ns of a rendered view: `plane_depth` z (1 channel), `rendered_normal` Ñ (3
/// channels, camera space), optional rendered alpha A (1 channel, constant), the view's
/// [`EdgeGuide`] (δ from the ground-truth image) and the camera intrinsics.
pub fn normal_losses(
    plane_depth: &Image,
    rendered_normal: &Image,
    alpha: Option<&Image>,
    guide: &EdgeGuide,
    intrinsics: &Intrinsics,
    cfg: &NormalLossConfig,
) -> Result<NormalLossOutput> {
    check_inputs(plane_depth, rendered_normal, alpha, guide, intrinsics, cfg)?;
    let (w, h) = (plane_depth.width(), plane_depth.height());
    let z = plane_depth.data();
    let a = alpha.map(|a| a.data());
    let nt = rendered_normal.data();
    let delta = guide.delta.data();
    let nhat = depth_normal(z, w, h, intrinsics, a);
    let mut g_nhat = vec![0.0f32; w * h * 3];
    let mut g_nt = vec![0.0f32; w * h * 3];
    let l_nc = normal_consistency(
        &nhat,
        nt,
        delta,
        cfg.lambda_nc as f64,
        Some(&mut g_nhat),
        Some(&mut g_nt),
    );
    let (l_ns, active) = normal_smoothing(
        &nhat,
        nt,
        delta,
        w,
        h,
        cfg.tau as f64,
        cfg.gate,
        cfg.pairs,
        cfg.lambda_ns as f64,
        Some(&mut g_nhat),
    );
    let mut g_z = vec![0.0f32; w * h];
    depth_normal_backward(z, w, h, intrinsics, a, &g_nhat, &mut g_z);
    NormalLossOutput::assemble(cfg, (w, h), (l_nc, l_ns, active), nhat, g_z, g_nt)
}

impl NormalLossOutput {
    /// The output of a `size` view from the terms' values (L_nc, L_ns, active pairs), N̂ and
    /// the two gradients, with the weighted total.
    pub(crate) fn assemble(
        cfg: &NormalLossConfig,
        (w, h): (usize, usize),
        (l_nc, l_ns, active): (f64, f64, usize),
        nhat: Vec<f32>,
        grad_z: Vec<f32>,
        grad_normal: Vec<f32>,
    ) -> Result<Self> {
        Ok(Self {
            l_nc,
            l_ns,
            ns_active_pairs: active,
            total: cfg.lambda_nc as f64 * l_nc + cfg.lambda_ns as f64 * l_ns,
            depth_normal: Image::from_vec(w, h, 3, nhat)?,
            grad_plane_depth: Image::from_vec(w, h, 1, grad_z)?,
            grad_normal: Image::from_vec(w, h, 3, grad_normal)?,
        })
    }
}

/// The checks of [`normal_losses`]' inputs (shared with the device twin): channel counts, one
/// size for every image, finite non-negative weights and τ, finite intrinsics with positive
/// focal lengths.
pub(crate) fn check_inputs(
    plane_depth: &Image,
    rendered_normal: &Image,
    alpha: Option<&Image>,
    guide: &EdgeGuide,
    intrinsics: &Intrinsics,
    cfg: &NormalLossConfig,
) -> Result<()> {
    let (w, h) = (plane_depth.width(), plane_depth.height());
    if plane_depth.channels() != 1 {
        return Err(LossError::Channels(format!(
            "plane depth has {} channels, needs 1",
            plane_depth.channels()
        )));
    }
    if rendered_normal.channels() != 3 {
        return Err(LossError::Channels(format!(
            "rendered normal has {} channels, needs 3",
            rendered_normal.channels()
        )));
    }
    if rendered_normal.width() != w || rendered_normal.height() != h {
        return Err(LossError::ShapeMismatch(format!(
            "rendered normal is {}×{}, plane depth {w}×{h}",
            rendered_normal.width(),
            rendered_normal.height()
        )));
    }
    if let Some(a) = alpha
        && (a.width() != w || a.height() != h || a.channels() != 1)
    {
        return Err(LossError::ShapeMismatch(format!(
            "alpha is {}×{}×{}, needs {w}×{h}×1",
            a.width(),
            a.height(),
            a.channels()
        )));
    }
    check_view((w, h), guide, intrinsics, cfg)
}

/// The checks of a view of `w` × `h` rendered pixels that do not look at the rendered images:
/// the guide's size, finite non-negative weights and τ, finite intrinsics with positive focal
/// lengths (shared with the device twin's surface on the device).
pub(crate) fn check_view((w, h): (usize, usize), guide: &EdgeGuide, intrinsics: &Intrinsics, cfg: &NormalLossConfig) -> Result<()> {
    if guide.delta.width() != w || guide.delta.height() != h {
        return Err(LossError::ShapeMismatch(format!(
            "edge guide is {}×{}, plane depth {w}×{h}",
            guide.delta.width(),
            guide.delta.height()
        )));
    }
    for (name, v) in [("λ1", cfg.lambda_nc), ("λ2", cfg.lambda_ns), ("τ", cfg.tau)] {
        if !v.is_finite() || v < 0.0 {
            return Err(LossError::InvalidParameter(format!(
                "{name} = {v} must be finite and ≥ 0"
            )));
        }
    }
    for (x, k) in [
        ("fx", intrinsics.fx),
        ("fy", intrinsics.fy),
        ("cx", intrinsics.cx),
        ("cy", intrinsics.cy),
    ] {
        if !k.is_finite() || ((x == "fx" || x == "fy") && k <= 0.0) {
            return Err(LossError::InvalidParameter(format!("intrinsics {x} = {k}")));
        }
    }
    Ok(())
}
