//! Opening a finished run (docs/architecture.md §Runs): its configuration and model, checked
//! to belong together (report.json pairs them), and its scene, checked to be the run's.

use crate::error::{Context, Result, refuse};
use crate::fingerprint::fingerprint_matches;
use crate::provenance::MadeFrom;
use crate::run_config::{RunConfig, absolute_scene_path, check_split, load_scene, view_indices};
use gs_core::{Gaussians, Scene};
use gs_train::TrainedModel;
use std::path::{Path, PathBuf};

/// Refuses a run folder whose model is missing or is not the model of its config.json's run
/// `run_id`. report.json, written at the end before point_cloud.ply, carries the id of the
/// run and the fingerprint of the model it describes; returns that fingerprint (absent in
/// reports written before it existed) for [`check_model`].
fn check_pairing(dir: &Path, run_id: Option<&str>) -> Result<Option<String>> {
    let report = dir.join("report.json");
    let fields = gs_io::read_capped(&report, gs_io::JSON_CAP, "a run report").ok().and_then(|t| serde_json::from_slice::<serde_json::Value>(&t).ok());
    let field = |k: &str| fields.as_ref().and_then(|v| v.get(k)?.as_str().map(String::from));
    let (model_id, fingerprint) = (field("run_id"), field("model_fingerprint"));
    if !dir.join("point_cloud.ply").is_file() {
        let why = if model_id.is_some() && model_id.as_deref() == run_id {
            "the training run stopped after its report, while writing its model"
        } else {
            "the training run has not written its model (still running, or stopped before it could)"
        };
        refuse!(
            "{}: no point_cloud.ply: {why}; resume it with --resume {} if that exists, or train again",
            dir.display(),
            dir.join("checkpoint.bin").display()
        );
    }
    let Some(id) = run_id else { return Ok(fingerprint) };
    match model_id {
        Some(m) if m == id => Ok(fingerprint),
        Some(m) => refuse!(
            "{}: config.json is of run {id} but report.json is of run {m}: the folder mixes two training runs (a re-train that did not finish?); train again into it with --force",
            dir.display()
        ),
        None => refuse!(
            "{}: config.json is of run {id} but {} is missing or names no run, so point_cloud.ply may be another run's model (a training that did not finish?); train again into it with --force",
            dir.display(),
            report.display()
        ),
    }
}

/// Reads a run folder's `config.json` and its model `point_cloud.ply`, refusing a folder whose
/// model is missing or belongs to another run; the scene is not loaded (`export` needs none).
pub fn read_run_model(dir: &Path) -> Result<(RunConfig, Gaussians)> {
    let cfg_path = dir.join("config.json");
    let text = gs_io::read_capped(&cfg_path, gs_io::JSON_CAP, "a run configuration")
        .with_context(|| format!("{}: cannot read the run's configuration (is this a `vagsl train` output folder?)", cfg_path.display()))?;
    let config: RunConfig =
        serde_json::from_slice(&text).with_context(|| format!("{}: not a vagsl run configuration", cfg_path.display()))?;
    let fingerprint = check_pairing(dir, config.run_id.as_deref())?;
    let mut gaussians = gs_io::read_gaussian_ply(&dir.join("point_cloud.ply"))?;
    check_model(dir, &gaussians, fingerprint.as_deref())?;
    // Coefficients above the degree reached stay 0 during training, so the maximum degree
    // renders exactly what the trainer rendered last.
    gaussians.sh_degree = config.train.sh_degree_max;
    Ok((config, gaussians))
}

/// Refuses a model that is not the one report.json describes (`fingerprint`): a run stopped
/// after writing its report but before its model leaves the previous model of the folder.
fn check_model(dir: &Path, gaussians: &Gaussians, fingerprint: Option<&str>) -> Result<()> {
    match fingerprint {
        Some(f) if !fingerprint_matches(f, gaussians) => refuse!(
            "{}: point_cloud.ply is not the model report.json describes (the run stopped while writing its model, leaving an older one); resume it with --resume {} if that exists, or train again",
            dir.display(),
            dir.join("checkpoint.bin").display()
        ),
        _ => Ok(()),
    }
}

/// A finished (or checkpointed) run opened for rendering, meshing or evaluation: it owns what
/// [`OpenRun::model`] lends as a [`TrainedModel`].
pub struct OpenRun {
    /// The run folder.
    pub dir: PathBuf,
    /// The scene, loaded as during training.
    pub scene: Scene,
    gaussians: Gaussians,
    train: Vec<usize>,
    test: Vec<usize>,
    raster: gs_raster::RasterConfig,
    extent: f64,
    /// The run's model, for the records of the files made from it.
    pub made_from: MadeFrom,
}

impl OpenRun {
    /// Opens `dir`: reads `config.json` and `point_cloud.ply`, reloads the scene (from `scene`
    /// when given: the run's scene folder, moved since training) and checks it is the scene the
    /// run was trained on.
    pub fn open(dir: &Path, scene: Option<&Path>) -> Result<Self> {
        let (mut config, gaussians) = read_run_model(dir)?;
        if let Some(p) = scene {
            if config.scene.path.is_none() {
                refuse!("--scene {}: the run in {} was trained on the built-in scene, which has no folder", p.display(), dir.display());
            }
            config.scene.path = Some(absolute_scene_path(p));
        }
        let scene = load_scene(&config.scene).with_context(|| match (&config.scene.path, scene) {
            (Some(p), None) => format!(
                "the run in {} was trained on the scene {}; if the run or the scene has moved, give the scene's folder with --scene PATH",
                dir.display(),
                p.display()
            ),
            _ => format!("reopening the run in {}", dir.display()),
        })?;
        config.check_scene(&scene, &format!("the run in {}", dir.display()), "give the run's own scene folder with --scene PATH")?;
        let train = view_indices(&scene, &config.train_views)?;
        let test = view_indices(&scene, &config.test_views)?;
        check_split(&config, &scene, dir)?;
        let extent = scene.extent_of(&train);
        let raster = config.train.raster_config();
        let made_from = MadeFrom::of(&config, &gaussians);
        Ok(Self { dir: dir.to_path_buf(), scene, gaussians, train, test, raster, extent, made_from })
    }

    /// The trained model of the run.
    pub fn model(&self) -> TrainedModel<'_> {
        TrainedModel {
            scene: &self.scene,
            train: &self.train,
            test: &self.test,
            raster: &self.raster,
            extent: self.extent,
            gaussians: &self.gaussians,
        }
    }
}

/// Peak resident memory of this process in bytes (Linux `VmHWM`), if known.
pub fn peak_memory_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

