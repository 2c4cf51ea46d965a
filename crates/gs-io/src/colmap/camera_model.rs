//! COLMAP camera models without fisheye: parameters, projection with distortion
//! (`img_from_cam`) and its inverse by Newton iteration (`cam_from_img`), with COLMAP's
//! formulas (`src/colmap/sensor/models.h`) and pixel convention (top-left pixel centre at
//! `(0.5, 0.5)`).

/// A supported COLMAP camera model. Fisheye and other models are rejected with
/// [`IoError::Unsupported`](crate::IoError::Unsupported) by the readers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum CameraModel {
    /// `f cx cy` (id 0).
    SimplePinhole,
    /// `fx fy cx cy` (id 1).
    Pinhole,
    /// `f cx cy k` (id 2).
    SimpleRadial,
    /// `f cx cy k1 k2` (id 3).
    Radial,
    /// `fx fy cx cy k1 k2 p1 p2` (id 4).
    OpenCv,
    /// `fx fy cx cy k1 k2 p1 p2 k3 k4 k5 k6` (id 6), rational radial model.
    FullOpenCv,
}

/// Names of COLMAP models this crate knows about but does not support, by id.
const UNSUPPORTED_MODELS: &[(i32, &str)] = &[
    (5, "OPENCV_FISHEYE"),
    (7, "FOV"),
    (8, "SIMPLE_RADIAL_FISHEYE"),
    (9, "RADIAL_FISHEYE"),
    (10, "THIN_PRISM_FISHEYE"),
    (11, "RAD_TAN_THIN_PRISM_FISHEYE"),
    (12, "SIMPLE_DIVISION"),
    (13, "DIVISION"),
    (14, "SIMPLE_FISHEYE"),
    (15, "FISHEYE"),
];

/// Outcome of looking a model up by id or name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelLookup {
    /// A supported model.
    Supported(CameraModel),
    /// A COLMAP model that exists but vagsl does not support (fisheye etc.), with its name.
    Unsupported(&'static str),
    /// Not a COLMAP model at all.
    Unknown,
}

impl CameraModel {
    /// All supported models.
    pub const ALL: [CameraModel; 6] = [
        CameraModel::SimplePinhole,
        CameraModel::Pinhole,
        CameraModel::SimpleRadial,
        CameraModel::Radial,
        CameraModel::OpenCv,
        CameraModel::FullOpenCv,
    ];

    /// COLMAP's numeric model id (as stored in `cameras.bin`).
    pub fn id(self) -> i32 {
        match self {
            CameraModel::SimplePinhole => 0,
            CameraModel::Pinhole => 1,
            CameraModel::SimpleRadial => 2,
            CameraModel::Radial => 3,
            CameraModel::OpenCv => 4,
            CameraModel::FullOpenCv => 6,
        }
    }

