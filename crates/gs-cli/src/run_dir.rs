//! A training run's output folder: `config.json` says which scene (and how it was loaded) and
//! which views trained, so `render`, `mesh` and `eval-images` rebuild exactly the same views.

use anyhow::{Context, Result, bail};
use gs_core::{Gaussians, Scene};
use gs_train::{TrainConfig, TrainedModel};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// How the scene of a run is loaded.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneSource {
    /// Scene folder; `None` = the built-in procedural scene.
    pub path: Option<PathBuf>,
    /// `-r` factor, if given.
    pub resolution_factor: Option<u32>,
    /// Target width, if given.
    pub width: Option<u32>,
    /// Whether every 8th view was held out.
    pub eval: bool,
}

impl SceneSource {
    /// The scene in words for messages: its folder, or "the built-in scene".
    pub fn describe(&self) -> String {
        self.path.as_ref().map_or("the built-in scene".to_string(), |p| p.display().to_string())
    }
}

/// The absolute, canonical form of a scene path as typed, so a run does not depend on the
/// folder a command is started from (a path that cannot be resolved is kept, made absolute,
/// for the loader to report).
pub fn absolute_scene_path(p: &Path) -> PathBuf {
    std::fs::canonicalize(p).unwrap_or_else(|_| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf()))
}

/// The identity of a loaded scene, so a run is not reopened on another scene: the number of
/// views and sparse points, SHA-256 over every view's name, image size, intrinsics and pose,
/// and SHA-256 over the photos' pixels as loaded (photos swapped between names, or edited,
/// under the same cameras are noticed; the photos are in memory anyway, hashing them costs
/// about a tenth of a second per 100 MB).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneFingerprint {
    /// Number of views.
    pub views: usize,
    /// Number of sparse points.
    pub points: usize,
    /// SHA-256 (hex) of the views' names, sizes, intrinsics and poses.
    pub cameras_sha256: String,
    /// SHA-256 (hex) of every view's pixels (f32 bits, in view order); absent in runs
    /// written before it existed, whose pixels then go unchecked.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pixels_sha256: Option<String>,
}

impl SceneFingerprint {
    /// The fingerprint of `scene` as loaded (after any `-r`/`--width`).
    pub fn of(scene: &Scene) -> Self {
        use sha2::{Digest, Sha256};
        let mut h = Sha256::new();
        for v in &scene.views {
            let c = &v.camera;
            h.update((v.name.len() as u64).to_le_bytes());
            h.update(v.name.as_bytes());
            h.update(c.width.to_le_bytes());
            h.update(c.height.to_le_bytes());
            let k = &c.intrinsics;
            let pose = c.rotation.to_cols_array().into_iter().chain(c.translation.to_array());
            for x in [k.fx, k.fy, k.cx, k.cy].into_iter().chain(pose) {
                h.update(x.to_bits().to_le_bytes());
            }
        }
        let cameras_sha256 = h.finalize().iter().map(|b| format!("{b:02x}")).collect();
        let mut p = Sha256::new();
        for v in &scene.views {
            let bytes: Vec<u8> = v.image.data().iter().flat_map(|x| x.to_le_bytes()).collect();
            p.update(&bytes);
        }
        let pixels_sha256 = Some(p.finalize().iter().map(|b| format!("{b:02x}")).collect());
        Self { views: scene.views.len(), points: scene.points.len(), cameras_sha256, pixels_sha256 }
    }

    /// How `now` differs from this fingerprint, in words (`None` when it does not; pixels are
    /// compared only when both fingerprints have them).
    pub fn difference(&self, now: &Self) -> Option<String> {
        let pixels_differ = matches!((&self.pixels_sha256, &now.pixels_sha256), (Some(a), Some(b)) if a != b);
        if (self.views, self.points, &self.cameras_sha256) == (now.views, now.points, &now.cameras_sha256) && !pixels_differ {
            None
        } else if self.views != now.views {
            Some(format!("it has {} views, the run's scene had {}", now.views, self.views))
        } else if self.points != now.points {
            Some(format!("it has {} sparse points, the run's scene had {}", now.points, self.points))
        } else if self.cameras_sha256 != now.cameras_sha256 {
            Some(format!("its {} views differ in image names, sizes or cameras", now.views))
        } else {
            Some(format!("its photos' pixels differ under the same {} names and cameras (photos swapped or edited?)", now.views))
        }
    }
}

/// A new run id: 16 hex digits from the clock, the process id and the settings. It only labels
/// the run's files (config.json, report.json) and never reaches the trainer.
pub fn new_run_id(config: &TrainConfig) -> String {
    use sha2::{Digest, Sha256};
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos());
    let mut h = Sha256::new();
    h.update(nanos.to_le_bytes());
    h.update(std::process::id().to_le_bytes());
    h.update(config.summary().as_bytes());
    h.finalize()[..8].iter().map(|b| format!("{b:02x}")).collect()
}

