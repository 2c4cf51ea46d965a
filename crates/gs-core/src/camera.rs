//! Pinhole cameras in COLMAP's conventions.
//!
//! A [`Camera`] stores the world→camera rotation `R` and translation `t`
//! (`x_c = R·x_w + t`), looks along +z with x right and y down, and uses
//! continuous pixel coordinates in which the centre of the top-left pixel is
//! `(0.5, 0.5)`: pixel `(i, j)` (column `i`, row `j`) has its centre at
//! `(i + 0.5, j + 0.5)` (docs/architecture.md §Conventions). Poses are kept in f64 so that scenes far
//! from the origin keep their precision; hot paths take the f32 views.

use crate::error::{CoreError, Result};
use glam::{DMat3, DQuat, DVec2, DVec3, Mat3, Vec3};

/// PINHOLE intrinsics `fx fy cx cy` in pixels (after undistortion every camera is PINHOLE).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels, in the pixel-centre-at-0.5 convention.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
}

impl Intrinsics {
    /// Intrinsics from `fx fy cx cy`.
    pub fn new(fx: f64, fy: f64, cx: f64, cy: f64) -> Self {
        Self { fx, fy, cx, cy }
    }

    /// The 3×3 matrix K (column-major glam matrix).
    pub fn matrix(&self) -> DMat3 {
        DMat3::from_cols(
            DVec3::new(self.fx, 0.0, 0.0),
            DVec3::new(0.0, self.fy, 0.0),
            DVec3::new(self.cx, self.cy, 1.0),
        )
    }

    /// K⁻¹ (column-major glam matrix).
    pub fn inverse_matrix(&self) -> DMat3 {
        DMat3::from_cols(
            DVec3::new(1.0 / self.fx, 0.0, 0.0),
            DVec3::new(0.0, 1.0 / self.fy, 0.0),
            DVec3::new(-self.cx / self.fx, -self.cy / self.fy, 1.0),
        )
    }
}

/// A posed PINHOLE camera with its image size.
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// PINHOLE intrinsics.
    pub intrinsics: Intrinsics,
    /// World→camera rotation R (orthonormal, det +1).
    pub rotation: DMat3,
    /// World→camera translation t.
    pub translation: DVec3,
}

impl Camera {
    /// A camera from its size, intrinsics and world→camera pose; checks that every value is
    /// finite, the focal lengths positive, the size non-zero and R a rotation (to 1e-6).
    pub fn new(
        width: u32,
        height: u32,
        intrinsics: Intrinsics,
        rotation: DMat3,
        translation: DVec3,
    ) -> Result<Self> {
        let cam = Self { width, height, intrinsics, rotation, translation };
        cam.validate()?;
        Ok(cam)
    }

    /// A camera from a COLMAP quaternion `(qw, qx, qy, qz)` (normalised here) and translation.
    pub fn from_quaternion(
        width: u32,
        height: u32,
        intrinsics: Intrinsics,
        qvec: [f64; 4],
        translation: [f64; 3],
    ) -> Result<Self> {
        let rotation = rotation_from_quaternion(qvec)?;
        Self::new(width, height, intrinsics, rotation, DVec3::from_array(translation))
    }

    /// A camera at `eye` looking at `target`, with `up` giving the image's "up" (−y) direction.
    pub fn look_at(
        width: u32,
        height: u32,
        intrinsics: Intrinsics,
        eye: DVec3,
        target: DVec3,
        up: DVec3,
    ) -> Result<Self> {
        let z = (target - eye).normalize_or_zero();
        let x = z.cross(up).normalize_or_zero();
        if z == DVec3::ZERO || x == DVec3::ZERO {
            return Err(CoreError::InvalidCamera(
                "look_at: eye equals target or up is parallel to the view direction".into(),
            ));
        }
        let y = z.cross(x);
        // Rows of R are the camera axes in world coordinates.
        let rotation = DMat3::from_cols(x, y, z).transpose();
        let translation = -(rotation * eye);
        Self::new(width, height, intrinsics, rotation, translation)
    }

