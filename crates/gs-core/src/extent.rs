//! The scene extent r (docs/method.md §Inputs): 1.1 × the largest distance of a camera centre from the
//! mean centre, as 3DGS, made robust to bad input (issue #21, D5/D6).
//!
//! r scales the position learning rate and the densification thresholds, so one
//! mis-registered camera a million units away, or a rotation-only capture whose centres all
//! coincide, would silently wreck training. The rule here:
//!
//! - **Outliers.** With at least [`MIN_CAMERAS_FOR_OUTLIERS`] cameras, a camera whose centre is
//!   more than [`OUTLIER_FACTOR`] × the median distance from the component-wise median centre
//!   (or whose centre is not finite) is an outlier; r is computed from the others, and the
//!   outliers are reported so the caller can name them. When no camera is an outlier, r is
//!   computed exactly as before (same sums in the same order), so normal scenes keep their
//!   bytes.
//! - **Coincident cameras.** Two or more centres that (almost) coincide have no spread: r then
//!   comes from the sparse points by the same robust rule, or, without usable points, is the
//!   old default 1.1 and [`ExtentReport::warnings`] (used by [`crate::Scene::check_extent`])
//!   refuses the scene.

use crate::camera::Camera;
use crate::error::{CoreError, Result};
use crate::point::ScenePoint;
use glam::DVec3;

/// A centre farther than this many median distances from the median centre is an outlier.
pub const OUTLIER_FACTOR: f64 = 10.0;

/// Fewer cameras than this are never called outliers (the median means little).
pub const MIN_CAMERAS_FOR_OUTLIERS: usize = 4;

/// Camera centres spread less than this fraction of the sparse points' spread coincide.
pub const COINCIDENT_FRACTION: f64 = 1e-6;

/// The robust spread of a set of positions.
#[derive(Debug, Clone, PartialEq)]
struct Spread {
    /// Largest distance of an inlier from the inliers' mean.
    radius: f64,
    /// Length of the inliers' mean (to judge "almost zero" spreads).
    mean_norm: f64,
    /// Indices of the outliers, ascending.
    outliers: Vec<usize>,
}

/// r from a spread radius: 1.1 × the radius, or 1.1 × 1 when there is no spread (so
/// thresholds stay usable).
fn padded(radius: f64) -> f64 {
    1.1 * if radius > 0.0 { radius } else { 1.0 }
}

/// The median of `v` (sorted in place); `v` must not be empty.
fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) }
}

/// The spread of `positions` after removing outliers (see the module docs).
fn robust_spread(positions: &[DVec3], min_for_outliers: usize) -> Spread {
    let mut outliers: Vec<usize> = (0..positions.len()).filter(|&i| !positions[i].is_finite()).collect();
    let finite: Vec<usize> = (0..positions.len()).filter(|&i| positions[i].is_finite()).collect();
    if finite.len() >= min_for_outliers.max(1) {
        let axis = |f: fn(&DVec3) -> f64| median(&mut finite.iter().map(|&i| f(&positions[i])).collect::<Vec<_>>());
        let centre = DVec3::new(axis(|p| p.x), axis(|p| p.y), axis(|p| p.z));
        let dist: Vec<f64> = finite.iter().map(|&i| (positions[i] - centre).length()).collect();
        let m = median(&mut dist.clone());
        if m > 0.0 && m.is_finite() {
            outliers.extend(finite.iter().zip(&dist).filter(|(_, d)| !d.is_finite() || **d > OUTLIER_FACTOR * m).map(|(&i, _)| i));
            outliers.sort_unstable();
        }
    }
    let inliers: Vec<DVec3> =
        (0..positions.len()).filter(|i| outliers.binary_search(i).is_err()).map(|i| positions[i]).collect();
    if inliers.is_empty() {
        return Spread { radius: 0.0, mean_norm: 0.0, outliers };
    }
    // The 3DGS formula, unchanged: mean centre, then the largest distance from it.
    let mean = inliers.iter().copied().sum::<DVec3>() / inliers.len() as f64;
    let radius = inliers.iter().map(|c| (*c - mean).length()).fold(0.0, f64::max);
    Spread { radius, mean_norm: mean.length(), outliers }
}

/// Scene extent r of a camera set alone: 1.1 × the largest distance of a camera centre from
/// the mean centre, outlier cameras left out (see the module docs). Cameras with no spread (one
/// camera, coincident centres) give r = 1.1 × 1 so thresholds stay usable; use
/// [`extent_report`] to fall back to the sparse points instead.
pub fn scene_extent(cameras: &[&Camera]) -> f64 {
    let centres: Vec<DVec3> = cameras.iter().map(|c| c.center()).collect();
    padded(robust_spread(&centres, MIN_CAMERAS_FOR_OUTLIERS).radius)
}

