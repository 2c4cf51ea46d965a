//! The output folder of `vagsl train`: a run already there is never overwritten silently,
//! `--force` removes exactly the files vagsl writes into a run folder (and nothing a user put
//! beside them), and a start that fails leaves no empty folder behind.

use anyhow::{Context, Result, bail};
use std::path::Path;

/// The files vagsl writes into a run folder: `train` (configuration, model, report,
/// checkpoint, exposure, curves), `mesh` (mesh and its report), `eval-images` (its four score
/// files), `eval-mesh` (its scores of the run's mesh) and `view` (the report page).
pub const RUN_FILES: &[&str] = &[
    "config.json",
    "point_cloud.ply",
    "report.json",
    "checkpoint.bin",
    "metrics.jsonl",
    "exposure.json",
    "mesh.ply",
    "mesh.json",
    "eval_images.json",
    "eval_images_train.json",
    "eval_images_masked.json",
    "eval_images_train_masked.json",
    "eval_mesh.json",
    "report.html",
];

/// The folders vagsl writes into a run folder: `render`'s default output and the report
/// page's images and data.
pub const RUN_FOLDERS: &[&str] = &["renders", "report"];

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

/// The files `train` itself writes or continues (configuration, model, report, checkpoint,
/// curves, exposure); every other file of [`RUN_FILES`] is made by a later command from the
/// model (`mesh`, `eval-images`, `eval-mesh`, `view`).
pub const TRAIN_FILES: &[&str] = &["config.json", "point_cloud.ply", "report.json", "checkpoint.bin", "metrics.jsonl", "exposure.json"];

/// The files of [`RUN_FILES`] derived from a run's model: a resumed run replaces the model, so
/// these would describe an older one.
pub fn derived_files() -> Vec<&'static str> {
    RUN_FILES.iter().copied().filter(|f| !TRAIN_FILES.contains(f)).collect()
}

/// Makes `out` ready when training really starts: with `force` the previous run's files
/// ([`RUN_FILES`], [`RUN_FOLDERS`]) are removed, so no stale mesh, checkpoint or renders stay
/// beside the new model; with `resume` the outputs derived from the model being continued
/// ([`derived_files`], [`RUN_FOLDERS`]) are removed, for the same reason; then the folder is
/// created if missing.
pub fn prepare(out: &Path, force: bool, resume: bool) -> Result<()> {
    if force {
        let removed = remove_listed(out, RUN_FILES)?;
        if !removed.is_empty() {
            eprintln!("--force: removed the previous run's {} from {}", removed.join(", "), out.display());
        }
    } else if resume {
        let removed = remove_listed(out, &derived_files())?;
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
