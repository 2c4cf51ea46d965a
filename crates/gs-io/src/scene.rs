//! Scene loading: a scene folder → [`gs_core::Scene`] of undistorted PINHOLE views.
//!
//! The folder holds a COLMAP model or a `transforms.json` ([`crate::layout`],
//! [`crate::transforms`]); both become the same [`SceneModel`] ([`read_scene_model`]), so everything
//! below applies to both. COLMAP: `SCENE/sparse/0` (text or binary; `SCENE/sparse` is accepted
//! too), `SCENE/images/<name>`
//! (PNG/JPEG, 8- or 16-bit, grey or RGB(A); values / 255 or / 65535, no gamma; alpha dropped)
//! and optional `SCENE/masks/<stem>.png`. Every image is undistorted to PINHOLE like
//! `colmap image_undistorter` ([`crate::undistort`]), then downscaled (docs/method.md §Inputs:
//! `-r 1|2|4|8`, a target width, or by default to at most 1600 px wide) with an area filter.
//! Images are decoded in parallel with rayon.

use crate::colmap::{ColmapCamera, ColmapModel, ColmapPoint3D, ModelFormat, detect_format, read_model};
use crate::layout::{SceneLayout, SceneModel, detect_layout, find_model_dir};
use crate::photo::image_size;
use crate::error::{IoError, Result};
use crate::undistort::{UndistortMap, UndistortOptions, undistort_camera};
use gs_core::{Camera, Image, Intrinsics, Scene, View};
use rayon::prelude::*;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

pub use crate::photo::{decode_mask, decode_mask_bytes, decode_rgb, decode_rgb_bytes};

/// Default maximum width of the [`Resolution::Auto`] rule (3DGS/PGSR).
pub const AUTO_MAX_WIDTH: u32 = 1600;

/// Output resolution of the loaded views (docs/method.md §Inputs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Resolution {
    /// Downscale images wider than [`AUTO_MAX_WIDTH`] to that width; keep smaller ones.
    #[default]
    Auto,
    /// Divide width and height by this factor (`-r 1|2|4|8`; 1 = full resolution), rounded.
    Factor(u32),
    /// Scale to this width, height keeping the aspect ratio (rounded).
    Width(u32),
}

impl Resolution {
    /// Output size for an (undistorted) image of `width × height`; an error message for a
    /// zero factor or width, and for a target width beyond the photo's: upscaling adds no
    /// detail, only memory (3,000 px asked of 540-px photos once ran a training out of memory).
    pub fn output_size(self, width: u32, height: u32) -> std::result::Result<(u32, u32), String> {
        let scaled = |target_w: f64| {
            let s = target_w / width as f64;
            ((target_w.round() as u32).max(1), ((height as f64 * s).round() as u32).max(1))
        };
        match self {
            Resolution::Auto if width > AUTO_MAX_WIDTH => Ok(scaled(AUTO_MAX_WIDTH as f64)),
            Resolution::Auto => Ok((width, height)),
            Resolution::Factor(0) => Err("resolution factor must be at least 1".into()),
            Resolution::Factor(n) => Ok((
                ((width as f64 / n as f64).round() as u32).max(1),
                ((height as f64 / n as f64).round() as u32).max(1),
            )),
            Resolution::Width(0) => Err("target width must be at least 1".into()),
            Resolution::Width(w) if w > width => Err(format!(
                "target width {w} px is wider than the photo ({width} × {height} px after undistortion); upscaling adds no detail, only memory: ask for at most {width} px"
            )),
            Resolution::Width(w) => Ok(scaled(w as f64)),
        }
    }
}

/// What to do with `SCENE/masks`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MaskPolicy {
    /// Do not load masks.
    Ignore,
    /// Load `masks/<stem>.png` (or `masks/<name>.png`) where it exists.
    #[default]
    IfPresent,
    /// Every view must have a mask; a missing one is an error.
    Require,
}

