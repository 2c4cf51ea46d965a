//! Which model a derived file was made from: `mesh.json`, `eval_images*.json` and
//! `eval_mesh.json` record the run id and the fingerprint of the model (`made_from`), and
//! every reader of a derived file refuses one made from another model than the run's own (a
//! mesh made while a `--resume` or a re-train ran, left beside the newer model).

use crate::run_dir::{RunConfig, model_fingerprint};
use anyhow::{Result, bail};
use gs_core::Gaussians;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The model a derived file comes from.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct MadeFrom {
    /// The run's id (absent for runs written before ids existed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub run_id: Option<String>,
    /// [`model_fingerprint`] of the model.
    pub model_fingerprint: String,
}

impl MadeFrom {
    /// The record of a run's model.
    pub fn of(config: &RunConfig, gaussians: &Gaussians) -> Self {
        Self { run_id: config.run_id.clone(), model_fingerprint: model_fingerprint(gaussians) }
    }

    /// The model in words: `model F of run ID`.
    pub fn describe(&self) -> String {
        match &self.run_id {
            Some(id) => format!("model {} of run {id}", self.model_fingerprint),
            None => format!("model {}", self.model_fingerprint),
        }
    }
}

/// `value` (a JSON object) with `made_from` added.
pub fn with_made_from(value: &impl Serialize, made_from: &MadeFrom) -> Result<serde_json::Value> {
    let mut v = serde_json::to_value(value)?;
    if let Some(map) = v.as_object_mut() {
        map.insert("made_from".into(), serde_json::to_value(made_from)?);
    }
    Ok(v)
}

/// The `made_from` record of the JSON file `path`; `None` when the file is missing, is not
/// JSON or has none (written before records existed, or by `mesh --depth-dir`).
pub fn read_made_from(path: &Path) -> Option<MadeFrom> {
    let bytes = gs_io::read_capped(path, gs_io::JSON_CAP, "a JSON file").ok()?;
    let v: serde_json::Value = serde_json::from_slice(&bytes).ok()?;
    serde_json::from_value(v.get("made_from")?.clone()).ok()
}

/// Refuses a derived file (`what`, with its record in `record`) made from another model than
/// `current`, naming both and the command that makes it again (`remake`).
pub fn check(what: &Path, record: &Path, current: &MadeFrom, remake: &str) -> Result<()> {
    match read_made_from(record) {
        Some(m) if m != *current => bail!(
            "{}: made from {}, but the run's model is now {} (made while a --resume or re-train ran?), so it describes an older model; make it again with `{remake}`",
            what.display(),
            m.describe(),
            current.describe()
        ),
        _ => Ok(()),
    }
}
