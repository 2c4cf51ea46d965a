//! The error type of gs-features.

use thiserror::Error;

/// Errors raised by gs-features for invalid input (never for internal invariants).
#[derive(Debug, Error, Clone, PartialEq)]
pub enum FeatureError {
    /// A weight blob that is truncated, has the wrong magic/version/shapes or a bad checksum.
    #[error("weight blob {source_name}: {problem}")]
    CorruptWeights {
        /// Where the blob came from (file path or "bundled").
        source_name: String,
        /// What is wrong with it.
        problem: String,
    },
    /// An input image the network cannot take (wrong channel count, too small, too large,
    /// non-finite values).
    #[error("invalid input image: {0}")]
    InvalidImage(String),
    /// A parameter outside its documented range (channel reduction, cache index, caps).
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// The device failed (a kernel did not build, or a dispatch or readback failed).
    #[error("device: {0}")]
    Device(String),
    /// Reading a weight file from disk failed.
    #[error("cannot read {path}: {message}")]
    Io {
        /// The file.
        path: String,
        /// The OS error text.
        message: String,
    },
}

/// Result alias of gs-features.
pub type Result<T> = std::result::Result<T, FeatureError>;
