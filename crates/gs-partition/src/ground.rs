//! The ground frame of a capture (docs/architecture.md §Partitioned training): blocks are
//! rectangles on the ground plane, so a partition needs the plane's "up" and two axes on it.
//! Up is the mean of the cameras' image-up directions (photos are taken upright, whatever the
//! reconstruction's axes); the first ground axis follows the camera path's longest spread
//! (a street's direction), so a strip partition cuts across it.

use crate::error::{Result, refuse};
use glam::DVec3;
use gs_core::Camera;
use serde::{Deserialize, Serialize};

/// A right-handed frame with `up` normal to the ground plane and `u`, `v` on it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GroundFrame {
    /// A point of the plane: the mean camera centre.
    pub origin: [f64; 3],
    /// The first ground axis: the direction of the camera centres' largest spread.
    pub u: [f64; 3],
    /// The second ground axis, `up × u`.
    pub v: [f64; 3],
    /// The plane's normal: the cameras' mean image-up direction.
    pub up: [f64; 3],
}

/// The cameras' mean up direction must have at least this length (of 1): below it the cameras
/// disagree on which way is up (rolled or upside-down photos), and no ground plane is defined.
const MIN_UP_AGREEMENT: f64 = 0.3;

impl GroundFrame {
    /// The frame of a capture from its cameras, with `points` (sparse points) to orient the
    /// ground axes when every camera stands at one place.
    pub fn of(cameras: &[Camera], points: &[DVec3]) -> Result<Self> {
        if cameras.is_empty() {
            refuse!("the scene has no cameras to partition");
        }
        let up = up_direction(cameras)?;
        let centres: Vec<DVec3> = cameras.iter().map(Camera::center).collect();
        let origin = centres.iter().sum::<DVec3>() / centres.len() as f64;
        let (e1, e2) = plane_basis(up);
        let u = principal_axis(&centres, origin, e1, e2)
            .or_else(|| {
                let mean = if points.is_empty() { origin } else { points.iter().sum::<DVec3>() / points.len() as f64 };
                principal_axis(points, mean, e1, e2)
            })
            .unwrap_or(e1);
        let v = up.cross(u).normalize();
        Ok(Self { origin: origin.to_array(), u: u.to_array(), v: v.to_array(), up: up.to_array() })
    }

    /// Coordinates of `p` along the ground axes `(u, v)`, from the origin (the formula the
    /// blocks' growth regions use too, `gs_train::region::ground_coords`).
    pub fn coords(&self, p: DVec3) -> [f64; 2] {
        gs_train::region::ground_coords(self.origin, self.u, self.v, p.to_array())
    }

    /// Checks a frame read from a file: finite, unit, orthogonal axes.
    pub fn validate(&self) -> std::result::Result<(), String> {
        let [u, v, up] = [self.u, self.v, self.up].map(DVec3::from_array);
        let finite = self.origin.iter().chain(&self.u).chain(&self.v).chain(&self.up).all(|x| x.is_finite());
        let unit = [u, v, up].iter().all(|a| (a.length() - 1.0).abs() < 1e-6);
        let orthogonal = u.dot(v).abs() < 1e-6 && u.dot(up).abs() < 1e-6 && v.dot(up).abs() < 1e-6;
        if finite && unit && orthogonal { Ok(()) } else { Err("the ground frame's axes are not finite, unit and orthogonal".into()) }
    }
}

/// The ground's normal: the direction most nearly orthogonal to every camera's image x axis
/// (photos are taken without roll, so image rows are level, whether the camera looks ahead,
/// down at a street, or straight down from a drone), found by inverse iteration on
/// Σ xᵢxᵢᵀ from the cameras' mean image-up direction, which also picks its sign. When the x
/// axes leave more than one direction free (every camera facing the same way), the iteration
/// keeps the part of the image-up direction in that free plane (then the ground tilts with the
/// cameras' common pitch, which still partitions the scene, with slanted block walls).
fn up_direction(cameras: &[Camera]) -> Result<DVec3> {
    let n = cameras.len() as f64;
    let axis = |c: &Camera, k: DVec3| c.rotation.transpose() * k;
    let image_up = cameras.iter().map(|c| axis(c, DVec3::NEG_Y)).sum::<DVec3>() / n;
    let looking = cameras.iter().map(|c| axis(c, DVec3::Z)).sum::<DVec3>() / n;
    // Image up, or for cameras whose image-up directions cancel (a drone's headings), the
    // reverse of where they look on average (down).
    let cue = if image_up.length() >= MIN_UP_AGREEMENT { image_up } else { image_up - looking };
    if cue.length() < MIN_UP_AGREEMENT {
        refuse!(
            "the cameras disagree on which way is up (their image-up directions average to length {:.2} of 1, and they look in no common direction): the photos are not taken upright, so no ground plane can be found to partition on",
            image_up.length()
        );
    }
    let mut m = gs_core::glam::DMat3::ZERO;
    for c in cameras {
        let x = axis(c, DVec3::X);
        m += gs_core::glam::DMat3::from_cols(x * x.x, x * x.y, x * x.z) / n;
    }
    let shifted = m + gs_core::glam::DMat3::IDENTITY * 1e-6;
    let inverse = shifted.inverse();
    let mut up = cue.normalize();
    for _ in 0..60 {
        let next = inverse * up;
        if !next.is_finite() || next.length() == 0.0 {
            break;
        }
        up = next.normalize();
    }
    Ok(if up.dot(cue) < 0.0 { -up } else { up })
}

