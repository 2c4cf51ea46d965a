//! Image dimensions of the kernels' row-major buffers, and the deterministic parallel sum they
//! reduce with. (The float trait [`crate::Real`] is gs-core's, re-exported at the crate root.)

/// Size of a row-major `[H][W][C]` buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Dims {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Values per pixel.
    pub channels: usize,
}

impl Dims {
    /// A new size.
    pub const fn new(width: usize, height: usize, channels: usize) -> Self {
        Self {
            width,
            height,
            channels,
        }
    }
    /// width × height.
    pub const fn pixels(&self) -> usize {
        self.width * self.height
    }
    /// width × height × channels.
    pub const fn len(&self) -> usize {
        self.width * self.height * self.channels
    }
    /// Whether the buffer is empty.
    pub const fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// The same size with a different channel count.
    pub const fn with_channels(&self, channels: usize) -> Self {
        Self {
            width: self.width,
            height: self.height,
            channels,
        }
    }
    /// Size of a `gs_core::Image`.
    pub fn of(img: &gs_core::Image) -> Self {
        Self::new(img.width(), img.height(), img.channels())
    }
}

/// Deterministic parallel sum: `f(i)` for `i in 0..n` evaluated in parallel, partial results
/// added in index order (bit-identical for any thread count).
pub(crate) fn ordered_sum(n: usize, f: impl Fn(usize) -> f64 + Sync + Send) -> f64 {
    use rayon::prelude::*;
    let parts: Vec<f64> = (0..n).into_par_iter().map(f).collect();
    parts.iter().sum()
}
