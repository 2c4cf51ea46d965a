//! Where a scene's model and images live.

use anyhow::{Result, bail};
use std::path::{Path, PathBuf};

/// The COLMAP model folder of `path`: `path/sparse/0`, `path/sparse`, or `path` itself,
/// whichever holds a model.
pub fn model_dir(path: &Path) -> Result<PathBuf> {
    if !path.exists() {
        bail!("{}: no such file or folder", path.display());
    }
    for candidate in [path.join("sparse").join("0"), path.join("sparse"), path.to_path_buf()] {
        if gs_io::colmap::detect_format(&candidate).is_ok() {
            return Ok(candidate);
        }
    }
    bail!(
        "{}: no COLMAP model found (looked in sparse/0, sparse and the folder itself for cameras/images/points3D .txt or .bin)",
        path.display()
    )
}

/// The images folder of a scene whose model lies in `model_dir`: `SCENE/images` for a
/// `SCENE/sparse/0` model.
pub fn images_dir(scene: &Path, model_dir: &Path) -> Option<PathBuf> {
    let mut candidates = vec![scene.join("images")];
    if let Some(parent) = model_dir.parent() {
        candidates.push(parent.join("images"));
        if let Some(grand) = parent.parent() {
            candidates.push(grand.join("images"));
        }
    }
    candidates.into_iter().find(|p| p.is_dir())
}