    /// COLMAP's model name (as written in `cameras.txt`).
    pub fn name(self) -> &'static str {
        match self {
            CameraModel::SimplePinhole => "SIMPLE_PINHOLE",
            CameraModel::Pinhole => "PINHOLE",
            CameraModel::SimpleRadial => "SIMPLE_RADIAL",
            CameraModel::Radial => "RADIAL",
            CameraModel::OpenCv => "OPENCV",
            CameraModel::FullOpenCv => "FULL_OPENCV",
        }
    }

    /// Number of parameters of the model.
    pub fn num_params(self) -> usize {
        match self {
            CameraModel::SimplePinhole => 3,
            CameraModel::Pinhole => 4,
            CameraModel::SimpleRadial => 4,
            CameraModel::Radial => 5,
            CameraModel::OpenCv => 8,
            CameraModel::FullOpenCv => 12,
        }
    }

    /// Looks a model up by its numeric id.
    pub fn lookup_id(id: i32) -> ModelLookup {
        if let Some(m) = Self::ALL.iter().find(|m| m.id() == id) {
            return ModelLookup::Supported(*m);
        }
        match UNSUPPORTED_MODELS.iter().find(|(i, _)| *i == id) {
            Some((_, name)) => ModelLookup::Unsupported(name),
            None => ModelLookup::Unknown,
        }
    }

    /// Looks a model up by its name.
    pub fn lookup_name(name: &str) -> ModelLookup {
        if let Some(m) = Self::ALL.iter().find(|m| m.name() == name) {
            return ModelLookup::Supported(*m);
        }
        match UNSUPPORTED_MODELS.iter().find(|(_, n)| *n == name) {
            Some((_, name)) => ModelLookup::Unsupported(name),
            None => ModelLookup::Unknown,
        }
    }

    /// Whether the model has a single focal length `f` (SIMPLE_* and RADIAL).
    fn single_focal(self) -> bool {
        matches!(self, CameraModel::SimplePinhole | CameraModel::SimpleRadial | CameraModel::Radial)
    }

    /// Index of the first distortion ("extra") parameter.
    fn extra_start(self) -> usize {
        if self.single_focal() { 3 } else { 4 }
    }

    /// `(fx, fy, cx, cy)` of a parameter vector of this model (caller checked the length).
    pub fn pinhole_part(self, params: &[f64]) -> [f64; 4] {
        if self.single_focal() {
            [params[0], params[0], params[1], params[2]]
        } else {
            [params[0], params[1], params[2], params[3]]
        }
    }

    /// The distortion ("extra") parameters of a parameter vector of this model.
    pub fn extra_params(self, params: &[f64]) -> &[f64] {
        &params[self.extra_start().min(params.len())..]
    }

    /// Distortion offset `(du, dv)` at normalised coordinates `(u, v)` (COLMAP's
    /// `Distortion`): the distorted point is `(u + du, v + dv)`.
    pub fn distortion(self, extra: &[f64], u: f64, v: f64) -> [f64; 2] {
        let (u2, v2, uv) = (u * u, v * v, u * v);
        let r2 = u2 + v2;
        match self {
            CameraModel::SimplePinhole | CameraModel::Pinhole => [0.0, 0.0],
            CameraModel::SimpleRadial => {
                let radial = extra[0] * r2;
                [u * radial, v * radial]
            }
            CameraModel::Radial => {
                let radial = extra[0] * r2 + extra[1] * r2 * r2;
                [u * radial, v * radial]
            }
            CameraModel::OpenCv => {
                let (k1, k2, p1, p2) = (extra[0], extra[1], extra[2], extra[3]);
                let radial = k1 * r2 + k2 * r2 * r2;
                [
                    u * radial + 2.0 * p1 * uv + p2 * (r2 + 2.0 * u2),
                    v * radial + 2.0 * p2 * uv + p1 * (r2 + 2.0 * v2),
                ]
            }
            CameraModel::FullOpenCv => {
                let [k1, k2, p1, p2, k3, k4, k5, k6] =
                    [extra[0], extra[1], extra[2], extra[3], extra[4], extra[5], extra[6], extra[7]];
                let (r4, r6) = (r2 * r2, r2 * r2 * r2);
                let radial = (1.0 + k1 * r2 + k2 * r4 + k3 * r6) / (1.0 + k4 * r2 + k5 * r4 + k6 * r6);
                [
                    u * radial + 2.0 * p1 * uv + p2 * (r2 + 2.0 * u2) - u,
                    v * radial + 2.0 * p2 * uv + p1 * (r2 + 2.0 * v2) - v,
                ]
            }
        }
    }

    /// Jacobian of the distorted point `(u + du, v + dv)` with respect to `(u, v)`, row-major
    /// `[[∂x/∂u, ∂x/∂v], [∂y/∂u, ∂y/∂v]]` (analytic; COLMAP uses central differences).
    pub fn distortion_jacobian(self, extra: &[f64], u: f64, v: f64) -> [[f64; 2]; 2] {
        let r2 = u * u + v * v;
        // radial(r2) multiplies (u, v); g = d radial / d r2; d r2/du = 2u.
        let (radial, g, p1, p2) = match self {
            CameraModel::SimplePinhole | CameraModel::Pinhole => (0.0, 0.0, 0.0, 0.0),
            CameraModel::SimpleRadial => (extra[0] * r2, extra[0], 0.0, 0.0),
            CameraModel::Radial => {
                (extra[0] * r2 + extra[1] * r2 * r2, extra[0] + 2.0 * extra[1] * r2, 0.0, 0.0)
            }
            CameraModel::OpenCv => (
                extra[0] * r2 + extra[1] * r2 * r2,
                extra[0] + 2.0 * extra[1] * r2,
                extra[2],
                extra[3],
            ),
            CameraModel::FullOpenCv => {
                let [k1, k2, p1, p2, k3, k4, k5, k6] =
                    [extra[0], extra[1], extra[2], extra[3], extra[4], extra[5], extra[6], extra[7]];
                let num = 1.0 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2;
                let den = 1.0 + k4 * r2 + k5 * r2 * r2 + k6 * r2 * r2 * r2;
                let dnum = k1 + 2.0 * k2 * r2 + 3.0 * k3 * r2 * r2;
                let dden = k4 + 2.0 * k5 * r2 + 3.0 * k6 * r2 * r2;
                // Offset form: u·(radial − 1); the "1 +" below restores the identity.
                (num / den - 1.0, (dnum * den - num * dden) / (den * den), p1, p2)
            }
        };
        let dxdu = 1.0 + radial + u * g * 2.0 * u + 2.0 * p1 * v + p2 * 6.0 * u;
        let dxdv = u * g * 2.0 * v + 2.0 * p1 * u + p2 * 2.0 * v;
        let dydu = v * g * 2.0 * u + 2.0 * p2 * v + p1 * 2.0 * u;
        let dydv = 1.0 + radial + v * g * 2.0 * v + 2.0 * p2 * u + p1 * 6.0 * v;
        [[dxdu, dxdv], [dydu, dydv]]
    }

    /// Inverts the distortion: the normalised `(u, v)` whose distorted image is `(xd, yd)`
    /// (COLMAP's `IterativeUndistortion`, Newton's method; here with the analytic Jacobian and
    /// step halving when a step does not reduce the residual). Returns `None` when it does not
    /// converge to 1e-12 (far outside the valid region of the model).
    pub fn undistort_normalized(self, extra: &[f64], xd: f64, yd: f64) -> Option<[f64; 2]> {
        if matches!(self, CameraModel::SimplePinhole | CameraModel::Pinhole) {
            return Some([xd, yd]);
        }
        let residual = |u: f64, v: f64| {
            let d = self.distortion(extra, u, v);
            [u + d[0] - xd, v + d[1] - yd]
        };
        let (mut u, mut v) = (xd, yd);
        let mut r = residual(u, v);
        let tol = 1e-12 * (1.0 + xd.abs() + yd.abs());
        for _ in 0..100 {
            let err = r[0].abs().max(r[1].abs());
            if err <= tol {
                return Some([u, v]);
            }
            let j = self.distortion_jacobian(extra, u, v);
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            if !det.is_finite() || det.abs() < 1e-300 {
                return None;
            }
            let su = (j[1][1] * r[0] - j[0][1] * r[1]) / det;
            let sv = (-j[1][0] * r[0] + j[0][0] * r[1]) / det;
            let mut t = 1.0;
            loop {
                let (nu, nv) = (u - t * su, v - t * sv);
                let nr = residual(nu, nv);
                if nr[0].abs().max(nr[1].abs()) < err || t < 1e-6 {
                    u = nu;
                    v = nv;
                    r = nr;
                    break;
                }
                t *= 0.5;
            }
            if !(u.is_finite() && v.is_finite()) {
                return None;
            }
        }
        (r[0].abs().max(r[1].abs()) <= tol.max(1e-10)).then_some([u, v])
    }
}

