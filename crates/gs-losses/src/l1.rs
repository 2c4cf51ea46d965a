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
    let sum = ordered_sum(n.div_ceil(CHUNK), |k| {
        let r = k * CHUNK..((k + 1) * CHUNK).min(n);
        rendered[r.clone()]
            .iter()
            .zip(&target[r])
            .map(|(&a, &b)| (a - b).abs().to_f64())
            .sum()
    });
    sum / n as f64
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
