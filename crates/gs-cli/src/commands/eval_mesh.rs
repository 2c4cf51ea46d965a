//! `vagsl eval-mesh`: accuracy, completeness, Chamfer and F1 of a mesh against a ground truth
//! (docs/method.md §Metrics), with area-weighted sampling and kd-tree distances (gs-tsdf).

use anyhow::{Context, Result, bail};
use gs_core::TriangleMesh;
use gs_tsdf::{Aabb, EvalOptions, evaluate_meshes};
use std::path::{Path, PathBuf};

/// Options of `vagsl eval-mesh`.
#[derive(Debug, Clone, clap::Args)]
pub struct EvalMeshArgs {
    /// Predicted mesh (PLY or OBJ).
    #[arg(long)]
    pub pred: PathBuf,
    /// Ground-truth mesh (PLY or OBJ).
    #[arg(long)]
    pub gt: PathBuf,
    /// Threshold τ of precision / recall / F1 (default: 0.5 % of the GT bounding-box diagonal).
    #[arg(long)]
    pub tau: Option<f64>,
    /// Points sampled uniformly by area on each mesh.
    #[arg(long, default_value_t = EvalOptions::DEFAULT_SAMPLES)]
    pub samples: usize,
    /// Crop the prediction to the GT's bounding box expanded by this fraction of its size per
    /// side (the object protocol uses 0.05).
    #[arg(long, value_parser = parse_crop, allow_hyphen_values = true)]
    pub crop_to_gt: Option<f64>,
    /// With --crop-to-gt: also drop everything below this z (e.g. a floor at z = 0: 0.005).
    #[arg(long)]
    pub min_z: Option<f64>,
    /// Clamp distances at this value before averaging (DTU: 20 mm).
    #[arg(long)]
    pub max_distance: Option<f64>,
    /// Seed of the sampling.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

/// `--crop-to-gt`: a finite fraction above -0.5 (at -0.5 the box shrinks to nothing).
fn parse_crop(s: &str) -> std::result::Result<f64, String> {
    let f: f64 = s.trim().parse().map_err(|e| format!("'{s}': {e}"))?;
    if !f.is_finite() || f <= -0.5 {
        return Err(format!(
            "'{s}': the ground truth's box grows by this fraction of its size on each side, so it must be a finite number above -0.5 (below, the box is empty); the object protocol uses 0.05"
        ));
    }
    Ok(f)
}

/// Reads a PLY or OBJ triangle mesh.
pub fn read_mesh(path: &Path) -> Result<TriangleMesh> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_lowercase());
    Ok(match ext.as_deref() {
        Some("obj") => gs_io::read_obj(path)?,
        Some("ply") => gs_io::read_mesh_ply(path)?,
        _ => bail!("{}: unknown mesh format (PLY or OBJ expected)", path.display()),
    })
}

/// Runs `vagsl eval-mesh`; a mesh inside a run folder gets its scores saved there as
/// `eval_mesh.json` (shown by `vagsl view`).
pub fn run(args: &EvalMeshArgs) -> Result<()> {
    let saved_in = args.pred.parent().filter(|d| gs_run::run_folder::holds_run(d));
    if let Some(run) = saved_in {
        // A link, device or folder in the scores' place is refused before the work.
        gs_io::check_output_path(&run.join("eval_mesh.json"))?;
    }
    let pred = read_mesh(&args.pred)?;
    let gt = read_mesh(&args.gt)?;
    let b = Aabb::of_mesh(&gt).with_context(|| format!("{}: the ground-truth mesh has no vertices", args.gt.display()))?;
    let crop = args.crop_to_gt.map(|f| b.grown(f, args.min_z));
    if args.min_z.is_some() && crop.is_none() {
        bail!("--min-z applies with --crop-to-gt");
    }
    let defaults = EvalOptions::for_gt(&b, crop);
    let opts = EvalOptions {
        samples: args.samples,
        tau: args.tau.unwrap_or(defaults.tau),
        max_distance: args.max_distance,
        seed: args.seed,
        ..defaults
    };
    let report = evaluate_meshes(&pred, &gt, &opts)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        let m = &report.metrics;
        println!("accuracy     {:.6} (pred → GT, mean)", m.accuracy);
        println!("completeness {:.6} (GT → pred, mean)", m.completeness);
        println!("chamfer      {:.6}", m.chamfer);
        println!("precision {:.4} recall {:.4} F1 {:.4} at τ = {:.6}", m.precision, m.recall, m.f1, m.tau);
    }
    // A run's own mesh keeps its scores beside it, for `vagsl view` (after printing them, so a
    // read-only folder does not cost the numbers).
    if let Some(run) = saved_in {
        let mut saved = serde_json::to_value(&report.metrics)?;
        saved["ground_truth"] = serde_json::Value::from(gs_run::run_config::absolute_scene_path(&args.gt).display().to_string());
        // The scores describe the mesh, so they carry the record of the model it came from.
        if let Some(m) = gs_run::provenance::read_made_from(&args.pred.with_extension("json")) {
            saved["made_from"] = serde_json::to_value(m)?;
        }
        gs_run::write_json(&run.join("eval_mesh.json"), &saved)
            .map_err(|e| anyhow::Error::new(e).context("the scores above were computed but could not be saved"))?;
    }
    Ok(())
}
