//! Curvature split: Gaussians too large for the curve of the surface they lie on are split
//! (docs/method.md §Densification).
//!
//! A flat Gaussian of extent a (two standard deviations of its largest scale) lying on a surface
//! of curvature κ departs from it by the sag s = a²κ/2 at its rim. Seen edge-on, that rim sticks
//! out past the surface's silhouette unless the Gaussian sinks in by about s, and every view
//! of a thin curved part (a tube, a rim) sees some of it edge-on: the training then settles
//! those Gaussians inside the surface, and the mesh fused from their depth lies behind it
//! (docs/suite-full.md, stop 51: spring's tube). Their image gradient is small, so the
//! gradient rule never splits them.
//!
//! The rule estimates κ at Gaussian i from its nearest neighbours j within 3σᵢ:
//! κᵢⱼ = |nᵢ × nⱼ| / ‖μᵢ − μⱼ‖ (sine of the angle between the unoriented normals over the
//! distance), κᵢ = the median over at least three such neighbours. i is split when its sag
//! 2σᵢ²κᵢ exceeds `max_sag_pixels` pixel footprints, the footprint being the world size of a
//! pixel where i is largest on screen: 3σᵢ / (largest screen radius, px).

use gs_core::glam::Vec3;
use gs_core::{DensifyStats, Gaussians};
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use kiddo::SquaredEuclidean;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::num::NonZero;

/// Neighbours asked of the k-d tree for every Gaussian (itself included).
const NEIGHBOURS: usize = 9;
/// Fewest neighbours within reach for a curvature estimate.
const MIN_NEIGHBOURS: usize = 3;
/// Neighbours count within this many of the Gaussian's largest standard deviations.
const REACH_SIGMAS: f32 = 3.0;

/// The curvature split's setting (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CurvatureSplit {
    /// Split Gaussians that sag off their surface. Off by default.
    pub enabled: bool,
    /// Largest sag allowed, in pixel footprints.
    pub max_sag_pixels: f32,
}

impl Default for CurvatureSplit {
    fn default() -> Self {
        Self { enabled: false, max_sag_pixels: 0.5 }
    }
}

/// Which Gaussians sag more than the rule allows (all false when it is off). Gaussians no view
/// saw since the statistics were reset (largest radius 0) are never flagged.
pub fn sagging(g: &Gaussians, stats: &DensifyStats, rule: &CurvatureSplit) -> Vec<bool> {
    let n = g.len();
    if !rule.enabled || n <= MIN_NEIGHBOURS {
        return vec![false; n];
    }
    let tree: ImmutableKdTree<f32, u32, 3, 32> = ImmutableKdTree::new_from_slice(&g.means);
    let normals: Vec<Vec3> = (0..n).map(|i| g.normal(i)).collect();
    let k = NonZero::new(NEIGHBOURS.min(n)).expect("n > MIN_NEIGHBOURS");
    (0..n)
        .into_par_iter()
        .map(|i| {
            let radius_px = stats.max_radius[i];
            if radius_px <= 0.0 {
                return false;
            }
            let sigma = g.scale(i).into_iter().fold(0.0f32, f32::max);
            let reach = REACH_SIGMAS * sigma;
            let centre = Vec3::from(g.means[i]);
            let mut bends: Vec<f32> = tree
                .nearest_n::<SquaredEuclidean>(&g.means[i], k)
                .iter()
                .filter(|nb| nb.item as usize != i)
                .filter_map(|nb| {
                    let j = nb.item as usize;
                    let d = centre.distance(Vec3::from(g.means[j]));
                    (d > 0.0 && d <= reach).then(|| normals[i].cross(normals[j]).length() / d)
                })
                .collect();
            if bends.len() < MIN_NEIGHBOURS {
                return false;
            }
            bends.sort_unstable_by(f32::total_cmp);
            let kappa = bends[bends.len() / 2];
            let footprint = REACH_SIGMAS * sigma / radius_px;
            2.0 * sigma * sigma * kappa > rule.max_sag_pixels * footprint
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Discs of scale `sigma` (flat along their normal) on a ring of radius `radius` around the
    /// z axis (a cylinder's cross-sections at three heights), or on the plane x = `radius`
    /// when `radius` is infinite.
    fn discs(radius: f32, sigma: f32) -> Gaussians {
        let mut g = Gaussians::with_len(0).unwrap();
        let step = sigma;
        for h in 0..3 {
            for k in 0..40 {
                let (mean, normal) = if radius.is_finite() {
                    let t = k as f32 * step / radius;
                    ([radius * t.cos(), radius * t.sin(), h as f32 * step], Vec3::new(t.cos(), t.sin(), 0.0))
                } else {
                    ([1.0, k as f32 * step, h as f32 * step], Vec3::X)
                };
                // The local x axis (smallest scale) turned onto the normal.
                let q = gs_core::glam::Quat::from_rotation_arc(Vec3::X, normal);
                g.push(mean, [(sigma * 0.05).ln(), sigma.ln(), sigma.ln()], [q.w, q.x, q.y, q.z], 0.0, [[0.0; 3]; 16]);
            }
        }
        g
    }

    /// Every Gaussian seen at `radius_px` pixels.
    fn seen(n: usize, radius_px: f32) -> DensifyStats {
        let mut st = DensifyStats::new(n);
        st.max_radius = vec![radius_px; n];
        st
    }

    #[test]
    fn large_discs_on_a_tight_curve_are_split_and_on_a_plane_not() {
        let rule = CurvatureSplit { enabled: true, max_sag_pixels: 0.5 };
        // σ = 0.01 on a tube of radius 0.03: sag 2·1e-4/0.03 ≈ 0.0067; at 30 px the footprint
        // is 0.001: 6.7 footprints.
        let (tube, plane) = (discs(0.03, 0.01), discs(f32::INFINITY, 0.01));
        let flags = sagging(&tube, &seen(tube.len(), 30.0), &rule);
        assert!(flags.iter().all(|f| *f), "{} of {}", flags.iter().filter(|f| **f).count(), flags.len());
        assert!(sagging(&plane, &seen(plane.len(), 30.0), &rule).iter().all(|f| !*f));
        // Seen from far away (a footprint of 0.1), the same tube sags 0.07 footprints: kept.
        assert!(sagging(&tube, &seen(tube.len(), 0.3), &rule).iter().all(|f| !*f));
        // Unseen Gaussians and a switched-off rule flag nothing.
        assert!(sagging(&tube, &seen(tube.len(), 0.0), &rule).iter().all(|f| !*f));
        let off = CurvatureSplit { enabled: false, ..rule };
        assert!(sagging(&tube, &seen(tube.len(), 30.0), &off).iter().all(|f| !*f));
    }

    #[test]
    fn the_estimate_follows_the_curve() {
        // A gentle curve (radius 3): sag 2·1e-4/3 ≈ 6.7e-5, below half of a 0.001 footprint.
        let gentle = discs(3.0, 0.01);
        let rule = CurvatureSplit { enabled: true, max_sag_pixels: 0.5 };
        assert!(sagging(&gentle, &seen(gentle.len(), 30.0), &rule).iter().all(|f| !*f));
        // The same curve with a threshold 100× smaller (0.005 footprints) flags it.
        let strict = CurvatureSplit { max_sag_pixels: 0.005, ..rule };
        assert!(sagging(&gentle, &seen(gentle.len(), 30.0), &strict).iter().all(|f| *f));
    }
}