/// Options of [`load_scene`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LoadOptions {
    /// Output resolution.
    pub resolution: Resolution,
    /// Mask handling.
    pub masks: MaskPolicy,
    /// Undistortion options (COLMAP defaults).
    pub undistort: UndistortOptions,
    /// Images folder relative to the scene (default `images`).
    pub images_dir: Option<PathBuf>,
    /// Load only these image names (all when `None`); an unknown name is an error.
    pub only_images: Option<Vec<String>>,
}

/// The mask file of an image name, if one exists: `masks/<stem>.png`, then `masks/<name>.png`.
pub fn mask_path(masks_dir: &Path, name: &str) -> Option<PathBuf> {
    let rel = Path::new(name);
    let stem = rel.with_extension("png");
    let full = PathBuf::from(format!("{name}.png"));
    [masks_dir.join(stem), masks_dir.join(full)].into_iter().find(|p| p.is_file())
}

/// The camera of a view after undistortion at the file's size, before downscaling.
struct CameraPlan {
    /// The undistorted PINHOLE camera.
    pinhole: ColmapCamera,
    /// The resampling map; `None` when the camera has no distortion.
    map: Option<UndistortMap>,
}

/// Reads the model of the scene folder `dir` in whichever layout it has. `images_dir`
/// (relative to `dir`, default `images`) is where a COLMAP scene's photos lie; a transforms
/// scene names its files itself.
pub fn read_scene_model(dir: &Path, images_dir: Option<&Path>) -> Result<SceneModel> {
    let layout = detect_layout(dir)?;
    match &layout {
        SceneLayout::Colmap { model_dir, .. } => {
            let model = read_model(model_dir)?;
            let images = dir.join(images_dir.unwrap_or(Path::new("images")));
            let image_paths = model.images.values().map(|i| (i.id, images.join(&i.name))).collect();
            Ok(SceneModel {
                origin: model_dir.clone(),
                model,
                image_paths,
                mask_paths: BTreeMap::new(),
                held_out: None,
                layout,
            })
        }
        SceneLayout::Transforms(files) => crate::transforms::read_transforms_scene(files),
    }
}

