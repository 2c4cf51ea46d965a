//! Scenes in the nerfstudio / instant-ngp `transforms.json` layout, read and written.
//!
//! Read: the Blender synthetic variant (`camera_angle_x`, `file_path` without extension, split
//! files), instant-ngp and nerfstudio (`fl_x fl_y cx cy w h`, `k1 k2 k3 k4 p1 p2`,
//! `camera_model` PINHOLE / OPENCV, `aabb_scale`, `ply_file_path`, `applied_transform`,
//! `test_filenames`) and per-frame intrinsics over the global ones (Polycam, Record3D). The
//! result is a [`SceneModel`]: COLMAP cameras (PINHOLE, OPENCV, FULL_OPENCV — so undistortion
//! works unchanged), COLMAP world→camera poses ([`convention`]) and the initial points.
//!
//! - `file_path` is relative to the JSON's folder; one without an extension is tried with
//!   `.png`, `.jpg`, `.jpeg` (and upper case). A view's name is that path without a leading
//!   `./` and without a leading `images/` (as a COLMAP scene names photos relative to
//!   `images/`), e.g. `train/r_0.png` or `frame_00001.png`.
//! - A missing `w`/`h` is read from the image file's header.
//! - `applied_transform` (nerfstudio's map from the COLMAP world) is undone on the poses and
//!   on the `ply_file_path` points, so a converted scene lies in its original world frame.
//! - `aabb_scale` (instant-ngp's grid size) is checked and otherwise ignored; instant-ngp's
//!   `scale`/`offset` (a similarity it applies on load) are ignored.
//! - Held-out views: the frames of `transforms_test.json`, or nerfstudio's `test_filenames`.

pub mod convention;
mod parse;
mod write;

pub use convention::{Rigid, colmap_pose_from_opengl, opengl_from_colmap};
pub use parse::{DISTORTION_KEYS, Frame, Lens, MAX_SIZE, ORTHONORMAL_TOLERANCE, TransformsFile, parse_transforms};
pub use write::{POINTS_FILE, transforms_json, write_transforms};

use crate::colmap::{ColmapCamera, ColmapImage, ColmapModel, ColmapPoint3D};
use crate::error::{IoError, Result};
use crate::layout::{SceneLayout, SceneModel, TransformsFiles};
use gs_core::glam::DVec3;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

/// Extensions tried, in order, for a `file_path` without one (Blender synthetic `./train/r_0`).
pub const IMAGE_EXTENSIONS: [&str; 6] = ["png", "jpg", "jpeg", "PNG", "JPG", "JPEG"];

/// Reads and parses one transforms file.
pub fn read_transforms(path: &Path) -> Result<TransformsFile> {
    let bytes = crate::read_capped(path, crate::JSON_CAP, "a transforms file")?;
    parse_transforms(&bytes, path)
}

/// The view name of a `file_path` (see the module docs).
pub fn view_name(file_path: &str) -> String {
    let mut s = file_path.replace('\\', "/");
    while let Some(rest) = s.strip_prefix("./") {
        s = rest.to_string();
    }
    match s.strip_prefix("images/") {
        Some(rest) if !rest.is_empty() => rest.to_string(),
        _ => s,
    }
}

/// The image file of a frame (probing extensions when `file_path` has none) and its
/// `file_path` with the extension found; an error naming the JSON, the frame and the file.
fn image_file(json: &Path, dir: &Path, frame: &Frame) -> Result<(PathBuf, String)> {
    let path = dir.join(&frame.file_path);
    if path.is_file() {
        return Ok((path, frame.file_path.clone()));
    }
    if Path::new(&frame.file_path).extension().is_none() {
        for ext in IMAGE_EXTENSIONS {
            let cand = PathBuf::from(format!("{}.{ext}", path.display()));
            if cand.is_file() {
                return Ok((cand, format!("{}.{ext}", frame.file_path)));
            }
        }
        return Err(IoError::invalid(
            json,
            format!("{}: missing image file {} (also tried .png, .jpg, .jpeg)", frame.label(), path.display()),
        ));
    }
    Err(IoError::invalid(json, format!("{}: missing image file {}", frame.label(), path.display())))
}

/// Everything gathered while resolving the frames of the scene's files.
#[derive(Default)]
struct Collected {
    cameras: Vec<ColmapCamera>,
    images: Vec<ColmapImage>,
    image_paths: BTreeMap<u32, PathBuf>,
    mask_paths: BTreeMap<u32, PathBuf>,
    names: HashMap<String, PathBuf>,
}

