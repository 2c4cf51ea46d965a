//! Which views and sparse points each block trains on (docs/architecture.md §Partitioned
//! training). A view belongs to a block when its camera stands in the block's grown region, or
//! when at least a fraction (`visibility`) of the sparse points in its image lie in that region
//! — VastGaussian's visibility rule, with sparse points standing in for the surface. A block's
//! points are those in its grown region and those its views see, so what lies behind the
//! region starts from points too instead of growing floaters.

use crate::regions::Rect;
use crate::ground::GroundFrame;
use glam::DVec3;
use gs_core::Camera;
use rayon::prelude::*;

/// The views and points of one block, as indices into the capture's lists.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Members {
    /// Indices of the block's views.
    pub views: Vec<usize>,
    /// Indices of the block's sparse points.
    pub points: Vec<usize>,
}

/// The points (indices) that `camera` sees: in front of it and inside its image.
pub fn visible_points(camera: &Camera, points: &[DVec3]) -> Vec<usize> {
    points
        .iter()
        .enumerate()
        .filter(|(_, p)| camera.world_to_camera(**p).z > 1e-9 && camera.project(**p).is_some_and(|(uv, _)| camera.contains(uv)))
        .map(|(i, _)| i)
        .collect()
}

/// The members of every block of `regions` (grown regions), from `cameras` (the views that may
/// train) and `points`, under `frame`. Deterministic and independent of the thread count.
pub fn assign(frame: &GroundFrame, regions: &[Rect], cameras: &[Camera], points: &[DVec3], visibility: f64) -> Vec<Members> {
    let ground: Vec<[f64; 2]> = points.iter().map(|p| frame.coords(*p)).collect();
    let seen: Vec<Vec<usize>> = cameras.par_iter().map(|c| visible_points(c, points)).collect();
    regions
        .iter()
        .map(|r| {
            let views: Vec<usize> = (0..cameras.len())
                .filter(|&c| {
                    let inside = seen[c].iter().filter(|&&i| r.contains(ground[i])).count();
                    r.contains(frame.coords(cameras[c].center())) || (!seen[c].is_empty() && inside as f64 >= visibility * seen[c].len() as f64)
                })
                .collect();
            let mut take = vec![false; points.len()];
            for (i, g) in ground.iter().enumerate() {
                take[i] = r.contains(*g);
            }
            for &c in &views {
                for &i in &seen[c] {
                    take[i] = true;
                }
            }
            Members { views, points: (0..points.len()).filter(|&i| take[i]).collect() }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use gs_core::Intrinsics;

    #[test]
    fn views_follow_what_they_see() {
        // Cameras along x at y = 0 looking at +y; points on a wall at y = 2.
        let cams: Vec<Camera> = (0..8)
            .map(|i| {
                let eye = DVec3::new(i as f64, 0.0, 1.0);
                Camera::look_at(64, 48, Intrinsics::new(40.0, 40.0, 32.0, 24.0), eye, eye + DVec3::Y, DVec3::Z).unwrap()
            })
            .collect();
        let pts: Vec<DVec3> = (0..80).map(|i| DVec3::new(i as f64 * 0.1, 2.0, 0.5 + 0.01 * (i % 7) as f64)).collect();
        let frame = GroundFrame { origin: [0.0; 3], u: [1.0, 0.0, 0.0], v: [0.0, 1.0, 0.0], up: [0.0, 0.0, 1.0] };
        let left = Rect { min: [-1.0, -5.0], max: [3.0, 5.0] };
        let right = Rect { min: [3.5, -5.0], max: [9.0, 5.0] };
        let m = assign(&frame, &[left, right], &cams, &pts, 0.25);
        assert_eq!(m[0].views, vec![0, 1, 2, 3]);
        assert_eq!(m[1].views, vec![3, 4, 5, 6, 7]);
        assert!(m[0].points.iter().all(|&i| pts[i].x < 5.5), "a left point far right");
        assert!(m[1].points.contains(&79));
        // A stricter visibility keeps fewer cross-border views.
        let strict = assign(&frame, &[left, right], &cams, &pts, 0.9);
        assert_eq!(strict[1].views, vec![4, 5, 6, 7]);
    }
}