    fn validate(&self) -> Result<()> {
        let k = &self.intrinsics;
        if self.width == 0 || self.height == 0 {
            return Err(CoreError::InvalidCamera(format!(
                "image size {}x{} is empty",
                self.width, self.height
            )));
        }
        if !(k.fx.is_finite() && k.fy.is_finite() && k.fx > 0.0 && k.fy > 0.0) {
            return Err(CoreError::InvalidCamera(format!(
                "focal lengths must be finite and positive, got fx={} fy={}",
                k.fx, k.fy
            )));
        }
        if !(k.cx.is_finite() && k.cy.is_finite()) {
            return Err(CoreError::InvalidCamera(format!(
                "principal point must be finite, got cx={} cy={}",
                k.cx, k.cy
            )));
        }
        if !self.translation.is_finite() || !self.rotation.is_finite() {
            return Err(CoreError::InvalidCamera("pose contains NaN or infinity".into()));
        }
        let should_be_identity = self.rotation * self.rotation.transpose();
        if !should_be_identity.abs_diff_eq(DMat3::IDENTITY, 1e-6)
            || (self.rotation.determinant() - 1.0).abs() > 1e-6
        {
            return Err(CoreError::InvalidCamera("rotation is not orthonormal with det +1".into()));
        }
        Ok(())
    }

    /// COLMAP quaternion `(qw, qx, qy, qz)` of R with qw ≥ 0.
    pub fn quaternion(&self) -> [f64; 4] {
        let q = DQuat::from_mat3(&self.rotation).normalize();
        let q = if q.w < 0.0 { -q } else { q };
        [q.w, q.x, q.y, q.z]
    }

    /// Camera centre in world coordinates, C = −Rᵀt.
    pub fn center(&self) -> DVec3 {
        -(self.rotation.transpose() * self.translation)
    }

    /// The optical axis (+z of the camera) in world coordinates.
    pub fn optical_axis(&self) -> DVec3 {
        self.rotation.row(2)
    }

    /// World point → camera coordinates, `R·x + t`.
    pub fn world_to_camera(&self, p: DVec3) -> DVec3 {
        self.rotation * p + self.translation
    }

    /// Camera coordinates → world point, `Rᵀ(x − t)`.
    pub fn camera_to_world(&self, p: DVec3) -> DVec3 {
        self.rotation.transpose() * (p - self.translation)
    }

    /// Camera-space point → continuous pixel coordinates `(fx·x/z + cx, fy·y/z + cy)`.
    /// The caller checks `z > 0`.
    pub fn project_camera(&self, p: DVec3) -> DVec2 {
        let k = &self.intrinsics;
        DVec2::new(k.fx * p.x / p.z + k.cx, k.fy * p.y / p.z + k.cy)
    }

    /// World point → `(pixel, depth)` when it lies in front of the camera (`z > 0`).
    pub fn project(&self, p: DVec3) -> Option<(DVec2, f64)> {
        let pc = self.world_to_camera(p);
        (pc.z > 0.0).then(|| (self.project_camera(pc), pc.z))
    }

    /// Whether continuous pixel coordinates lie inside the image, `0 ≤ u < W`, `0 ≤ v < H`.
    pub fn contains(&self, pixel: DVec2) -> bool {
        pixel.x >= 0.0 && pixel.y >= 0.0 && pixel.x < self.width as f64 && pixel.y < self.height as f64
    }

