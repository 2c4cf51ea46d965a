//! # gs-features
//!
//! The feature extractor f(·) behind VA-GS's multi-view feature-alignment loss L_f
//! (docs/method.md §L_f): the first seven convolutions of ImageNet-pretrained VGG16
//! (torchvision IMAGENET1K_V1, bundled in the crate as f16 with a CRC-32-checked header), run
//! inference-only on the CPU with rayon, or on a wgpu device with `Vgg16Gpu` (the `wgpu`
//! feature: the same maps to f32 rounding). F is taken at conv2_2 (128 channels, 1/2 resolution,
//! the default) or conv3_3 (256 channels, 1/4 resolution), computed once per training image
//! ([`FeatureCache`]), and sampled bilinearly at image pixel coordinates with its gradient
//! w.r.t. the position ([`FeatureMap::sample_bilinear_into`]; gs-mvs implements its
//! `FeatureMaps` trait for [`FeatureMap`], so these maps feed L_f directly).
//!
//! ```
//! use gs_core::Image;
//! use gs_features::{FeatureLevel, Vgg16, cosine};
//!
//! let net = Vgg16::bundled().unwrap(); // verifies size and checksum of the bundled weights
//! let image = Image::filled(32, 24, 3, 0.5).unwrap(); // RGB in [0, 1], row-major [H][W][C]
//! let f = net.extract(&image, FeatureLevel::Conv2_2).unwrap();
//! assert_eq!((f.width(), f.height(), f.channels()), (16, 12, 128));
//!
//! // Sample at image pixel (u, v) = (10.3, 7.9): value and ∂F/∂u, ∂F/∂v for L_f's gradient.
//! let s = f.sample_bilinear(10.3, 7.9);
//! assert!(s.inside && s.value.len() == 128 && s.d_du.len() == 128);
//! let mut value = vec![0.0; 128];
//! assert!(f.sample_bilinear_into(10.3, 7.9, &mut value, None));
//! assert!((cosine(&value, &s.value) - 1.0).abs() < 1e-6);
//! ```
//!
//! Input convention: RGB values in [0, 1] normalised as torchvision ImageNet,
//! `(x − (0.485, 0.456, 0.406)) / (0.229, 0.224, 0.225)`. Feature pixel `k` at stride `s`
//! covers image pixels `[s·k, s·(k+1))` with its centre at `s·(k + 0.5)`.

pub mod cache;
pub mod conv;
pub mod error;
#[cfg(feature = "wgpu")]
pub mod gpu;
pub mod map;
pub mod net;
pub mod weights;

pub use cache::FeatureCache;
pub use conv::ConvAlgorithm;
pub use error::{FeatureError, Result};
#[cfg(feature = "wgpu")]
pub use gpu::Vgg16Gpu;
pub use map::{
    COSINE_EPS, FeatureMap, FeatureSample, StoragePrecision, cosine, cosine_with_grad,
};
pub use net::{DEFAULT_MAX_PIXELS, ExtractOptions, FeatureLevel, Vgg16, projection_matrix};
pub use weights::{BUNDLED_VGG16_BLOB, VggWeights};