/// What the scene extent was computed from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExtentBasis {
    /// The camera centres (the normal case; fewer than two cameras give r = 1.1 as before).
    Cameras,
    /// The sparse points, because the camera centres coincide.
    SparsePoints,
    /// Nothing: the camera centres coincide and the sparse points have no spread either;
    /// r = 1.1 so thresholds stay usable, and [`ExtentReport::warnings`] refuses the scene.
    Unscaled,
}

/// The scene extent and how it was obtained.
#[derive(Debug, Clone, PartialEq)]
pub struct ExtentReport {
    /// The extent r.
    pub radius: f64,
    /// What r was computed from.
    pub basis: ExtentBasis,
    /// Indices of the cameras left out as outliers, ascending.
    pub outliers: Vec<usize>,
}

/// The scene extent of `cameras`, falling back to the spread of `points` when two or more
/// camera centres coincide (spread ≤ [`COINCIDENT_FRACTION`] × the points' spread, or
/// numerically zero). Equal to [`scene_extent`] whenever the cameras have a spread.
pub fn extent_report(cameras: &[&Camera], points: &[ScenePoint]) -> ExtentReport {
    let centres: Vec<DVec3> = cameras.iter().map(|c| c.center()).collect();
    let cams = robust_spread(&centres, MIN_CAMERAS_FOR_OUTLIERS);
    let inliers = centres.len() - cams.outliers.len();
    if inliers < 2 {
        return ExtentReport { radius: padded(cams.radius), basis: ExtentBasis::Cameras, outliers: cams.outliers };
    }
    let positions: Vec<DVec3> = points.iter().map(|p| p.position).collect();
    let pts = robust_spread(&positions, MIN_CAMERAS_FOR_OUTLIERS);
    let numerically_zero = cams.radius <= 1e-9 * cams.mean_norm.max(1.0);
    let coincident = numerically_zero || cams.radius <= COINCIDENT_FRACTION * pts.radius;
    let (radius, basis) = match coincident {
        false => (padded(cams.radius), ExtentBasis::Cameras),
        true if pts.radius > 1e-9 * pts.mean_norm.max(1.0) => (padded(pts.radius), ExtentBasis::SparsePoints),
        true => (padded(0.0), ExtentBasis::Unscaled),
    };
    ExtentReport { radius, basis, outliers: cams.outliers }
}

