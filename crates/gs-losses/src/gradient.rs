//! PGSR's normalised image gradient ∇I, its backward, the edge term L1(∇Ĩ, ∇I) and the edge weight
//! δ = (1 − ∇I)² (docs/method.md §L_I, §L_nc).
//!
//! For interior pixels g = max(g_x, g_y) with g_x = mean_c |I(x+1,y) − I(x−1,y)| and g_y likewise
//! vertically; then g ← (g − min)/(max − min + 1e-6) with min and max over the interior (treated
//! as constants in the backward pass); border pixels are 1. Images narrower or lower than 3 pixels
//! have no interior: ∇I is 1 everywhere and its gradient is 0.

use crate::Real;
use crate::dims::{Dims, ordered_sum};
use rayon::prelude::*;

/// ε of the min–max normalisation (ours; PGSR has none and gives NaN on constant images).
pub const GRAD_NORM_EPS: f64 = 1e-6;

/// A normalised gradient map ∇I (`[H][W]`) with the interior min and max used to normalise it.
#[derive(Debug, Clone, PartialEq)]
pub struct GradientMap<T> {
    /// ∇I, one value per pixel, row-major.
    pub map: Vec<T>,
    /// Interior minimum of the raw gradient (0 when there is no interior).
    pub min: T,
    /// Interior maximum of the raw gradient (0 when there is no interior).
    pub max: T,
}

#[inline]
fn raw_at<T: Real>(img: &[T], dims: Dims, x: usize, y: usize) -> (T, T) {
    let (w, c) = (dims.width, dims.channels);
    let inv_c = T::from_f64(1.0 / c as f64);
    let (mut gx, mut gy) = (T::ZERO, T::ZERO);
    let r = (x + 1 + y * w) * c;
    let l = (x - 1 + y * w) * c;
    let d = (x + (y + 1) * w) * c;
    let u = (x + (y - 1) * w) * c;
    for k in 0..c {
        gx += (img[r + k] - img[l + k]).abs();
        gy += (img[d + k] - img[u + k]).abs();
    }
    (gx * inv_c, gy * inv_c)
}

fn has_interior(dims: Dims) -> bool {
    dims.width >= 3 && dims.height >= 3
}

/// ∇I of an `[H][W][C]` image (see the module docs).
pub fn image_gradient<T: Real>(img: &[T], dims: Dims) -> GradientMap<T> {
    assert_eq!(img.len(), dims.len(), "image_gradient: length mismatch");
    let (w, h) = (dims.width, dims.height);
    let mut map = vec![T::ONE; w * h];
    if !has_interior(dims) {
        return GradientMap {
            map,
            min: T::ZERO,
            max: T::ZERO,
        };
    }
    map.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        if y == 0 || y == h - 1 {
            return;
        }
        for (x, v) in row.iter_mut().enumerate().take(w - 1).skip(1) {
            let (gx, gy) = raw_at(img, dims, x, y);
            *v = gx.max(gy);
        }
    });
    let (lo, hi) = (1..h - 1)
        .into_par_iter()
        .map(|y| {
            let row = &map[y * w + 1..y * w + w - 1];
            row.iter()
                .fold((row[0], row[0]), |(a, b), &v| (a.min(v), b.max(v)))
        })
        .collect::<Vec<_>>()
        .into_iter()
        .fold(None, |acc: Option<(T, T)>, (a, b)| match acc {
            None => Some((a, b)),
            Some((p, q)) => Some((p.min(a), q.max(b))),
        })
        .expect("non-empty interior");
    let inv = T::ONE / (hi - lo + T::from_f64(GRAD_NORM_EPS));
    map.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        if y == 0 || y == h - 1 {
            return;
        }
        for v in row.iter_mut().take(w - 1).skip(1) {
            *v = (*v - lo) * inv;
        }
    });
    GradientMap {
        map,
        min: lo,
        max: hi,
    }
}

/// ∇I with a given normalisation range (min, max), e.g. the range of an earlier evaluation: the
/// function whose derivative [`image_gradient_backward`] computes (min and max held constant).
pub fn image_gradient_fixed_range<T: Real>(img: &[T], dims: Dims, min: T, max: T) -> Vec<T> {
    assert_eq!(
        img.len(),
        dims.len(),
        "image_gradient_fixed_range: length mismatch"
    );
    let (w, h) = (dims.width, dims.height);
    let mut map = vec![T::ONE; w * h];
    if !has_interior(dims) {
        return map;
    }
    let inv = T::ONE / (max - min + T::from_f64(GRAD_NORM_EPS));
    map.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        if y == 0 || y == h - 1 {
            return;
        }
        for (x, v) in row.iter_mut().enumerate().take(w - 1).skip(1) {
            let (gx, gy) = raw_at(img, dims, x, y);
            *v = (gx.max(gy) - min) * inv;
        }
    });
    map
}

