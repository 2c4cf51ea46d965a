//! The error type of gs-core.

use thiserror::Error;

/// Errors raised by gs-core when given invalid input (never for internal invariants).
#[derive(Debug, Error, Clone, PartialEq)]
pub enum CoreError {
    /// A camera with non-finite or non-positive intrinsics, zero size, or a non-finite pose.
    #[error("invalid camera: {0}")]
    InvalidCamera(String),
    /// An image whose buffer length does not match width × height × channels, or with zero size.
    #[error("invalid image: {0}")]
    InvalidImage(String),
    /// Arrays of a Gaussian model whose lengths disagree, or a degree outside 0..=3.
    #[error("invalid Gaussian model: {0}")]
    InvalidGaussians(String),
    /// An optimiser call whose parameter and gradient lengths disagree, or an unknown group.
    #[error("optimiser: {0}")]
    Optimizer(String),
    /// A value outside its documented range (resource caps, absurd parameters).
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// A scene that cannot be trained as given (e.g. no camera spread sets its scale).
    #[error("invalid scene: {0}")]
    InvalidScene(String),
}

/// Result alias of gs-core.
pub type Result<T> = std::result::Result<T, CoreError>;
