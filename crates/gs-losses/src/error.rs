//! The error type of gs-losses.

use thiserror::Error;

/// Errors raised by gs-losses for invalid input (never for internal invariants).
#[derive(Debug, Error, Clone, PartialEq)]
pub enum LossError {
    /// Two maps that must have the same size (rendered vs ground truth, depth vs normal…) differ.
    #[error("size mismatch: {0}")]
    ShapeMismatch(String),
    /// A map with the wrong channel count (e.g. a normal map that is not 3-channel).
    #[error("wrong channel count: {0}")]
    Channels(String),
    /// A parameter outside its documented range (negative weight, non-finite τ, image too small for LPIPS…).
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// A weights file that is truncated, has a wrong magic, size, layout or checksum.
    #[error("weights {file}: {problem}")]
    Weights {
        /// The file (or "bundled") that failed to load.
        file: String,
        /// What is wrong with it.
        problem: String,
    },
    /// A GPU device failure (a validation error, a lost device).
    #[error("GPU: {0}")]
    Device(String),
    /// An error from gs-core (e.g. building an output image).
    #[error(transparent)]
    Core(#[from] gs_core::CoreError),
}

/// Result alias of gs-losses.
pub type Result<T> = std::result::Result<T, LossError>;

/// The checks a parameter-space term (L_o, L_s) makes before it reads the model: a gradient
/// buffer of the model's length `n` (`items` names what the model holds, e.g. "opacity
/// logits") and a finite weight of the term `term`.
pub(crate) fn check_parameter_term(term: &str, items: &str, n: usize, grad_len: usize, weight: f32) -> Result<()> {
    if grad_len != n {
        return Err(LossError::ShapeMismatch(format!("{n} {items} but a gradient buffer of {grad_len}")));
    }
    if !weight.is_finite() {
        return Err(LossError::InvalidParameter(format!("the weight of {term} is {weight}")));
    }
    Ok(())
}
