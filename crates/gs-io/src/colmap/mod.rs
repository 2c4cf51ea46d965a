//! COLMAP sparse models (`cameras`, `images`, `points3D`), text and binary, read and write.
//!
//! Records keep every value exactly as in the files (f64, ids, `POINTS2D`, tracks), so
//! text → binary → text is lossless. [`read_model`] detects the format of a folder such as
//! `sparse/0`; every reader runs [`ColmapModel::validate`] and returns an [`IoError`] that
//! names the file, the record (line number for text, id and byte offset for binary) and the
//! problem.

mod binary;
mod camera_model;
mod text;

pub use binary::{
    parse_cameras_bin, parse_images_bin, parse_points3d_bin, read_binary, write_binary,
    write_cameras_bin, write_images_bin, write_points3d_bin,
};
pub use camera_model::{CameraModel, ModelLookup};
pub use text::{format_text, parse_text, read_text, write_text};

use crate::error::{IoError, Result};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A COLMAP camera: model, image size and parameters (in the model's order).
#[derive(Debug, Clone, PartialEq)]
pub struct ColmapCamera {
    /// Camera id.
    pub id: u32,
    /// Camera model.
    pub model: CameraModel,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Parameters, `model.num_params()` of them.
    pub params: Vec<f64>,
}

/// One 2D observation of an image: pixel position and the 3D point it belongs to, if any.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point2D {
    /// Continuous pixel coordinates (top-left pixel centre at `(0.5, 0.5)`).
    pub xy: [f64; 2],
    /// Id of the 3D point, `None` for COLMAP's −1.
    pub point3d_id: Option<u64>,
}

/// A registered image: world→camera pose, its camera and its 2D observations.
#[derive(Debug, Clone, PartialEq)]
pub struct ColmapImage {
    /// Image id.
    pub id: u32,
    /// World→camera rotation quaternion `(qw, qx, qy, qz)` as stored (not normalised).
    pub qvec: [f64; 4],
    /// World→camera translation.
    pub tvec: [f64; 3],
    /// Id of the camera.
    pub camera_id: u32,
    /// File name relative to the images folder.
    pub name: String,
    /// 2D observations (`POINTS2D`).
    pub points2d: Vec<Point2D>,
}

/// A triangulated 3D point with colour, mean reprojection error and track.
#[derive(Debug, Clone, PartialEq)]
pub struct ColmapPoint3D {
    /// Point id.
    pub id: u64,
    /// World position.
    pub xyz: [f64; 3],
    /// 8-bit colour.
    pub rgb: [u8; 3],
    /// Mean reprojection error in pixels as stored (COLMAP writes −1 when unknown).
    pub error: f64,
    /// Observations `(image_id, point2d_idx)`.
    pub track: Vec<(u32, u32)>,
}

impl ColmapPoint3D {
    /// The point as a scene's sparse point: its position, and its colour in `[0, 1]`.
    pub fn scene_point(&self) -> gs_core::ScenePoint {
        gs_core::ScenePoint { position: gs_core::glam::DVec3::from_array(self.xyz), color: self.rgb.map(|c| c as f32 / 255.0) }
    }
}

/// A COLMAP sparse model keyed by id.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ColmapModel {
    /// Cameras by id.
    pub cameras: BTreeMap<u32, ColmapCamera>,
    /// Registered images by id.
    pub images: BTreeMap<u32, ColmapImage>,
    /// 3D points by id.
    pub points3d: BTreeMap<u64, ColmapPoint3D>,
}

/// On-disk flavour of a model folder.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelFormat {
    /// `cameras.txt`, `images.txt`, `points3D.txt`.
    Text,
    /// `cameras.bin`, `images.bin`, `points3D.bin`.
    Binary,
}

impl ModelFormat {
    /// File extension of this format.
    pub fn extension(self) -> &'static str {
        match self {
            ModelFormat::Text => "txt",
            ModelFormat::Binary => "bin",
        }
    }
}

