//! L_o, the opacity entropy (docs/method.md §L_o): the mean binary entropy of the Gaussians'
//! opacities, H(o) = −o·ln o − (1 − o)·ln(1 − o), with o = σ(x) of the opacity logit x.
//!
//! Why: a surface trained by L_I alone is often a shell of semi-transparent Gaussians; L_o
//! pushes each opacity towards 0 or 1 (as SuGaR does before extracting a surface), so that a
//! surface's front layer becomes opaque and what lies behind it fades. Off by default: on the
//! validation suite it did not bring the meshed depth onto the surface and cost held-out PSNR
//! (docs/method.md §L_o). A parameter-space term: it reads the logits, not a render.
//!
//! In terms of the logit, ln o = −softplus(−x) and ln(1 − o) = −softplus(x), so
//! H = o·softplus(−x) + (1 − o)·softplus(x) and ∂H/∂x = −x·o·(1 − o): finite for every finite x.

use crate::error::{LossError, Result, check_parameter_term};

/// The default weight λ_o of L_o (docs/method.md §L_o): not a term of the paper.
pub const LAMBDA_O: f32 = 0.0;

/// ln(1 + eˣ) without overflow.
fn softplus(x: f64) -> f64 {
    x.max(0.0) + (-x.abs()).exp().ln_1p()
}

fn sigmoid(x: f64) -> f64 {
    if x >= 0.0 { 1.0 / (1.0 + (-x).exp()) } else { x.exp() / (1.0 + x.exp()) }
}

/// H(σ(x)) in nats, in f64 (0 at |x| → ∞, ln 2 at x = 0).
pub fn entropy_of_logit(x: f64) -> f64 {
    entropy_and_opacity(x).0
}

/// (H(σ(x)), σ(x)): the value and the opacity its gradient needs, from one sigmoid.
fn entropy_and_opacity(x: f64) -> (f64, f64) {
    let o = sigmoid(x);
    (o * softplus(-x) + (1.0 - o) * softplus(x), o)
}

/// The mean entropy (1/N)·Σ H(σ(xᵢ)) of `logits`, summed in index order (the same value at
/// any thread count), and `grad[i] += weight · ∂/∂xᵢ` of it. An empty model has L_o = 0.
/// Refuses a non-finite logit or weight, or a gradient buffer of another length.
pub fn opacity_entropy(logits: &[f32], weight: f32, grad: &mut [f32]) -> Result<f64> {
    check_parameter_term("L_o", "opacity logits", logits.len(), grad.len(), weight)?;
    if let Some(i) = logits.iter().position(|x| !x.is_finite()) {
        return Err(LossError::InvalidParameter(format!("opacity logit {i} is {}", logits[i])));
    }
    if logits.is_empty() {
        return Ok(0.0);
    }
    let n = logits.len() as f64;
    let scale = weight as f64 / n;
    let mut sum = 0.0;
    for (g, &x) in grad.iter_mut().zip(logits) {
        let x = x as f64;
        let (h, o) = entropy_and_opacity(x);
        sum += h;
        *g += (scale * -x * o * (1.0 - o)) as f32;
    }
    Ok(sum / n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_at_the_extremes() {
        assert!((entropy_of_logit(0.0) - std::f64::consts::LN_2).abs() < 1e-15);
        // Symmetric, and matching the definition in terms of o.
        for x in [-7.0, -1.3, 0.4, 2.0, 12.0] {
            let o: f64 = sigmoid(x);
            let h = -o * o.ln() - (1.0 - o) * (1.0 - o).ln();
            assert!((entropy_of_logit(x) - h).abs() < 1e-12, "x = {x}");
            assert!((entropy_of_logit(x) - entropy_of_logit(-x)).abs() < 1e-15);
        }
        // Saturated logits: no NaN or infinity, entropy and gradient → 0.
        let logits = [1e4_f32, -1e4, f32::MAX, -f32::MAX];
        let mut g = [0.0; 4];
        let v = opacity_entropy(&logits, 1.0, &mut g).unwrap();
        assert!(v.is_finite() && v < 1e-30 && g.iter().all(|x| *x == 0.0), "{v} {g:?}");
    }

    #[test]
    fn gradient_matches_f64_finite_differences() {
        let logits: Vec<f32> = vec![-6.0, -2.2, -0.7, 0.0, 0.3, 1.9, 5.5];
        let (w, n) = (0.25_f32, logits.len() as f64);
        let mut g = vec![0.5; logits.len()];
        opacity_entropy(&logits, w, &mut g).unwrap();
        for (i, &x) in logits.iter().enumerate() {
            let h = 1e-5;
            let fd = (entropy_of_logit(x as f64 + h) - entropy_of_logit(x as f64 - h)) / (2.0 * h) * w as f64 / n;
            let got = (g[i] - 0.5) as f64;
            assert!((got - fd).abs() < 1e-6 * (1.0 + fd.abs()), "logit {x}: {got} vs {fd}");
            // Towards 0 or 1: the descent direction −∂ moves x away from 0.
            assert!(x == 0.0 || -got * x as f64 > 0.0, "logit {x}");
        }
    }

    #[test]
    fn refusals_and_the_empty_model() {
        let mut g = [0.0; 2];
        assert!(matches!(opacity_entropy(&[0.0, f32::NAN], 1.0, &mut g), Err(LossError::InvalidParameter(m)) if m.contains("logit 1")));
        assert!(matches!(opacity_entropy(&[0.0, 1.0], f32::INFINITY, &mut g), Err(LossError::InvalidParameter(_))));
        assert!(matches!(opacity_entropy(&[0.0], 1.0, &mut g), Err(LossError::ShapeMismatch(_))));
        assert_eq!(opacity_entropy(&[], 1.0, &mut []).unwrap(), 0.0);
    }
}
