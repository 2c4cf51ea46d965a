//! Which pixels of a view other views see (docs/method.md §Metrics): where no training view
//! sees a held-out view's surface, no reconstruction from those views can know its colour, so
//! a score over the whole image mixes the method's error with the capture's coverage.

use crate::error::{MvsError, Result};
use crate::geometry::MapView;
use gs_core::{Camera, Image};
use rayon::prelude::*;

/// The relative depth agreement for a witness to see a point: |z_witness − z| ≤ this · z.
pub const SEEN_DEPTH_TOLERANCE: f64 = 0.02;

/// A camera with its depth map (camera z per pixel centre; ≤ 0 or not finite = no surface).
#[derive(Debug, Clone, Copy)]
pub struct DepthView<'a> {
    /// The camera.
    pub camera: &'a Camera,
    /// `W×H×1` camera-z map of `camera`.
    pub depth: &'a Image,
}

impl DepthView<'_> {
    /// The map's depth at pixel `(x, y)`, when that pixel is in the image and holds a surface.
    fn at(&self, x: i64, y: i64) -> Option<f64> {
        let (w, h) = (self.camera.width as i64, self.camera.height as i64);
        if x < 0 || y < 0 || x >= w || y >= h {
            return None;
        }
        let z = self.depth.data()[(y * w + x) as usize] as f64;
        (z.is_finite() && z > 0.0).then_some(z)
    }

    /// Whether the map holds world point `p`: `p` is in front of the camera, inside its image,
    /// and one of the (up to) four pixel centres around its projection has its depth within
    /// `tolerance`·z (the four, not the nearest alone, so that a surface seen at a grazing
    /// angle is not lost to the depth change across one pixel).
    fn holds(&self, p: gs_core::glam::DVec3, tolerance: f64) -> bool {
        let Some((px, z)) = self.camera.project(p) else { return false };
        if !self.camera.contains(px) {
            return false;
        }
        let (x0, y0) = ((px.x - 0.5).floor() as i64, (px.y - 0.5).floor() as i64);
        [(0, 0), (1, 0), (0, 1), (1, 1)]
            .into_iter()
            .filter_map(|(dx, dy)| self.at(x0 + dx, y0 + dy))
            .any(|zw| (zw - z).abs() <= tolerance * z)
    }

    fn check(&self, what: &str) -> Result<()> {
        MapView::from(self.depth).expect_size(self.camera, 1, &format!("{what} depth"))
    }
}

/// A `W×H×1` mask of `target`: 1 where the surface point of the pixel (its depth
/// back-projected through the pixel centre) is held by at least one of `witnesses` (see
/// [`DepthView`]; within `tolerance` of relative depth), 0 elsewhere and where the target has
/// no depth. An error names a map whose size is not its camera's.
pub fn seen_mask(target: DepthView<'_>, witnesses: &[DepthView<'_>], tolerance: f64) -> Result<Image> {
    if !(tolerance.is_finite() && tolerance > 0.0) {
        return Err(MvsError::InvalidConfig(format!("the depth tolerance must be positive, got {tolerance}")));
    }
    target.check("target")?;
    for (k, w) in witnesses.iter().enumerate() {
        w.check(&format!("witness {k}"))?;
    }
    let (w, h) = (target.camera.width as usize, target.camera.height as usize);
    let mut mask = Image::new(w, h, 1).map_err(|e| MvsError::InvalidInput(format!("mask: {e}")))?;
    mask.data_mut().par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, m) in row.iter_mut().enumerate() {
            let Some(z) = target.at(x as i64, y as i64) else { continue };
            let c = Camera::pixel_center(x as u32, y as u32);
            let p = target.camera.back_project(c.x, c.y, z);
            if witnesses.iter().any(|v| v.holds(p, tolerance)) {
                *m = 1.0;
            }
        }
    });
    Ok(mask)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::small_scene;

    #[test]
    fn a_view_sees_itself_and_a_far_view_sees_less() {
        let s = small_scene(64, 48, 5);
        let view = |k: usize| DepthView { camera: &s.cams[k], depth: &s.maps[k].depth };
        let d: Vec<&Image> = s.maps.iter().map(|m| &m.depth).collect();
        let surface = d[0].data().iter().filter(|z| **z > 0.0).count();
        let own = seen_mask(view(0), &[view(0)], SEEN_DEPTH_TOLERANCE).unwrap();
        assert_eq!(own.data().iter().filter(|m| **m == 1.0).count(), surface, "every surface pixel holds itself");
        let near = seen_mask(view(0), &[view(1)], SEEN_DEPTH_TOLERANCE).unwrap();
        let far = seen_mask(view(0), &[view(4)], SEEN_DEPTH_TOLERANCE).unwrap();
        let count = |m: &Image| m.data().iter().filter(|v| **v == 1.0).count();
        assert!(count(&near) > count(&far) && count(&far) < surface, "near {} far {} of {surface}", count(&near), count(&far));
        let both = seen_mask(view(0), &[view(1), view(4)], SEEN_DEPTH_TOLERANCE).unwrap();
        assert!(count(&both) >= count(&near), "a second witness never removes a pixel");
    }

    #[test]
    fn a_map_of_the_wrong_size_and_a_bad_tolerance_are_refused() {
        let cams = small_scene(16, 12, 2).cams;
        let good = Image::new(16, 12, 1).unwrap();
        let bad = Image::new(12, 16, 1).unwrap();
        let e = seen_mask(DepthView { camera: &cams[0], depth: &good }, &[DepthView { camera: &cams[1], depth: &bad }], 0.02)
            .unwrap_err()
            .to_string();
        assert!(e.contains("witness 0 depth") && e.contains("16x12x1") && e.contains("12x16x1"), "{e}");
        let view = DepthView { camera: &cams[0], depth: &good };
        assert!(seen_mask(view, &[], f64::NAN).is_err() && seen_mask(view, &[], 0.0).is_err());
        // No surface in the target: nothing is seen.
        assert!(seen_mask(view, &[view], 0.02).unwrap().data().iter().all(|m| *m == 0.0));
    }
}
