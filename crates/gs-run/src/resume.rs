//! The run a checkpoint continues (docs/architecture.md §Runs): its `config.json` gives the
//! scene and the run id, and options that would change the run are refused.

use crate::error::{Context, Result, refuse};
use crate::run_config::{RunConfig, SceneSource, absolute_scene_path};
use gs_train::TrainConfig;
use std::path::{Path, PathBuf};

/// The scene options a resume was given, to compare with the run's own.
#[derive(Debug, Clone)]
pub struct SceneOptions<'a> {
    /// The run's output folder (its config.json is looked for there first).
    pub output: &'a Path,
    /// SCENE, if given.
    pub scene: Option<&'a Path>,
    /// `-r`, if given.
    pub resolution: Option<u32>,
    /// `--width`, if given.
    pub width: Option<u32>,
    /// `--eval`.
    pub eval: bool,
}

/// The scene options of `a` that differ from the run's scene `run`, in words.
fn scene_changes(a: &SceneOptions, run: &SceneSource) -> Vec<String> {
    let show = |v: Option<u32>| v.map_or("none".to_string(), |v| v.to_string());
    let mut changes = Vec::new();
    if let Some(p) = a.scene {
        let p = absolute_scene_path(p);
        if run.path.as_ref() != Some(&p) {
            changes.push(format!("SCENE {} (the run's: {})", p.display(), run.describe()));
        }
    }
    if a.resolution.is_some() && a.resolution != run.resolution_factor {
        changes.push(format!("-r {} (the run's: {})", show(a.resolution), show(run.resolution_factor)));
    }
    if a.width.is_some() && a.width != run.width {
        changes.push(format!("--width {} (the run's: {})", show(a.width), show(run.width)));
    }
    if a.eval && !run.eval {
        changes.push("--eval (the run held out no views)".to_string());
    }
    changes
}

/// The run a resume from `checkpoint` (with settings `ck_config`) continues, and the file its
/// configuration came from: the `config.json` in the output folder, else the one beside the
/// checkpoint; an error when neither exists (a checkpoint copied on its own could otherwise
/// resume on any scene). Refuses `ignored` training options given (the checkpoint's settings
/// are used), scene options that would change the run, and a folder holding another run.
pub fn run_of_checkpoint(options: &SceneOptions, ignored: &[&str], checkpoint: &Path, ck_config: &TrainConfig) -> Result<(RunConfig, PathBuf)> {
    if !ignored.is_empty() {
        refuse!(
            "--resume continues with the checkpoint's own settings, so {} would be ignored; leave {} out (to change the settings, start a new run without --resume)",
            ignored.join(", "),
            if ignored.len() == 1 { "it" } else { "them" }
        );
    }
    let beside = checkpoint.parent().map(|d| d.join("config.json"));
    let candidates = [Some(options.output.join("config.json")), beside];
    let Some(file) = candidates.into_iter().flatten().find(|f| f.is_file()) else {
        refuse!(
            "{}: no config.json of the checkpoint's run in {} or beside the checkpoint; a checkpoint resumes only on the scene, resolution and views it was trained on, which that file records: put the run's config.json beside the checkpoint",
            checkpoint.display(),
            options.output.display()
        );
    };
    let text = std::fs::read_to_string(&file).with_context(|| format!("{}: cannot read the run's configuration", file.display()))?;
    let run: RunConfig = serde_json::from_str(&text).with_context(|| format!("{}: not a vagsl run configuration", file.display()))?;
    if run.train != *ck_config {
        refuse!(
            "{}: this run's settings are not those of the checkpoint {}, so the folder holds another run; resume into the checkpoint's own folder or a new one",
            file.display(),
            checkpoint.display()
        );
    }
    let changes = scene_changes(options, &run.scene);
    if !changes.is_empty() {
        refuse!(
            "--resume continues the run of {} on its own scene, and these options would change it: {}; leave them out",
            file.display(),
            changes.join(", ")
        );
    }
    Ok((run, file))
}
