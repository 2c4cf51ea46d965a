//! Parsing one `transforms.json` held in memory: intrinsics (global and per frame), frames
//! with their poses converted to COLMAP's world→camera convention, `ply_file_path` and
//! `applied_transform`. No file other than the JSON is touched here, so the fuzz target can
//! drive it with arbitrary bytes.

use super::convention::{Rigid, colmap_pose_from_opengl};
use crate::colmap::{CameraModel, ColmapCamera};
use crate::error::{IoError, Result};
use gs_core::glam::{DMat3, DVec3};
use serde_json::{Map, Value};
use std::path::Path;

/// Largest accepted `w` / `h` in pixels (far beyond any photo; keeps sizes sane).
pub const MAX_SIZE: u32 = 1 << 20;
/// Largest accepted |RᵀR − I| entry of a pose's rotation: generous for matrices printed with
/// float32 precision (≈1e-7), tight enough to refuse scaled or sheared matrices.
pub const ORTHONORMAL_TOLERANCE: f64 = 1e-3;

/// The distortion keys, in the order of [`Lens::distortion`].
pub const DISTORTION_KEYS: [&str; 6] = ["k1", "k2", "k3", "k4", "p1", "p2"];

/// Intrinsics of a transforms file: the file's global values with a frame's own values
/// (Polycam, Record3D) over them. Absent values stay `None` until [`Lens::camera`] fills in
/// the defaults.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Lens {
    /// Focal lengths in pixels (`fl_x`, `fl_y`).
    pub fl: [Option<f64>; 2],
    /// Horizontal and vertical field of view in radians (`camera_angle_x`, `camera_angle_y`).
    pub angle: [Option<f64>; 2],
    /// Principal point in pixels (`cx`, `cy`), COLMAP's convention (pixel centres at +0.5).
    pub principal: [Option<f64>; 2],
    /// Image size (`w`, `h`); when absent it is read from the image file.
    pub size: [Option<u32>; 2],
    /// `k1 k2 k3 k4 p1 p2` (see [`DISTORTION_KEYS`]).
    pub distortion: [Option<f64>; 6],
    /// Whether `camera_model` says `OPENCV` (kept even when every coefficient is zero).
    pub opencv: bool,
}

/// One frame: its image, optional mask and COLMAP world→camera pose.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Position in the file's `frames` array (0-based), for messages.
    pub index: usize,
    /// `file_path` as written (relative to the JSON's folder; may lack its extension).
    pub file_path: String,
    /// `mask_path`, if given.
    pub mask_path: Option<String>,
    /// The frame's intrinsics (global values with the frame's over them).
    pub lens: Lens,
    /// World→camera rotation `(qw, qx, qy, qz)`, unit norm.
    pub qvec: [f64; 4],
    /// World→camera translation.
    pub tvec: [f64; 3],
}

impl Frame {
    /// `frames[i] ('file_path')`: how messages name the frame.
    pub fn label(&self) -> String {
        frame_label(self.index, Some(&self.file_path))
    }
}

/// A parsed transforms file.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TransformsFile {
    /// The frames in file order.
    pub frames: Vec<Frame>,
    /// `ply_file_path` (initial points, relative to the JSON's folder), if given.
    pub ply_file_path: Option<String>,
    /// `applied_transform` (nerfstudio), already undone on the frames; points read from
    /// `ply_file_path` must be mapped with [`Rigid::inverse_apply`] too.
    pub applied_transform: Option<Rigid>,
    /// nerfstudio's `test_filenames`, if given.
    pub test_filenames: Option<Vec<String>>,
}

fn frame_label(index: usize, file_path: Option<&str>) -> String {
    match file_path {
        Some(p) => format!("frames[{index}] ('{p}')"),
        None => format!("frames[{index}]"),
    }
}