impl std::fmt::Display for CameraModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn extra_for(model: CameraModel) -> Vec<f64> {
        match model {
            CameraModel::SimplePinhole | CameraModel::Pinhole => vec![],
            CameraModel::SimpleRadial => vec![-0.12],
            CameraModel::Radial => vec![-0.1, 0.03],
            CameraModel::OpenCv => vec![0.0578, -0.0805, -0.00098, 0.00016],
            CameraModel::FullOpenCv => vec![-0.2, 0.05, 0.001, -0.002, 0.01, 0.02, -0.01, 0.005],
        }
    }

    #[test]
    fn ids_names_and_lookup_agree() {
        for m in CameraModel::ALL {
            assert_eq!(CameraModel::lookup_id(m.id()), ModelLookup::Supported(m));
            assert_eq!(CameraModel::lookup_name(m.name()), ModelLookup::Supported(m));
        }
        assert_eq!(CameraModel::lookup_id(5), ModelLookup::Unsupported("OPENCV_FISHEYE"));
        assert_eq!(CameraModel::lookup_name("FOV"), ModelLookup::Unsupported("FOV"));
        assert_eq!(CameraModel::lookup_id(-1), ModelLookup::Unknown);
        assert_eq!(CameraModel::lookup_name("pinhole"), ModelLookup::Unknown);
    }

    #[test]
    fn jacobian_matches_central_differences() {
        for m in CameraModel::ALL {
            let e = extra_for(m);
            for &(u, v) in &[(0.3, -0.2), (-0.5, 0.4), (0.01, 0.7)] {
                let j = m.distortion_jacobian(&e, u, v);
                let h = 1e-6;
                let f = |u: f64, v: f64| {
                    let d = m.distortion(&e, u, v);
                    [u + d[0], v + d[1]]
                };
                let (a, b) = (f(u + h, v), f(u - h, v));
                let (c, d) = (f(u, v + h), f(u, v - h));
                let num = [[(a[0] - b[0]) / (2.0 * h), (c[0] - d[0]) / (2.0 * h)], [
                    (a[1] - b[1]) / (2.0 * h),
                    (c[1] - d[1]) / (2.0 * h),
                ]];
                for r in 0..2 {
                    for c in 0..2 {
                        assert!((j[r][c] - num[r][c]).abs() < 1e-7, "{m} {r}{c}: {} vs {}", j[r][c], num[r][c]);
                    }
                }
            }
        }
    }

    #[test]
    fn undistort_inverts_distort() {
        for m in CameraModel::ALL {
            let e = extra_for(m);
            for i in 0..11 {
                for k in 0..11 {
                    let (u, v) = (-0.6 + 0.12 * i as f64, -0.6 + 0.12 * k as f64);
                    let d = m.distortion(&e, u, v);
                    let back = m.undistort_normalized(&e, u + d[0], v + d[1]).unwrap();
                    assert!((back[0] - u).abs() < 1e-10 && (back[1] - v).abs() < 1e-10, "{m} at ({u}, {v})");
                }
            }
        }
    }
}
