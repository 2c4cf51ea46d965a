//! The error type of gs-synth.

use thiserror::Error;

/// Errors raised by gs-synth for invalid options or meshes (never for internal invariants).
#[derive(Debug, Error)]
pub enum SynthError {
    /// A [`BuiltinOptions`](crate::BuiltinOptions) field outside its documented range.
    #[error("invalid built-in scene option: {0}")]
    InvalidOptions(String),
    /// A mesh that cannot be ray-cast (out-of-range indices, non-finite vertices, no triangles).
    #[error("invalid mesh: {0}")]
    InvalidMesh(String),
    /// An error from gs-core (camera or image construction).
    #[error(transparent)]
    Core(#[from] gs_core::CoreError),
    /// A scene folder that cannot be written (it exists, or the file system refused).
    #[error("cannot write the scene: {0}")]
    Write(String),
    /// A file of the scene folder that gs-io could not write.
    #[error(transparent)]
    Io(#[from] gs_io::IoError),
}

/// Result alias of gs-synth.
pub type Result<T> = std::result::Result<T, SynthError>;
