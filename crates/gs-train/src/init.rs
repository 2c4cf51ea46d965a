//! Initial Gaussians (docs/method.md §Parameters): from the sparse SfM points with the 3DGS k-nearest-
//! neighbour scale, or random points in the cameras' bounding cube / on an enclosing sphere.

use crate::config::InitMode;
use crate::error::{Result, TrainError};
use gs_core::gaussians::{inverse_sigmoid, rgb_to_sh_dc};
use gs_core::glam::DVec3;
use gs_core::sh::SH_COEFFS;
use gs_core::{Gaussians, Rng, Scene, ScenePoint};
use kiddo::SquaredEuclidean;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use rayon::prelude::*;
use std::num::NonZero;

/// Initial opacity of every Gaussian (docs/method.md §Parameters).
pub const INITIAL_OPACITY: f32 = 0.1;
/// Floor of the squared kNN distance (3DGS `clamp_min(dist2, 1e-7)`).
pub const MIN_SQUARED_DISTANCE: f64 = 1e-7;

/// Mean squared distance of every point to its 3 nearest other points (fewer when there are
/// fewer points; `MIN_SQUARED_DISTANCE` for a lone point), floored at `MIN_SQUARED_DISTANCE`.
pub fn knn_mean_squared_distance(points: &[[f64; 3]]) -> Vec<f64> {
    if points.len() < 2 {
        return vec![MIN_SQUARED_DISTANCE; points.len()];
    }
    let tree: ImmutableKdTree<f64, u32, 3, 32> = ImmutableKdTree::new_from_slice(points);
    let k = 4.min(points.len());
    points
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            let nn = tree.nearest_n::<SquaredEuclidean>(p, NonZero::new(k).expect("k ≥ 2"));
            // Exclude the point itself (by index; duplicates of it still count as neighbours).
            let others: Vec<f64> = nn.iter().filter(|n| n.item as usize != i).map(|n| n.distance).take(3).collect();
            let m = others.iter().sum::<f64>() / others.len().max(1) as f64;
            m.max(MIN_SQUARED_DISTANCE)
        })
        .collect()
}

/// Gaussians at `points`: SH DC from the colour, other SH 0, isotropic scale √(kNN mean
/// squared distance), identity rotation, opacity 0.1.
pub fn gaussians_from_points(points: &[ScenePoint]) -> Result<Gaussians> {
    if points.is_empty() {
        return Err(TrainError::InvalidScene("no points to initialise Gaussians from".into()));
    }
    if let Some(k) = points.iter().position(|p| !p.position.is_finite() || !p.color.iter().all(|c| c.is_finite())) {
        return Err(TrainError::InvalidScene(format!("point {k} has a non-finite position or colour")));
    }
    let xyz: Vec<[f64; 3]> = points.iter().map(|p| p.position.to_array()).collect();
    let d2 = knn_mean_squared_distance(&xyz);
    let mut g = Gaussians::with_len(0)?;
    for (p, d2) in points.iter().zip(d2) {
        let log_scale = (0.5 * d2.ln()) as f32;
        let mut sh = [[0.0f32; 3]; SH_COEFFS];
        for c in 0..3 {
            sh[0][c] = rgb_to_sh_dc(p.color[c].clamp(0.0, 1.0));
        }
        g.push(p.position.as_vec3().to_array(), [log_scale; 3], [1.0, 0.0, 0.0, 0.0], inverse_sigmoid(INITIAL_OPACITY), sh);
    }
    Ok(g)
}

/// `count` random points (grey, 0.5) in the cameras' bounding cube (expanded by 10%) or on
/// the sphere around the camera centres' mean with radius = the scene extent.
pub fn random_points(scene: &Scene, mode: InitMode, count: usize, seed: u64) -> Result<Vec<ScenePoint>> {
    let centres: Vec<DVec3> = scene.views.iter().map(|v| v.camera.center()).collect();
    if centres.is_empty() {
        return Err(TrainError::InvalidScene("no views to place random points around".into()));
    }
    let mut rng = Rng::new(seed).fork(0x1417);
    let extent = scene.extent().max(1e-6);
    let mean = centres.iter().copied().sum::<DVec3>() / centres.len() as f64;
    let (lo, hi) = centres.iter().fold((DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)), |(l, h), c| (l.min(*c), h.max(*c)));
    let pad = ((hi - lo) * 0.1).max(DVec3::splat(0.1 * extent));
    let (lo, hi) = (lo - pad, hi + pad);
    let pts = (0..count)
        .map(|_| {
            let position = match mode {
                InitMode::Sphere => {
                    let d = DVec3::new(rng.normal() as f64, rng.normal() as f64, rng.normal() as f64);
                    mean + d.normalize_or(DVec3::X) * extent
                }
                _ => lo + (hi - lo) * DVec3::new(rng.uniform_f64(), rng.uniform_f64(), rng.uniform_f64()),
            };
            ScenePoint { position, color: [0.5; 3] }
        })
        .collect();
    Ok(pts)
}

/// The initial Gaussians of `scene` for `mode` (points mode without points falls back to the
/// sphere, the better of the two random options in the paper's supplement).
pub fn initial_gaussians(scene: &Scene, mode: InitMode, random_count: usize, seed: u64) -> Result<(Gaussians, InitMode)> {
    let mode = if mode == InitMode::Points && scene.points.is_empty() { InitMode::Sphere } else { mode };
    let g = match mode {
        InitMode::Points => gaussians_from_points(&scene.points)?,
        _ => gaussians_from_points(&random_points(scene, mode, random_count, seed)?)?,
    };
    Ok((g, mode))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn knn_scale_of_a_grid() {
        // A 10×10×10 grid of spacing 0.1: the 3 nearest others are at 0.1 → scale 0.1.
        let mut pts = Vec::new();
        for i in 0..10 {
            for j in 0..10 {
                for k in 0..10 {
                    pts.push(ScenePoint { position: DVec3::new(i as f64, j as f64, k as f64) * 0.1, color: [0.2, 0.5, 1.0] });
                }
            }
        }
        let g = gaussians_from_points(&pts).unwrap();
        for s in &g.log_scales {
            assert!((s[0].exp() - 0.1).abs() < 1e-5, "{s:?}");
        }
        assert!((g.opacity(0) - 0.1).abs() < 1e-6);
        let c = gs_core::sh::eval_sh(0, &g.sh[0], [0.0, 0.0, 1.0]);
        assert!((c[0] + 0.5 - 0.2).abs() < 1e-5 && (c[2] + 0.5 - 1.0).abs() < 1e-5);
    }

    #[test]
    fn degenerate_point_sets() {
        let one = [ScenePoint { position: DVec3::ONE, color: [0.5; 3] }];
        let g = gaussians_from_points(&one).unwrap();
        assert!((g.log_scales[0][0] - (0.5 * MIN_SQUARED_DISTANCE.ln()) as f32).abs() < 1e-5);
        let dup = vec![one[0]; 5];
        assert!(gaussians_from_points(&dup).unwrap().log_scales.iter().all(|s| s[0].is_finite()));
        assert!(gaussians_from_points(&[]).is_err());
        let nan = [ScenePoint { position: DVec3::new(f64::NAN, 0.0, 0.0), color: [0.5; 3] }];
        assert!(gaussians_from_points(&nan).unwrap_err().to_string().contains("point 0"));
    }
}