/// Paths of the three files of a model folder in one format (used to name files in errors).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ModelPaths {
    /// `cameras.{txt,bin}`.
    pub cameras: PathBuf,
    /// `images.{txt,bin}`.
    pub images: PathBuf,
    /// `points3D.{txt,bin}`.
    pub points3d: PathBuf,
}

impl ModelPaths {
    /// The three file paths of `dir` in `format`.
    pub fn new(dir: &Path, format: ModelFormat) -> Self {
        let ext = format.extension();
        Self {
            cameras: dir.join(format!("cameras.{ext}")),
            images: dir.join(format!("images.{ext}")),
            points3d: dir.join(format!("points3D.{ext}")),
        }
    }
}

/// Detects whether `dir` holds a binary or a text model (binary wins when both are complete,
/// as in COLMAP). An error naming the folder when neither set of three files is complete.
pub fn detect_format(dir: &Path) -> Result<ModelFormat> {
    if !dir.is_dir() {
        return Err(IoError::invalid(dir, "COLMAP model folder does not exist"));
    }
    for format in [ModelFormat::Binary, ModelFormat::Text] {
        let p = ModelPaths::new(dir, format);
        if p.cameras.is_file() && p.images.is_file() && p.points3d.is_file() {
            return Ok(format);
        }
    }
    Err(IoError::invalid(
        dir,
        "no COLMAP model here: expected cameras/images/points3D .bin or .txt",
    ))
}

/// Reads a model folder (`sparse/0`) in whichever format it holds, then validates it.
pub fn read_model(dir: &Path) -> Result<ColmapModel> {
    match detect_format(dir)? {
        ModelFormat::Binary => read_binary(dir),
        ModelFormat::Text => read_text(dir),
    }
}

/// Largest accepted magnitude of a camera centre or point coordinate: far beyond any real
/// capture (Earth-centred coordinates are ~6.4e6 m), small enough that squared distances and
/// A number for people: as written in the usual range, in scientific notation outside it (1e300
/// as `1e300`, not 301 digits).
pub fn readable(x: f64) -> String {
    if x == 0.0 || (1e-3..1e6).contains(&x.abs()) { format!("{}", (x * 1e4).round() / 1e4) } else { format!("{x:.3e}") }
}

/// The widest field of view a camera may have, degrees (a pinhole model reaches 180° only at
/// a zero focal length; the widest rectilinear lenses are about 120°).
pub const MAX_FOV_DEG: f64 = 170.0;
/// The narrowest field of view, degrees (a 2000 mm lens on a full-frame sensor is about 1°).
pub const MIN_FOV_DEG: f64 = 0.01;

/// sums over thousands of cameras stay finite in f64 and positions finite in f32.
pub const MAX_COORDINATE: f64 = 1e12;

