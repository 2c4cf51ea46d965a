//! `vagsl convert`: COLMAP text ↔ binary, COLMAP → transforms.json and transforms.json → COLMAP.

use crate::scene_path::{images_dir, model_dir};
use anyhow::{Context, Result, bail};
use gs_io::colmap::ColmapModel;
use gs_io::{SceneLayout, detect_layout};
use std::path::{Path, PathBuf};

/// Output format of `convert`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// `cameras.txt`, `images.txt`, `points3D.txt`.
    Text,
    /// `cameras.bin`, `images.bin`, `points3D.bin`.
    Bin,
    /// `transforms.json` (nerfstudio / instant-ngp) plus the points as `sparse_pc.ply`.
    Transforms,
}

/// Converts the scene or model at `input` to `to`, writing into `output` (created if missing);
/// every file is written atomically.
///
/// - COLMAP → text / bin: into `output`, default the input model folder (lossless).
/// - COLMAP → transforms: `output/transforms.json` + `sparse_pc.ply`, default the scene folder
///   (the parent of its `images/`). Photos are referenced, never copied: as `images/NAME`, where
///   `output/images` is the scene's images folder or a symbolic link to it made here.
/// - transforms → text / bin: a COLMAP model (cameras, poses, points; no observations, no
///   split) into `output`, default `SCENE/sparse/0`. A COLMAP scene finds its photos at
///   `SCENE/images/NAME`; photos elsewhere are reported.
pub fn run(input: &Path, to: Format, output: Option<&Path>) -> Result<()> {
    if let Ok(dir) = model_dir(input) {
        let data = gs_io::colmap::read_model(&dir)?;
        return match to {
            Format::Transforms => colmap_to_transforms(input, &dir, &data, output),
            _ => write_colmap(&data, to, &output.map_or(dir.clone(), Path::to_path_buf)),
        };
    }
    if !input.exists() {
        bail!("{}: no such file or folder", input.display());
    }
    let SceneLayout::Transforms(files) = detect_layout(input)? else {
        bail!("{}: unreadable COLMAP model", input.display());
    };
    if to == Format::Transforms {
        bail!("{}: the scene is already in the transforms.json layout", input.display());
    }
    let sm = gs_io::transforms::read_transforms_scene(&files)?;
    let out = output.map_or_else(|| input.join("sparse").join("0"), Path::to_path_buf);
    write_colmap(&sm.model, to, &out)?;
    let images = input.join("images");
    let elsewhere: Vec<&str> = sm
        .model
        .images
        .values()
        .filter(|i| !same_file(&images.join(&i.name), &sm.image_paths[&i.id]))
        .map(|i| i.name.as_str())
        .collect();
    if let Some(first) = elsewhere.first() {
        eprintln!(
            "warning: {} of {} photos do not lie at {}/NAME (e.g. '{first}'); a COLMAP scene looks for them there",
            elsewhere.len(),
            sm.model.images.len(),
            images.display()
        );
    }
    Ok(())
}

fn same_file(a: &Path, b: &Path) -> bool {
    matches!((std::fs::canonicalize(a), std::fs::canonicalize(b)), (Ok(x), Ok(y)) if x == y)
}

/// Writes `data` as a COLMAP model in `to` (text or binary) into `out`.
fn write_colmap(data: &ColmapModel, to: Format, out: &Path) -> Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create output folder", out.display()))?;
    let kind = match to {
        Format::Bin => {
            gs_io::colmap::write_binary(data, out)?;
            "binary"
        }
        _ => {
            gs_io::colmap::write_text(data, out)?;
            "text"
        }
    };
    println!(
        "wrote {kind} model ({} cameras, {} images, {} points) to {}",
        data.cameras.len(),
        data.images.len(),
        data.points3d.len(),
        out.display()
    );
    Ok(())
}

/// Writes `out/transforms.json` (+ `sparse_pc.ply`) for the COLMAP model `data` of the scene
/// `input`, with `out/images` leading to the scene's photos.
fn colmap_to_transforms(input: &Path, model_dir: &Path, data: &ColmapModel, output: Option<&Path>) -> Result<()> {
    let images = images_dir(input, model_dir)
        .with_context(|| format!("{}: no images folder found beside the model; transforms.json must name the photos", input.display()))?;
    let images = std::fs::canonicalize(&images).with_context(|| format!("{}: cannot resolve", images.display()))?;
    let scene_root = images.parent().map_or_else(|| images.clone(), Path::to_path_buf);
    let out: PathBuf = output.map_or(scene_root, Path::to_path_buf);
    std::fs::create_dir_all(&out).with_context(|| format!("{}: cannot create output folder", out.display()))?;
    let link = out.join("images");
    if link.symlink_metadata().is_ok() {
        if !same_file(&link, &images) {
            bail!(
                "{}: already exists and is not the scene's images folder {}; choose another output folder",
                link.display(),
                images.display()
            );
        }
    } else {
        link_folder(&images, &link)?;
    }
    gs_io::transforms::write_transforms(data, &out, "images")?;
    println!(
        "wrote transforms.json ({} frames, {} cameras, {} points in {}) to {}; photos in {}",
        data.images.len(),
        data.cameras.len(),
        data.points3d.len(),
        gs_io::transforms::POINTS_FILE,
        out.display(),
        images.display()
    );
    Ok(())
}

#[cfg(unix)]
fn link_folder(target: &Path, link: &Path) -> Result<()> {
    std::os::unix::fs::symlink(target, link)
        .with_context(|| format!("{}: cannot link to the photos in {}", link.display(), target.display()))
}

#[cfg(not(unix))]
fn link_folder(target: &Path, link: &Path) -> Result<()> {
    bail!(
        "{}: linking to the photos in {} needs a Unix system; write transforms.json into the scene folder (omit -o)",
        link.display(),
        target.display()
    )
}
