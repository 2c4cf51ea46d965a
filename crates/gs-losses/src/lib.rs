//! Single-view VA-GS losses with analytic backward passes, and image metrics.
//!
//! Every loss is a forward/backward pair over `gs_core::Image` buffers (row-major `[H][W][C]` f32):
//!
//! - [`image_loss()`]: L_I = (1 − β1)·L1 + β1·(1 − SSIM) + β2·L1(∇Ĩ, ∇I) and ∂L_I/∂Ĩ
//!   (docs/method.md §L_I; SSIM with the 3DGS 11×11 Gaussian window, zero-padded statistics).
//! - [`normal_losses`]: L_nc (§L_nc) and L_ns (§L_ns) from the plane depth z and the rendered
//!   normal Ñ, with ∂/∂z and ∂/∂Ñ (the caller chains ∂/∂z into Ñ and D).
//! - [`opacity_entropy`]: L_o (§L_o), the mean binary entropy of the opacities, with ∂/∂logit
//!   (a parameter-space term: it reads the model, not a render).
//! - [`smallest_scale_mean`]: L_s (§L_s), PGSR's flattening term, the mean smallest scale, with
//!   ∂/∂log-scale (parameter-space too).
//! - [`EdgeGuide`]: ∇I and δ = (1 − ∇I)² of a ground-truth image, computed once per view.
//! - Metrics: [`psnr`], [`ssim_metric`], [`Lpips`] (AlexNet, v0.1, bundled f16 weights).
//!
//! - With the `wgpu` feature: [`ImageLossGpu`] and [`NormalGpu`], the device twins of
//!   [`image_loss()`] and [`normal_losses`] (same inputs, checks and outputs; per-value terms
//!   summed on the host in the reference's order; docs/architecture.md §GPU).
//!
//! The kernels behind them ([`l1`], [`ssim`], [`gradient`], [`normal`], [`normal_loss`]) are
//! generic over f32/f64 ([`Real`]) so that gradients are checked in f64 against finite
//! differences and values against the f64 reference of `synth-bunny`.
//!
//! ```
//! use gs_core::{Image, Intrinsics};
//! use gs_losses::{EdgeGuide, ImageLossConfig, NormalLossConfig, image_loss, normal_losses};
//!
//! let (w, h) = (16, 12);
//! let gt = Image::from_vec(w, h, 3, (0..w * h * 3).map(|i| (i % 7) as f32 / 7.0).collect()).unwrap();
//! let rendered = Image::filled(w, h, 3, 0.5).unwrap();
//! let guide = EdgeGuide::from_gt(&gt).unwrap();
//!
//! let li = image_loss(&rendered, &gt, Some(&guide), &ImageLossConfig::default()).unwrap();
//! assert!(li.total > 0.0 && li.grad_rendered.is_finite());
//!
//! // A fronto-parallel plane at z = 2 facing the camera: N̂ = (0, 0, −1) in the interior.
//! let k = Intrinsics::new(20.0, 20.0, 8.0, 6.0);
//! let z = Image::filled(w, h, 1, 2.0).unwrap();
//! let mut n = Image::new(w, h, 3).unwrap();
//! for p in n.data_mut().chunks_mut(3) { p[2] = -1.0; }
//! let out = normal_losses(&z, &n, None, &guide, &k, &NormalLossConfig::default()).unwrap();
//! assert!(out.l_nc < 1e-6);
//! assert_eq!(out.depth_normal.pixel(5, 5), &[0.0, 0.0, -1.0]);
//! ```

#[cfg(feature = "wgpu")]
mod device;
pub mod dims;
pub mod error;
pub mod exposure;
#[cfg(feature = "wgpu")]
pub mod exposure_gpu;
pub mod flatness;
pub mod gradient;
#[cfg(feature = "wgpu")]
pub mod image_gpu;
pub mod image_loss;
pub mod l1;
pub mod lpips;
pub mod metrics;
pub mod normal;
pub mod normal_loss;
#[cfg(feature = "wgpu")]
pub mod normal_gpu;
pub mod opacity;
pub mod ssim;


pub use dims::Dims;
pub use error::{LossError, Result};
pub use exposure::{ExposureParams, apply_exposure, exposure_backward, exposure_gains};
pub use flatness::smallest_scale_mean;
pub use gs_core::float::Real;
pub use image_loss::{EdgeGuide, ImageLossConfig, ImageLossOutput, image_loss};
pub use lpips::Lpips;
pub use metrics::{masked_on_black, psnr, psnr_masked, ssim_metric, ssim_metric_with};
pub use normal_loss::{NormalLossConfig, NormalLossOutput, NsGate, NsPairs, normal_losses};
pub use opacity::opacity_entropy;
pub use ssim::SsimRegion;
#[cfg(feature = "wgpu")]
pub use exposure_gpu::ExposureGpu;
#[cfg(feature = "wgpu")]
pub use image_gpu::{ImageLossGpu, PendingDeviceImageLoss, PendingImageLoss};
#[cfg(feature = "wgpu")]
pub use normal_gpu::{NormalGpu, PendingDeviceNormalLosses, PendingNormalLosses};

