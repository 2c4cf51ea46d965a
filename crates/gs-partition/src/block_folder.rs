//! A block written as an ordinary scene folder (docs/architecture.md §Partitioned training):
//! `images/` and `masks/` hold symbolic links to the scene's own files (nothing is copied), and
//! `sparse/0/` a COLMAP text model of the block's views and points, so `vagsl train BLOCK`
//! reads it like any scene.

use crate::assign::Members;
use crate::capture::Capture;
use crate::error::{Context, Result};
use gs_io::colmap::{ColmapModel, write_text};
use std::path::{Path, PathBuf};

/// Writes the block of `members` into the new folder `dir`.
pub fn write_block(capture: &Capture, members: &Members, dir: &Path) -> Result<()> {
    let sm = &capture.model;
    let mut model = ColmapModel::default();
    for &v in &members.views {
        let id = capture.ids[v];
        let mut img = sm.model.images[&id].clone();
        // Observations would refer to points the block may not have; the trainer does not use them.
        img.points2d.clear();
        let target = absolute(&sm.image_paths[&id]);
        link(&target, &dir.join("images").join(&img.name))?;
        let mask = sm.mask_paths.get(&id).cloned().or_else(|| gs_io::mask_path(&capture.dir.join("masks"), &img.name));
        if let Some(m) = mask {
            let name = Path::new(&img.name).with_extension("png");
            link(&absolute(&m), &dir.join("masks").join(name))?;
        }
        model.cameras.entry(img.camera_id).or_insert_with(|| sm.model.cameras[&img.camera_id].clone());
        model.images.insert(id, img);
    }
    for &p in &members.points {
        let id = capture.point_ids[p];
        let mut pt = sm.model.points3d[&id].clone();
        pt.track.clear();
        model.points3d.insert(id, pt);
    }
    let sparse = dir.join("sparse").join("0");
    std::fs::create_dir_all(&sparse).with_context(|| format!("{}: cannot create the block's model folder", sparse.display()))?;
    write_text(&model, &sparse)?;
    Ok(())
}

/// `p` absolute and canonical when it exists, so a link works from any folder.
fn absolute(p: &Path) -> PathBuf {
    gs_run::run_config::absolute_scene_path(p)
}

/// A symbolic link at `at` to `target`, creating `at`'s folders.
fn link(target: &Path, at: &Path) -> Result<()> {
    if let Some(parent) = at.parent() {
        std::fs::create_dir_all(parent).with_context(|| format!("{}: cannot create the folder", parent.display()))?;
    }
    #[cfg(unix)]
    let made = std::os::unix::fs::symlink(target, at);
    #[cfg(not(unix))]
    let made = std::fs::hard_link(target, at);
    made.with_context(|| format!("{}: cannot link it to {}", at.display(), target.display()))
}
