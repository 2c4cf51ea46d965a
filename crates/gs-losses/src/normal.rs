//! Depth normal N̂ from the plane depth (docs/method.md §L_nc) and its backward into the depth map.
//!
//! P(i, j) = z(i, j)·K⁻¹(i + 0.5, j + 0.5, 1)ᵀ (pixel centres, docs/architecture.md §Conventions);
//! N̂(i, j) = A(i, j) · normalise(cross(P(i+1, j) − P(i−1, j), P(i, j−1) − P(i, j+1))) with
//! normalise(n) = n / max(‖n‖, 1e-12). With x right and y down (COLMAP), this cross product points
//! towards the camera (negative z) for any surface seen from the front, so no flip is applied.
//! N̂ = 0 on the image border. The alpha A is a constant (no gradient). Depth holes (z = 0) are
//! not special-cased: they produce the formula's literal value (and a zero normal where every
//! neighbour is 0).

use crate::Real;
use gs_core::Intrinsics;
use rayon::prelude::*;

/// The ε of the normalisation n / max(‖n‖, ε).
pub const NORMALIZE_EPS: f64 = 1e-12;

/// x of the ray K⁻¹(i + 0.5, j + 0.5, 1) through column i's pixel centres (in f64; the device
/// twin uploads these and [`ray_y`]'s as f32, as [`ray`] rounds them).
#[inline]
pub(crate) fn ray_x(k: &Intrinsics, i: usize) -> f64 {
    (i as f64 + 0.5 - k.cx) / k.fx
}

/// y of the ray through row j's pixel centres.
#[inline]
pub(crate) fn ray_y(k: &Intrinsics, j: usize) -> f64 {
    (j as f64 + 0.5 - k.cy) / k.fy
}

#[inline]
fn ray<T: Real>(k: &Intrinsics, i: usize, j: usize) -> [T; 3] {
    [T::from_f64(ray_x(k, i)), T::from_f64(ray_y(k, j)), T::ONE]
}

#[inline]
fn point<T: Real>(z: &[T], w: usize, k: &Intrinsics, i: usize, j: usize) -> [T; 3] {
    let r = ray::<T>(k, i, j);
    let d = z[j * w + i];
    [r[0] * d, r[1] * d, r[2] * d]
}

#[inline]
fn sub<T: Real>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline]
fn cross<T: Real>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The two difference vectors (dx, dy) and the raw cross product at an interior pixel.
#[inline]
fn local<T: Real>(
    z: &[T],
    w: usize,
    k: &Intrinsics,
    i: usize,
    j: usize,
) -> ([T; 3], [T; 3], [T; 3]) {
    let dx = sub(point(z, w, k, i + 1, j), point(z, w, k, i - 1, j));
    let dy = sub(point(z, w, k, i, j - 1), point(z, w, k, i, j + 1));
    (dx, dy, cross(dx, dy))
}

/// N̂ (`[H][W][3]`, camera space) of the depth map `z` (`[H][W]`); `alpha` (`[H][W]`) multiplies
/// the result when given.
pub fn depth_normal<T: Real>(
    z: &[T],
    width: usize,
    height: usize,
    k: &Intrinsics,
    alpha: Option<&[T]>,
) -> Vec<T> {
    assert_eq!(z.len(), width * height, "depth_normal: depth length");
    if let Some(a) = alpha {
        assert_eq!(a.len(), width * height, "depth_normal: alpha length");
    }
    let mut out = vec![T::ZERO; width * height * 3];
    if width < 3 || height < 3 {
        return out;
    }
    let eps = T::from_f64(NORMALIZE_EPS);
    out.par_chunks_mut(width * 3)
        .enumerate()
        .for_each(|(j, row)| {
            if j == 0 || j == height - 1 {
                return;
            }
            for i in 1..width - 1 {
                let (_, _, n) = local(z, width, k, i, j);
                let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                let a = alpha.map_or(T::ONE, |a| a[j * width + i]);
                let s = a / len.max(eps);
                row[i * 3] = n[0] * s;
                row[i * 3 + 1] = n[1] * s;
                row[i * 3 + 2] = n[2] * s;
            }
        });
    out
}

