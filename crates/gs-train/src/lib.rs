//! # gs-train
//!
//! The VA-GS training pipeline (method-spec §3–§8) composed from the vagsl crates: initial
//! Gaussians from SfM points, the phase schedule (colour warm-up → edge + L_nc + L_ns + L_p →
//! L_f), Adam with the log-linear position schedule, densification with absolute gradients,
//! opacity reset, multi-view trim, checksummed checkpoints that resume bit-identically, mesh
//! extraction from rendered plane depths and held-out image metrics.
//!
//! ```no_run
//! use gs_train::{Trainer, TrainConfig, Preset, MeshOptions};
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let scene = gs_io::load_scene(std::path::Path::new("scene"), &Default::default())?;
//! let (train, _test) = scene.split(true);
//! let config = TrainConfig::preset(Preset::Fast);
//! let mut trainer = Trainer::new(&scene, train.clone(), config)?;
//! trainer.run(|_, report| { println!("{} {:.4}", report.iteration, report.losses.total); true })?;
//! let (mesh, _) = trainer.extract_mesh(&train, &MeshOptions::default())?;
//! gs_io::write_mesh_ply(std::path::Path::new("mesh.ply"), &mesh)?;
//! # Ok(()) }
//! ```

pub mod checkpoint;
pub mod config;
pub mod densify;
pub mod error;
pub mod exposure;
pub mod init;
pub mod output;
pub mod trainer;

pub use config::{DensifyConfig, FeatureLayer, GateReading, InitMode, LearningRates, LossSwitches, LossWeights, NccReading, Phase, Preset, ShPolicy, TrainConfig};
pub use densify::{DensifyReport, DensifyStats};
pub use error::{Result, TrainError};
pub use exposure::{Exposure, ExposureParams};
pub use output::{FINE_VOXEL_FRACTION, ImageMetrics, MeshOptions, MeshReport, ViewMetrics, evaluate_images, extract_mesh};
pub use trainer::{LossValues, ShBandDecision, StepReport, TrainState, Trainer};
