//! SSIM with the 3DGS window (11×11 Gaussian, σ = 1.5, C1 = 0.01², C2 = 0.03²; docs/method.md §L_I),
//! forward and analytic backward, computed with separable convolutions.
//!
//! **Border handling.** The local statistics μ, σ² and σ_12 are zero-padded 'same' convolutions,
//! exactly what 3DGS's `F.conv2d(img, window, padding=5, groups=C)` computes (the window is not
//! renormalised near the border). [`SsimRegion::Full`] then averages the SSIM map over every pixel
//! and channel: this is the training loss and the default metric. [`SsimRegion::Interior`]
//! averages only over pixels at least 5 pixels from every border, where the window never leaves
//! the image; there zero padding, reflection and any other border rule agree, and the value equals
//! scikit-image's `structural_similarity(gaussian_weights=True, sigma=1.5,
//! use_sample_covariance=False, data_range=1, channel_axis=-1)` (which filters with reflection and
//! then crops 5 pixels before averaging).

use crate::error::{LossError, Result};
use crate::Real;
use crate::dims::{Dims, ordered_sum};
use rayon::prelude::*;

/// Window radius (11 taps).
pub const SSIM_RADIUS: usize = 5;
/// σ of the Gaussian window.
pub const SSIM_SIGMA: f64 = 1.5;
/// Stabiliser of the luminance term, (0.01·data_range)².
pub const SSIM_C1: f64 = 0.01 * 0.01;
/// Stabiliser of the contrast–structure term, (0.03·data_range)².
pub const SSIM_C2: f64 = 0.03 * 0.03;

/// Which pixels the SSIM map is averaged over (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SsimRegion {
    /// Every pixel (3DGS / PGSR / VA-GS training loss; zero-padded statistics at the border).
    #[default]
    Full,
    /// Only pixels ≥ 5 px from each border (scikit-image compatible). Needs width, height ≥ 11.
    Interior,
}

/// The normalised 1-D Gaussian window (11 taps, σ 1.5); the 2-D window is its outer product.
pub fn gaussian_window_1d() -> [f64; 2 * SSIM_RADIUS + 1] {
    let mut g = [0.0; 2 * SSIM_RADIUS + 1];
    for (k, gk) in g.iter_mut().enumerate() {
        let x = k as f64 - SSIM_RADIUS as f64;
        *gk = (-(x * x) / (2.0 * SSIM_SIGMA * SSIM_SIGMA)).exp();
    }
    let s: f64 = g.iter().sum();
    g.iter_mut().for_each(|v| *v /= s);
    g
}

/// Zero-padded 'same' separable Gaussian filter of an `[H][W][C]` buffer (self-adjoint, as the
/// window is symmetric). `tmp` and `out` have the length of `src`.
pub(crate) fn blur<T: Real>(src: &[T], dims: Dims, tmp: &mut [T], out: &mut [T]) {
    let g: Vec<T> = gaussian_window_1d()
        .iter()
        .map(|&v| T::from_f64(v))
        .collect();
    let (w, h, c) = (dims.width, dims.height, dims.channels);
    let row = w * c;
    let r = SSIM_RADIUS as isize;
    // Horizontal pass: contiguous slice updates per tap (vectorisable).
    tmp.par_chunks_mut(row).enumerate().for_each(|(y, trow)| {
        let srow = &src[y * row..(y + 1) * row];
        trow.iter_mut().for_each(|v| *v = T::ZERO);
        for (k, &gk) in g.iter().enumerate() {
            let dx = k as isize - r;
            let x0 = (-dx).max(0) as usize;
            let x1 = (w as isize - dx).min(w as isize);
            if x1 <= x0 as isize {
                continue;
            }
            let x1 = x1 as usize;
            let dst = &mut trow[x0 * c..x1 * c];
            let s0 = (x0 as isize + dx) as usize * c;
            let s = &srow[s0..s0 + dst.len()];
            for (d, &v) in dst.iter_mut().zip(s) {
                *d += gk * v;
            }
        }
    });
    // Vertical pass.
    out.par_chunks_mut(row).enumerate().for_each(|(y, orow)| {
        orow.iter_mut().for_each(|v| *v = T::ZERO);
        for (k, &gk) in g.iter().enumerate() {
            let yy = y as isize + k as isize - r;
            if yy < 0 || yy >= h as isize {
                continue;
            }
            let trow = &tmp[yy as usize * row..(yy as usize + 1) * row];
            for (d, &v) in orow.iter_mut().zip(trow) {
                *d += gk * v;
            }
        }
    });
}