/// Adds `Σ dl_dn · ∂N̂/∂z` to `grad_z` (`dl_dn` is `[H][W][3]`, `grad_z` is `[H][W]`).
pub fn depth_normal_backward<T: Real>(
    z: &[T],
    width: usize,
    height: usize,
    k: &Intrinsics,
    alpha: Option<&[T]>,
    dl_dn: &[T],
    grad_z: &mut [T],
) {
    let (w, h) = (width, height);
    assert_eq!(z.len(), w * h, "depth_normal_backward: depth length");
    assert_eq!(
        dl_dn.len(),
        w * h * 3,
        "depth_normal_backward: upstream length"
    );
    assert_eq!(
        grad_z.len(),
        w * h,
        "depth_normal_backward: gradient length"
    );
    if w < 3 || h < 3 {
        return;
    }
    let eps = T::from_f64(NORMALIZE_EPS);
    // ga = ∂L/∂dx, gb = ∂L/∂dy per interior pixel.
    let mut ga = vec![T::ZERO; w * h * 3];
    let mut gb = vec![T::ZERO; w * h * 3];
    ga.par_chunks_mut(w * 3)
        .zip(gb.par_chunks_mut(w * 3))
        .enumerate()
        .for_each(|(j, (ra, rb))| {
            if j == 0 || j == h - 1 {
                return;
            }
            for i in 1..w - 1 {
                let p = j * w + i;
                let g = [dl_dn[p * 3], dl_dn[p * 3 + 1], dl_dn[p * 3 + 2]];
                if g[0] == T::ZERO && g[1] == T::ZERO && g[2] == T::ZERO {
                    continue;
                }
                let a = alpha.map_or(T::ONE, |a| a[p]);
                let (dx, dy, n) = local(z, w, k, i, j);
                let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                let gn = if len > eps {
                    let inv = T::ONE / len;
                    let u = [n[0] * inv, n[1] * inv, n[2] * inv];
                    let ug = u[0] * g[0] + u[1] * g[1] + u[2] * g[2];
                    let s = a * inv;
                    [
                        (g[0] - u[0] * ug) * s,
                        (g[1] - u[1] * ug) * s,
                        (g[2] - u[2] * ug) * s,
                    ]
                } else {
                    let s = a / eps;
                    [g[0] * s, g[1] * s, g[2] * s]
                };
                let da = cross(dy, gn);
                let db = cross(gn, dx);
                ra[i * 3..i * 3 + 3].copy_from_slice(&da);
                rb[i * 3..i * 3 + 3].copy_from_slice(&db);
            }
        });
    let get = |v: &Vec<T>, i: usize, j: usize| -> [T; 3] {
        let q = (j * w + i) * 3;
        [v[q], v[q + 1], v[q + 2]]
    };
    grad_z.par_chunks_mut(w).enumerate().for_each(|(j, row)| {
        for (i, gz) in row.iter_mut().enumerate() {
            let mut s = [T::ZERO; 3];
            let mut acc = |v: [T; 3], sign: T| {
                s[0] += sign * v[0];
                s[1] += sign * v[1];
                s[2] += sign * v[2];
            };
            if i >= 1 {
                acc(get(&ga, i - 1, j), T::ONE);
            }
            if i + 1 < w {
                acc(get(&ga, i + 1, j), -T::ONE);
            }
            if j + 1 < h {
                acc(get(&gb, i, j + 1), T::ONE);
            }
            if j >= 1 {
                acc(get(&gb, i, j - 1), -T::ONE);
            }
            let r = ray::<T>(k, i, j);
            *gz += s[0] * r[0] + s[1] * r[1] + s[2] * r[2];
        }
    });
}
