//! The error type of gs-train.

use std::path::PathBuf;
use thiserror::Error;

/// Errors of the training pipeline: invalid configuration or input, and the errors of the
/// crates it composes (each names its file or map).
#[derive(Debug, Error)]
pub enum TrainError {
    /// A configuration file (`--config FILE`) that cannot be read as settings.
    #[error("{path}: {problem}")]
    ConfigFile {
        /// The configuration file.
        path: PathBuf,
        /// What is wrong with it.
        problem: String,
    },
    /// A configuration value outside its documented range.
    #[error("invalid training configuration: {0}")]
    InvalidConfig(String),
    /// A scene the trainer cannot use (no views, no training views, mismatched sizes).
    #[error("invalid scene: {0}")]
    InvalidScene(String),
    /// A checkpoint that cannot be read back (names the file and the problem).
    #[error("checkpoint {path}: {problem}")]
    Checkpoint {
        /// The checkpoint file.
        path: PathBuf,
        /// What is wrong with it.
        problem: String,
    },
    /// Training diverged (a loss or parameter became NaN/Inf); names the iteration.
    #[error("training diverged at iteration {iteration}: {problem}")]
    Diverged {
        /// 1-based iteration.
        iteration: u64,
        /// What became non-finite.
        problem: String,
    },
    /// A job whose estimated memory exceeds the caller's limit (names both, and what to change).
    #[error("{0}")]
    MemoryLimit(String),
    /// From gs-core.
    #[error(transparent)]
    Core(#[from] gs_core::CoreError),
    /// From gs-io.
    #[error(transparent)]
    File(#[from] gs_io::IoError),
    /// From gs-raster.
    #[error(transparent)]
    Raster(#[from] gs_raster::RasterError),
    /// From gs-losses.
    #[error(transparent)]
    Loss(#[from] gs_losses::LossError),
    /// From gs-mvs.
    #[error(transparent)]
    Mvs(#[from] gs_mvs::MvsError),
    /// From gs-features.
    #[error(transparent)]
    Features(#[from] gs_features::FeatureError),
    /// From gs-tsdf.
    #[error(transparent)]
    Tsdf(#[from] gs_tsdf::TsdfError),
}

/// Result alias of gs-train.
pub type Result<T> = std::result::Result<T, TrainError>;
