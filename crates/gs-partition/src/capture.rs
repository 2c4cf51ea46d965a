//! The capture to partition, read without decoding a photo (docs/architecture.md
//! §Partitioned training): its model (cameras, poses, sparse points, image and mask files) and
//! the train/test split the whole scene would have, so no block ever trains on a view the
//! merged run is scored on.

use crate::error::{Result, refuse};
use glam::DVec3;
use gs_core::{Camera, Intrinsics};
use gs_io::SceneModel;
use gs_run::SceneSource;
use std::path::{Component, Path};

/// A scene's model with its cameras as [`Camera`]s, views sorted by name.
pub struct Capture {
    /// The scene folder.
    pub dir: std::path::PathBuf,
    /// The model as read (COLMAP folder or transforms.json).
    pub model: SceneModel,
    /// Image ids, sorted by image name.
    pub ids: Vec<u32>,
    /// The pinhole camera of each view (in `ids` order), at the files' size; distortion is
    /// left out, which moves a point by at most a few pixels — enough to decide visibility.
    pub cameras: Vec<Camera>,
    /// Sparse point positions (in the model's id order) and their ids.
    pub points: Vec<DVec3>,
    /// Ids of `points`.
    pub point_ids: Vec<u64>,
    /// Indices (into `ids`) of the views that train.
    pub train: Vec<usize>,
    /// Names of the views the whole scene holds out (empty without `eval`).
    pub held_out: Vec<String>,
}

impl Capture {
    /// Reads the scene of `source` (a folder: the built-in scene has none to partition).
    pub fn read(source: &SceneSource) -> Result<Self> {
        let Some(dir) = &source.path else {
            refuse!("the built-in scene has no folder to partition; write it with `vagsl synth -o DIR`, or give a scene folder")
        };
        let model = gs_io::read_scene_model(dir, None)?;
        let mut ids: Vec<u32> = model.model.images.keys().copied().collect();
        ids.sort_by(|a, b| model.model.images[a].name.cmp(&model.model.images[b].name));
        let mut cameras = Vec::with_capacity(ids.len());
        for id in &ids {
            let img = &model.model.images[id];
            if !is_plain_relative(Path::new(&img.name)) {
                refuse!("{}: image '{}' is not a plain relative file name; a block cannot link it", model.origin.display(), img.name);
            }
            let Some(cam) = model.model.cameras.get(&img.camera_id) else {
                refuse!("{}: image '{}' names camera {}, which the model does not have", model.origin.display(), img.name, img.camera_id)
            };
            let [fx, fy, cx, cy] = cam.pinhole();
            cameras.push(Camera::from_quaternion(cam.width, cam.height, Intrinsics::new(fx, fy, cx, cy), img.qvec, img.tvec)?);
        }
        let names: Vec<&str> = ids.iter().map(|id| model.model.images[id].name.as_str()).collect();
        let (train, test) = gs_core::split_names(&names, model.held_out.as_deref(), source.eval);
        let held_out = test.iter().map(|&i| names[i].to_string()).collect();
        let point_ids: Vec<u64> = model.model.points3d.keys().copied().collect();
        let points = point_ids.iter().map(|id| DVec3::from_array(model.model.points3d[id].xyz)).collect();
        Ok(Self { dir: dir.clone(), model, ids, cameras, points, point_ids, train, held_out })
    }

    /// The name of view `i`.
    pub fn name(&self, i: usize) -> &str {
        &self.model.model.images[&self.ids[i]].name
    }

    /// Pixels of view `i` at the files' size.
    pub fn pixels(&self, i: usize) -> f64 {
        self.cameras[i].width as f64 * self.cameras[i].height as f64
    }
}

/// Whether `p` is a non-empty relative path of plain names (no `..`, no root).
pub(crate) fn is_plain_relative(p: &Path) -> bool {
    !p.as_os_str().is_empty() && p.components().all(|c| matches!(c, Component::Normal(_)))
}
