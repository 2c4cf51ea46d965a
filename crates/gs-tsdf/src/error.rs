//! The error type of gs-tsdf.

use thiserror::Error;

/// Everything that can go wrong in fusion, extraction, clean-up and metrics.
#[derive(Debug, Error)]
pub enum TsdfError {
    /// A parameter is out of its valid range (voxel size ≤ 0, NaN, …).
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// An input image does not match its camera or has the wrong channel count.
    #[error("invalid input for view {view}: {problem}")]
    InvalidInput {
        /// Index of the view in the caller's sequence (or 0 for a single call).
        view: usize,
        /// What is wrong.
        problem: String,
    },
    /// Allocating the blocks a view touches would exceed the configured block cap.
    #[error(
        "TSDF block cap exceeded: {needed} blocks needed, cap is {cap} (voxel size {voxel_size}); \
         raise max_blocks or use a larger voxel size"
    )]
    BlockCapExceeded {
        /// Blocks that would exist after this view.
        needed: usize,
        /// The configured cap.
        cap: usize,
        /// The voxel size in use.
        voxel_size: f64,
    },
    /// The operating system refused the memory for the blocks of a view.
    #[error(
        "out of memory: {blocks} TSDF blocks need {} of block storage; use a larger voxel size",
        format_bytes(*bytes)
    )]
    OutOfMemory {
        /// Blocks that would exist after this view.
        blocks: usize,
        /// Bytes of block storage requested.
        bytes: u64,
    },
    /// A point lies so far from the origin that its block index does not fit in 32 bits.
    #[error("point {point:?} is too far from the origin for voxel size {voxel_size} (block index overflow)")]
    OutOfRange {
        /// The offending world point.
        point: [f64; 3],
        /// The voxel size in use.
        voxel_size: f64,
    },
    /// A mesh or point set is empty or invalid where a non-empty one is required.
    #[error("{0}")]
    InvalidMesh(String),
    /// An error reported by gs-core.
    #[error(transparent)]
    Core(#[from] gs_core::CoreError),
}

/// `Result` with [`TsdfError`].
pub type Result<T> = std::result::Result<T, TsdfError>;

/// `bytes` in words with binary units ("512 B", "3.2 MiB", "14.1 GiB"), as this crate's messages
/// and its callers' print them.
pub fn format_bytes(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["KiB", "MiB", "GiB", "TiB", "PiB"];
    if bytes < 1024 {
        return format!("{bytes} B");
    }
    let mut v = bytes as f64 / 1024.0;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    format!("{v:.1} {}", UNITS[u])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_in_words() {
        assert_eq!(format_bytes(512), "512 B");
        assert_eq!(format_bytes(3 * 1024 * 1024 + 200 * 1024), "3.2 MiB");
        assert_eq!(format_bytes(8 << 30), "8.0 GiB");
    }
}