/// Parses a transforms file held in memory; `path` only names the file in errors. Every
/// problem is an [`IoError`] naming the file and, where there is one, the frame.
pub fn parse_transforms(bytes: &[u8], path: &Path) -> Result<TransformsFile> {
    let root: Value = serde_json::from_slice(bytes).map_err(|e| IoError::format(path, crate::json_error_words(bytes, &e)))?;
    let Value::Object(root) = root else {
        return Err(IoError::format(path, "expected a JSON object at the top level"));
    };
    let global = read_lens(&root, &Lens::default()).map_err(|m| IoError::format(path, m))?;
    let applied_transform = match root.get("applied_transform") {
        None | Some(Value::Null) => None,
        Some(v) => Some(read_rigid(v, "applied_transform").map_err(|m| IoError::format(path, m))?),
    };
    let ply_file_path = optional_string(&root, "ply_file_path").map_err(|m| IoError::format(path, m))?;
    if let Some(v) = root.get("aabb_scale")
        && !v.as_f64().is_some_and(|s| s > 0.0)
    {
        return Err(IoError::format(path, "'aabb_scale' must be a positive number"));
    }
    let test_filenames = match root.get("test_filenames") {
        None => None,
        Some(Value::Array(a)) => Some(
            a.iter()
                .map(|v| v.as_str().map(str::to_string).ok_or("'test_filenames' must hold strings".to_string()))
                .collect::<std::result::Result<Vec<_>, _>>()
                .map_err(|m| IoError::format(path, m))?,
        ),
        Some(_) => return Err(IoError::format(path, "'test_filenames' must be an array of strings")),
    };
    let frames = match root.get("frames") {
        Some(Value::Array(a)) => a,
        Some(_) => return Err(IoError::format(path, "'frames' must be an array")),
        None => return Err(IoError::format(path, "missing 'frames' (the list of posed images)")),
    };
    let frames = frames
        .iter()
        .enumerate()
        .map(|(i, f)| read_frame(i, f, &global, applied_transform.as_ref()).map_err(|m| IoError::format(path, m)))
        .collect::<Result<Vec<_>>>()?;
    Ok(TransformsFile { frames, ply_file_path, applied_transform, test_filenames })
}

/// One element of `frames`; the message names the frame.
fn read_frame(index: usize, v: &Value, global: &Lens, applied: Option<&Rigid>) -> std::result::Result<Frame, String> {
    let Value::Object(obj) = v else {
        return Err(format!("{}: a frame must be a JSON object", frame_label(index, None)));
    };
    let file_path = optional_string(obj, "file_path").map_err(|m| format!("{}: {m}", frame_label(index, None)))?;
    let Some(file_path) = file_path.filter(|p| !p.is_empty()) else {
        return Err(format!("{}: missing 'file_path' (the image of the frame)", frame_label(index, None)));
    };
    let label = frame_label(index, Some(&file_path));
    let in_frame = |m: String| format!("{label}: {m}");
    let mask_path = optional_string(obj, "mask_path").map_err(in_frame)?;
    let lens = read_lens(obj, global).map_err(in_frame)?;
    let matrix = obj.get("transform_matrix").ok_or_else(|| in_frame("missing 'transform_matrix'".into()))?;
    let c2w = read_rigid(matrix, "transform_matrix").map_err(in_frame)?;
    let c2w = match applied {
        Some(a) => Rigid { rotation: a.rotation.transpose() * c2w.rotation, translation: a.inverse_apply(c2w.translation) },
        None => c2w,
    };
    let (qvec, tvec) = colmap_pose_from_opengl(&c2w);
    Ok(Frame { index, file_path, mask_path, lens, qvec, tvec })
}

fn optional_string(obj: &Map<String, Value>, key: &str) -> std::result::Result<Option<String>, String> {
    match obj.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(Value::String(s)) => Ok(Some(s.clone())),
        Some(_) => Err(format!("'{key}' must be a string")),
    }
}