/// Adds `Σ_p dl_dgrad[p] · ∂∇I[p]/∂img` to `grad_img`, with min and max constant. At a tie
/// g_x = g_y the gradient goes to g_x; |0| has subgradient 0.
pub fn image_gradient_backward<T: Real>(
    img: &[T],
    dims: Dims,
    gmap: &GradientMap<T>,
    dl_dgrad: &[T],
    grad_img: &mut [T],
) {
    let (w, h, c) = (dims.width, dims.height, dims.channels);
    assert_eq!(
        img.len(),
        dims.len(),
        "image_gradient_backward: image length"
    );
    assert_eq!(
        grad_img.len(),
        dims.len(),
        "image_gradient_backward: gradient length"
    );
    assert_eq!(
        dl_dgrad.len(),
        w * h,
        "image_gradient_backward: upstream length"
    );
    if !has_interior(dims) {
        return;
    }
    let scale =
        T::ONE / (gmap.max - gmap.min + T::from_f64(GRAD_NORM_EPS)) * T::from_f64(1.0 / c as f64);
    // Coefficients of the chosen axis per interior pixel.
    let mut cx = vec![T::ZERO; w * h];
    let mut cy = vec![T::ZERO; w * h];
    cx.par_chunks_mut(w)
        .zip(cy.par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, (rx, ry))| {
            if y == 0 || y == h - 1 {
                return;
            }
            for x in 1..w - 1 {
                let up = dl_dgrad[y * w + x];
                if up == T::ZERO {
                    continue;
                }
                let (gx, gy) = raw_at(img, dims, x, y);
                if gx >= gy {
                    rx[x] = up * scale;
                } else {
                    ry[x] = up * scale;
                }
            }
        });
    let at = |x: usize, y: usize, k: usize| img[(y * w + x) * c + k];
    grad_img
        .par_chunks_mut(w * c)
        .enumerate()
        .for_each(|(y, grow)| {
            for x in 0..w {
                for k in 0..c {
                    let v = at(x, y, k);
                    let mut g = T::ZERO;
                    // pixel (x−1, y): g_x = |I(x) − I(x−2)|
                    if x >= 2 {
                        g += cx[y * w + x - 1] * (v - at(x - 2, y, k)).sign0();
                    }
                    // pixel (x+1, y): g_x = |I(x+2) − I(x)|
                    if x + 2 < w {
                        g -= cx[y * w + x + 1] * (at(x + 2, y, k) - v).sign0();
                    }
                    if y >= 2 {
                        g += cy[(y - 1) * w + x] * (v - at(x, y - 2, k)).sign0();
                    }
                    if y + 2 < h {
                        g -= cy[(y + 1) * w + x] * (at(x, y + 2, k) - v).sign0();
                    }
                    grow[x * c + k] += g;
                }
            }
        });
}

/// The edge term L1(∇Ĩ, ∇I) = mean over all H·W pixels of |∇Ĩ − ∇I| (border pixels are 1 in both
/// and contribute 0). Returns the value and adds `weight · ∂/∂∇Ĩ` to `dl_dgrad` when given.
pub fn edge_l1<T: Real>(
    grad_rendered: &[T],
    grad_gt: &[T],
    weight: f64,
    dl_dgrad: Option<&mut [T]>,
) -> f64 {
    assert_eq!(
        grad_rendered.len(),
        grad_gt.len(),
        "edge_l1: length mismatch"
    );
    let n = grad_rendered.len();
    if n == 0 {
        return 0.0;
    }
    let v = crate::l1::l1(grad_rendered, grad_gt);
    if let Some(g) = dl_dgrad {
        crate::l1::l1_backward(grad_rendered, grad_gt, weight, g);
    }
    v
}

/// Edge weight δ = clamp((1 − ∇I)², 0, 1) from the ground-truth gradient map (0 on the border).
pub fn edge_weight<T: Real>(grad_gt: &[T]) -> Vec<T> {
    grad_gt
        .par_iter()
        .map(|&g| {
            let d = (T::ONE - g) * (T::ONE - g);
            d.max(T::ZERO).min(T::ONE)
        })
        .collect()
}

/// Mean of a map (deterministic), used for reports and tests.
pub fn mean<T: Real>(v: &[T]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    ordered_sum(v.len().div_ceil(4096), |k| {
        v[k * 4096..((k + 1) * 4096).min(v.len())]
            .iter()
            .map(|x| x.to_f64())
            .sum()
    }) / v.len() as f64
}
