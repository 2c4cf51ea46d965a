//! Which layout a scene folder has, and its model before any image is decoded.
//!
//! A scene folder holds either a COLMAP sparse model (`sparse/0`, `sparse` or the folder
//! itself, with `images/`) or a nerfstudio / instant-ngp `transforms.json` (or the Blender
//! synthetic `transforms_train.json` + `transforms_test.json`). When both are present the
//! COLMAP model wins: it is usually the original (it carries the observations), and a
//! `transforms.json` beside it was most often derived from it. Within the transforms layout a
//! `transforms.json` wins over the split files; `transforms_val.json` is not read (as in 3DGS).

use crate::colmap::{ColmapModel, ModelFormat, detect_format};
use crate::error::{IoError, Result};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The files of a scene in the transforms layout.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TransformsFiles {
    /// `transforms.json`, or `transforms_train.json`.
    pub main: PathBuf,
    /// `transforms_test.json` beside a `transforms_train.json`: its frames are the held-out views.
    pub test: Option<PathBuf>,
}

/// The layout of a scene folder.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SceneLayout {
    /// A COLMAP model in this folder, in this format.
    Colmap {
        /// The model folder.
        model_dir: PathBuf,
        /// Text or binary.
        format: ModelFormat,
    },
    /// A transforms.json scene.
    Transforms(TransformsFiles),
}

impl SceneLayout {
    /// The layout in words: `COLMAP text`, `COLMAP binary` or `transforms.json`.
    pub fn describe(&self) -> &'static str {
        match self {
            SceneLayout::Colmap { format: ModelFormat::Text, .. } => "COLMAP text",
            SceneLayout::Colmap { format: ModelFormat::Binary, .. } => "COLMAP binary",
            SceneLayout::Transforms(_) => "transforms.json",
        }
    }
}

/// Detects the layout of `dir` (see the module docs); an error naming the folder and both
/// expected layouts when it has neither.
pub fn detect_layout(dir: &Path) -> Result<SceneLayout> {
    if !dir.is_dir() {
        return Err(IoError::invalid(dir, "scene folder does not exist"));
    }
    if let Ok(model_dir) = find_model_dir(dir) {
        let format = detect_format(&model_dir)?;
        return Ok(SceneLayout::Colmap { model_dir, format });
    }
    let main = dir.join("transforms.json");
    if main.is_file() {
        return Ok(SceneLayout::Transforms(TransformsFiles { main, test: None }));
    }
    let train = dir.join("transforms_train.json");
    if train.is_file() {
        let test = Some(dir.join("transforms_test.json")).filter(|p| p.is_file());
        return Ok(SceneLayout::Transforms(TransformsFiles { main: train, test }));
    }
    Err(IoError::invalid(
        dir,
        "no COLMAP model and no transforms.json here: expected either a COLMAP model (cameras, images and \
         points3D .bin or .txt in sparse/0, sparse or the folder itself, photos in images/) or a \
         transforms.json (or transforms_train.json + transforms_test.json)",
    ))
}

/// A scene's model in either layout, before any image is decoded: the cameras, poses and
/// points as a [`ColmapModel`] (one source of truth for both layouts), where each image and
/// mask file lies, and the scene's own held-out views.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneModel {
    /// The layout it was read from.
    pub layout: SceneLayout,
    /// The file or folder errors about the model name (model folder or JSON file).
    pub origin: PathBuf,
    /// Cameras, images (names, poses) and points; transforms scenes have no observations.
    pub model: ColmapModel,
    /// The image file of each image id.
    pub image_paths: BTreeMap<u32, PathBuf>,
    /// Mask files given explicitly per image (`mask_path` of a transforms frame).
    pub mask_paths: BTreeMap<u32, PathBuf>,
    /// Names of the views the files hold out (see [`gs_core::Scene::held_out`]).
    pub held_out: Option<Vec<String>>,
}

/// The COLMAP model folder of a scene: `dir` itself when it holds a model, else
/// `dir/sparse/0`, else `dir/sparse`.
pub fn find_model_dir(dir: &Path) -> Result<PathBuf> {
    for cand in [dir.to_path_buf(), dir.join("sparse").join("0"), dir.join("sparse")] {
        if cand.is_dir() && detect_format(&cand).is_ok() {
            return Ok(cand);
        }
    }
    Err(IoError::invalid(dir, "no COLMAP model found (looked in ., sparse/0 and sparse)"))
}
