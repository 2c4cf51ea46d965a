//! The error type of gs-mvs.

use thiserror::Error;

/// Errors raised by gs-mvs for invalid input (never for internal invariants).
#[derive(Debug, Error, Clone, PartialEq)]
pub enum MvsError {
    /// A map whose size or channel count does not match its camera (names the map and both sizes).
    #[error("{map}: expected {expected}, got {got}")]
    SizeMismatch {
        /// Which map (e.g. `reference normal`, `source 2 plane_depth`).
        map: String,
        /// Expected `W×H×C`.
        expected: String,
        /// Actual `W×H×C`.
        got: String,
    },
    /// A configuration value outside its documented range.
    #[error("invalid configuration: {0}")]
    InvalidConfig(String),
    /// Inputs that disagree with each other (e.g. a weight list of the wrong length).
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// A GPU device failure (no adapter, a validation error, a lost device).
    #[error("GPU: {0}")]
    Device(String),
}

/// Result alias of gs-mvs.
pub type Result<T> = std::result::Result<T, MvsError>;
