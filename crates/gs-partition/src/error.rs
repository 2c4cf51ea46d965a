//! The error type of gs-partition (docs/architecture.md §Errors and files): a refusal in words
//! naming the plan, block or file, or a lower layer's error with what was being done.

use thiserror::Error;

/// Errors of partitioning and merging.
#[derive(Debug, Error)]
pub enum PartitionError {
    /// A scene, plan, block run or option that cannot be partitioned or merged, in words.
    #[error("{0}")]
    Refused(String),
    /// An error of a lower layer, with what was being done (`context: cause`).
    #[error("{context}")]
    Context {
        /// What was being done, naming the file or block.
        context: String,
        /// The cause.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync + 'static>,
    },
    /// A file could not be read or written.
    #[error(transparent)]
    Io(#[from] gs_io::IoError),
    /// A run could not be opened, checked or written.
    #[error(transparent)]
    Run(#[from] gs_run::RunError),
    /// A camera or model was invalid.
    #[error(transparent)]
    Core(#[from] gs_core::CoreError),
    /// The training configuration or its memory estimate failed.
    #[error(transparent)]
    Train(#[from] gs_train::TrainError),
    /// A record could not be encoded or decoded as JSON.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

/// Result alias of gs-partition.
pub type Result<T> = std::result::Result<T, PartitionError>;

/// Shorthand for a [`PartitionError::Refused`] returned at once.
macro_rules! refuse {
    ($($t:tt)*) => { return Err($crate::PartitionError::Refused(format!($($t)*))) };
}
pub(crate) use refuse;

/// Adds what was being done to an error.
pub(crate) trait Context<T> {
    /// Wraps the error with `f()`'s words.
    fn with_context(self, f: impl FnOnce() -> String) -> Result<T>;
}

impl<T, E: std::error::Error + Send + Sync + 'static> Context<T> for std::result::Result<T, E> {
    fn with_context(self, f: impl FnOnce() -> String) -> Result<T> {
        self.map_err(|e| PartitionError::Context { context: f(), source: Box::new(e) })
    }
}
