//! L_s, the flattening term (docs/method.md §L_s): the mean smallest scale of the Gaussians,
//! (1/N)·Σᵢ minₖ exp(ℓᵢₖ), with ℓ the log-scales. PGSR's scale loss (weight 100 there).
//!
//! Why: a flat Gaussian has one well-defined normal and a plane depth that is not smeared along
//! it, and, seen edge-on at a silhouette, it covers almost nothing beyond its own plane. Off by
//! default: VA-GS keeps full 3D Gaussians, whose ablation finds flattening no better for meshes,
//! and on our suite it moved the worst mesh further from its floor (docs/suite-quick.md, stop
//! 60). A parameter-space term: it reads the log-scales, not a render.
//!
//! ∂/∂ℓᵢₖ = exp(ℓᵢₖ)/N on the smallest axis k of Gaussian i (the lowest index among equal
//! scales, as [`gs_core::Gaussians::normal`] breaks ties), 0 on the others.

use crate::error::{LossError, Result, check_parameter_term};
use gs_core::gaussians::smallest_axis;

/// The default weight λ_s of L_s: off (docs/method.md §L_s).
pub const LAMBDA_S: f32 = 0.0;

/// The mean smallest scale of `log_scales`, summed in index order in f64 (the same value at
/// any thread count), and `grad[i][k] += weight · ∂/∂ℓᵢₖ` of it. An empty model has L_s = 0.
/// Refuses a non-finite log-scale or weight, or a gradient buffer of another length.
pub fn smallest_scale_mean(log_scales: &[[f32; 3]], weight: f32, grad: &mut [[f32; 3]]) -> Result<f64> {
    check_parameter_term("L_s", "log-scale rows", log_scales.len(), grad.len(), weight)?;
    if let Some(i) = log_scales.iter().position(|l| l.iter().any(|x| !x.is_finite())) {
        let [a, b, c] = log_scales[i];
        return Err(LossError::InvalidParameter(format!("log-scale row {i} is ({a}, {b}, {c}): not finite")));
    }
    if log_scales.is_empty() {
        return Ok(0.0);
    }
    let n = log_scales.len() as f64;
    let per = weight as f64 / n;
    let mut sum = 0.0;
    for (g, l) in grad.iter_mut().zip(log_scales) {
        let k = smallest_axis(*l);
        let s = (l[k] as f64).exp();
        sum += s;
        g[k] += (per * s) as f32;
    }
    Ok(sum / n)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn value(l: &[[f64; 3]]) -> f64 {
        l.iter().map(|r| r.iter().copied().fold(f64::INFINITY, f64::min).exp()).sum::<f64>() / l.len() as f64
    }

    #[test]
    fn gradient_matches_f64_finite_differences() {
        let rows: Vec<[f32; 3]> = vec![[-3.0, -5.5, -4.0], [-1.0, -0.5, -2.0], [-7.0, -6.0, -6.5], [0.4, 0.2, 0.3]];
        let w = 100.0_f32;
        let mut g = vec![[0.25_f32; 3]; rows.len()];
        let v = smallest_scale_mean(&rows, w, &mut g).unwrap();
        let as64: Vec<[f64; 3]> = rows.iter().map(|r| r.map(|x| x as f64)).collect();
        assert!((v - value(&as64)).abs() < 1e-12);
        for i in 0..rows.len() {
            for k in 0..3 {
                let h = 1e-6;
                let (mut up, mut down) = (as64.clone(), as64.clone());
                up[i][k] += h;
                down[i][k] -= h;
                let fd = (value(&up) - value(&down)) / (2.0 * h) * w as f64;
                let got = (g[i][k] - 0.25) as f64;
                assert!((got - fd).abs() < 1e-5 * (1.0 + fd.abs()), "row {i} axis {k}: {got} vs {fd}");
            }
        }
    }

    #[test]
    fn ties_extremes_refusals_and_the_empty_model() {
        // Equal scales: the lowest axis, as the Gaussian's normal takes it.
        let mut g = [[0.0; 3]; 2];
        smallest_scale_mean(&[[-2.0, -2.0, -2.0], [-1.0, -2.0, -2.0]], 1.0, &mut g).unwrap();
        assert!(g[0][0] > 0.0 && g[0][1] == 0.0 && g[1][1] > 0.0 && g[1][2] == 0.0);
        // Tiny and large scales stay finite.
        let mut g = [[0.0; 3]; 2];
        let v = smallest_scale_mean(&[[-80.0, -70.0, -60.0], [30.0, 31.0, 32.0]], 1.0, &mut g).unwrap();
        assert!(v.is_finite() && g.iter().flatten().all(|x| x.is_finite()));
        assert!(g[0][0] > 0.0 && g[1][0] > 0.0 && g[0][1] == 0.0);
        assert!(matches!(smallest_scale_mean(&[[0.0, f32::NAN, 0.0]], 1.0, &mut [[0.0; 3]]), Err(LossError::InvalidParameter(m)) if m.contains("row 0")));
        assert!(matches!(smallest_scale_mean(&[[0.0; 3]], f32::NAN, &mut [[0.0; 3]]), Err(LossError::InvalidParameter(_))));
        assert!(matches!(smallest_scale_mean(&[[0.0; 3]], 1.0, &mut []), Err(LossError::ShapeMismatch(_))));
        assert_eq!(smallest_scale_mean(&[], 1.0, &mut []).unwrap(), 0.0);
    }
}