fn optional_number(obj: &Map<String, Value>, key: &str) -> std::result::Result<Option<f64>, String> {
    match obj.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(v) => match v.as_f64() {
            Some(x) if x.is_finite() => Ok(Some(x)),
            _ => Err(format!("'{key}' must be a finite number, got {}", short(v))),
        },
    }
}

/// A JSON value shortened for a message.
fn short(v: &Value) -> String {
    let s = v.to_string();
    if s.chars().count() > 40 { format!("{}…", s.chars().take(40).collect::<String>()) } else { s }
}

/// The lens keys of `obj` over `base`, each checked on its own (positive focal lengths and
/// sizes, a field of view in (0, π), finite coefficients, a known camera model).
fn read_lens(obj: &Map<String, Value>, base: &Lens) -> std::result::Result<Lens, String> {
    let mut lens = base.clone();
    for (k, key) in ["fl_x", "fl_y"].iter().enumerate() {
        if let Some(f) = optional_number(obj, key)? {
            if f <= 0.0 {
                return Err(format!("focal length '{key}' must be positive, got {f}"));
            }
            lens.fl[k] = Some(f);
        }
    }
    for (k, key) in ["camera_angle_x", "camera_angle_y"].iter().enumerate() {
        if let Some(a) = optional_number(obj, key)? {
            if !(a > 0.0 && a < std::f64::consts::PI) {
                return Err(format!("field of view '{key}' must lie between 0 and π radians, got {a}"));
            }
            lens.angle[k] = Some(a);
        }
    }
    for (k, key) in ["cx", "cy"].iter().enumerate() {
        if let Some(c) = optional_number(obj, key)? {
            lens.principal[k] = Some(c);
        }
    }
    for (k, key) in ["w", "h"].iter().enumerate() {
        if let Some(s) = optional_number(obj, key)? {
            if s.fract() != 0.0 || s < 1.0 || s > MAX_SIZE as f64 {
                return Err(format!("image size '{key}' must be a whole number of pixels from 1 to {MAX_SIZE}, got {s}"));
            }
            lens.size[k] = Some(s as u32);
        }
    }
    for (k, key) in DISTORTION_KEYS.iter().enumerate() {
        if let Some(d) = optional_number(obj, key)? {
            lens.distortion[k] = Some(d);
        }
    }
    match optional_string(obj, "camera_model")?.as_deref() {
        None => {}
        Some("PINHOLE") => lens.opencv = false,
        Some("OPENCV") => lens.opencv = true,
        Some(m @ ("OPENCV_FISHEYE" | "EQUIRECTANGULAR")) => {
            return Err(format!("unsupported camera_model {m}: vagsl reads PINHOLE and OPENCV (fisheye lenses are refused as in COLMAP scenes)"));
        }
        Some(m) => return Err(format!("unknown camera_model '{m}' (expected PINHOLE or OPENCV)")),
    }
    Ok(lens)
}

