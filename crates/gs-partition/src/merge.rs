//! `vagsl merge` as a library call (docs/architecture.md §Partitioned training): every block's
//! run is checked — trained to its last iteration, on this plan's block scene, with the same
//! settings as the others — and its Gaussians inside the block's core region are kept. The
//! cores tile the ground plane, so each place is modelled by exactly one block, the one whose
//! views surround it. The result is an ordinary run of the whole scene: `mesh`, `render`,
//! `eval-images` and `view` open it like any other.

use crate::error::{Context, Result, refuse};
use crate::ground::GroundFrame;
use crate::plan::{Block, Plan};
use crate::regions::Region;
use glam::DVec3;
use gs_core::{Gaussians, Scene};
use gs_run::{MadeFrom, RunConfig, SceneFingerprint};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// What the merge took from one block.
#[derive(Debug, Clone, Serialize)]
pub struct BlockSummary {
    /// The block's index.
    pub index: usize,
    /// Its run folder.
    pub run: PathBuf,
    /// Its views.
    pub views: usize,
    /// Iterations it trained.
    pub iterations: u64,
    /// Gaussians its run ended with.
    pub gaussians_trained: usize,
    /// Gaussians inside its core region, kept.
    pub gaussians_kept: usize,
    /// Wall seconds of its training loop (its report's `train_seconds`).
    pub train_seconds: f64,
    /// Peak resident memory of its training, bytes (its report's), if known.
    pub peak_memory_bytes: Option<u64>,
    /// Its training memory estimate, bytes (the plan's).
    pub estimate_bytes: u64,
    /// Its core region: the merged model's Gaussians there are this block's, and `vagsl mesh`
    /// fuses the merged run block by block over these regions.
    pub core: Region,
}

/// `OUT/report.json` of a merged run.
#[derive(Debug, Clone, Serialize)]
pub struct MergeReport {
    /// The merged run's id and model fingerprint (the provenance record of its files).
    #[serde(flatten)]
    pub made_from: MadeFrom,
    /// The plan folder merged.
    pub plan: PathBuf,
    /// The ground frame the blocks' core regions are drawn in.
    pub frame: GroundFrame,
    /// Iterations of the plan's settings for the whole scene (each block trained its share,
    /// listed per block).
    pub iterations: u64,
    /// Always false: a merge takes only finished blocks.
    pub interrupted: bool,
    /// Gaussians of the merged model.
    pub gaussians: usize,
    /// SH degree of the merged model.
    pub sh_degree: u32,
    /// Sum of the blocks' training times, seconds (the work; the wall time depends on how many ran at once).
    pub train_seconds: f64,
    /// The longest block's training time, seconds (the wall time with every block at once).
    pub longest_block_seconds: f64,
    /// The largest peak memory of a block's training, bytes, if every block reports one.
    pub peak_memory_bytes: Option<u64>,
    /// Seconds the merge took (checks, cropping, loading the scene).
    pub merge_seconds: f64,
    /// Per block.
    pub blocks: Vec<BlockSummary>,
}

/// A merged run, ready to write.
pub struct Merged {
    /// Its `config.json`.
    pub config: RunConfig,
    /// Its model.
    pub gaussians: Gaussians,
    /// Its `report.json`.
    pub report: MergeReport,
}

/// Checks the run of `block` and returns its configuration, model and report fields.
fn open_block(plan_dir: &Path, block: &Block) -> Result<(RunConfig, Gaussians, serde_json::Value)> {
    let name = block.name();
    let dir = plan_dir.join(&block.run);
    let retrain = format!("train it with `bash {}/run-block.sh {}`", plan_dir.display(), block.index);
    if !gs_run::run_folder::holds_run(&dir) {
        refuse!("block {name}: no run in {}; {retrain} (or submit {}/slurm.sbatch)", dir.display(), plan_dir.display());
    }
    let (config, gaussians) = gs_run::read_run_model(&dir).with_context(|| format!("block {name}: its run in {} cannot be merged", dir.display()))?;
    let report_path = dir.join("report.json");
    let report: serde_json::Value = gs_io::read_capped(&report_path, gs_io::JSON_CAP, "a run report")
        .ok()
        .and_then(|t| serde_json::from_slice(&t).ok())
        .unwrap_or(serde_json::Value::Null);
    let iterations = report.get("iterations").and_then(|v| v.as_u64());
    if report.get("interrupted").and_then(|v| v.as_bool()) != Some(false) || iterations != Some(config.train.iterations) {
        refuse!(
            "block {name}: the run in {} stopped at iteration {} of {} (interrupted); resume it: {retrain}",
            dir.display(),
            iterations.map_or("?".to_string(), |i| i.to_string()),
            config.train.iterations
        );
    }
    match &config.fingerprint {
        Some(f) => {
            if let Some(diff) = block.fingerprint.difference(f) {
                refuse!(
                    "block {name}: the run in {} was not trained on this plan's block scene {} ({diff}): it belongs to another plan or scene; {retrain} after removing it",
                    dir.display(),
                    plan_dir.join(&block.scene).display()
                );
            }
        }
        None => refuse!("block {name}: the run in {} records no scene fingerprint (an older vagsl?); {retrain}", dir.display()),
    }
    if config.scene.eval {
        refuse!("block {name}: the run in {} held out views (--eval); a block trains on all its views (the plan holds out the scene's), {retrain}", dir.display());
    }
    Ok((config, gaussians, report))
}

