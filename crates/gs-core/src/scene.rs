//! A loaded scene: posed views with their images, and sparse points.
//!
//! gs-io builds a [`Scene`] from a COLMAP model (undistorted to PINHOLE, optionally
//! downscaled); gs-synth builds the built-in scene. The scene extent and the source-view
//! candidates of docs/method.md §Inputs and §Schedule live here so every crate computes them the same way.

use crate::camera::Camera;
use crate::error::Result;
pub use crate::extent::scene_extent;
use crate::extent::{ExtentReport, extent_report};
use crate::image::Image;
pub use crate::camera::camera_ring;
pub use crate::point::ScenePoint;
use glam::DVec3;

/// One posed training or test image.
#[derive(Debug, Clone)]
pub struct View {
    /// Image name as in the COLMAP model (e.g. `0008.png`).
    pub name: String,
    /// Undistorted PINHOLE camera at the image's resolution.
    pub camera: Camera,
    /// RGB image, `[H][W][3]` in `[0, 1]`.
    pub image: Image,
    /// Optional object mask, `[H][W][1]`, 1 = object.
    pub mask: Option<Image>,
}

/// Posed images plus sparse points.
#[derive(Debug, Clone, Default)]
pub struct Scene {
    /// Views sorted by name (the 3DGS split protocol relies on this order).
    pub views: Vec<View>,
    /// Sparse points, possibly empty.
    pub points: Vec<ScenePoint>,
    /// The views the scene's own files hold out for evaluation (the frames of a
    /// `transforms_test.json`), by name; `None` when the files define no split, and then `--eval`
    /// holds out every 8th view.
    pub held_out: Option<Vec<String>>,
}

/// Parameters of the source-view candidate rule of docs/method.md §Schedule.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NeighbourRule {
    /// Maximum angle between optical axes, degrees (30).
    pub max_angle_deg: f64,
    /// Minimum centre distance as a multiple of the scene extent r (0.01).
    pub min_distance: f64,
    /// Maximum centre distance as a multiple of r (1.5).
    pub max_distance: f64,
    /// How many nearest candidates are kept (8).
    pub max_candidates: usize,
}

impl Default for NeighbourRule {
    fn default() -> Self {
        Self { max_angle_deg: 30.0, min_distance: 0.01, max_distance: 1.5, max_candidates: 8 }
    }
}

/// For every camera, the indices of its source-view candidates: optical axis within
/// `max_angle_deg`, centre distance in `(min·r, max·r)`, nearest `max_candidates` by centre
/// distance (ties by index). Computed once per scene.
pub fn source_view_candidates(cameras: &[&Camera], rule: &NeighbourRule) -> Vec<Vec<usize>> {
    let r = scene_extent(cameras);
    let cos_max = rule.max_angle_deg.to_radians().cos();
    let centres: Vec<DVec3> = cameras.iter().map(|c| c.center()).collect();
    let axes: Vec<DVec3> = cameras.iter().map(|c| c.optical_axis()).collect();
    (0..cameras.len())
        .map(|i| {
            let mut cands: Vec<(f64, usize)> = (0..cameras.len())
                .filter(|&j| j != i)
                .filter_map(|j| {
                    let d = (centres[j] - centres[i]).length();
                    let ok = axes[i].dot(axes[j]) >= cos_max
                        && d > rule.min_distance * r
                        && d < rule.max_distance * r;
                    ok.then_some((d, j))
                })
                .collect();
            cands.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            cands.truncate(rule.max_candidates);
            cands.into_iter().map(|(_, j)| j).collect()
        })
        .collect()
}

impl Scene {
    /// The cameras of all views, in order.
    pub fn cameras(&self) -> Vec<&Camera> {
        self.views.iter().map(|v| &v.camera).collect()
    }

    /// The cameras of `views` (indices into [`Scene::views`]), in that order.
    pub fn cameras_of(&self, views: &[usize]) -> Vec<&Camera> {
        views.iter().map(|&i| &self.views[i].camera).collect()
    }

    /// Scene extent r of docs/method.md §Inputs, robust to outlier and coincident cameras
    /// ([`crate::extent`]).
    pub fn extent(&self) -> f64 {
        self.extent_report().radius
    }

