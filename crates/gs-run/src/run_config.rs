//! A run's `config.json` (docs/architecture.md §Runs): which scene (and how it was loaded)
//! and which views trained, so `render`, `mesh` and `eval-images` rebuild exactly the same
//! views; loading that scene again and checking it is the run's.

use crate::error::{Context, Result, refuse};
use crate::fingerprint::SceneFingerprint;
use gs_core::Scene;
use gs_train::TrainConfig;
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
                refuse!("-r/--width apply to scene folders; the built-in scene has a fixed size");
            }
            Ok(gs_synth::generate(&gs_synth::BuiltinOptions::default())?.scene)
        }
        Some(p) => {
            let resolution = match (src.resolution_factor, src.width) {
                (Some(_), Some(_)) => refuse!("give either -r or --width, not both"),
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
                refuse!("--ncc-scale {s}: the grey images would be {w} px wide, wider than the originals ({widest} px); lower -r or --ncc-scale");
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
                refuse!(
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
                refuse!("--ncc-scale {s}: view {n} at {s}x has intrinsics {}, expected {}", words(k.1), words(k.0));
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
            refuse!(
                "{place} is not the scene {whose} was trained on ({diff}); {remedy}"
            );
        }
        Ok(())
    }
}

/// Refuses a scene whose train/test split is no longer the run's (training views relisted as
/// test views would be scored as held out). Runs written before fingerprints are not checked.
pub fn check_split(config: &RunConfig, scene: &Scene, dir: &Path) -> Result<()> {
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
        refuse!(
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

/// Writes `value` as pretty JSON to `path` atomically.
pub fn write_json(path: &Path, value: &impl Serialize) -> Result<()> {
    let text = serde_json::to_string_pretty(value)?;
    gs_io::write_atomic(path, |w| w.write_all(text.as_bytes()))?;
    Ok(())
}
