//! A minimal float trait so that every kernel runs in f32 (training) and f64 (gradient checks,
//! reference comparisons) from one source.

use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// The float operations the loss kernels need; implemented for `f32` and `f64`.
pub trait Real:
    Copy
    + Send
    + Sync
    + PartialOrd
    + Default
    + std::fmt::Debug
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + 'static
{
    /// 0.
    const ZERO: Self;
    /// 1.
    const ONE: Self;
    /// Conversion from f64 (rounding for f32).
    fn from_f64(v: f64) -> Self;
    /// Conversion to f64 (exact).
    fn to_f64(self) -> f64;
    /// |x|.
    fn abs(self) -> Self;
    /// √x.
    fn sqrt(self) -> Self;
    /// Larger of two values.
    fn max(self, o: Self) -> Self;
    /// Smaller of two values.
    fn min(self, o: Self) -> Self;
    /// Whether the value is finite.
    fn is_finite(self) -> bool;
    /// Sign with sign(0) = 0 (the subgradient of |x| that PyTorch's autograd uses); branchless.
    fn sign0(self) -> Self;
}

macro_rules! impl_real {
    ($t:ty) => {
        impl Real for $t {
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;
            #[inline]
            fn from_f64(v: f64) -> Self {
                v as $t
            }
            #[inline]
            fn to_f64(self) -> f64 {
                self as f64
            }
            #[inline]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline]
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            #[inline]
            fn max(self, o: Self) -> Self {
                <$t>::max(self, o)
            }
            #[inline]
            fn min(self, o: Self) -> Self {
                <$t>::min(self, o)
            }
            #[inline]
            fn is_finite(self) -> bool {
                <$t>::is_finite(self)
            }
            #[inline]
            fn sign0(self) -> Self {
                ((self > 0.0) as i32 - (self < 0.0) as i32) as $t
            }
        }
    };
}
impl_real!(f32);
impl_real!(f64);

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