    /// The extent r of a training run: the cameras of `views` (the training views) with the
    /// scene's sparse points as fallback. The trainer and a reopened run both use it, so they
    /// scale by the same r.
    pub fn extent_of(&self, views: &[usize]) -> f64 {
        extent_report(&self.cameras_of(views), &self.points).radius
    }

    /// The scene extent with what it was computed from and the outlier cameras left out.
    pub fn extent_report(&self) -> ExtentReport {
        extent_report(&self.cameras(), &self.points)
    }

    /// Checks that the scene has a scale: warnings in words naming outlier views and an extent
    /// taken from the sparse points (for the caller to print), or an error when nothing sets
    /// the scale (coincident cameras and no spread-out points).
    pub fn check_extent(&self) -> Result<Vec<String>> {
        let names: Vec<&str> = self.views.iter().map(|v| v.name.as_str()).collect();
        self.extent_report().warnings(&names)
    }

    /// Indices of `(train, test)` views, each in name order: with `eval`, the scene's own
    /// [`held_out`](Self::held_out) views when it has them (as 3DGS does for the Blender
    /// `transforms_test.json`), else every 8th view (index % 8 == 0, views sorted by name; 3DGS
    /// protocol); without `eval`, all views train.
    pub fn split(&self, eval: bool) -> (Vec<usize>, Vec<usize>) {
        let names: Vec<&str> = self.views.iter().map(|v| v.name.as_str()).collect();
        split_names(&names, self.held_out.as_deref(), eval)
    }
}

/// The train/test split of views named `names` (in any order; indices into `names`): the
/// `held_out` names when given, else every 8th name in sorted order (3DGS protocol); without
/// `eval`, all views train. [`Scene::split`] of a loaded scene, for callers that have only the
/// names (e.g. partitioning a capture without loading its photos).
pub fn split_names(names: &[&str], held_out: Option<&[String]>, eval: bool) -> (Vec<usize>, Vec<usize>) {
    let mut order: Vec<usize> = (0..names.len()).collect();
    order.sort_by(|&a, &b| names[a].cmp(names[b]));
    let (mut train, mut test) = (Vec::new(), Vec::new());
    for (k, &i) in order.iter().enumerate() {
        let is_held_out = match held_out {
            Some(list) => list.iter().any(|n| n == names[i]),
            None => k % 8 == 0,
        };
        if eval && is_held_out { test.push(i) } else { train.push(i) }
    }
    (train, test)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ring(n: usize) -> Vec<Camera> {
        camera_ring(n)
    }

    #[test]
    fn extent_of_a_ring() {
        let cams = ring(12);
        let refs: Vec<&Camera> = cams.iter().collect();
        // Mean centre is (0, 0, 1); every centre is at distance 3.
        assert!((scene_extent(&refs) - 3.3).abs() < 1e-9);
    }

    #[test]
    fn neighbours_are_nearby_and_aligned() {
        let cams = ring(24);
        let refs: Vec<&Camera> = cams.iter().collect();
        let nb = source_view_candidates(&refs, &NeighbourRule::default());
        // 15° apart per step: neighbours within 30° are ±1 and ±2 steps.
        assert_eq!(nb[0].len(), 4);
        assert!(nb[0].contains(&1) && nb[0].contains(&23) && nb[0].contains(&2) && nb[0].contains(&22));
        assert_eq!(&nb[0][..2].iter().map(|&j| j.min(24 - j)).collect::<Vec<_>>(), &[1, 1]);
    }

    #[test]
    fn split_uses_the_scenes_own_held_out_views() {
        let views: Vec<View> = ring(10)
            .into_iter()
            .enumerate()
            .map(|(i, camera)| View {
                name: format!("{i:02}.png"),
                camera,
                image: Image::new(1, 1, 3).unwrap(),
                mask: None,
            })
            .collect();
        let mut scene = Scene { views, points: Vec::new(), held_out: None };
        assert_eq!(scene.split(true), ((1..10).filter(|&i| i != 8).collect(), vec![0, 8]));
        scene.held_out = Some(vec!["03.png".into(), "07.png".into()]);
        assert_eq!(scene.split(true).1, vec![3, 7]);
        assert_eq!(scene.split(false), ((0..10).collect(), vec![]));
    }
}