/// The five filtered moments μ_a, μ_b, E[a²], E[b²], E[ab].
struct Moments<T> {
    mu_a: Vec<T>,
    mu_b: Vec<T>,
    e_aa: Vec<T>,
    e_bb: Vec<T>,
    e_ab: Vec<T>,
}

fn moments<T: Real>(a: &[T], b: &[T], dims: Dims) -> Moments<T> {
    let n = dims.len();
    let mut tmp = vec![T::ZERO; n];
    let mut prod = vec![T::ZERO; n];
    let f = |src: &[T], tmp: &mut [T]| {
        let mut out = vec![T::ZERO; n];
        blur(src, dims, tmp, &mut out);
        out
    };
    let mu_a = f(a, &mut tmp);
    let mu_b = f(b, &mut tmp);
    prod.par_iter_mut()
        .zip(a.par_iter())
        .for_each(|(p, &x)| *p = x * x);
    let e_aa = f(&prod, &mut tmp);
    prod.par_iter_mut()
        .zip(b.par_iter())
        .for_each(|(p, &x)| *p = x * x);
    let e_bb = f(&prod, &mut tmp);
    prod.par_iter_mut()
        .zip(a.par_iter().zip(b.par_iter()))
        .for_each(|(p, (&x, &y))| *p = x * y);
    let e_ab = f(&prod, &mut tmp);
    Moments {
        mu_a,
        mu_b,
        e_aa,
        e_bb,
        e_ab,
    }
}

/// Pixel range `[x0, x1) × [y0, y1)` averaged over, or an error when it is empty.
fn region_bounds(dims: Dims, region: SsimRegion) -> Result<(usize, usize, usize, usize)> {
    if dims.is_empty() {
        return Err(LossError::InvalidParameter("SSIM of an empty image".into()));
    }
    match region {
        SsimRegion::Full => Ok((0, dims.width, 0, dims.height)),
        SsimRegion::Interior => {
            let r = SSIM_RADIUS;
            if dims.width < 2 * r + 1 || dims.height < 2 * r + 1 {
                return Err(LossError::InvalidParameter(format!(
                    "SSIM over the interior needs an image of at least 11×11 pixels, got {}×{}",
                    dims.width, dims.height
                )));
            }
            Ok((r, dims.width - r, r, dims.height - r))
        }
    }
}

#[inline]
fn ssim_pixel<T: Real>(ma: T, mb: T, eaa: T, ebb: T, eab: T) -> T {
    let (c1, c2) = (T::from_f64(SSIM_C1), T::from_f64(SSIM_C2));
    let two = T::from_f64(2.0);
    let saa = eaa - ma * ma;
    let sbb = ebb - mb * mb;
    let sab = eab - ma * mb;
    ((two * ma * mb + c1) * (two * sab + c2)) / ((ma * ma + mb * mb + c1) * (saa + sbb + c2))
}

/// Mean SSIM of `a` and `b` (`[H][W][C]`, same size) over `region`; symmetric in a and b.
pub fn ssim<T: Real>(a: &[T], b: &[T], dims: Dims, region: SsimRegion) -> Result<f64> {
    check_len(a, b, dims)?;
    let (x0, x1, y0, y1) = region_bounds(dims, region)?;
    let m = moments(a, b, dims);
    let c = dims.channels;
    let row = dims.width * c;
    let sum = ordered_sum(y1 - y0, |k| {
        let y = y0 + k;
        let mut s = 0.0;
        for i in y * row + x0 * c..y * row + x1 * c {
            s += ssim_pixel(m.mu_a[i], m.mu_b[i], m.e_aa[i], m.e_bb[i], m.e_ab[i]).to_f64();
        }
        s
    });
    Ok(sum / ((x1 - x0) * (y1 - y0) * c) as f64)
}

