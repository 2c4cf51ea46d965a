//! The edge-aware image loss L_I = (1 − β1)·L1 + β1·(1 − SSIM) + β2·L1(∇Ĩ, ∇I) (docs/method.md §L_I)
//! over `gs_core::Image` buffers, and the per-view [`EdgeGuide`] (∇I and δ of the ground truth).

use crate::error::{LossError, Result};
use crate::gradient::{edge_l1, edge_weight, image_gradient, image_gradient_backward};
use crate::l1::{l1, l1_backward};
use crate::dims::Dims;
use crate::ssim::{SsimRegion, ssim_backward};
use gs_core::Image;

/// ∇I and δ = clamp((1 − ∇I)², 0, 1) of a ground-truth image; computed once per training view
/// and shared by the edge term of L_I and by L_nc / L_ns.
#[derive(Debug, Clone, PartialEq)]
pub struct EdgeGuide {
    /// ∇I (1 channel, border = 1).
    pub gradient: Image,
    /// δ (1 channel, border = 0).
    pub delta: Image,
}

impl EdgeGuide {
    /// The guide of a ground-truth image (any channel count; channels are averaged).
    pub fn from_gt(gt: &Image) -> Result<Self> {
        let dims = Dims::of(gt);
        let g = image_gradient(gt.data(), dims);
        let delta = edge_weight(&g.map);
        Ok(Self {
            gradient: Image::from_vec(dims.width, dims.height, 1, g.map)?,
            delta: Image::from_vec(dims.width, dims.height, 1, delta)?,
        })
    }
}

/// β1 of the paper: weight of D-SSIM in L_I (L1 gets 1 − β1).
pub const BETA1: f32 = 0.2;
/// β2 of the paper: weight of the edge term L1(∇Ĩ, ∇I) in L_I.
pub const BETA2: f32 = 0.03;

/// Weights of L_I.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageLossConfig {
    /// β1, weight of D-SSIM (paper: 0.2); L1 gets 1 − β1.
    pub beta1: f32,
    /// β2, weight of the edge term (paper: 0.03).
    pub beta2: f32,
    /// Whether the edge term is on (off during the colour-only warm-up, docs/method.md §Schedule).
    pub edge: bool,
}

impl Default for ImageLossConfig {
    fn default() -> Self {
        Self {
            beta1: BETA1,
            beta2: BETA2,
            edge: true,
        }
    }
}

/// Values of L_I and its gradient with respect to the rendered image: a host [`Image`], or
/// (`ImageLossOutput<gs_gpu::DeviceImage>`, the device twin's `finish_on_device`) an image
/// kept on the device.
#[derive(Debug, Clone)]
pub struct ImageLossOutput<G = Image> {
    /// L1(Ĩ, I).
    pub l1: f64,
    /// SSIM(Ĩ, I) (so D-SSIM = 1 − ssim).
    pub ssim: f64,
    /// L1(∇Ĩ, ∇I), or `None` when the edge term is off.
    pub edge: Option<f64>,
    /// L_I.
    pub total: f64,
    /// ∂L_I/∂Ĩ, same size as the rendered image.
    pub grad_rendered: G,
}

/// L_I of a rendered image Ĩ against the ground truth I. `guide` must be
/// [`EdgeGuide::from_gt`] of `gt` (required only when the edge term is on).
pub fn image_loss(
    rendered: &Image,
    gt: &Image,
    guide: Option<&EdgeGuide>,
    cfg: &ImageLossConfig,
) -> Result<ImageLossOutput> {
    let dims = Dims::of(rendered);
    let guide = check_inputs(dims, gt, guide, cfg)?;
    let (a, b) = (rendered.data(), gt.data());
    let (b1, b2) = (cfg.beta1 as f64, cfg.beta2 as f64);
    let mut grad = vec![0.0f32; dims.len()];
    let l1v = l1(a, b);
    l1_backward(a, b, 1.0 - b1, &mut grad);
    let s = ssim_backward(a, b, dims, SsimRegion::Full, -b1, &mut grad)?;
    let edge = guide.map(|guide| {
        let gr = image_gradient(a, dims);
        let mut up = vec![0.0f32; dims.pixels()];
        let e = edge_l1(&gr.map, guide.gradient.data(), b2, Some(&mut up));
        image_gradient_backward(a, dims, &gr, &up, &mut grad);
        e
    });
    ImageLossOutput::assemble(cfg, l1v, s, edge, Image::from_vec(dims.width, dims.height, dims.channels, grad)?)
}

impl<G> ImageLossOutput<G> {
    /// The output of the three terms' values and the summed gradient, with L_I's total.
    pub(crate) fn assemble(cfg: &ImageLossConfig, l1: f64, ssim: f64, edge: Option<f64>, grad_rendered: G) -> Result<Self> {
        let (b1, b2) = (cfg.beta1 as f64, cfg.beta2 as f64);
        let total = (1.0 - b1) * l1 + b1 * (1.0 - ssim) + edge.map_or(0.0, |e| b2 * e);
        Ok(Self { l1, ssim, edge, total, grad_rendered })
    }

    /// The same values with the gradient made into another form (e.g. moved to a device).
    pub fn map_grad<H, E>(self, f: impl FnOnce(G) -> std::result::Result<H, E>) -> std::result::Result<ImageLossOutput<H>, E> {
        let Self { l1, ssim, edge, total, grad_rendered } = self;
        Ok(ImageLossOutput { l1, ssim, edge, total, grad_rendered: f(grad_rendered)? })
    }
}

/// The checks of [`image_loss`]' inputs (shared with the device twin): one size, weights in
/// range, and an edge guide of the image's size when the edge term is on, which is returned.
pub(crate) fn check_inputs<'g>(
    dims: Dims,
    gt: &Image,
    guide: Option<&'g EdgeGuide>,
    cfg: &ImageLossConfig,
) -> Result<Option<&'g EdgeGuide>> {
    if Dims::of(gt) != dims {
        return Err(LossError::ShapeMismatch(format!(
            "rendered image is {}×{}×{}, ground truth {}×{}×{}",
            dims.width,
            dims.height,
            dims.channels,
            gt.width(),
            gt.height(),
            gt.channels()
        )));
    }
    for (name, v) in [("β1", cfg.beta1), ("β2", cfg.beta2)] {
        if !v.is_finite() || v < 0.0 {
            return Err(LossError::InvalidParameter(format!(
                "{name} = {v} must be finite and ≥ 0"
            )));
        }
    }
    if cfg.beta1 > 1.0 {
        return Err(LossError::InvalidParameter(format!(
            "β1 = {} must be ≤ 1",
            cfg.beta1
        )));
    }
    if !cfg.edge {
        return Ok(None);
    }
    let guide = guide.ok_or_else(|| {
        LossError::InvalidParameter(
            "the edge term is on but no EdgeGuide of the ground truth was given".into(),
        )
    })?;
    if guide.gradient.width() != dims.width || guide.gradient.height() != dims.height {
        return Err(LossError::ShapeMismatch(format!(
            "edge guide is {}×{}, image {}×{}",
            guide.gradient.width(),
            guide.gradient.height(),
            dims.width,
            dims.height
        )));
    }
    Ok(Some(guide))
}