impl Collected {
    /// Adds the frames of one file: image files, sizes (from the header when `w`/`h` are
    /// absent), cameras (identical ones shared), poses; returns the view names added.
    fn add(&mut self, json: &Path, file: &TransformsFile) -> Result<Vec<String>> {
        let dir = json.parent().unwrap_or(Path::new("."));
        let mut added = Vec::with_capacity(file.frames.len());
        for frame in &file.frames {
            let (path, file_path) = image_file(json, dir, frame)?;
            let name = view_name(&file_path);
            if let Some(first) = self.names.insert(name.clone(), json.to_path_buf()) {
                return Err(IoError::invalid(
                    json,
                    format!("{}: the view name '{name}' is already taken by a frame of {}", frame.label(), first.display()),
                ));
            }
            let (width, height) = match frame.lens.size {
                [Some(w), Some(h)] => (w, h),
                _ => crate::photo::image_size(&path)?,
            };
            let cam = frame.lens.camera(0, width, height).map_err(|m| IoError::format(json, format!("{}: {m}", frame.label())))?;
            let camera_id = match self.cameras.iter().find(|c| (c.model, c.width, c.height, &c.params) == (cam.model, cam.width, cam.height, &cam.params)) {
                Some(c) => c.id,
                None => {
                    let id = self.cameras.len() as u32 + 1;
                    self.cameras.push(ColmapCamera { id, ..cam });
                    id
                }
            };
            let id = self.images.len() as u32 + 1;
            let image = ColmapImage { id, qvec: frame.qvec, tvec: frame.tvec, camera_id, name: name.clone(), points2d: Vec::new() };
            image.check_pose().map_err(|m| IoError::format(json, format!("{}: {m}", frame.label())))?;
            self.images.push(image);
            self.image_paths.insert(id, path);
            if let Some(m) = &frame.mask_path {
                self.mask_paths.insert(id, dir.join(m));
            }
            added.push(name);
        }
        Ok(added)
    }
}

/// The points of `ply_file_path` (relative to the JSON's folder) as COLMAP points (ids from 1,
/// no track, error −1; grey where the file has no colours), `applied_transform` undone.
fn read_points(json: &Path, file: &TransformsFile) -> Result<Vec<ColmapPoint3D>> {
    let Some(rel) = &file.ply_file_path else { return Ok(Vec::new()) };
    let path = json.parent().unwrap_or(Path::new(".")).join(rel);
    if !path.is_file() {
        return Err(IoError::invalid(json, format!("'ply_file_path' names {}, which does not exist", path.display())));
    }
    let cloud = crate::ply::mesh::read_mesh_ply(&path)?;
    cloud
        .positions
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let mut xyz = DVec3::from_array(p.map(f64::from));
            if let Some(a) = &file.applied_transform {
                xyz = a.inverse_apply(xyz);
            }
            let rgb = cloud.colors.as_ref().and_then(|c| c.get(i).copied()).unwrap_or([128; 3]);
            let point = ColmapPoint3D { id: i as u64 + 1, xyz: xyz.to_array(), rgb, error: -1.0, track: Vec::new() };
            point.check().map_err(|m| IoError::format(&path, m))?;
            Ok(point)
        })
        .collect()
}

/// Reads a transforms scene (see the module docs) into a [`SceneModel`]. Image files must
/// exist (only their headers are read, and only where `w`/`h` are absent).
pub fn read_transforms_scene(files: &TransformsFiles) -> Result<SceneModel> {
    let main = read_transforms(&files.main)?;
    let test = files.test.as_deref().map(|p| read_transforms(p).map(|f| (p, f))).transpose()?;
    let mut c = Collected::default();
    c.add(&files.main, &main)?;
    let held_out = match &test {
        Some((path, file)) => Some(c.add(path, file)?),
        None => match &main.test_filenames {
            Some(names) => Some(
                names
                    .iter()
                    .map(|n| {
                        let name = view_name(n);
                        c.names.contains_key(&name).then_some(name).ok_or_else(|| {
                            IoError::invalid(&files.main, format!("'test_filenames' names '{n}', which no frame has"))
                        })
                    })
                    .collect::<Result<Vec<_>>>()?,
            ),
            None => None,
        },
    };
    if c.images.is_empty() {
        return Err(IoError::invalid(&files.main, "no frames: the scene has no posed images"));
    }
    let points = read_points(&files.main, &main)?;
    let model = ColmapModel {
        cameras: c.cameras.into_iter().map(|cam| (cam.id, cam)).collect(),
        images: c.images.into_iter().map(|i| (i.id, i)).collect(),
        points3d: points.into_iter().map(|p| (p.id, p)).collect(),
    };
    Ok(SceneModel {
        layout: SceneLayout::Transforms(files.clone()),
        origin: files.main.clone(),
        model,
        image_paths: c.image_paths,
        mask_paths: c.mask_paths,
        held_out,
    })
}
