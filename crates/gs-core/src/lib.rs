//! # gs-core
//!
//! The types every vagsl crate shares: [`Camera`] (PINHOLE, COLMAP frames, pixel centres at
//! `i + 0.5`), [`Image`] (row-major `[H][W][C]` f32), the struct-of-arrays Gaussian model
//! [`Gaussians`], spherical harmonics forward/backward ([`sh`]), the Adam optimiser with
//! per-group learning rates ([`optim`]), a seeded [`Rng`], scene containers ([`Scene`]) and an
//! f64 finite-difference gradient checker ([`gradcheck`]) that other crates use in tests.
//!
//! ```
//! use gs_core::{Camera, Intrinsics};
//! use glam::DVec3;
//! let cam = Camera::look_at(640, 480, Intrinsics::new(500.0, 500.0, 320.0, 240.0),
//!     DVec3::new(0.0, -3.0, 1.0), DVec3::ZERO, DVec3::Z).unwrap();
//! let (pixel, depth) = cam.project(DVec3::ZERO).unwrap();
//! assert!((pixel.x - 320.0).abs() < 1e-9 && depth > 0.0);
//! ```

pub mod camera;
pub mod capsule;
pub mod densify_stats;
pub mod error;
pub mod extent;
pub mod float;
pub mod gaussians;
pub mod gradcheck;
pub mod half;
pub mod image;
pub mod mesh;
pub mod names;
pub mod optim;
pub mod point;
pub mod rng;
pub mod scene;
pub mod sh;

pub use camera::{Camera, Intrinsics};
pub use capsule::Capsule;
pub use densify_stats::{DensifyStats, screen_norm};
pub use error::{CoreError, Result};
pub use gaussians::Gaussians;
pub use image::Image;
pub use mesh::TriangleMesh;
pub use optim::{Adam, AdamConfig, ExponentialLr, GroupStep, Param};
pub use rng::Rng;
pub use extent::{ExtentBasis, ExtentReport, extent_report, scene_extent};
pub use point::ScenePoint;
pub use scene::{NeighbourRule, Scene, View, source_view_candidates, split_names};
pub use glam;
