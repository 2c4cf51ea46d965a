//! Image metrics for evaluation (docs/method.md §Metrics): PSNR and SSIM; LPIPS lives in [`crate::lpips`].

use crate::error::{LossError, Result};
use crate::dims::{Dims, ordered_sum};
use crate::ssim::{SsimRegion, ssim};
use gs_core::Image;

/// Largest PSNR reported: identical images give MSE = 0, which is clamped to 1e-10 (100 dB) so that
/// reports stay finite (JSON has no infinity).
pub const PSNR_MAX_DB: f64 = 100.0;

fn same_size(a: &Image, b: &Image) -> Result<Dims> {
    let d = Dims::of(a);
    if Dims::of(b) != d {
        return Err(LossError::ShapeMismatch(format!(
            "images are {}×{}×{} and {}×{}×{}",
            d.width,
            d.height,
            d.channels,
            b.width(),
            b.height(),
            b.channels()
        )));
    }
    Ok(d)
}

/// PSNR in dB for data range 1: 10·log10(1 / MSE), MSE over all pixels and channels, capped at
/// [`PSNR_MAX_DB`].
pub fn psnr(a: &Image, b: &Image) -> Result<f64> {
    same_size(a, b)?;
    let (x, y) = (a.data(), b.data());
    let n = x.len();
    const CH: usize = 1 << 14;
    let se = ordered_sum(n.div_ceil(CH), |k| {
        let r = k * CH..((k + 1) * CH).min(n);
        x[r.clone()]
            .iter()
            .zip(&y[r])
            .map(|(&p, &q)| ((p - q) as f64).powi(2))
            .sum()
    });
    psnr_of_squared_error(se, n)
}

/// PSNR in dB of a summed squared error over `count` values, capped at [`PSNR_MAX_DB`]; shared
/// by [`psnr`] and [`psnr_masked`].
fn psnr_of_squared_error(se: f64, count: usize) -> Result<f64> {
    if !se.is_finite() {
        return Err(LossError::InvalidParameter(
            "PSNR of images with non-finite values".into(),
        ));
    }
    let mse = (se / count as f64).max(1e-10);
    Ok((-10.0 * mse.log10()).min(PSNR_MAX_DB))
}

/// Checks that `mask` is one channel of `image`'s size and returns its inside pixels
/// (value ≥ 0.5), which must not be empty.
fn mask_pixels(image: &Image, mask: &Image) -> Result<Vec<usize>> {
    if (mask.width(), mask.height(), mask.channels()) != (image.width(), image.height(), 1) {
        return Err(LossError::ShapeMismatch(format!(
            "mask is {}×{}×{} but the image is {}×{} (one channel expected)",
            mask.width(),
            mask.height(),
            mask.channels(),
            image.width(),
            image.height()
        )));
    }
    let inside: Vec<usize> = mask.data().iter().enumerate().filter(|(_, m)| **m >= 0.5).map(|(i, _)| i).collect();
    if inside.is_empty() {
        return Err(LossError::InvalidParameter("mask has no pixel inside (all < 0.5)".into()));
    }
    Ok(inside)
}

/// PSNR in dB over the pixels inside `mask` (one channel, inside where ≥ 0.5) only: the object
/// metric of masked benchmarks (DTU), where a background that no training view explains would
/// otherwise dominate. Capped at [`PSNR_MAX_DB`].
pub fn psnr_masked(a: &Image, b: &Image, mask: &Image) -> Result<f64> {
    let d = same_size(a, b)?;
    let inside = mask_pixels(a, mask)?;
    let (x, y, c) = (a.data(), b.data(), d.channels);
    let se: f64 = inside
        .iter()
        .map(|&p| (0..c).map(|k| ((x[p * c + k] - y[p * c + k]) as f64).powi(2)).sum::<f64>())
        .sum();
    psnr_of_squared_error(se, inside.len() * c)
}

/// `image` composited on black outside `mask` (inside where ≥ 0.5): SSIM and LPIPS of two such
/// composites compare the object only, as masked DTU evaluations do.
pub fn masked_on_black(image: &Image, mask: &Image) -> Result<Image> {
    mask_pixels(image, mask)?;
    let c = image.channels();
    let mut out = image.clone();
    for (px, m) in out.data_mut().chunks_exact_mut(c).zip(mask.data()) {
        if *m < 0.5 {
            px.fill(0.0);
        }
    }
    Ok(out)
}

/// SSIM metric (3DGS window, zero-padded statistics, mean over all pixels and channels) — the value
/// 3DGS / PGSR / VA-GS report. Use [`ssim_metric_with`] for the scikit-image compatible region.
pub fn ssim_metric(a: &Image, b: &Image) -> Result<f64> {
    ssim_metric_with(a, b, SsimRegion::Full)
}

/// SSIM metric averaged over `region` (see [`crate::ssim`] for the border conventions).
pub fn ssim_metric_with(a: &Image, b: &Image, region: SsimRegion) -> Result<f64> {
    let d = same_size(a, b)?;
    let v = ssim(a.data(), b.data(), d, region)?;
    if !v.is_finite() {
        return Err(LossError::InvalidParameter(
            "SSIM of images with non-finite values".into(),
        ));
    }
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn masked_psnr_sees_only_the_inside() {
        let a = Image::from_vec(4, 1, 3, vec![0.5; 12]).unwrap();
        let mut b = a.clone();
        // Outside pixels 2, 3 differ wildly; inside pixel 1 by 0.1 in one channel.
        b.pixel_mut(1, 0)[0] = 0.6;
        b.pixel_mut(2, 0).fill(1.0);
        b.pixel_mut(3, 0).fill(0.0);
        let mask = Image::from_vec(4, 1, 1, vec![1.0, 1.0, 0.0, 0.2]).unwrap();
        let expect = -10.0 * (0.01f64 / 6.0).log10();
        assert!((psnr_masked(&a, &b, &mask).unwrap() - expect).abs() < 1e-4);
        assert!(psnr(&a, &b).unwrap() < 10.0);
        let comp = masked_on_black(&b, &mask).unwrap();
        assert_eq!(comp.pixel(2, 0), &[0.0; 3]);
        assert_eq!(comp.pixel(1, 0), b.pixel(1, 0));
        // Wrong size, wrong channels, empty mask: errors, not panics.
        for bad in [
            Image::from_vec(3, 1, 1, vec![1.0; 3]).unwrap(),
            Image::from_vec(4, 1, 3, vec![1.0; 12]).unwrap(),
            Image::from_vec(4, 1, 1, vec![0.0; 4]).unwrap(),
        ] {
            assert!(psnr_masked(&a, &b, &bad).is_err());
            assert!(masked_on_black(&a, &bad).is_err());
        }
    }
}
