//! L1 = mean over pixels and channels of |Ĩ − I| (docs/method.md §L_I), with its backward.

use crate::Real;
use crate::dims::ordered_sum;
use rayon::prelude::*;

const CHUNK: usize = 1 << 14;

/// Mean absolute difference of `rendered` and `target` (same length). 0 for empty input.
pub fn l1<T: Real>(rendered: &[T], target: &[T]) -> f64 {
    assert_eq!(rendered.len(), target.len(), "l1: length mismatch");
    let n = rendered.len();
    if n == 0 {
        return 0.0;
    }
    chunked_mean(n, |i| (rendered[i] - target[i]).abs().to_f64())
}

/// The mean of `value(i)` over `i < n` in L1's fixed order: f64 sums of chunks of 16,384, the
/// chunks in order (the device twin sums its per-value terms the same way). `n` > 0.
pub(crate) fn chunked_mean(n: usize, value: impl Fn(usize) -> f64 + Sync + Send) -> f64 {
    ordered_sum(n.div_ceil(CHUNK), |k| (k * CHUNK..((k + 1) * CHUNK).min(n)).map(&value).sum()) / n as f64
}

/// Adds `weight · ∂L1/∂rendered` = `weight · sign(Ĩ − I) / n` to `grad` (sign(0) = 0).
pub fn l1_backward<T: Real>(rendered: &[T], target: &[T], weight: f64, grad: &mut [T]) {
    assert_eq!(rendered.len(), target.len(), "l1: length mismatch");
    assert_eq!(rendered.len(), grad.len(), "l1: gradient length mismatch");
    let n = rendered.len();
    if n == 0 {
        return;
    }
    let s = T::from_f64(weight / n as f64);
    grad.par_chunks_mut(CHUNK).enumerate().for_each(|(k, g)| {
        let o = k * CHUNK;
        for (i, gi) in g.iter_mut().enumerate() {
            *gi += s * (rendered[o + i] - target[o + i]).sign0();
        }
    });
}