/// Mean SSIM (returned) and its gradient: adds `weight · ∂SSIM/∂a` to `grad_a`.
/// For the D-SSIM term β1·(1 − SSIM) pass `weight = −β1`.
pub fn ssim_backward<T: Real>(
    a: &[T],
    b: &[T],
    dims: Dims,
    region: SsimRegion,
    weight: f64,
    grad_a: &mut [T],
) -> Result<f64> {
    check_len(a, b, dims)?;
    if grad_a.len() != dims.len() {
        return Err(LossError::ShapeMismatch(format!(
            "SSIM gradient buffer has {} values, the image {}",
            grad_a.len(),
            dims.len()
        )));
    }
    let (x0, x1, y0, y1) = region_bounds(dims, region)?;
    let m = moments(a, b, dims);
    let n = dims.len();
    let c = dims.channels;
    let row = dims.width * c;
    let wp = T::from_f64(weight / ((x1 - x0) * (y1 - y0) * c) as f64);
    let (c1, c2) = (T::from_f64(SSIM_C1), T::from_f64(SSIM_C2));
    let two = T::from_f64(2.0);
    // Per-pixel partials of S w.r.t. μ_a (total), E[a²] and E[ab], scaled by the mean weight.
    let mut d_mu = vec![T::ZERO; n];
    let mut d_aa = vec![T::ZERO; n];
    let mut d_ab = vec![T::ZERO; n];
    let sums: Vec<f64> = d_mu
        .par_chunks_mut(row)
        .zip(d_aa.par_chunks_mut(row))
        .zip(d_ab.par_chunks_mut(row))
        .enumerate()
        .map(|(y, ((dmu, daa), dab))| {
            if y < y0 || y >= y1 {
                return 0.0;
            }
            let mut s = 0.0;
            for li in x0 * c..x1 * c {
                let i = y * row + li;
                let (ma, mb) = (m.mu_a[i], m.mu_b[i]);
                let saa = m.e_aa[i] - ma * ma;
                let sbb = m.e_bb[i] - mb * mb;
                let sab = m.e_ab[i] - ma * mb;
                let num1 = two * ma * mb + c1;
                let num2 = two * sab + c2;
                let den1 = ma * ma + mb * mb + c1;
                let den2 = saa + sbb + c2;
                let dd = den1 * den2;
                let sv = num1 * num2 / dd;
                s += sv.to_f64();
                let ds_dmu = two * mb * num2 / dd - two * ma * sv / den1;
                let ds_dsab = two * num1 / dd;
                let ds_dsaa = -sv / den2;
                dmu[li] = wp * (ds_dmu - two * ma * ds_dsaa - mb * ds_dsab);
                daa[li] = wp * ds_dsaa;
                dab[li] = wp * ds_dsab;
            }
            s
        })
        .collect();
    let mean = sums.iter().sum::<f64>() / ((x1 - x0) * (y1 - y0) * c) as f64;
    drop(m);
    let mut tmp = vec![T::ZERO; n];
    let mut b_mu = vec![T::ZERO; n];
    let mut b_aa = vec![T::ZERO; n];
    let mut b_ab = vec![T::ZERO; n];
    blur(&d_mu, dims, &mut tmp, &mut b_mu);
    blur(&d_aa, dims, &mut tmp, &mut b_aa);
    blur(&d_ab, dims, &mut tmp, &mut b_ab);
    grad_a.par_iter_mut().enumerate().for_each(|(i, g)| {
        *g += b_mu[i] + two * a[i] * b_aa[i] + b[i] * b_ab[i];
    });
    Ok(mean)
}

fn check_len<T>(a: &[T], b: &[T], dims: Dims) -> Result<()> {
    if a.len() != dims.len() || b.len() != dims.len() {
        return Err(LossError::ShapeMismatch(format!(
            "SSIM inputs have {} and {} values, {}×{}×{} needs {}",
            a.len(),
            b.len(),
            dims.width,
            dims.height,
            dims.channels,
            dims.len()
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn window_is_normalised_and_symmetric() {
        let g = gaussian_window_1d();
        assert!((g.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        for k in 0..5 {
            assert_eq!(g[k], g[10 - k]);
        }
    }

    #[test]
    fn blur_is_zero_padded_and_self_adjoint() {
        let dims = Dims::new(7, 4, 2);
        let x: Vec<f64> = (0..dims.len())
            .map(|i| ((i * 37) % 11) as f64 / 11.0)
            .collect();
        let y: Vec<f64> = (0..dims.len())
            .map(|i| ((i * 13) % 7) as f64 / 7.0)
            .collect();
        let (mut t, mut bx, mut by) = (
            vec![0.0; dims.len()],
            vec![0.0; dims.len()],
            vec![0.0; dims.len()],
        );
        blur(&x, dims, &mut t, &mut bx);
        blur(&y, dims, &mut t, &mut by);
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(p, q)| p * q).sum::<f64>();
        assert!((dot(&bx, &y) - dot(&x, &by)).abs() < 1e-12);
        // A constant image loses mass at the border (zero padding, no renormalisation).
        let ones = vec![1.0; dims.len()];
        blur(&ones, dims, &mut t, &mut bx);
        let g = gaussian_window_1d();
        let expect: f64 = g[5..].iter().sum::<f64>() * g[5..9].iter().sum::<f64>();
        assert!((bx[0] - expect).abs() < 1e-12, "{} vs {expect}", bx[0]);
    }
}
