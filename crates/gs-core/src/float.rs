//! A minimal float abstraction so that the same kernels run in f32 (training) and f64
//! (finite-difference gradient checks, reference conformance). Shared by gs-losses and gs-mvs.

use std::fmt::Debug;
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// The float types the kernels run in: `f32` (hot path) and `f64` (tests, references).
pub trait Real:
    Copy
    + Send
    + Sync
    + Default
    + Debug
    + PartialOrd
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
    /// Square root.
    fn sqrt(self) -> Self;
    /// e^x.
    fn exp(self) -> Self;
    /// Largest integer ≤ x.
    fn floor(self) -> Self;
    /// |x|.
    fn abs(self) -> Self;
    /// Whether x is neither NaN nor infinite.
    fn is_finite(self) -> bool;
    /// max(x, y) (ignores a NaN argument like `f32::max`).
    fn max(self, other: Self) -> Self;
    /// min(x, y).
    fn min(self, other: Self) -> Self;
    /// Sign with sign(0) = 0 (the subgradient of |x| that PyTorch's autograd uses); branchless.
    fn sign0(self) -> Self;
    /// Conversion from a pixel index.
    #[inline]
    fn from_usize(v: usize) -> Self {
        Self::from_f64(v as f64)
    }
    /// ⌊x⌋ as an integer for finite x with |x| < 2²⁴ (pixel coordinates): truncation and one
    /// compare in the type itself, without libm or a round trip through f64.
    fn floor_index(self) -> isize;
    /// Conversion from a signed pixel index (exact for |v| < 2²⁴).
    fn from_isize(v: isize) -> Self;
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
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            #[inline]
            fn exp(self) -> Self {
                <$t>::exp(self)
            }
            #[inline]
            fn floor(self) -> Self {
                <$t>::floor(self)
            }
            #[inline]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline]
            fn is_finite(self) -> bool {
                <$t>::is_finite(self)
            }
            #[inline]
            fn max(self, other: Self) -> Self {
                <$t>::max(self, other)
            }
            #[inline]
            fn min(self, other: Self) -> Self {
                <$t>::min(self, other)
            }
            #[inline]
            fn sign0(self) -> Self {
                ((self > 0.0) as i32 - (self < 0.0) as i32) as $t
            }
            #[inline]
            fn floor_index(self) -> isize {
                let i = self as isize;
                if (i as $t) > self { i - 1 } else { i }
            }
            #[inline]
            fn from_isize(v: isize) -> Self {
                v as $t
            }
        }
    };
}
impl_real!(f32);
impl_real!(f64);

#[cfg(test)]
mod tests {
    use super::Real;

    #[test]
    fn sign0_and_conversions() {
        assert_eq!((2.5f32.sign0(), (-1e-30f64).sign0(), 0.0f32.sign0()), (1.0, -1.0, 0.0));
        assert_eq!(f32::from_usize(7), 7.0);
        assert_eq!(<f64 as Real>::floor(-0.5), -1.0);
        for v in [-1.0f32, -0.75, -0.0, 0.0, 0.25, 1.0, 479.99997, 480.0] {
            assert_eq!(v.floor_index(), v.floor() as isize, "{v}");
            assert_eq!((v as f64).floor_index(), (v as f64).floor() as isize, "{v}");
        }
        assert_eq!(f32::from_isize(-1), -1.0);
    }
}
