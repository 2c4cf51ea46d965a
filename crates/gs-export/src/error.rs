//! The error type of gs-export: every variant names the file it concerns.

use std::path::PathBuf;
use thiserror::Error;

/// Errors of gs-export.
#[derive(Debug, Error)]
pub enum ExportError {
    /// Reading or writing the file failed (the OS refused, or a gs-io reader rejected it).
    #[error(transparent)]
    Io(#[from] gs_io::IoError),
    /// A file that is not a valid file of its format (wrong magic, truncated, bad counts…).
    #[error("{path}: {message}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A valid file that uses something gs-export does not read (e.g. spz version 4).
    #[error("{path}: unsupported: {message}")]
    Unsupported {
        /// The file.
        path: PathBuf,
        /// What is unsupported.
        message: String,
    },
    /// Data that the chosen format cannot hold (nothing was written).
    #[error("{path}: cannot be written as {format}: {message}")]
    Unencodable {
        /// The file that was to be written.
        path: PathBuf,
        /// The format's name.
        format: &'static str,
        /// Why.
        message: String,
    },
    /// The format cannot be told from the file name.
    #[error("{path}: {message}")]
    UnknownFormat {
        /// The file.
        path: PathBuf,
        /// What is wrong and what to do.
        message: String,
    },
}

/// Result alias of gs-export.
pub type Result<T> = std::result::Result<T, ExportError>;

impl ExportError {
    /// An [`ExportError::Format`] for `path`.
    pub fn format(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Self::Format { path: path.into(), message: message.into() }
    }
    /// An [`ExportError::Unsupported`] for `path`.
    pub fn unsupported(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Self::Unsupported { path: path.into(), message: message.into() }
    }
    /// An [`ExportError::Unencodable`] for `path` in `format`.
    pub fn unencodable(path: impl Into<PathBuf>, format: &'static str, message: impl Into<String>) -> Self {
        Self::Unencodable { path: path.into(), format, message: message.into() }
    }
}