/// A 3×4 or 4×4 matrix (rows) whose 3×3 part is a rotation: finite, orthonormal within
/// [`ORTHONORMAL_TOLERANCE`], determinant +1, last row (if any) `0 0 0 1`.
fn read_rigid(v: &Value, key: &str) -> std::result::Result<Rigid, String> {
    let rows = v.as_array().filter(|r| r.len() == 3 || r.len() == 4);
    let rows = rows.ok_or_else(|| format!("'{key}' must be a 3×4 or 4×4 matrix (an array of rows)"))?;
    let mut m = [[0.0f64; 4]; 4];
    m[3] = [0.0, 0.0, 0.0, 1.0];
    for (r, row) in rows.iter().enumerate() {
        let row = row.as_array().filter(|c| c.len() == 4).ok_or_else(|| format!("'{key}' row {r} must hold 4 numbers"))?;
        for (c, x) in row.iter().enumerate() {
            m[r][c] = x
                .as_f64()
                .filter(|x| x.is_finite())
                .ok_or_else(|| format!("'{key}' row {r} column {c} must be a finite number, got {}", short(x)))?;
        }
    }
    let bottom = m[3];
    if (bottom[0].abs().max(bottom[1].abs()).max(bottom[2].abs())) > 1e-6 || (bottom[3] - 1.0).abs() > 1e-6 {
        return Err(format!("'{key}' last row must be 0 0 0 1, got {bottom:?}"));
    }
    let rotation = DMat3::from_cols_array_2d(&[
        [m[0][0], m[1][0], m[2][0]],
        [m[0][1], m[1][1], m[2][1]],
        [m[0][2], m[1][2], m[2][2]],
    ]);
    let gram = rotation.transpose() * rotation - DMat3::IDENTITY;
    let err = gram.to_cols_array().iter().fold(0.0f64, |a, x| a.max(x.abs()));
    if err.is_nan() || err > ORTHONORMAL_TOLERANCE {
        return Err(format!(
            "'{key}' is not a rigid transform: its 3×3 rotation part is not orthonormal (|RᵀR − I| = {err:.3e} > {ORTHONORMAL_TOLERANCE:e}; a scaled or sheared matrix?)"
        ));
    }
    if rotation.determinant() <= 0.0 {
        return Err(format!("'{key}' is a reflection (determinant −1), not a rotation"));
    }
    let translation = DVec3::new(m[0][3], m[1][3], m[2][3]);
    let far = translation.abs().max_element();
    if far > crate::colmap::MAX_COORDINATE {
        return Err(format!("'{key}' translation lies about {far:e} from the origin, beyond {:e}", crate::colmap::MAX_COORDINATE));
    }
    Ok(Rigid { rotation, translation })
}

impl Lens {
    /// The COLMAP camera of this lens for a `width × height` image: focal lengths from
    /// `fl_x`/`fl_y` or else from `camera_angle_x`/`camera_angle_y` (`f = w / 2 / tan(angle / 2)`;
    /// a missing vertical one equals the horizontal), principal point default the image centre,
    /// and the model PINHOLE without distortion, OPENCV with `k1 k2 p1 p2` (or when
    /// `camera_model` says OPENCV), FULL_OPENCV with `k3`. A non-zero `k4` (an r⁸ term no COLMAP
    /// model has) is refused. The message describes the problem.
    pub fn camera(&self, id: u32, width: u32, height: u32) -> std::result::Result<ColmapCamera, String> {
        let half = [0.5 * width as f64, 0.5 * height as f64];
        let from_angle = |k: usize| self.angle[k].map(|a| half[k] / (0.5 * a).tan());
        let fx = self.fl[0].or_else(|| from_angle(0)).ok_or(
            "no focal length: give 'fl_x' (pixels) or 'camera_angle_x' (radians), globally or in the frame",
        )?;
        let fy = self.fl[1].or_else(|| from_angle(1)).unwrap_or(fx);
        let cx = self.principal[0].unwrap_or(half[0]);
        let cy = self.principal[1].unwrap_or(half[1]);
        let [k1, k2, k3, k4, p1, p2] = self.distortion.map(|d| d.unwrap_or(0.0));
        if k4 != 0.0 {
            return Err(format!(
                "'k4' = {k4} (the r⁸ radial term) has no COLMAP camera model; vagsl reads k1 k2 k3 p1 p2"
            ));
        }
        let (model, params) = if k3 != 0.0 {
            (CameraModel::FullOpenCv, vec![fx, fy, cx, cy, k1, k2, p1, p2, k3, 0.0, 0.0, 0.0])
        } else if self.opencv || [k1, k2, p1, p2].iter().any(|&d| d != 0.0) {
            (CameraModel::OpenCv, vec![fx, fy, cx, cy, k1, k2, p1, p2])
        } else {
            (CameraModel::Pinhole, vec![fx, fy, cx, cy])
        };
        let cam = ColmapCamera { id, model, width, height, params };
        cam.check()?;
        Ok(cam)
    }
}
