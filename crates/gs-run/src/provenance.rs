//! Which model a derived file was made from (docs/architecture.md §Provenance): one record,
//! [`MadeFrom`] (the run id and the model's fingerprint), carried by every file made from a
//! run's model — `report.json` (flattened), `mesh.json`, `eval_images*.json`,
//! `eval_mesh.json`, the renders' `renders.json`, the report page's `report/made_from.json`
//! and the run's index of exports, `exports.json` — and every reader refuses a file made from
//! another model than the run's own (a mesh made while a `--resume` or a re-train ran, left
//! beside the newer model), naming both.

use crate::error::{Result, RunError};
use crate::fingerprint::{legacy_model_fingerprint, model_fingerprint};
use crate::run_config::RunConfig;
use gs_core::Gaussians;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The record of a render folder: `DIR/renders.json`.
pub const RENDERS_RECORD: &str = "renders.json";
/// The record of the report page: `RUN/report/made_from.json`.
pub const REPORT_PAGE_RECORD: &str = "report/made_from.json";
/// The run's index of its exports: `RUN/exports.json`.
pub const EXPORTS_INDEX: &str = "exports.json";

/// The model a derived file comes from.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MadeFrom {
    /// The run's id (absent for runs written before ids existed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub run_id: Option<String>,
    /// [`model_fingerprint`] of the model.
    pub model_fingerprint: String,
    /// The fingerprint's older form, to match records written before it covered the SH
    /// coefficients (never written).
    #[serde(skip)]
    legacy_fingerprint: Option<String>,
}

impl PartialEq for MadeFrom {
    fn eq(&self, other: &Self) -> bool {
        self.run_id == other.run_id && self.model_fingerprint == other.model_fingerprint
    }
}

impl MadeFrom {
    /// The record of a run's model.
    pub fn of(config: &RunConfig, gaussians: &Gaussians) -> Self {
        Self::new(config.run_id.clone(), gaussians)
    }

    /// The record of the model `gaussians` of run `run_id`.
    pub fn new(run_id: Option<String>, gaussians: &Gaussians) -> Self {
        Self { run_id, model_fingerprint: model_fingerprint(gaussians), legacy_fingerprint: Some(legacy_model_fingerprint(gaussians)) }
    }

    /// The model in words: `model F of run ID`.
    pub fn describe(&self) -> String {
        match &self.run_id {
            Some(id) => format!("model {} of run {id}", self.model_fingerprint),
            None => format!("model {}", self.model_fingerprint),
        }
    }

    /// Whether the record `recorded` names this model (a record of the fingerprint's older
    /// form, written before it covered the SH coefficients, is matched in that form).
    pub fn is_recorded_by(&self, recorded: &MadeFrom) -> bool {
        if recorded.run_id != self.run_id {
            return false;
        }
        recorded.model_fingerprint == self.model_fingerprint || self.legacy_fingerprint.as_ref() == Some(&recorded.model_fingerprint)
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
        Some(m) if !current.is_recorded_by(&m) => Err(RunError::Stale(format!(
            "{}: made from {}, but the run's model is now {} (made while a --resume or re-train ran?), so it describes an older model; make it again with `{remake}`",
            what.display(),
            m.describe(),
            current.describe()
        ))),
        _ => Ok(()),
    }
}

/// Writes `DIR/renders.json`, the record of a render folder: the split, the views rendered
/// and the model they were rendered from.
pub fn write_renders_record(dir: &Path, split: &str, views: &[String], made_from: &MadeFrom) -> Result<()> {
    let record = serde_json::json!({ "split": split, "views": views });
    crate::run_config::write_json(&dir.join(RENDERS_RECORD), &with_made_from(&record, made_from)?)
}

/// Refuses a render folder `dir` whose `renders.json` names another model than `current`.
pub fn check_renders(dir: &Path, current: &MadeFrom, remake: &str) -> Result<()> {
    check(dir, &dir.join(RENDERS_RECORD), current, remake)
}

/// Writes `RUN/report/made_from.json`, the record of the report page.
pub fn write_report_page_record(run: &Path, made_from: &MadeFrom) -> Result<()> {
    let record = serde_json::json!({ "page": "report.html" });
    crate::run_config::write_json(&run.join(REPORT_PAGE_RECORD), &with_made_from(&record, made_from)?)
}

/// Refuses a report page of `run` made from another model than `current` (a page without a
/// record, or no page, is not refused).
pub fn check_report_page(run: &Path, current: &MadeFrom) -> Result<()> {
    check(&run.join("report.html"), &run.join(REPORT_PAGE_RECORD), current, &format!("vagsl view {}", run.display()))
}

/// One export in the run's index.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ExportRecord {
    /// The exported file, absolute.
    pub file: PathBuf,
    /// The format's name (`gs_export::Format::name`).
    pub format: String,
    /// The model it was made from.
    pub made_from: MadeFrom,
}

/// Adds an export to `RUN/exports.json` (replacing the entry of the same file), written
/// atomically. An index that cannot be read is started again.
pub fn record_export(run: &Path, file: &Path, format: &str, made_from: &MadeFrom) -> Result<()> {
    let mut list = read_exports(run);
    let file = std::path::absolute(file).unwrap_or_else(|_| file.to_path_buf());
    list.retain(|e| e.file != file);
    list.push(ExportRecord { file, format: format.to_string(), made_from: made_from.clone() });
    crate::run_config::write_json(&run.join(EXPORTS_INDEX), &serde_json::json!({ "exports": list }))
}

/// The exports recorded in `RUN/exports.json` (empty when there is none or it is unreadable).
pub fn read_exports(run: &Path) -> Vec<ExportRecord> {
    let Ok(bytes) = gs_io::read_capped(&run.join(EXPORTS_INDEX), gs_io::JSON_CAP, "a JSON file") else { return Vec::new() };
    serde_json::from_slice::<serde_json::Value>(&bytes)
        .ok()
        .and_then(|v| serde_json::from_value(v.get("exports")?.clone()).ok())
        .unwrap_or_default()
}

/// Refuses the export `file` of `run` when the index records it as made from another model
/// than `current` (an export the index does not list is not refused).
pub fn check_export(run: &Path, file: &Path, current: &MadeFrom) -> Result<()> {
    let abs = std::path::absolute(file).unwrap_or_else(|_| file.to_path_buf());
    match read_exports(run).into_iter().find(|e| e.file == abs) {
        Some(e) if !current.is_recorded_by(&e.made_from) => Err(RunError::Stale(format!(
            "{}: made from {}, but the run's model is now {} (made while a --resume or re-train ran?), so it describes an older model; make it again with `vagsl export {} --format {} -o {}`",
            file.display(),
            e.made_from.describe(),
            current.describe(),
            run.display(),
            e.format,
            file.display()
        ))),
        _ => Ok(()),
    }
}