/// Merges the blocks of the plan in `plan_dir`. Loads the whole scene once (for its
/// fingerprint and split); `note` receives a line per block.
pub fn merge(plan_dir: &Path, note: &mut dyn FnMut(String)) -> Result<Merged> {
    let t0 = std::time::Instant::now();
    let plan = Plan::read(plan_dir)?;
    let mut merged: Option<Gaussians> = None;
    let mut blocks = Vec::new();
    for block in &plan.blocks {
        let (config, mut g, report) = open_block(plan_dir, block)?;
        if serde_json::to_value(&config.train)? != serde_json::to_value(&block.train)? {
            refuse!(
                "block {}: its run in {} was trained with other settings than the plan gives it ({} against {}); train it again with `bash {}/run-block.sh {}` after removing it",
                block.name(),
                plan_dir.join(&block.run).display(),
                config.train.summary(),
                block.train.summary(),
                plan_dir.display(),
                block.index
            );
        }
        let trained = g.len();
        let keep: Vec<bool> = g.means.iter().map(|m| block.core.contains(plan.frame.coords(DVec3::new(m[0] as f64, m[1] as f64, m[2] as f64)))).collect();
        g.retain(&keep)?;
        note(format!("block {}: kept {} of {} Gaussians ({})", block.name(), g.len(), trained, block.core.describe()));
        blocks.push(BlockSummary {
            index: block.index,
            run: plan_dir.join(&block.run),
            views: block.views.len(),
            iterations: block.train.iterations,
            gaussians_trained: trained,
            gaussians_kept: g.len(),
            train_seconds: report.get("train_seconds").and_then(|v| v.as_f64()).unwrap_or(0.0),
            peak_memory_bytes: report.get("peak_memory_bytes").and_then(|v| v.as_u64()),
            estimate_bytes: block.memory_bytes,
            core: block.core,
        });
        match &mut merged {
            None => merged = Some(g),
            Some(m) => {
                m.sh_degree = m.sh_degree.max(g.sh_degree);
                m.extend_from(&g);
            }
        }
    }
    let gaussians = merged.unwrap_or_default();
    if gaussians.is_empty() {
        refuse!("{}: the blocks kept no Gaussian inside their core regions: nothing to merge", plan_dir.display());
    }
    let scene = gs_run::run_config::load_scene(&plan.scene)?;
    let config = merged_config(&plan, &scene)?;
    let made_from = MadeFrom::new(config.run_id.clone(), &gaussians);
    let report = MergeReport {
        made_from,
        plan: gs_run::run_config::absolute_scene_path(plan_dir),
        frame: plan.frame,
        iterations: config.train.iterations,
        interrupted: false,
        gaussians: gaussians.len(),
        sh_degree: gaussians.sh_degree,
        train_seconds: blocks.iter().map(|b| b.train_seconds).sum(),
        longest_block_seconds: blocks.iter().map(|b| b.train_seconds).fold(0.0, f64::max),
        peak_memory_bytes: blocks.iter().map(|b| b.peak_memory_bytes).collect::<Option<Vec<u64>>>().map(|v| v.into_iter().max().unwrap_or(0)),
        merge_seconds: t0.elapsed().as_secs_f64(),
        blocks,
    };
    Ok(Merged { config, gaussians, report })
}

/// The merged run's configuration: the whole scene with the plan's split, the blocks' settings.
fn merged_config(plan: &Plan, scene: &Scene) -> Result<RunConfig> {
    let (train, test) = scene.split(plan.scene.eval);
    let names = |idx: &[usize]| idx.iter().map(|&i| scene.views[i].name.clone()).collect::<Vec<String>>();
    let (train_views, test_views) = (names(&train), names(&test));
    let (mut now, mut then) = (test_views.clone(), plan.held_out.clone());
    now.sort();
    then.sort();
    if now != then {
        refuse!(
            "{}: the scene now holds out {} views, the plan held out {}: the scene changed since it was partitioned; partition it again",
            plan.scene.describe(),
            now.len(),
            then.len()
        );
    }
    if let Some(missing) = plan.blocks.iter().flat_map(|b| &b.views).find(|v| !train_views.contains(v)) {
        refuse!("{}: view '{missing}' of the plan is not a training view of the scene any more; partition it again", plan.scene.describe());
    }
    Ok(RunConfig {
        scene: plan.scene.clone(),
        fingerprint: Some(SceneFingerprint::of(scene)),
        run_id: Some(gs_run::new_run_id(&plan.train)),
        train_views,
        test_views,
        train: plan.train.clone(),
    })
}

/// Writes a merged run into `out` (a new folder, or with `force` one whose run it replaces once
/// the new files are written): config.json, report.json, then point_cloud.ply.
pub fn write_merged(out: &Path, merged: &Merged, force: bool) -> Result<Option<String>> {
    gs_run::run_folder::check(out, force, false)?;
    let mut folder = gs_run::run_folder::prepare(out, force, false)?;
    let work = folder.work.clone();
    gs_run::write_json(&work.join("config.json"), &merged.config)?;
    gs_run::write_json(&work.join("report.json"), &merged.report)?;
    gs_io::write_gaussian_ply(&work.join("point_cloud.ply"), &merged.gaussians)?;
    Ok(folder.commit()?)
}
