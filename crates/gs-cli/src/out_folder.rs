//! The output folder of `vagsl train`: a run already there is never overwritten silently,
//! `--force` removes exactly the files vagsl writes into a run folder (and nothing a user put
//! beside them), and a start that fails leaves no empty folder behind.

use anyhow::{Context, Result, bail};
use std::path::Path;

/// The files vagsl writes into a run folder: `train` (configuration, model, report,
/// checkpoint, exposure), `mesh` (mesh and its report) and `eval-images` (its four score files).
pub const RUN_FILES: &[&str] = &[
    "config.json",
    "point_cloud.ply",
    "report.json",
    "checkpoint.bin",
    "exposure.json",
    "mesh.ply",
    "mesh.json",
    "eval_images.json",
    "eval_images_train.json",
    "eval_images_masked.json",
    "eval_images_train_masked.json",
];

/// The folders vagsl writes into a run folder: `render`'s default output.
pub const RUN_FOLDERS: &[&str] = &["renders"];

/// Whether `dir` holds a training run (its configuration or its model).
pub fn holds_run(dir: &Path) -> bool {
    dir.join("config.json").exists() || dir.join("point_cloud.ply").exists()
}

/// Refuses, before any work, an output folder that is a file or holds a run, unless the run is
/// to be replaced (`--force`) or continued (`--resume`).
pub fn check(out: &Path, force: bool, resume: bool) -> Result<()> {
    if out.exists() && !out.is_dir() {
        bail!("{}: exists and is not a folder; give an output folder with -o", out.display());
    }
    if holds_run(out) && !force && !resume {
        bail!(
            "{}: this folder already holds a vagsl run (config.json or point_cloud.ply), which training would overwrite; give another output folder with -o, or pass --force to replace that run",
            out.display()
        );
    }
    Ok(())
}

/// The outputs of later commands derived from a run's model (`mesh`, `eval-images`, `render`):
/// a resumed run replaces the model, so these would describe an older one.
pub const DERIVED_FILES: &[&str] = &[
    "mesh.ply",
    "mesh.json",
    "eval_images.json",
    "eval_images_train.json",
    "eval_images_masked.json",
    "eval_images_train_masked.json",
];

/// Makes `out` ready when training really starts: with `force` the previous run's files
/// ([`RUN_FILES`], [`RUN_FOLDERS`]) are removed, so no stale mesh, checkpoint or renders stay
/// beside the new model; with `resume` the outputs derived from the model being continued
/// ([`DERIVED_FILES`], [`RUN_FOLDERS`]) are removed, for the same reason; then the folder is
/// created if missing.
pub fn prepare(out: &Path, force: bool, resume: bool) -> Result<()> {
    if force {
        let removed = remove_listed(out, RUN_FILES)?;
        if !removed.is_empty() {
            eprintln!("--force: removed the previous run's {} from {}", removed.join(", "), out.display());
        }
    } else if resume {
        let removed = remove_listed(out, DERIVED_FILES)?;
        if !removed.is_empty() {
            eprintln!(
                "--resume: removed the previous model's {} from {} (made from the model this run replaces)",
                removed.join(", "),
                out.display()
            );
        }
    }
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create the output folder", out.display()))
}

/// Removes the listed files and [`RUN_FOLDERS`] found in `dir`; returns their names.
fn remove_listed(dir: &Path, files: &[&str]) -> Result<Vec<String>> {
    let mut removed = Vec::new();
    for name in files {
        let p = dir.join(name);
        if p.is_file() {
            std::fs::remove_file(&p).with_context(|| format!("{}: cannot remove the previous run's file", p.display()))?;
            removed.push(name.to_string());
        }
    }
    for name in RUN_FOLDERS {
        let p = dir.join(name);
        if p.is_dir() {
            std::fs::remove_dir_all(&p).with_context(|| format!("{}: cannot remove the previous run's folder", p.display()))?;
            removed.push(format!("{name}/"));
        }
    }
    Ok(removed)
}