fn finite_all(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// The largest magnitude among `v`'s components (the distance from the origin to within √3),
/// for the [`MAX_COORDINATE`] checks.
fn max_abs(v: &[f64]) -> f64 {
    v.iter().map(|x| x.abs()).fold(0.0, f64::max)
}

impl ColmapCamera {
    /// Checks the parameter count, finiteness, positive focal lengths and non-zero size;
    /// the message describes the problem (the caller adds file and record).
    pub fn check(&self) -> std::result::Result<(), String> {
        if self.params.len() != self.model.num_params() {
            return Err(format!(
                "camera {}: model {} needs {} parameters, got {}",
                self.id,
                self.model,
                self.model.num_params(),
                self.params.len()
            ));
        }
        if self.width == 0 || self.height == 0 {
            return Err(format!("camera {}: image size {}x{} is empty", self.id, self.width, self.height));
        }
        if !finite_all(&self.params) {
            return Err(format!("camera {}: parameters contain NaN or infinity", self.id));
        }
        let [fx, fy, _, _] = self.pinhole();
        if fx <= 0.0 || fy <= 0.0 {
            return Err(format!("camera {}: focal lengths must be positive, got {fx} {fy}", self.id));
        }
        self.check_lens()
    }

    /// Refuses a lens no photograph has (a corrupt or mistyped file, such as
    /// `camera_angle_x = 3.14159`): a field of view above [`MAX_FOV_DEG`] or below
    /// [`MIN_FOV_DEG`], a principal point more than one image size outside the image, or a
    /// distortion that moves an image corner to less than a tenth or more than ten times its
    /// distance from the centre (undistorting would shrink or blow up the photo).
    fn check_lens(&self) -> std::result::Result<(), String> {
        let [fx, fy, cx, cy] = self.pinhole();
        let (w, h) = (self.width as f64, self.height as f64);
        for (axis, f, size) in [("x", fx, w), ("y", fy, h)] {
            let fov = 2.0 * (0.5 * size / f).atan().to_degrees();
            if !(MIN_FOV_DEG..=MAX_FOV_DEG).contains(&fov) {
                return Err(format!(
                    "camera {}: focal length f{axis} = {} px gives a field of view of {}° across {size} px, outside {MIN_FOV_DEG}°–{MAX_FOV_DEG}° (a corrupt or mistyped camera?)",
                    self.id,
                    readable(f),
                    readable(fov)
                ));
            }
        }
        for (axis, c, size) in [("x", cx, w), ("y", cy, h)] {
            if c < -size || c > 2.0 * size {
                return Err(format!(
                    "camera {}: principal point c{axis} = {} px lies more than the image's size ({size} px) outside the image",
                    self.id,
                    readable(c)
                ));
            }
        }
        if self.is_undistorted() {
            return Ok(());
        }
        for corner in [[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]] {
            let uv = [(corner[0] - cx) / fx, (corner[1] - cy) / fy];
            let moved = self.img_from_cam(uv);
            let r0 = ((corner[0] - cx) / fx).hypot((corner[1] - cy) / fy);
            let r1 = ((moved[0] - cx) / fx).hypot((moved[1] - cy) / fy);
            let scale = r1 / r0;
            if r0 > 1e-9 && !(0.1..=10.0).contains(&scale) {
                return Err(format!(
                    "camera {}: its distortion ({}) moves the image corner ({}, {}) to {} times its distance from the centre (a real lens: 0.1 to 10); undistorting would shrink or blow up the photo",
                    self.id,
                    self.extra_params().iter().map(|&p| readable(p)).collect::<Vec<_>>().join(" "),
                    corner[0],
                    corner[1],
                    readable(scale)
                ));
            }
        }
        Ok(())
    }

    /// `(fx, fy, cx, cy)` of the camera.
    pub fn pinhole(&self) -> [f64; 4] {
        self.model.pinhole_part(&self.params)
    }

    /// The distortion parameters (empty for PINHOLE and SIMPLE_PINHOLE).
    pub fn extra_params(&self) -> &[f64] {
        self.model.extra_params(&self.params)
    }

    /// Whether the camera has no distortion: a pinhole model, or every distortion parameter
    /// below 1e-8 in magnitude (COLMAP's `IsUndistorted`).
    pub fn is_undistorted(&self) -> bool {
        self.extra_params().iter().all(|p| p.abs() <= 1e-8)
    }

    /// Normalised camera coordinates `(x/z, y/z)` → continuous pixel coordinates, with
    /// distortion (COLMAP's `ImgFromCam`).
    pub fn img_from_cam(&self, uv: [f64; 2]) -> [f64; 2] {
        let [fx, fy, cx, cy] = self.pinhole();
        let d = self.model.distortion(self.extra_params(), uv[0], uv[1]);
        [fx * (uv[0] + d[0]) + cx, fy * (uv[1] + d[1]) + cy]
    }

    /// Continuous pixel coordinates → normalised camera coordinates, inverting the
    /// distortion iteratively (COLMAP's `CamFromImg`); `None` where the iteration fails.
    pub fn cam_from_img(&self, xy: [f64; 2]) -> Option<[f64; 2]> {
        let [fx, fy, cx, cy] = self.pinhole();
        self.model.undistort_normalized(self.extra_params(), (xy[0] - cx) / fx, (xy[1] - cy) / fy)
    }

    /// The same camera for the image scaled to `width × height` (COLMAP's `Rescale`: focal
    /// lengths and principal point scale with the size ratio, distortion is unchanged).
    pub fn rescaled(&self, width: u32, height: u32) -> ColmapCamera {
        let sx = width as f64 / self.width as f64;
        let sy = height as f64 / self.height as f64;
        let mut params = self.params.clone();
        if matches!(self.model, CameraModel::SimplePinhole | CameraModel::SimpleRadial | CameraModel::Radial) {
            // One focal length: keep the model valid only for uniform scales; use the mean.
            params[0] *= 0.5 * (sx + sy);
            params[1] *= sx;
            params[2] *= sy;
        } else {
            params[0] *= sx;
            params[1] *= sy;
            params[2] *= sx;
            params[3] *= sy;
        }
        ColmapCamera { id: self.id, model: self.model, width, height, params }
    }
}

impl ColmapImage {
    /// Checks that the pose is finite, the quaternion has a usable norm and the camera centre
    /// lies within [`MAX_COORDINATE`] of the origin.
    pub fn check_pose(&self) -> std::result::Result<(), String> {
        if !finite_all(&self.qvec) || !finite_all(&self.tvec) {
            return Err(format!("image {} ({}): pose contains NaN or infinity", self.id, self.name));
        }
        let n2: f64 = self.qvec.iter().map(|q| q * q).sum();
        if n2.sqrt() < 1e-12 {
            return Err(format!("image {} ({}): quaternion has zero norm", self.id, self.name));
        }
        // The centre -Rᵀt lies |t| from the origin; beyond the limit distances overflow.
        let far = max_abs(&self.tvec);
        if far > MAX_COORDINATE {
            return Err(format!(
                "image {} ({}): camera centre lies about {far:e} from the origin, beyond the limit of \
                 {MAX_COORDINATE:e} (corrupt pose?)",
                self.id, self.name
            ));
        }
        Ok(())
    }

    /// The world→camera rotation matrix (normalising the quaternion).
    pub fn rotation(&self) -> Option<gs_core::glam::DMat3> {
        gs_core::camera::rotation_from_quaternion(self.qvec).ok()
    }
}

impl ColmapPoint3D {
    /// Checks that the position and error are finite and the position lies within
    /// [`MAX_COORDINATE`] of the origin.
    pub fn check(&self) -> std::result::Result<(), String> {
        if !finite_all(&self.xyz) {
            return Err(format!("point {}: position contains NaN or infinity", self.id));
        }
        let far = max_abs(&self.xyz);
        if far > MAX_COORDINATE {
            return Err(format!(
                "point {}: position lies about {far:e} from the origin, beyond the limit of {MAX_COORDINATE:e}",
                self.id
            ));
        }
        if !self.error.is_finite() {
            return Err(format!("point {}: error is NaN or infinite", self.id));
        }
        Ok(())
    }
}

impl ColmapModel {
    /// Checks the model as a whole: at least one image; every camera, pose and point valid;
    /// image names unique; every image's camera exists; every track entry names an existing
    /// image and an existing 2D point of it; every 2D point's 3D point exists. `paths` name the
    /// files in errors.
    pub fn validate(&self, paths: &ModelPaths) -> Result<()> {
        for cam in self.cameras.values() {
            cam.check().map_err(|m| IoError::format(&paths.cameras, m))?;
        }
        if self.images.is_empty() {
            return Err(IoError::invalid(&paths.images, "empty model: no registered images"));
        }
        for img in self.images.values() {
            img.check_pose().map_err(|m| IoError::format(&paths.images, m))?;
            if !self.cameras.contains_key(&img.camera_id) {
                return Err(IoError::invalid(
                    &paths.images,
                    format!("image {} ({}) references missing camera {}", img.id, img.name, img.camera_id),
                ));
            }
            for (k, p) in img.points2d.iter().enumerate() {
                if !finite_all(&p.xy) {
                    return Err(IoError::format(
                        &paths.images,
                        format!("image {} ({}): point2D {k} is NaN or infinite", img.id, img.name),
                    ));
                }
                if let Some(pid) = p.point3d_id
                    && !self.points3d.contains_key(&pid)
                {
                    return Err(IoError::invalid(
                        &paths.images,
                        format!("image {} ({}): point2D {k} references missing 3D point {pid}", img.id, img.name),
                    ));
                }
            }
        }
        self.check_unique_names(paths)?;
        for pt in self.points3d.values() {
            pt.check().map_err(|m| IoError::format(&paths.points3d, m))?;
            for &(image_id, idx) in &pt.track {
                let Some(img) = self.images.get(&image_id) else {
                    return Err(IoError::invalid(
                        &paths.points3d,
                        format!("point {}: track references missing image {image_id}", pt.id),
                    ));
                };
                if idx as usize >= img.points2d.len() {
                    return Err(IoError::invalid(
                        &paths.points3d,
                        format!(
                            "point {}: track references point2D {idx} of image {image_id}, which has {}",
                            pt.id,
                            img.points2d.len()
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Refuses two images with the same name: views, renders and run configurations are
    /// keyed by name, so a duplicate would silently overwrite or shadow the other view.
    fn check_unique_names(&self, paths: &ModelPaths) -> Result<()> {
        let mut seen: std::collections::HashMap<&str, u32> = std::collections::HashMap::new();
        for img in self.images.values() {
            if let Some(first) = seen.insert(img.name.as_str(), img.id) {
                return Err(IoError::invalid(
                    &paths.images,
                    format!(
                        "images {first} and {} have the same name '{}' (every image needs its own file name)",
                        img.id, img.name
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Total number of track entries (observations of 3D points).
    pub fn num_observations(&self) -> usize {
        self.points3d.values().map(|p| p.track.len()).sum()
    }

    /// Mean track length (0 without points).
    pub fn mean_track_length(&self) -> f64 {
        if self.points3d.is_empty() { 0.0 } else { self.num_observations() as f64 / self.points3d.len() as f64 }
    }

    /// Mean reprojection error in pixels, as COLMAP reports it: each 3D point's error is the
    /// mean distance over its track between the observation and the point projected with the
    /// image's pose and camera model (with distortion); the result is the mean over points.
    /// `None` without observations.
    pub fn mean_reprojection_error(&self) -> Option<f64> {
        let (mut sum, mut n_points) = (0.0, 0usize);
        for pt in self.points3d.values() {
            let p = gs_core::glam::DVec3::from_array(pt.xyz);
            let (mut point_sum, mut n_obs) = (0.0, 0usize);
            for &(image_id, idx) in &pt.track {
                let Some(img) = self.images.get(&image_id) else { continue };
                let (Some(cam), Some(r)) = (self.cameras.get(&img.camera_id), img.rotation()) else { continue };
                let Some(obs) = img.points2d.get(idx as usize) else { continue };
                let pc = r * p + gs_core::glam::DVec3::from_array(img.tvec);
                if pc.z <= 0.0 {
                    continue;
                }
                let px = cam.img_from_cam([pc.x / pc.z, pc.y / pc.z]);
                let e = ((px[0] - obs.xy[0]).powi(2) + (px[1] - obs.xy[1]).powi(2)).sqrt();
                if e.is_finite() {
                    point_sum += e;
                    n_obs += 1;
                }
            }
            if n_obs > 0 {
                sum += point_sum / n_obs as f64;
                n_points += 1;
            }
        }
        (n_points > 0).then(|| sum / n_points as f64)
    }
}