/// `OUT/config.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RunConfig {
    /// The scene.
    pub scene: SceneSource,
    /// The scene's fingerprint at training time; absent in configurations written before it
    /// existed, whose scene then goes unchecked.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fingerprint: Option<SceneFingerprint>,
    /// The run's id, written again into report.json with the model at the end, so a folder
    /// pairing this configuration with another run's model is noticed. Absent in older
    /// configurations (and `tradeoff`'s), whose pairing then goes unchecked.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub run_id: Option<String>,
    /// Names of the training views.
    pub train_views: Vec<String>,
    /// Names of the held-out views.
    pub test_views: Vec<String>,
    /// The effective training configuration.
    pub train: TrainConfig,
}

/// Loads the scene a source describes (the built-in scene is regenerated deterministically),
/// printing the scene-extent warnings (outlier cameras left out, an extent taken from the
/// sparse points) and refusing a scene whose cameras coincide with nothing else to set its scale.
pub fn load_scene(src: &SceneSource) -> Result<Scene> {
    let scene = load_scene_quietly(src)?;
    let place = src.describe();
    for w in scene.check_extent().with_context(|| format!("loading scene {place}"))? {
        eprintln!("warning: {place}: {w}");
    }
    Ok(scene)
}

/// [`load_scene`] without the scene-extent check.
fn load_scene_quietly(src: &SceneSource) -> Result<Scene> {
    match &src.path {
        None => {
            if src.resolution_factor.is_some() || src.width.is_some() {
                bail!("-r/--width apply to scene folders; the built-in scene has a fixed size");
            }
            Ok(gs_synth::generate(&gs_synth::BuiltinOptions::default())?.scene)
        }
        Some(p) => {
            let resolution = match (src.resolution_factor, src.width) {
                (Some(_), Some(_)) => bail!("give either -r or --width, not both"),
                (Some(f), None) => gs_io::Resolution::Factor(f),
                (None, Some(w)) => gs_io::Resolution::Width(w),
                (None, None) => gs_io::Resolution::Auto,
            };
            let opts = gs_io::LoadOptions { resolution, ..Default::default() };
            gs_io::load_scene(p, &opts).with_context(|| format!("loading scene {}", p.display()))
        }
    }
}

/// Grey GT images of the `train` views of `scene` at `s` × their resolution, for
/// `--ncc-scale` (the built-in scene is re-rendered at that size; a scene folder is reloaded at
/// `s` × the training width, which must not exceed the originals and must give exactly
/// `s·W × s·H` for every view).
pub fn high_resolution_greys(src: &SceneSource, scene: &Scene, train: &[usize], s: u32) -> Result<Vec<gs_core::Image>> {
    let names: Vec<String> = train.iter().map(|&i| scene.views[i].name.clone()).collect();
    let hi = match &src.path {
        None => {
            let o = gs_synth::BuiltinOptions::default();
            gs_synth::generate(&gs_synth::BuiltinOptions { width: o.width * s, height: o.height * s, ..o })?.scene
        }
        Some(p) => {
            let w = scene.views[train[0]].camera.width * s;
            let widest = gs_io::model_summary(p)?.cameras.iter().map(|c| c.width).max().unwrap_or(0);
            if w > widest {
                bail!("--ncc-scale {s}: the grey images would be {w} px wide, wider than the originals ({widest} px); lower -r or --ncc-scale");
            }
            let opts = gs_io::LoadOptions {
                resolution: gs_io::Resolution::Width(w),
                only_images: Some(names.clone()),
                ..Default::default()
            };
            gs_io::load_scene(p, &opts).with_context(|| format!("loading {} at {s}x for --ncc-scale", p.display()))?
        }
    };
    names
        .iter()
        .zip(train)
        .map(|(n, &i)| {
            let lo = &scene.views[i].camera;
            let v = hi.views.iter().find(|v| &v.name == n).with_context(|| format!("view {n} missing at {s}x"))?;
            if (v.camera.width, v.camera.height) != (lo.width * s, lo.height * s) {
                bail!(
                    "--ncc-scale {s}: view {n} loads at {}x{}, not exactly {s} × {}x{} (odd original size); use another -r/--width",
                    v.camera.width,
                    v.camera.height,
                    lo.width,
                    lo.height
                );
            }
            // The same camera, resized: the principal point and focal lengths scale exactly.
            let expect = lo.resized(v.camera.width, v.camera.height)?;
            let k = (&expect.intrinsics, &v.camera.intrinsics);
            if (k.0.fx - k.1.fx).abs() > 1e-6 * k.0.fx || (k.0.cx - k.1.cx).abs() > 1e-3 || (k.0.cy - k.1.cy).abs() > 1e-3 {
                let words = |k: &gs_core::Intrinsics| format!("fx {} fy {} cx {} cy {}", k.fx, k.fy, k.cx, k.cy);
                bail!("--ncc-scale {s}: view {n} at {s}x has intrinsics {}, expected {}", words(k.1), words(k.0));
            }
            Ok(v.image.to_grey()?)
        })
        .collect()
}

