//! Image metrics of a trained model on chosen views (method-spec §9): PSNR, SSIM and
//! LPIPS-alex, on whole images or on the object inside each view's mask.

use crate::error::{Result, TrainError};
use crate::model::TrainedModel;
use gs_core::Image;
use gs_losses::{Lpips, psnr, ssim_metric};
use gs_raster::{Rasterizer, RenderRequest};
use serde::Serialize;

/// Image metrics of one view.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ViewMetrics {
    /// Image name.
    pub name: String,
    /// PSNR, dB.
    pub psnr: f64,
    /// SSIM (method-spec §5.1 window).
    pub ssim: f64,
    /// LPIPS-alex v0.1 (when computed).
    pub lpips: Option<f64>,
    /// Fraction of the image inside the view's mask (masked evaluation only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mask_fraction: Option<f64>,
}

/// Metrics over a set of views, with their means.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ImageMetrics {
    /// Per view.
    pub views: Vec<ViewMetrics>,
    /// Mean PSNR.
    pub psnr: f64,
    /// Mean SSIM.
    pub ssim: f64,
    /// Mean LPIPS.
    pub lpips: Option<f64>,
    /// True when the metrics are of the object inside each view's mask: PSNR over the mask's
    /// pixels, SSIM and LPIPS of render and photo both composited on black outside it.
    pub masked: bool,
}

/// Renders `views` (indices into the model's scene) and scores them against their images (PSNR, SSIM and, with `lpips`,
/// LPIPS-alex). Rendered colours are clamped to [0, 1] as an 8-bit export would be. With
/// `masked` every view needs a mask and only the object inside it is scored (see
/// [`ImageMetrics::masked`]); a view without one is an error naming it.
pub fn evaluate_images(
    model: &TrainedModel<'_>,
    rasterizer: &mut Rasterizer,
    views: &[usize],
    lpips: Option<&Lpips>,
    masked: bool,
) -> Result<ImageMetrics> {
    if views.is_empty() {
        return Err(TrainError::InvalidScene("no views to evaluate (train with --eval to hold out test views)".into()));
    }
    let req = RenderRequest { color: true, alpha: false, ..RenderRequest::default() };
    let mut out = Vec::with_capacity(views.len());
    for &i in views {
        let mut img: Image = model.render(rasterizer, i, &req)?.color.expect("requested");
        img.data_mut().iter_mut().for_each(|v| *v = v.clamp(0.0, 1.0));
        out.push(score_view(&model.scene.views[i], &img, lpips, masked)?);
    }
    let k = out.len() as f64;
    Ok(ImageMetrics {
        psnr: out.iter().map(|v| v.psnr).sum::<f64>() / k,
        ssim: out.iter().map(|v| v.ssim).sum::<f64>() / k,
        lpips: lpips.map(|_| out.iter().filter_map(|v| v.lpips).sum::<f64>() / k),
        views: out,
        masked,
    })
}

/// Scores one render (colours already clamped to [0, 1]) against its view's photo: PSNR, SSIM
/// and, with `lpips`, LPIPS-alex; with `masked` only the object inside the view's mask (an
/// error naming the view when it has none). [`evaluate_images`] calls this for every view; a
/// caller that keeps its renders (the report page) calls it directly.
pub fn score_view(view: &gs_core::View, img: &Image, lpips: Option<&Lpips>, masked: bool) -> Result<ViewMetrics> {
    if !masked {
        return Ok(ViewMetrics {
            name: view.name.clone(),
            psnr: psnr(img, &view.image)?,
            ssim: ssim_metric(img, &view.image)?,
            lpips: lpips.map(|l| l.distance(img, &view.image)).transpose()?,
            mask_fraction: None,
        });
    }
    let mask = view.mask.as_ref().ok_or_else(|| {
        TrainError::InvalidScene(format!("view {} has no mask (masked evaluation needs masks/<stem>.png for every view)", view.name))
    })?;
    let named = |e: gs_losses::LossError| TrainError::InvalidScene(format!("mask of view {}: {e}", view.name));
    let (render_obj, photo_obj) =
        (gs_losses::masked_on_black(img, mask).map_err(named)?, gs_losses::masked_on_black(&view.image, mask).map_err(named)?);
    Ok(ViewMetrics {
        name: view.name.clone(),
        psnr: gs_losses::psnr_masked(img, &view.image, mask).map_err(named)?,
        ssim: ssim_metric(&render_obj, &photo_obj)?,
        lpips: lpips.map(|l| l.distance(&render_obj, &photo_obj)).transpose()?,
        mask_fraction: Some(mask.data().iter().filter(|m| **m >= 0.5).count() as f64 / mask.data().len() as f64),
    })
}