/// Loads a scene folder, COLMAP or transforms.json (see the module docs), into a [`Scene`]
/// with undistorted, downscaled PINHOLE views sorted by name, the sparse points (colours / 255;
/// none when a transforms scene names no `ply_file_path`, and training then starts from random
/// points) and the scene's own held-out views.
/// Errors name the file: bad models, missing or undecodable images, images whose size does not
/// match their camera (other than a uniform rescale), masks of the wrong size.
pub fn load_scene(scene_dir: &Path, opts: &LoadOptions) -> Result<Scene> {
    let sm = read_scene_model(scene_dir, opts.images_dir.as_deref())?;
    let (model, model_dir) = (&sm.model, &sm.origin);
    let masks_dir = scene_dir.join("masks");

    let mut selected: Vec<&crate::colmap::ColmapImage> = match &opts.only_images {
        None => model.images.values().collect(),
        Some(names) => names
            .iter()
            .map(|n| {
                model.images.values().find(|i| &i.name == n).ok_or_else(|| {
                    IoError::invalid(model_dir, format!("image '{n}' is not in the model"))
                })
            })
            .collect::<Result<_>>()?,
    };
    selected.sort_by(|a, b| a.name.cmp(&b.name));
    if let Some(w) = selected.windows(2).find(|w| w[0].name == w[1].name) {
        return Err(IoError::invalid(model_dir, format!("image '{}' is selected twice", w[0].name)));
    }

    // Pass 1 (headers only): file sizes, so cameras can be matched to the files' resolution.
    let sizes: Vec<(PathBuf, (u32, u32))> = selected
        .iter()
        .map(|img| {
            let p = sm.image_paths[&img.id].clone();
            image_size(&p).map(|s| (p, s))
        })
        .collect::<Result<_>>()?;

    // One undistortion plan per (camera, file size).
    let mut plans: HashMap<(u32, u32, u32), CameraPlan> = HashMap::new();
    for (img, (path, (w, h))) in selected.iter().zip(&sizes) {
        let key = (img.camera_id, *w, *h);
        if plans.contains_key(&key) {
            continue;
        }
        let cam = &model.cameras[&img.camera_id];
        let cam = if (cam.width, cam.height) == (*w, *h) {
            cam.clone()
        } else {
            // Accept a uniformly rescaled image folder (e.g. half-size images).
            let (cw, ch) = (cam.width as u64, cam.height as u64);
            let mismatch = (*w as u64 * ch).abs_diff(*h as u64 * cw);
            if mismatch > cw.max(ch) {
                return Err(IoError::invalid(
                    path,
                    format!(
                        "image is {w}x{h} but its camera {} is {}x{} (not a uniform rescale)",
                        cam.id, cam.width, cam.height
                    ),
                ));
            }
            cam.rescaled(*w, *h)
        };
        let pinhole = undistort_camera(&cam, &opts.undistort).map_err(|m| IoError::invalid(model_dir, m))?;
        let map = (!cam.is_undistorted()).then(|| UndistortMap::new(&cam, &pinhole));
        plans.insert(key, CameraPlan { pinhole, map });
    }

    // Pass 2: decode, undistort and downscale in parallel.
    let views: Vec<View> = selected
        .par_iter()
        .zip(sizes.par_iter())
        .map(|(img, (path, (w, h)))| -> Result<View> {
            let plan = &plans[&(img.camera_id, *w, *h)];
            let (uw, uh) = (plan.pinhole.width, plan.pinhole.height);
            let (ow, oh) = opts.resolution.output_size(uw, uh).map_err(|m| IoError::invalid(path, m))?;
            let [fx, fy, cx, cy] = plan.pinhole.pinhole();
            let core = |e| IoError::Core { path: path.clone(), source: e };
            let camera = Camera::from_quaternion(uw, uh, Intrinsics::new(fx, fy, cx, cy), img.qvec, img.tvec)
                .and_then(|c| c.resized(ow, oh))
                .map_err(core)?;
            let prepare = |decoded: Image, file: &Path| -> Result<Image> {
                let undistorted = match &plan.map {
                    Some(map) => map.apply(&decoded).map_err(|m| IoError::invalid(file, m))?,
                    None => decoded,
                };
                if (ow, oh) == (uw, uh) {
                    Ok(undistorted)
                } else {
                    undistorted
                        .resize_area(ow as usize, oh as usize)
                        .map_err(|e| IoError::Core { path: file.to_path_buf(), source: e })
                }
            };
            let image = prepare(decode_rgb(path)?, path)?;
            let mask = match opts.masks {
                MaskPolicy::Ignore => None,
                policy => match sm.mask_paths.get(&img.id).cloned().or_else(|| mask_path(&masks_dir, &img.name)) {
                    Some(mp) => {
                        let m = decode_mask(&mp)?;
                        if (m.width(), m.height()) != (*w as usize, *h as usize) {
                            return Err(IoError::invalid(
                                &mp,
                                format!("mask is {}x{} but its image is {w}x{h}", m.width(), m.height()),
                            ));
                        }
                        let mut m = prepare(m, &mp)?;
                        for v in m.data_mut() {
                            *v = if *v >= 0.5 { 1.0 } else { 0.0 };
                        }
                        Some(m)
                    }
                    None if policy == MaskPolicy::Require => {
                        return Err(IoError::invalid(
                            masks_dir.join(Path::new(&img.name).with_extension("png")),
                            "missing mask file",
                        ));
                    }
                    None => None,
                },
            };
            Ok(View { name: img.name.clone(), camera, image, mask })
        })
        .collect::<Result<_>>()?;

    let points = model.points3d.values().map(ColmapPoint3D::scene_point).collect();
    Ok(Scene { views, points, held_out: sm.held_out.clone() })
}

/// Per-camera line of a [`ModelSummary`].
#[derive(Debug, Clone, PartialEq)]
pub struct CameraSummary {
    /// Camera id.
    pub id: u32,
    /// Model name.
    pub model: &'static str,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Whether the camera has no distortion.
    pub undistorted: bool,
}

