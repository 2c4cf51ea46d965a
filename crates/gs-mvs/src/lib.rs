//! # gs-mvs
//!
//! The VA-GS multi-view terms (docs/method.md §L_p, §L_f, §Visibility): the photometric alignment L_p
//! (per-pixel plane homography, 7×7 NCC on grey GT images, weighted by the visibility υ and the
//! occlusion weight ω, averaged per source, **summed** over sources) and the feature alignment
//! L_f (cosine of feature vectors at reprojected points, **averaged** over sources), each with
//! its exact backward pass into the reference view's rendered maps (Ñ, D for L_p; plane depth
//! z for L_f). Source views are chosen per docs/method.md §Schedule by [`SourceViewSelector`]. The loss weights
//! λ3 = 0.15 and λ4 = 1.0 are applied by the caller.
//!
//! All kernels are generic over [`Real`] (`f32` for training, `f64` for gradient checks and
//! reference conformance) and take borrowed [`MapView`]s (`MapView::from(&image)` for a
//! [`gs_core::Image`]).
//!
//! ```
//! use gs_core::{Camera, Intrinsics, glam::DVec3};
//! use gs_mvs::analytic_scene::{AnalyticScene, AxisBox};
//! use gs_mvs::{photometric_loss, PhotometricConfig, PhotometricReference, PhotometricSource};
//!
//! let k = Intrinsics::new(40.0, 40.0, 24.0, 16.0);
//! let r = Camera::look_at(48, 32, k, DVec3::new(0.0, -2.0, 1.5), DVec3::ZERO, DVec3::Z).unwrap();
//! let s = Camera::look_at(48, 32, k, DVec3::new(0.5, -2.0, 1.5), DVec3::ZERO, DVec3::Z).unwrap();
//! let scene = AnalyticScene { boxes: vec![], frequency: 4.0 };
//! let (mr, ms) = (scene.render(&r), scene.render(&s));
//! let reference = PhotometricReference {
//!     camera: &r,
//!     normal: (&mr.normal).into(),
//!     distance: (&mr.distance).into(),
//!     plane_depth: (&mr.plane_depth).into(),
//!     grey: (&mr.grey).into(),
//! };
//! let source = PhotometricSource { camera: &s, plane_depth: (&ms.plane_depth).into(), grey: (&ms.grey).into() };
//! let out = photometric_loss(&reference, &[source], &PhotometricConfig::default()).unwrap();
//! // Exact geometry and a perfect image pair: the NCC cost is near zero.
//! assert!(out.loss < 0.05 && out.per_source[0].n_valid > 100);
//! assert_eq!(out.grad_normal.len(), 48 * 32 * 3);
//! ```

// `!(x > 0)` is deliberate throughout: it is true for NaN, which must be rejected.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod analytic_scene;
pub mod coverage;
pub mod error;
pub mod feature_alignment;
#[cfg(feature = "wgpu")]
pub mod feature_gpu;
pub mod geometry;
pub mod photometric;
#[cfg(feature = "wgpu")]
pub mod photometric_gpu;
pub mod selection;
pub mod visibility;

#[cfg(test)]
mod testutil;

pub use coverage::{DepthView, SEEN_DEPTH_TOLERANCE, seen_mask};
pub use error::{MvsError, Result};
pub use gs_core::float::Real;
pub use feature_alignment::{
    AlignView, FeatureMaps, FeatureOutput, FeatureReference, FeatureSource, FeatureSourceStats,
    GridFeatureMaps, feature_loss, feature_loss_with_weights,
};
pub use geometry::{MapView, plane_homography, sample_bilinear, sample_bilinear_grad};
pub use photometric::{
    DEFAULT_MAX_PIXELS_PER_SOURCE, NccMode, PhotometricConfig, PhotometricOutput, PhotometricReference, PhotometricSource,
    SourceStats, photometric_loss, photometric_loss_with_weights,
};
#[cfg(feature = "wgpu")]
pub use feature_gpu::FeatureGpu;
#[cfg(feature = "wgpu")]
pub use feature_gpu::on_device::{DeviceAlignView, FeaturesOnDevice, PendingFeatures};
#[cfg(feature = "wgpu")]
pub use photometric_gpu::{DeviceSource, DeviceVisibility, PendingPhotometric, PhotometricGpu, PhotometricOnDevice, SourceDepth, SurfaceReference, ViewKeys, surface_depth, upload_surface};
pub use selection::{SourceSelection, SourceViewSelector};
pub use visibility::{Visibility, VisibilityStats, compute_visibility};
