//! Real spherical harmonics up to degree 3 (the 3DGS basis and sign conventions), forward and
//! backward.
//!
//! Colour of a Gaussian seen along unit direction `d = (μ − C)/‖μ − C‖` is
//! `c = Σ_k b_k(d)·sh_k + 0.5`, clamped at 0 (docs/method.md §Rendering). [`sh_basis`] gives the `b_k`,
//! [`sh_basis_jacobian`] their derivatives w.r.t. `d`, and [`eval_sh`] / [`eval_sh_backward`]
//! the colour and its gradients w.r.t. the coefficients and the direction.

/// Coefficients per colour channel at degree 3.
pub const SH_COEFFS: usize = 16;
/// Highest supported degree.
pub const MAX_SH_DEGREE: u32 = 3;

/// Y_0^0.
pub const SH_C0: f32 = 0.282_094_79;
const C1: f32 = 0.488_602_51;
const C2: [f32; 5] = [1.092_548_4, -1.092_548_4, 0.315_391_57, -1.092_548_4, 0.546_274_2];
const C3: [f32; 7] = [-0.590_043_6, 2.890_611_4, -0.457_045_8, 0.373_176_33, -0.457_045_8, 1.445_305_7, -0.590_043_6];

/// Number of coefficients used by `degree` (`(degree + 1)²`).
pub fn coeffs_for_degree(degree: u32) -> usize {
    let d = degree.min(MAX_SH_DEGREE) as usize + 1;
    d * d
}

/// SH basis values `b_k(d)` for `k < (degree+1)²` (the rest are 0), `d` a unit vector.
pub fn sh_basis(degree: u32, d: [f32; 3]) -> [f32; SH_COEFFS] {
    let [x, y, z] = d;
    let mut b = [0.0f32; SH_COEFFS];
    b[0] = SH_C0;
    if degree >= 1 {
        b[1] = -C1 * y;
        b[2] = C1 * z;
        b[3] = -C1 * x;
    }
    if degree >= 2 {
        let (xx, yy, zz, xy, yz, xz) = (x * x, y * y, z * z, x * y, y * z, x * z);
        b[4] = C2[0] * xy;
        b[5] = C2[1] * yz;
        b[6] = C2[2] * (2.0 * zz - xx - yy);
        b[7] = C2[3] * xz;
        b[8] = C2[4] * (xx - yy);
        if degree >= 3 {
            b[9] = C3[0] * y * (3.0 * xx - yy);
            b[10] = C3[1] * xy * z;
            b[11] = C3[2] * y * (4.0 * zz - xx - yy);
            b[12] = C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy);
            b[13] = C3[4] * x * (4.0 * zz - xx - yy);
            b[14] = C3[5] * z * (xx - yy);
            b[15] = C3[6] * x * (xx - 3.0 * yy);
        }
    }
    b
}

/// `∂b_k/∂d` for every basis function: row `k` is the gradient of `b_k` w.r.t. `(x, y, z)`.
pub fn sh_basis_jacobian(degree: u32, d: [f32; 3]) -> [[f32; 3]; SH_COEFFS] {
    let [x, y, z] = d;
    let mut j = [[0.0f32; 3]; SH_COEFFS];
    if degree >= 1 {
        j[1] = [0.0, -C1, 0.0];
        j[2] = [0.0, 0.0, C1];
        j[3] = [-C1, 0.0, 0.0];
    }
    if degree >= 2 {
        let (xx, yy, zz) = (x * x, y * y, z * z);
        j[4] = [C2[0] * y, C2[0] * x, 0.0];
        j[5] = [0.0, C2[1] * z, C2[1] * y];
        j[6] = [-2.0 * C2[2] * x, -2.0 * C2[2] * y, 4.0 * C2[2] * z];
        j[7] = [C2[3] * z, 0.0, C2[3] * x];
        j[8] = [2.0 * C2[4] * x, -2.0 * C2[4] * y, 0.0];
        if degree >= 3 {
            j[9] = [C3[0] * 6.0 * x * y, C3[0] * (3.0 * xx - 3.0 * yy), 0.0];
            j[10] = [C3[1] * y * z, C3[1] * x * z, C3[1] * x * y];
            j[11] = [-2.0 * C3[2] * x * y, C3[2] * (4.0 * zz - xx - 3.0 * yy), 8.0 * C3[2] * y * z];
            j[12] = [-6.0 * C3[3] * x * z, -6.0 * C3[3] * y * z, C3[3] * (6.0 * zz - 3.0 * xx - 3.0 * yy)];
            j[13] = [C3[4] * (4.0 * zz - 3.0 * xx - yy), -2.0 * C3[4] * x * y, 8.0 * C3[4] * x * z];
            j[14] = [2.0 * C3[5] * x * z, -2.0 * C3[5] * y * z, C3[5] * (xx - yy)];
            j[15] = [C3[6] * (3.0 * xx - 3.0 * yy), -6.0 * C3[6] * x * y, 0.0];
        }
    }
    j
}