impl ExtentReport {
    /// Warnings in words for the caller to print (`names[i]` names camera `i`): the outlier
    /// cameras left out, and an extent taken from the sparse points. An error when the
    /// cameras coincide and the points give no extent either: nothing sets the scene's scale.
    pub fn warnings(&self, names: &[&str]) -> Result<Vec<String>> {
        let mut out = Vec::new();
        if !self.outliers.is_empty() {
            let listed: Vec<&str> = self.outliers.iter().map(|&i| names.get(i).copied().unwrap_or("?")).collect();
            let who = match listed.len() {
                1 => "1 camera lies".to_string(),
                n => format!("{n} cameras lie"),
            };
            out.push(format!(
                "{who} more than {OUTLIER_FACTOR} times the median distance from the other cameras and \
                 {} left out of the scene extent (mis-registered?): {}",
                if listed.len() == 1 { "is" } else { "are" },
                listed.join(", ")
            ));
        }
        match self.basis {
            ExtentBasis::Cameras => {}
            ExtentBasis::SparsePoints => out.push(format!(
                "the camera centres coincide (rotation-only capture?); the scene extent r = {:.6} comes from the \
                 sparse points",
                self.radius
            )),
            ExtentBasis::Unscaled => {
                return Err(CoreError::InvalidScene(
                    "the camera centres coincide (rotation-only capture?) and there are no spread-out sparse points, \
                     so nothing sets the scene's scale; capture the object from several positions"
                        .into(),
                ));
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Intrinsics;
    use crate::camera::camera_ring;

    fn look_at(eye: DVec3, target: DVec3) -> Camera {
        Camera::look_at(64, 48, Intrinsics::new(60.0, 60.0, 32.0, 24.0), eye, target, DVec3::Z).unwrap()
    }

    /// The 3DGS rule as it was before outliers were handled.
    fn plain_extent(cameras: &[&Camera]) -> f64 {
        let centres: Vec<DVec3> = cameras.iter().map(|c| c.center()).collect();
        let mean = centres.iter().copied().sum::<DVec3>() / centres.len() as f64;
        1.1 * centres.iter().map(|c| (*c - mean).length()).fold(0.0, f64::max)
    }

    fn cube_points() -> Vec<ScenePoint> {
        (0..27)
            .map(|k| ScenePoint {
                position: DVec3::new((k % 3) as f64 - 1.0, ((k / 3) % 3) as f64 - 1.0, (k / 9) as f64 - 1.0),
                color: [0.5; 3],
            })
            .collect()
    }

    #[test]
    fn normal_captures_keep_the_plain_extent_bit_for_bit() {
        // A ring, and an irregular capture (varying radius and height, one camera at twice the
        // typical distance, which is not an outlier).
        let ring = camera_ring(12);
        let irregular: Vec<Camera> = (0..20)
            .map(|k| {
                let a = k as f64 * 0.7;
                let r = if k == 5 { 6.0 } else { 2.0 + 0.13 * k as f64 };
                look_at(DVec3::new(r * a.cos(), r * a.sin(), 0.5 + 0.05 * k as f64), DVec3::ZERO)
            })
            .collect();
        for cams in [&ring, &irregular] {
            let refs: Vec<&Camera> = cams.iter().collect();
            let report = extent_report(&refs, &cube_points());
            assert_eq!(report.radius.to_bits(), plain_extent(&refs).to_bits());
            assert_eq!(scene_extent(&refs).to_bits(), plain_extent(&refs).to_bits());
            assert_eq!((report.basis, report.outliers.len()), (ExtentBasis::Cameras, 0));
            assert!(report.warnings(&vec!["v"; refs.len()]).unwrap().is_empty());
        }
    }

    #[test]
    fn one_far_camera_does_not_inflate_the_extent() {
        let mut cams = camera_ring(12);
        cams.push(look_at(DVec3::new(0.5, 0.0, 1e6), DVec3::ZERO));
        let refs: Vec<&Camera> = cams.iter().collect();
        assert!(plain_extent(&refs) > 1e5);
        let report = extent_report(&refs, &[]);
        assert_eq!(report.outliers, [12]);
        assert_eq!(report.radius.to_bits(), plain_extent(&refs[..12]).to_bits());
        assert_eq!(scene_extent(&refs), report.radius);
        let names: Vec<String> = (0..13).map(|k| format!("{k:04}.jpg")).collect();
        let names: Vec<&str> = names.iter().map(String::as_str).collect();
        let w = report.warnings(&names).unwrap();
        assert_eq!(w.len(), 1);
        assert!(w[0].starts_with("1 camera lies more than 10 times") && w[0].ends_with(": 0012.jpg"), "{}", w[0]);
    }

    #[test]
    fn coincident_cameras_fall_back_to_the_points_or_are_refused() {
        let eye = DVec3::new(0.0, 0.0, 5.0);
        let cams: Vec<Camera> =
            (0..8).map(|k| look_at(eye, DVec3::new((k as f64).cos(), (k as f64).sin(), 0.0))).collect();
        let refs: Vec<&Camera> = cams.iter().collect();
        let points = cube_points();
        let report = extent_report(&refs, &points);
        assert_eq!(report.basis, ExtentBasis::SparsePoints);
        assert!((report.radius - 1.1 * 3f64.sqrt()).abs() < 1e-12, "{}", report.radius);
        let w = report.warnings(&["a"; 8]).unwrap();
        assert!(w[0].contains("comes from the sparse points"), "{w:?}");
        // No points (or all at one spot): nothing sets the scale.
        for pts in [vec![], vec![points[0]; 5]] {
            let report = extent_report(&refs, &pts);
            assert_eq!((report.basis, report.radius), (ExtentBasis::Unscaled, 1.1));
            let e = report.warnings(&["a"; 8]).unwrap_err().to_string();
            assert!(e.contains("camera centres coincide") && e.contains("nothing sets the scene's scale"), "{e}");
        }
        // One camera keeps the old r = 1.1 and is not an error.
        let report = extent_report(&refs[..1], &[]);
        assert_eq!((report.basis, report.radius), (ExtentBasis::Cameras, 1.1));
        assert!(report.warnings(&["a"]).unwrap().is_empty());
    }

    #[test]
    fn median_of_odd_and_even_lengths() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
    }

    #[test]
    fn robust_spread_flags_far_and_non_finite_positions() {
        let mut p: Vec<DVec3> = (0..8).map(|k| DVec3::new(k as f64, 0.0, 0.0)).collect();
        p.push(DVec3::new(1e6, 0.0, 0.0));
        p.push(DVec3::new(f64::NAN, 0.0, 0.0));
        let s = robust_spread(&p, MIN_CAMERAS_FOR_OUTLIERS);
        assert_eq!(s.outliers, [8, 9]);
        assert_eq!(s.radius, 3.5);
        // Too few positions: nothing is an outlier.
        let s = robust_spread(&[DVec3::ZERO, DVec3::X, DVec3::splat(1e6)], MIN_CAMERAS_FOR_OUTLIERS);
        assert!(s.outliers.is_empty());
    }
}