/// Counts and statistics of a model, for `vagsl info` (no image is decoded).
#[derive(Debug, Clone, PartialEq)]
pub struct ModelSummary {
    /// The model folder that was read.
    pub model_dir: PathBuf,
    /// Text or binary.
    pub format: ModelFormat,
    /// Cameras.
    pub cameras: Vec<CameraSummary>,
    /// Number of registered images.
    pub num_images: usize,
    /// Number of 3D points.
    pub num_points: usize,
    /// Number of track entries.
    pub num_observations: usize,
    /// Mean track length.
    pub mean_track_length: f64,
    /// Mean reprojection error in pixels with the distortion model, if there are observations.
    pub mean_reprojection_error: Option<f64>,
}

/// Reads and summarises the model of a scene or model folder (see [`find_model_dir`]).
pub fn model_summary(dir: &Path) -> Result<ModelSummary> {
    let model_dir = find_model_dir(dir)?;
    let format = detect_format(&model_dir)?;
    let model: ColmapModel = read_model(&model_dir)?;
    Ok(ModelSummary {
        format,
        cameras: model
            .cameras
            .values()
            .map(|c| CameraSummary {
                id: c.id,
                model: c.model.name(),
                width: c.width,
                height: c.height,
                undistorted: c.is_undistorted(),
            })
            .collect(),
        num_images: model.images.len(),
        num_points: model.points3d.len(),
        num_observations: model.num_observations(),
        mean_track_length: model.mean_track_length(),
        mean_reprojection_error: model.mean_reprojection_error(),
        model_dir,
    })
}

impl std::fmt::Display for ModelSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let fmt = match self.format {
            ModelFormat::Text => "text",
            ModelFormat::Binary => "binary",
        };
        writeln!(f, "model: {} ({fmt})", self.model_dir.display())?;
        writeln!(f, "images: {}, points: {}, observations: {}", self.num_images, self.num_points, self.num_observations)?;
        writeln!(f, "mean track length: {:.3}", self.mean_track_length)?;
        match self.mean_reprojection_error {
            Some(e) => writeln!(f, "mean reprojection error: {e:.4} px")?,
            None => writeln!(f, "mean reprojection error: n/a (no observations)")?,
        }
        // Group identical camera lines (many datasets have one camera per image).
        let mut groups: Vec<(&CameraSummary, usize)> = Vec::new();
        for c in &self.cameras {
            match groups.iter_mut().find(|(g, _)| (g.model, g.width, g.height) == (c.model, c.width, c.height)) {
                Some((_, n)) => *n += 1,
                None => groups.push((c, 1)),
            }
        }
        writeln!(f, "cameras: {}", self.cameras.len())?;
        for (c, n) in groups {
            let d = if c.undistorted { "no distortion" } else { "distorted" };
            writeln!(f, "  {n} × {} {}x{} ({d})", c.model, c.width, c.height)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolution_rules() {
        assert_eq!(Resolution::Auto.output_size(800, 600).unwrap(), (800, 600));
        assert_eq!(Resolution::Auto.output_size(3200, 2400).unwrap(), (1600, 1200));
        assert_eq!(Resolution::Auto.output_size(1601, 1000).unwrap(), (1600, 999));
        assert_eq!(Resolution::Factor(1).output_size(3200, 2400).unwrap(), (3200, 2400));
        assert_eq!(Resolution::Factor(2).output_size(539, 959).unwrap(), (270, 480));
        assert_eq!(Resolution::Factor(8).output_size(480, 360).unwrap(), (60, 45));
        assert_eq!(Resolution::Width(240).output_size(480, 360).unwrap(), (240, 180));
        assert!(Resolution::Factor(0).output_size(10, 10).is_err());
        assert!(Resolution::Width(0).output_size(10, 10).is_err());
        assert_eq!(Resolution::Width(480).output_size(480, 360).unwrap(), (480, 360));
        let e = Resolution::Width(3000).output_size(540, 960).unwrap_err();
        assert!(e.contains("3000 px is wider than the photo (540 × 960 px"), "{e}");
    }
}