/// Raw SH value `Σ_k b_k(d)·coeffs_k` per channel (no +0.5, no clamp).
pub fn eval_sh(degree: u32, coeffs: &[[f32; 3]; SH_COEFFS], d: [f32; 3]) -> [f32; 3] {
    let b = sh_basis(degree, d);
    let n = coeffs_for_degree(degree);
    let mut c = [0.0f32; 3];
    for k in 0..n {
        for ch in 0..3 {
            c[ch] += b[k] * coeffs[k][ch];
        }
    }
    c
}

/// Gradients of [`eval_sh`]: returns `(∂L/∂coeffs, ∂L/∂d)` given `∂L/∂c`. Coefficients above
/// `degree` get zero gradient.
pub fn eval_sh_backward(
    degree: u32,
    coeffs: &[[f32; 3]; SH_COEFFS],
    d: [f32; 3],
    grad_color: [f32; 3],
) -> ([[f32; 3]; SH_COEFFS], [f32; 3]) {
    let b = sh_basis(degree, d);
    let jac = sh_basis_jacobian(degree, d);
    let n = coeffs_for_degree(degree);
    let mut g_coeffs = [[0.0f32; 3]; SH_COEFFS];
    let mut g_dir = [0.0f32; 3];
    for k in 0..n {
        let mut s = 0.0;
        for ch in 0..3 {
            g_coeffs[k][ch] = b[k] * grad_color[ch];
            s += coeffs[k][ch] * grad_color[ch];
        }
        for a in 0..3 {
            g_dir[a] += s * jac[k][a];
        }
    }
    (g_coeffs, g_dir)
}

/// Gaussian colour of docs/method.md §Rendering: `max(eval_sh + 0.5, 0)` and, per channel, whether it
/// was clamped (the backward passes zero gradient there).
pub fn sh_to_color(degree: u32, coeffs: &[[f32; 3]; SH_COEFFS], d: [f32; 3]) -> ([f32; 3], [bool; 3]) {
    let raw = eval_sh(degree, coeffs, d);
    let mut c = [0.0; 3];
    let mut clamped = [false; 3];
    for ch in 0..3 {
        let v = raw[ch] + 0.5;
        clamped[ch] = v < 0.0;
        c[ch] = v.max(0.0);
    }
    (c, clamped)
}

