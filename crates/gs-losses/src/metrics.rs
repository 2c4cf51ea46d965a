//! Image metrics for evaluation (method-spec §9): PSNR and SSIM; LPIPS lives in [`crate::lpips`].

use crate::error::{LossError, Result};
use crate::real::{Dims, ordered_sum};
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
    if !se.is_finite() {
        return Err(LossError::InvalidParameter(
            "PSNR of images with non-finite values".into(),
        ));
    }
    let mse = (se / n as f64).max(1e-10);
    Ok((-10.0 * mse.log10()).min(PSNR_MAX_DB))
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
