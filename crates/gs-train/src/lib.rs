//! # gs-train
//!
//! The VA-GS training pipeline (docs/method.md §Parameters to §TSDF) composed from the vagsl crates. The data
//! path of one iteration:
//!
//! 1. [`plan`]: a pure [`StepPlan`] from the [`TrainConfig`] and the iteration — view, source
//!    views, channels to render, active loss terms and their weights ([`LossWeights`], zero for the terms left off), the
//!    means' learning rate and the density control to run afterwards.
//! 2. [`StepExecutor::execute`] on the [`ReferenceExecutor`]: render on the chosen rasterizer,
//!    evaluate every term through the [`LossTerm`] contract into the output-gradient buffers,
//!    back-propagate, Adam over the typed parameter layout ([`Param`]). The [`Trainer`] owns the
//!    [`TrainState`] and passes it to the executor explicitly, with the run's fixed
//!    [`RunInputs`].
//! 3. [`StepExecutor::refine`] ([`refine`]): clone / split / prune, opacity reset, multi-view trim.
//!
//! Per-view data (edge guides, grey images, VGG16 features) lives in [`caches`]. A model —
//! training or trained — is a [`TrainedModel`], which meshing ([`extract_mesh`], or
//! [`fuse_mesh`] of any depth source), rendering and evaluation ([`evaluate_images`]) take.
//! Checkpoints resume bit-identically.
//!
//! ```no_run
//! use gs_train::{Trainer, TrainConfig, Preset, MeshOptions};
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let scene = gs_io::load_scene(std::path::Path::new("scene"), &Default::default())?;
//! let (train, _test) = scene.split(true);
//! let config = TrainConfig::preset(Preset::Fast);
//! let mut trainer = Trainer::new(&scene, train, config)?;
//! trainer.run(|_, report| { println!("{} {:.4}", report.iteration, report.losses.total); true })?;
//! let (mesh, _) = trainer.extract_mesh(&MeshOptions::default())?;
//! gs_io::write_mesh_ply(std::path::Path::new("mesh.ply"), &mesh)?;
//! # Ok(()) }
//! ```

pub mod budget;
pub mod caches;
pub mod checkpoint;
pub mod config;
pub mod densify;
pub mod devices;
pub mod error;
pub mod evaluate;
pub mod executor;
pub mod exposure;
pub mod capture_path;
pub mod floaters;
pub mod init;
pub mod training_memory;
pub mod mesh;
pub mod mesh_pieces;
pub mod model;
pub mod params;
pub mod plan;
pub mod profile;
pub mod refine;
pub mod region;
pub mod sh_policy;
pub mod smoothing;
pub mod source_depths;
pub mod terms;
pub mod trainer;

pub use config::{DensifyConfig, InitMode, LearningRates, LossSwitches, LossWeights, Phase, Preset, ShPolicy, TrainConfig};
pub use budget::{Budget, GrowthLimit};
pub use region::GrowthRegion;
pub use densify::{DensifyReport, DensifyStats, Growth};
pub use error::{Result, TrainError};
pub use evaluate::{ImageMetrics, PixelMasks, VEIL_MIN_COVER, Veil, ViewMetrics, evaluate_images, find_veil, score_view, seen_masks};
pub use devices::TermsUsed;
pub use executor::{PartPlace, ReferenceExecutor, RunInputs, StepExecutor};
pub use exposure::{Exposure, ExposureParams};
pub use floaters::{FloaterReport, FloaterRule, FreeSpaceVotes};
pub use mesh::{
    ComponentCleanup, DEFAULT_COMPONENT_SHARE, DEFAULT_SIMPLIFY_ERROR, DEFAULT_SURFACE_CUT, DepthFilterReport, DepthSource, FINE_VOXEL_FRACTION, MIN_COMPONENT_TRIANGLES,
    MeshOptions, MeshReport, Simplify, SimplifyApplied, default_voxel, extract_mesh, fuse_mesh, length_text,
};
pub use mesh_pieces::{FusionPieces, PieceReport, extract_mesh_in_pieces, fuse_mesh_in_pieces};
pub use model::TrainedModel;
pub use params::Param;
pub use plan::{RefinePlan, StepPlan, plan_step};
pub use profile::{Part, StepProfile};
pub use refine::RefineReport;
pub use sh_policy::ShBandDecision;
pub use source_depths::{SourceDepths, StoredDepth};
pub use terms::{Fold, GradientBuffers, LossTerm, LossValues, TermInputs};
pub use trainer::{BackendChoice, BackendProbe, StepReport, TrainState, Trainer};
