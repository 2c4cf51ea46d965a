//! Finite-difference gradient checks in f64, shared by every crate's tests.
//!
//! ```
//! use gs_core::gradcheck::{check_gradient, GradCheck};
//! // L(x) = x0² + 3·x1, ∂L/∂x = (2·x0, 3).
//! let x = [1.5, -2.0];
//! let analytic = [3.0, 3.0];
//! let report = check_gradient(|x: &[f64]| x[0] * x[0] + 3.0 * x[1], &x, &analytic, &GradCheck::default());
//! assert!(report.is_ok());
//! ```

/// Options of [`check_gradient`].
#[derive(Debug, Clone, PartialEq)]
pub struct GradCheck {
    /// Central-difference step.
    pub eps: f64,
    /// Relative tolerance: `|a − n| ≤ atol + rtol·max(|a|, |n|)`.
    pub rtol: f64,
    /// Absolute tolerance.
    pub atol: f64,
    /// Check only these coordinates (all when `None`), to keep large problems cheap.
    pub indices: Option<Vec<usize>>,
}

impl Default for GradCheck {
    fn default() -> Self {
        Self { eps: 1e-6, rtol: 1e-5, atol: 1e-8, indices: None }
    }
}

/// Outcome of a gradient check: the worst coordinate and the error sizes.
#[derive(Debug, Clone, PartialEq)]
pub struct GradReport {
    /// Number of coordinates compared.
    pub checked: usize,
    /// Largest absolute difference between analytic and numeric gradient.
    pub max_abs_err: f64,
    /// Coordinate with the largest violation ratio (error / allowed).
    pub worst_index: usize,
    /// Analytic gradient at `worst_index`.
    pub worst_analytic: f64,
    /// Numeric gradient at `worst_index`.
    pub worst_numeric: f64,
    /// Coordinates outside tolerance.
    pub failures: usize,
}

/// Central differences `(f(x + eε) − f(x − eε)) / 2ε` for the requested coordinates.
pub fn numeric_gradient(mut f: impl FnMut(&[f64]) -> f64, x: &[f64], eps: f64, indices: &[usize]) -> Vec<f64> {
    let mut xp = x.to_vec();
    indices
        .iter()
        .map(|&i| {
            let orig = xp[i];
            xp[i] = orig + eps;
            let fp = f(&xp);
            xp[i] = orig - eps;
            let fm = f(&xp);
            xp[i] = orig;
            (fp - fm) / (2.0 * eps)
        })
        .collect()
}

/// Compares `analytic` with central differences of `f` at `x`. `Ok` with the report when every
/// checked coordinate is within tolerance, `Err` with the report otherwise.
pub fn check_gradient(
    f: impl FnMut(&[f64]) -> f64,
    x: &[f64],
    analytic: &[f64],
    opts: &GradCheck,
) -> Result<GradReport, GradReport> {
    assert_eq!(x.len(), analytic.len(), "check_gradient: x and analytic differ in length");
    let indices: Vec<usize> = opts.indices.clone().unwrap_or_else(|| (0..x.len()).collect());
    let numeric = numeric_gradient(f, x, opts.eps, &indices);
    let mut report = GradReport {
        checked: indices.len(),
        max_abs_err: 0.0,
        worst_index: indices.first().copied().unwrap_or(0),
        worst_analytic: 0.0,
        worst_numeric: 0.0,
        failures: 0,
    };
    let mut worst_ratio = -1.0;
    for (k, &i) in indices.iter().enumerate() {
        let (a, n) = (analytic[i], numeric[k]);
        let err = (a - n).abs();
        let allowed = opts.atol + opts.rtol * a.abs().max(n.abs());
        let ratio = if err.is_finite() { err / allowed } else { f64::INFINITY };
        if !(ratio <= 1.0) {
            report.failures += 1;
        }
        report.max_abs_err = report.max_abs_err.max(if err.is_finite() { err } else { f64::INFINITY });
        if ratio > worst_ratio || ratio.is_nan() {
            worst_ratio = if ratio.is_nan() { f64::INFINITY } else { ratio };
            report.worst_index = i;
            report.worst_analytic = a;
            report.worst_numeric = n;
        }
    }
    if report.failures == 0 { Ok(report) } else { Err(report) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detects_a_wrong_gradient() {
        let f = |x: &[f64]| x[0].sin() * x[1];
        let x = [0.3, 2.0];
        let good = [0.3f64.cos() * 2.0, 0.3f64.sin()];
        assert!(check_gradient(f, &x, &good, &GradCheck::default()).is_ok());
        let bad = [good[0] * 1.01, good[1]];
        let err = check_gradient(f, &x, &bad, &GradCheck::default()).unwrap_err();
        assert_eq!(err.worst_index, 0);
        assert_eq!(err.failures, 1);
    }

    #[test]
    fn nan_is_a_failure() {
        let f = |x: &[f64]| x[0];
        assert!(check_gradient(f, &[1.0], &[f64::NAN], &GradCheck::default()).is_err());
    }
}