/// Backward of `n = v/‖v‖`: `∂L/∂v = (∂L/∂n − n (n·∂L/∂n)) / ‖v‖` (zero for a zero vector).
pub fn normalize_backward(v: [f32; 3], grad_n: [f32; 3]) -> [f32; 3] {
    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if len <= 0.0 || !len.is_finite() {
        return [0.0; 3];
    }
    let n = [v[0] / len, v[1] / len, v[2] / len];
    let dot = n[0] * grad_n[0] + n[1] * grad_n[1] + n[2] * grad_n[2];
    [(grad_n[0] - n[0] * dot) / len, (grad_n[1] - n[1] * dot) / len, (grad_n[2] - n[2] * dot) / len]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gradcheck::{GradCheck, check_gradient};
    use crate::rng::Rng;

    fn random_coeffs(rng: &mut Rng) -> [[f32; 3]; SH_COEFFS] {
        let mut c = [[0.0; 3]; SH_COEFFS];
        for k in c.iter_mut() {
            for v in k.iter_mut() {
                *v = rng.normal() * 0.5;
            }
        }
        c
    }

    /// L = w · eval_sh(coeffs, normalize(v)); checked w.r.t. coefficients and the raw direction.
    #[test]
    fn sh_gradients_match_finite_differences_for_degrees_0_to_3() {
        let mut rng = Rng::new(11);
        for degree in 0..=3 {
            for _trial in 0..5 {
                let coeffs = random_coeffs(&mut rng);
                let v = [rng.normal(), rng.normal(), rng.normal()];
                let w = [rng.normal(), rng.normal(), rng.normal()];
                // Analytic gradient.
                let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                let d = [v[0] / len, v[1] / len, v[2] / len];
                let (gc, gd) = eval_sh_backward(degree, &coeffs, d, w);
                let gv = normalize_backward(v, gd);
                let mut x: Vec<f64> = coeffs.iter().flatten().map(|&c| c as f64).collect();
                x.extend(v.iter().map(|&c| c as f64));
                let mut analytic: Vec<f64> = gc.iter().flatten().map(|&c| c as f64).collect();
                analytic.extend(gv.iter().map(|&c| c as f64));
                // f64 reference loss using the same basis formula in f64 via f32 casts is too
                // coarse, so evaluate the f32 basis on f64-perturbed inputs with a large step.
                let loss = |x: &[f64]| -> f64 {
                    let mut c = [[0.0f32; 3]; SH_COEFFS];
                    for k in 0..SH_COEFFS {
                        for ch in 0..3 {
                            c[k][ch] = x[k * 3 + ch] as f32;
                        }
                    }
                    let v = [x[48], x[49], x[50]];
                    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                    let d = [(v[0] / l) as f32, (v[1] / l) as f32, (v[2] / l) as f32];
                    let col = eval_sh(degree, &c, d);
                    (0..3).map(|ch| col[ch] as f64 * w[ch] as f64).sum()
                };
                let report = check_gradient(loss, &x, &analytic, &GradCheck { eps: 1e-3, rtol: 2e-2, atol: 2e-3, ..Default::default() });
                assert!(report.is_ok(), "degree {degree}: {report:?}");
            }
        }
    }

    #[test]
    fn degree_zero_is_constant_and_higher_coeffs_ignored() {
        let mut c = [[0.0; 3]; SH_COEFFS];
        c[0] = [1.0, 2.0, 3.0];
        c[5] = [9.0, 9.0, 9.0];
        let a = eval_sh(0, &c, [1.0, 0.0, 0.0]);
        let b = eval_sh(0, &c, [0.0, 0.0, 1.0]);
        assert_eq!(a, b);
        assert!((a[0] - SH_C0).abs() < 1e-7);
        let (col, clamped) = sh_to_color(0, &[[-10.0; 3]; SH_COEFFS], [0.0, 0.0, 1.0]);
        assert_eq!(col, [0.0; 3]);
        assert_eq!(clamped, [true; 3]);
    }

    #[test]
    fn basis_is_orthonormal_on_the_sphere() {
        // Monte-Carlo check of ∫ b_i b_j = δ_ij over the unit sphere (area 4π).
        let mut rng = Rng::new(5);
        let n = 200_000;
        let mut gram = [[0.0f64; SH_COEFFS]; SH_COEFFS];
        for _ in 0..n {
            let v = [rng.normal(), rng.normal(), rng.normal()];
            let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            let b = sh_basis(3, [v[0] / l, v[1] / l, v[2] / l]);
            for i in 0..SH_COEFFS {
                for j in 0..SH_COEFFS {
                    gram[i][j] += (b[i] * b[j]) as f64;
                }
            }
        }
        let scale = 4.0 * std::f64::consts::PI / n as f64;
        for i in 0..SH_COEFFS {
            for j in 0..SH_COEFFS {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((gram[i][j] * scale - want).abs() < 0.03, "({i},{j}) = {}", gram[i][j] * scale);
            }
        }
    }
}
