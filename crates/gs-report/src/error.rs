//! Errors of gs-report.

use std::path::PathBuf;

/// What can go wrong while writing a report page.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// Writing a file of the page failed.
    #[error(transparent)]
    Io(#[from] gs_io::IoError),
    /// A folder of the page could not be created.
    #[error("{path}: cannot create the folder: {source}")]
    Folder {
        /// The folder.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The model or mesh cannot be shown (too large for a browser's textures, invalid).
    #[error("{0}")]
    Invalid(String),
}

/// Result alias of gs-report.
pub type Result<T> = std::result::Result<T, ReportError>;
