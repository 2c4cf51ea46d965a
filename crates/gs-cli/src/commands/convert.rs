//! `vagsl convert`: COLMAP text ↔ binary.

use crate::scene_path::model_dir;
use anyhow::{Context, Result};
use std::path::Path;

/// Output format of `convert`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// `cameras.txt`, `images.txt`, `points3D.txt`.
    Text,
    /// `cameras.bin`, `images.bin`, `points3D.bin`.
    Bin,
}

/// Reads the model under `model` (any format) and writes it to `output` (default: the same
/// folder) in `to`; every file is written atomically.
pub fn run(model: &Path, to: Format, output: Option<&Path>) -> Result<()> {
    let dir = model_dir(model)?;
    let data = gs_io::colmap::read_model(&dir)?;
    let out = output.map(Path::to_path_buf).unwrap_or_else(|| dir.clone());
    std::fs::create_dir_all(&out).with_context(|| format!("{}: cannot create output folder", out.display()))?;
    match to {
        Format::Text => gs_io::colmap::write_text(&data, &out)?,
        Format::Bin => gs_io::colmap::write_binary(&data, &out)?,
    }
    println!(
        "wrote {} model ({} cameras, {} images, {} points) to {}",
        match to {
            Format::Text => "text",
            Format::Bin => "binary",
        },
        data.cameras.len(),
        data.images.len(),
        data.points3d.len(),
        out.display()
    );
    Ok(())
}