    /// The camera-space ray `K⁻¹(u, v, 1)ᵀ` through continuous pixel coordinates (z = 1).
    pub fn ray(&self, u: f64, v: f64) -> DVec3 {
        let k = &self.intrinsics;
        DVec3::new((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0)
    }

    /// The continuous coordinates of the centre of pixel `(column, row)`: `(i + 0.5, j + 0.5)`.
    pub fn pixel_center(column: u32, row: u32) -> DVec2 {
        DVec2::new(column as f64 + 0.5, row as f64 + 0.5)
    }

    /// Back-projects continuous pixel coordinates at camera-space `depth` (z, not ray length)
    /// to a world point.
    pub fn back_project(&self, u: f64, v: f64, depth: f64) -> DVec3 {
        self.camera_to_world(self.ray(u, v) * depth)
    }

    /// Horizontal field of view in radians.
    pub fn fov_x(&self) -> f64 {
        2.0 * (self.width as f64 / (2.0 * self.intrinsics.fx)).atan()
    }

    /// Vertical field of view in radians.
    pub fn fov_y(&self) -> f64 {
        2.0 * (self.height as f64 / (2.0 * self.intrinsics.fy)).atan()
    }

    /// The same camera for an image resized to `width × height`: intrinsics scale with the
    /// size ratio (exact under the pixel-centre-at-0.5 convention, where the image spans
    /// `[0, W] × [0, H]`).
    pub fn resized(&self, width: u32, height: u32) -> Result<Self> {
        let sx = width as f64 / self.width as f64;
        let sy = height as f64 / self.height as f64;
        let k = &self.intrinsics;
        Self::new(
            width,
            height,
            Intrinsics::new(k.fx * sx, k.fy * sy, k.cx * sx, k.cy * sy),
            self.rotation,
            self.translation,
        )
    }

    /// Relative pose from this (reference) camera to `source`: `(R_rs, t_rs)` with
    /// `R_rs = R_s R_rᵀ`, `t_rs = t_s − R_rs t_r`, so `x_s = R_rs x_r + t_rs` (docs/method.md §L_p).
    pub fn relative_pose_to(&self, source: &Camera) -> (DMat3, DVec3) {
        let r_rs = source.rotation * self.rotation.transpose();
        let t_rs = source.translation - r_rs * self.translation;
        (r_rs, t_rs)
    }

    /// R as f32 for hot paths.
    pub fn rotation_f32(&self) -> Mat3 {
        self.rotation.as_mat3()
    }

    /// t as f32 for hot paths.
    pub fn translation_f32(&self) -> Vec3 {
        self.translation.as_vec3()
    }
}

/// Rotation matrix of a (possibly non-normalised) quaternion `(w, x, y, z)`; an error when its
/// norm is zero or not finite.
pub fn rotation_from_quaternion(qvec: [f64; 4]) -> Result<DMat3> {
    let [w, x, y, z] = qvec;
    let norm = (w * w + x * x + y * y + z * z).sqrt();
    if !norm.is_finite() || norm < 1e-12 {
        return Err(CoreError::InvalidCamera(format!(
            "quaternion ({w}, {x}, {y}, {z}) has no usable norm"
        )));
    }
    Ok(DMat3::from_quat(DQuat::from_xyzw(x / norm, y / norm, z / norm, w / norm)))
}

/// `n` 64×48 cameras evenly on a circle of radius 3 at height 1 around the z axis, all looking
/// at the origin: a small, exactly known capture for tests and examples.
pub fn camera_ring(n: usize) -> Vec<Camera> {
    (0..n)
        .map(|k| {
            let a = k as f64 / n as f64 * std::f64::consts::TAU;
            let eye = DVec3::new(3.0 * a.cos(), 3.0 * a.sin(), 1.0);
            Camera::look_at(64, 48, Intrinsics::new(60.0, 60.0, 32.0, 24.0), eye, DVec3::ZERO, DVec3::Z)
                .expect("eye off the z axis, not at the target")
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn test_camera() -> Camera {
        Camera::from_quaternion(
            640,
            480,
            Intrinsics::new(500.0, 510.0, 321.0, 239.0),
            [0.9, 0.1, -0.2, 0.3],
            [0.1, -0.2, 3.0],
        )
        .unwrap()
    }

    #[test]
    fn project_back_project_round_trip() {
        let cam = test_camera();
        let p = DVec3::new(0.3, -0.2, 0.5);
        let (px, depth) = cam.project(p).unwrap();
        let q = cam.back_project(px.x, px.y, depth);
        assert!((p - q).length() < 1e-12);
    }

    #[test]
    fn pixel_centre_convention() {
        // A point on the optical axis lands at (cx, cy); the top-left pixel's centre is (0.5, 0.5).
        let cam = Camera::new(4, 4, Intrinsics::new(2.0, 2.0, 2.0, 2.0), DMat3::IDENTITY, DVec3::ZERO)
            .unwrap();
        let centre = Camera::pixel_center(0, 0);
        assert_eq!(centre, DVec2::new(0.5, 0.5));
        let ray = cam.ray(centre.x, centre.y);
        assert_eq!(ray, DVec3::new(-0.75, -0.75, 1.0));
        let back = cam.project_camera(ray * 3.0);
        assert!((back - centre).length() < 1e-12);
        assert_eq!(cam.project_camera(DVec3::new(0.0, 0.0, 1.0)), DVec2::new(2.0, 2.0));
    }

    #[test]
    fn centre_and_quaternion_round_trip() {
        let cam = test_camera();
        assert!(cam.world_to_camera(cam.center()).length() < 1e-12);
        let q = cam.quaternion();
        let again = Camera::from_quaternion(640, 480, cam.intrinsics, q, cam.translation.to_array()).unwrap();
        assert!(again.rotation.abs_diff_eq(cam.rotation, 1e-12));
    }

    #[test]
    fn look_at_points_the_axis_at_the_target() {
        let cam = Camera::look_at(
            100,
            80,
            Intrinsics::new(80.0, 80.0, 50.0, 40.0),
            DVec3::new(3.0, 0.0, 1.0),
            DVec3::ZERO,
            DVec3::Z,
        )
        .unwrap();
        let (px, _) = cam.project(DVec3::ZERO).unwrap();
        assert!((px - DVec2::new(50.0, 40.0)).length() < 1e-9);
        // World up projects above the centre (smaller v).
        let (up, _) = cam.project(DVec3::new(0.0, 0.0, 0.5)).unwrap();
        assert!(up.y < 40.0);
    }

    #[test]
    fn resized_keeps_projection_consistent() {
        let cam = test_camera();
        let half = cam.resized(320, 240).unwrap();
        let p = DVec3::new(0.1, 0.2, 0.3);
        let (a, _) = cam.project(p).unwrap();
        let (b, _) = half.project(p).unwrap();
        assert!((a * 0.5 - b).length() < 1e-9);
    }

    #[test]
    fn relative_pose_maps_reference_to_source() {
        let r = test_camera();
        let s = Camera::from_quaternion(640, 480, r.intrinsics, [1.0, 0.0, 0.3, 0.0], [0.5, 0.0, 2.0]).unwrap();
        let (r_rs, t_rs) = r.relative_pose_to(&s);
        let p = DVec3::new(0.2, 0.1, -0.3);
        let via = r_rs * r.world_to_camera(p) + t_rs;
        assert!((via - s.world_to_camera(p)).length() < 1e-12);
    }

    #[test]
    fn rejects_invalid_cameras() {
        let k = Intrinsics::new(1.0, 1.0, 0.0, 0.0);
        assert!(Camera::new(0, 10, k, DMat3::IDENTITY, DVec3::ZERO).is_err());
        assert!(Camera::new(10, 10, Intrinsics::new(f64::NAN, 1.0, 0.0, 0.0), DMat3::IDENTITY, DVec3::ZERO).is_err());
        assert!(Camera::new(10, 10, Intrinsics::new(-1.0, 1.0, 0.0, 0.0), DMat3::IDENTITY, DVec3::ZERO).is_err());
        assert!(Camera::new(10, 10, k, DMat3::from_diagonal(DVec3::splat(2.0)), DVec3::ZERO).is_err());
        assert!(Camera::from_quaternion(10, 10, k, [0.0; 4], [0.0; 3]).is_err());
        assert!(Camera::new(10, 10, k, DMat3::IDENTITY, DVec3::new(f64::INFINITY, 0.0, 0.0)).is_err());
    }
}
