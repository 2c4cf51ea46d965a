//! The camera convention of `transforms.json` and its exact conversion to COLMAP's.
//!
//! A frame's `transform_matrix` is camera→world in the OpenGL / Blender convention: its
//! columns are the camera's x (right), y (up) and z (backwards, away from what it sees) axes
//! in world coordinates, and its last column is the camera centre C. COLMAP stores
//! world→camera with x right, y down, z forward (into the scene). The two camera frames differ
//! by a half turn about x, so
//!
//! ```text
//! R_c2w(COLMAP) = R_c2w(OpenGL) · diag(1, −1, −1)      (negate the y and z columns)
//! R_w2c = R_c2w(COLMAP)ᵀ,   t = −R_w2c · C
//! ```
//!
//! and back: `C = −R_w2cᵀ t`, `R_c2w(OpenGL) = R_w2cᵀ · diag(1, −1, −1)`. The world frame is
//! kept as it is (no axis swap), so points and meshes stay where they were.

use gs_core::glam::{DMat3, DQuat, DVec3};

/// A rigid transform `x ↦ R x + t` (a `transform_matrix` or nerfstudio's `applied_transform`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rigid {
    /// Rotation R (orthonormal, det +1 within the parser's tolerance).
    pub rotation: DMat3,
    /// Translation t (for a camera→world matrix: the camera centre).
    pub translation: DVec3,
}

impl Rigid {
    /// `Rᵀ (x − t)`: the inverse transform of a point.
    pub fn inverse_apply(&self, x: DVec3) -> DVec3 {
        self.rotation.transpose() * (x - self.translation)
    }

    /// The 4×4 matrix, rows, as `transforms.json` stores it.
    pub fn rows(&self) -> [[f64; 4]; 4] {
        let (r, t) = (self.rotation, self.translation);
        [
            [r.x_axis.x, r.y_axis.x, r.z_axis.x, t.x],
            [r.x_axis.y, r.y_axis.y, r.z_axis.y, t.y],
            [r.x_axis.z, r.y_axis.z, r.z_axis.z, t.z],
            [0.0, 0.0, 0.0, 1.0],
        ]
    }
}

/// COLMAP's world→camera `(qvec, tvec)` of an OpenGL camera→world transform (see the module
/// docs). The quaternion is that of the nearest rotation, normalised, and `tvec` is computed
/// from it, so the camera centre is exactly `c2w.translation` up to rounding.
pub fn colmap_pose_from_opengl(c2w: &Rigid) -> ([f64; 4], [f64; 3]) {
    let r = c2w.rotation;
    let r_w2c = DMat3::from_cols(r.x_axis, -r.y_axis, -r.z_axis).transpose();
    let q = DQuat::from_mat3(&r_w2c).normalize();
    let t = -(DMat3::from_quat(q) * c2w.translation);
    ([q.w, q.x, q.y, q.z], t.to_array())
}

/// The OpenGL camera→world transform of a COLMAP world→camera rotation and translation.
pub fn opengl_from_colmap(r_w2c: DMat3, tvec: DVec3) -> Rigid {
    let c2w = r_w2c.transpose();
    Rigid { rotation: DMat3::from_cols(c2w.x_axis, -c2w.y_axis, -c2w.z_axis), translation: -(c2w * tvec) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn opengl_camera_looking_down_minus_z_is_colmap_identity() {
        // OpenGL identity: camera at C looking along world −z with y up. In COLMAP terms the
        // camera looks along −z with y down: R_w2c = diag(1, −1, −1).
        let c = DVec3::new(1.0, 2.0, 3.0);
        let (q, t) = colmap_pose_from_opengl(&Rigid { rotation: DMat3::IDENTITY, translation: c });
        let r = DMat3::from_quat(DQuat::from_xyzw(q[1], q[2], q[3], q[0]));
        let d = r - DMat3::from_diagonal(DVec3::new(1.0, -1.0, -1.0));
        assert!(d.to_cols_array().iter().all(|x| x.abs() < 1e-15), "{r}");
        // A point 5 in front of the camera (world −z) has COLMAP depth +5.
        let p = r * (c - DVec3::new(0.0, 0.0, 5.0)) + DVec3::from_array(t);
        assert!((p - DVec3::new(0.0, 0.0, 5.0)).length() < 1e-14, "{p}");
        let back = opengl_from_colmap(r, DVec3::from_array(t));
        assert!((back.translation - c).length() < 1e-14);
        assert!((back.rotation - DMat3::IDENTITY).to_cols_array().iter().all(|x| x.abs() < 1e-15));
    }
}