impl RunConfig {
    /// Refuses a `scene` that is not the one this run was trained on (by its fingerprint; a
    /// configuration without one is not checked). `whose` names the run and `remedy` says
    /// how to give the right scene, in the message.
    pub fn check_scene(&self, scene: &Scene, whose: &str, remedy: &str) -> Result<()> {
        let Some(then) = &self.fingerprint else { return Ok(()) };
        if let Some(diff) = then.difference(&SceneFingerprint::of(scene)) {
            let place = self.scene.describe();
            bail!(
                "{place} is not the scene {whose} was trained on ({diff}); {remedy}"
            );
        }
        Ok(())
    }
}

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
        bail!(
            "{}: no point_cloud.ply: {why}; resume it with --resume {} if that exists, or train again",
            dir.display(),
            dir.join("checkpoint.bin").display()
        );
    }
    let Some(id) = run_id else { return Ok(fingerprint) };
    match model_id {
        Some(m) if m == id => Ok(fingerprint),
        Some(m) => bail!(
            "{}: config.json is of run {id} but report.json is of run {m}: the folder mixes two training runs (a re-train that did not finish?); train again into it with --force",
            dir.display()
        ),
        None => bail!(
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
        Some(f) if f != model_fingerprint(gaussians) => bail!(
            "{}: point_cloud.ply is not the model report.json describes (the run stopped while writing its model, leaving an older one); resume it with --resume {} if that exists, or train again",
            dir.display(),
            dir.join("checkpoint.bin").display()
        ),
        _ => Ok(()),
    }
}

/// A fingerprint of a model, as written and read back through its PLY: FNV-1a (64 bits) of
/// the count and of the f32 bits of the positions, scales, rotations and opacities.
pub fn model_fingerprint(g: &Gaussians) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    };
    eat(&(g.len() as u64).to_le_bytes());
    let floats = g.means.iter().flatten().chain(g.log_scales.iter().flatten()).chain(g.rotations.iter().flatten()).chain(&g.opacity_logits);
    for v in floats {
        eat(&v.to_bits().to_le_bytes());
    }
    format!("{h:016x}")
}

/// Refuses a scene whose train/test split is no longer the run's (training views relisted as
/// test views would be scored as held out). Runs written before fingerprints are not checked.
fn check_split(config: &RunConfig, scene: &Scene, dir: &Path) -> Result<()> {
    if config.fingerprint.is_none() {
        return Ok(());
    }
    let (train, test) = scene.split(config.scene.eval);
    let names = |idx: &[usize]| idx.iter().map(|&i| scene.views[i].name.clone()).collect::<Vec<_>>();
    let (mut now, mut then) = (names(&test), config.test_views.clone());
    now.sort();
    then.sort();
    if now != then || train.len() != config.train_views.len() {
        let moved: Vec<&String> = now.iter().filter(|n| !then.contains(n)).chain(then.iter().filter(|n| !now.contains(n))).take(3).collect();
        bail!(
            "{}: the scene {} now holds out {} views ({} in training), the run held out {} ({} in training): its split changed (e.g. {}), so held-out scores would include training views; restore the scene's split or train again",
            dir.display(),
            config.scene.describe(),
            now.len(),
            train.len(),
            then.len(),
            config.train_views.len(),
            moved.iter().map(|s| s.as_str()).collect::<Vec<_>>().join(", ")
        );
    }
    Ok(())
}

/// Indices of the named views in `scene` (an error names a missing view).
pub fn view_indices(scene: &Scene, names: &[String]) -> Result<Vec<usize>> {
    names
        .iter()
        .map(|n| {
            scene.views.iter().position(|v| &v.name == n).with_context(|| format!("view '{n}' of the run is not in the scene"))
        })
        .collect()
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
    pub made_from: crate::provenance::MadeFrom,
}

impl OpenRun {
    /// Opens `dir`: reads `config.json` and `point_cloud.ply`, reloads the scene (from `scene`
    /// when given: the run's scene folder, moved since training) and checks it is the scene the
    /// run was trained on.
    pub fn open(dir: &Path, scene: Option<&Path>) -> Result<Self> {
        let (mut config, gaussians) = read_run_model(dir)?;
        if let Some(p) = scene {
            if config.scene.path.is_none() {
                bail!("--scene {}: the run in {} was trained on the built-in scene, which has no folder", p.display(), dir.display());
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
        let made_from = crate::provenance::MadeFrom::of(&config, &gaussians);
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

/// Writes `value` as pretty JSON to `path` atomically.
pub fn write_json(path: &Path, value: &impl Serialize) -> Result<()> {
    let text = serde_json::to_string_pretty(value)?;
    gs_io::write_atomic(path, |w| w.write_all(text.as_bytes()))?;
    Ok(())
}

/// Peak resident memory of this process in bytes (Linux `VmHWM`), if known.
pub fn peak_memory_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}