/// Two unit vectors spanning the plane normal to `up`.
fn plane_basis(up: DVec3) -> (DVec3, DVec3) {
    let helper = if up.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let e1 = (helper - up * helper.dot(up)).normalize();
    (e1, up.cross(e1))
}

/// The unit direction in the plane `(e1, e2)` along which `pts` spread most around `mean`
/// (the larger eigenvector of their 2×2 covariance), signed so that its largest component is
/// positive; `None` when they do not spread at all.
fn principal_axis(pts: &[DVec3], mean: DVec3, e1: DVec3, e2: DVec3) -> Option<DVec3> {
    let (mut a, mut b, mut c) = (0.0, 0.0, 0.0);
    for p in pts {
        let d = *p - mean;
        let (x, y) = (d.dot(e1), d.dot(e2));
        a += x * x;
        b += x * y;
        c += y * y;
    }
    if !(a + c > 1e-18) {
        return None;
    }
    let theta = 0.5 * (2.0 * b).atan2(a - c);
    let axis = (e1 * theta.cos() + e2 * theta.sin()).normalize();
    let largest = axis.to_array().into_iter().fold(0.0f64, |m, x| if x.abs() > m.abs() { x } else { m });
    Some(if largest < 0.0 { -axis } else { axis })
}

#[cfg(test)]
mod tests {
    use super::*;
    use gs_core::Intrinsics;

    fn camera_at(eye: DVec3, target: DVec3) -> Camera {
        Camera::look_at(64, 48, Intrinsics::new(50.0, 50.0, 32.0, 24.0), eye, target, DVec3::Z).unwrap()
    }

    #[test]
    fn a_street_of_cameras_gives_z_up_and_the_street_axis() {
        let cams: Vec<Camera> = (0..10)
            .map(|i| {
                let eye = DVec3::new(i as f64 - 4.5, 0.1 * (i % 2) as f64, 1.5);
                camera_at(eye, eye + DVec3::new(0.0, if i % 2 == 0 { 1.0 } else { -1.0 }, -0.3))
            })
            .collect();
        let f = GroundFrame::of(&cams, &[]).unwrap();
        assert!((DVec3::from_array(f.up) - DVec3::Z).length() < 1e-9, "up {:?}", f.up);
        assert!(f.u[0] > 0.999, "u {:?}", f.u);
        f.validate().unwrap();
        let [a, _] = f.coords(DVec3::new(3.0, 0.0, 0.0));
        assert!((a - 3.0).abs() < 1e-2, "{a}");
    }

    #[test]
    fn upside_down_halves_are_refused() {
        let mut cams = vec![camera_at(DVec3::new(0.0, -3.0, 0.0), DVec3::ZERO)];
        let flipped = Camera::look_at(64, 48, Intrinsics::new(50.0, 50.0, 32.0, 24.0), DVec3::new(0.0, 3.0, 0.0), DVec3::ZERO, -DVec3::Z).unwrap();
        cams.push(flipped);
        let e = GroundFrame::of(&cams, &[]).unwrap_err().to_string();
        assert!(e.contains("disagree on which way is up"), "{e}");
    }

    #[test]
    fn pitched_and_nadir_cameras_still_find_z_up() {
        // A street looked at 40° down, cameras facing either side and a few at a slant: image
        // up is tilted, rows are level.
        let pitched: Vec<Camera> = (0..6).map(|i| {
            let eye = DVec3::new(i as f64, 0.0, 2.0);
            let side = if i % 2 == 0 { 1.0 } else { -1.0 };
            camera_at(eye, eye + DVec3::new(0.3 * (i % 3) as f64, side, -0.84))
        }).collect();
        let f = GroundFrame::of(&pitched, &[]).unwrap();
        assert!(f.up[2] > 0.999, "pitched: up {:?}", f.up);
        // A drone looking straight down with headings all around.
        let nadir: Vec<Camera> = (0..8).map(|i| {
            let a = i as f64 * 0.8;
            let eye = DVec3::new(i as f64 * 3.0, (i % 3) as f64, 30.0);
            Camera::look_at(64, 48, Intrinsics::new(50.0, 50.0, 32.0, 24.0), eye, eye - DVec3::Z, DVec3::new(a.cos(), a.sin(), 0.0)).unwrap()
        }).collect();
        let f = GroundFrame::of(&nadir, &[]).unwrap();
        assert!(f.up[2] > 0.999, "nadir: up {:?}", f.up);
    }

    #[test]
    fn cameras_at_one_place_take_the_axis_from_the_points() {
        let cams = vec![camera_at(DVec3::new(0.0, 0.0, 1.0), DVec3::new(0.0, 1.0, 1.0)); 3];
        let pts: Vec<DVec3> = (0..20).map(|i| DVec3::new(0.1 * (i % 3) as f64, i as f64, 0.0)).collect();
        let f = GroundFrame::of(&cams, &pts).unwrap();
        assert!(f.up[2] > 0.999 && f.u[1].abs() > 0.99, "up {:?} u {:?}", f.up, f.u);
    }
}
