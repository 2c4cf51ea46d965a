//! The error type of gs-synth.

use thiserror::Error;

/// Errors raised by gs-synth for invalid options or meshes (never for internal invariants).
#[derive(Debug, Error, Clone, PartialEq)]
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
}

/// Result alias of gs-synth.
pub type Result<T> = std::result::Result<T, SynthError>;
