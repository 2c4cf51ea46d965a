//! The error type of gs-io: every variant names the file it concerns.

use std::path::PathBuf;
use thiserror::Error;

/// Errors of gs-io. Each names the file and, where there is one, the record (line number,
/// image id, byte offset) and the problem.
#[derive(Debug, Error)]
pub enum IoError {
    /// The OS refused to open, read, write or rename a file.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A text file that does not parse; `line` is 1-based.
    #[error("{path}:{line}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A binary or structured file whose content is malformed (truncated, wrong magic, wrong
    /// counts, NaN values, unknown model id, non-UTF-8 text…).
    #[error("{path}: {message}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A valid file that uses something vagsl does not support (e.g. a fisheye camera model).
    #[error("{path}: unsupported: {message}")]
    Unsupported {
        /// The file.
        path: PathBuf,
        /// What is unsupported.
        message: String,
    },
    /// A model that is internally inconsistent (an image referencing a missing camera, a
    /// missing image file, an empty model).
    #[error("{path}: {message}")]
    Invalid {
        /// The file or folder.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// An error from gs-core while building cameras, images or Gaussians from a file.
    #[error("{path}: {source}")]
    Core {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: gs_core::CoreError,
    },
}

/// Result alias of gs-io.
pub type Result<T> = std::result::Result<T, IoError>;

impl IoError {
    /// An [`IoError::Io`] for `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io { path: path.into(), source }
    }
    /// An [`IoError::Format`] for `path`.
    pub fn format(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Self::Format { path: path.into(), message: message.into() }
    }
    /// An [`IoError::Parse`] for `path` at 1-based `line`.
    pub fn parse(path: impl Into<PathBuf>, line: usize, message: impl Into<String>) -> Self {
        Self::Parse { path: path.into(), line, message: message.into() }
    }
    /// An [`IoError::Invalid`] for `path`.
    pub fn invalid(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Self::Invalid { path: path.into(), message: message.into() }
    }
}
