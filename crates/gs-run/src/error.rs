//! The error type of gs-run (docs/architecture.md §Errors and files): a refusal in words, or a library
//! error with the context it happened in. Messages name the file and the problem.

use thiserror::Error;

/// Errors of run handling.
#[derive(Debug, Error)]
pub enum RunError {
    /// A run, scene, folder or derived file that is not what the operation needs, in words
    /// (e.g. a model of another run, a scene that is not the run's, an output folder that holds
    /// a run).
    #[error("{0}")]
    Refused(String),
    /// A derived file made from another model than the run's own (docs/architecture.md
    /// §Provenance); the message names both models and the command that makes it again.
    #[error("{0}")]
    Stale(String),
    /// An error of a lower layer, with what was being done (`context: cause`).
    #[error("{context}")]
    Context {
        /// What was being done, naming the file.
        context: String,
        /// The cause.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync + 'static>,
    },
    /// A file could not be read or written.
    #[error(transparent)]
    Io(#[from] gs_io::IoError),
    /// A scene, camera or model was invalid.
    #[error(transparent)]
    Core(#[from] gs_core::CoreError),
    /// Training, rendering for the curves, or the memory check failed.
    #[error(transparent)]
    Train(#[from] gs_train::TrainError),
    /// The built-in scene could not be generated.
    #[error(transparent)]
    Synth(#[from] gs_synth::SynthError),
    /// Meshing or scoring for the curves failed.
    #[error(transparent)]
    Tsdf(#[from] gs_tsdf::TsdfError),
    /// The rasterizer could not be made.
    #[error(transparent)]
    Raster(#[from] gs_raster::RasterError),
    /// A record could not be encoded as JSON.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
}

/// Result alias of gs-run.
pub type Result<T> = std::result::Result<T, RunError>;

/// Shorthand for a [`RunError::Refused`] returned at once.
macro_rules! refuse {
    ($($t:tt)*) => { return Err($crate::RunError::Refused(format!($($t)*))) };
}
pub(crate) use refuse;

/// Adds what was being done to an error (as `anyhow::Context` does, within this crate's type).
pub(crate) trait Context<T> {
    /// Wraps the error with the message `f` makes.
    fn with_context<F: FnOnce() -> String>(self, f: F) -> Result<T>;
}

impl<T, E: std::error::Error + Send + Sync + 'static> Context<T> for std::result::Result<T, E> {
    fn with_context<F: FnOnce() -> String>(self, f: F) -> Result<T> {
        self.map_err(|e| RunError::Context { context: f(), source: Box::new(e) })
    }
}

impl<T> Context<T> for Option<T> {
    fn with_context<F: FnOnce() -> String>(self, f: F) -> Result<T> {
        self.ok_or_else(|| RunError::Refused(f()))
    }
}

/// An error and its causes joined by ": " (each cause left out when the text before it
/// already ends with it), for a message recorded in a file rather than printed.
pub fn chain_text(e: &(dyn std::error::Error + 'static)) -> String {
    let mut text = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        let t = c.to_string();
        if !text.ends_with(&t) {
            text.push_str(": ");
            text.push_str(&t);
        }
        cause = c.source();
    }
    text
}
