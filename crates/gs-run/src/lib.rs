//! Run handling for vagsl (docs/architecture.md §Runs): everything a front end needs to open,
//! check and write training runs without the command line — a job runner for partitioned
//! scenes, a Python binding or a server as much as `vagsl` itself.
//!
//! - [`run_config`]: a run's `config.json` ([`RunConfig`], [`SceneSource`]) and loading its scene.
//! - [`fingerprint`]: scene and model fingerprints, run ids.
//! - [`open_run`]: opening a finished run, checking model, report and scene belong together.
//! - [`provenance`]: the one record ([`MadeFrom`]) every derived file carries, and its checks.
//! - [`run_folder`]: the output folder of `train` (lock, `--force` staging, `--resume`), and the
//!   output-file check of every command.
//! - [`resume`]: the run a checkpoint continues.
//! - [`metrics_log`]: the training curves, `metrics.jsonl`.
//! - [`budget_check`]: memory sizes and the training-memory check.

mod error;

pub mod budget_check;
pub mod fingerprint;
pub mod metrics_log;
pub mod open_run;
pub mod provenance;
pub mod resume;
pub mod run_config;
pub mod run_folder;

pub use error::{Result, RunError, chain_text};
pub use fingerprint::{SceneFingerprint, model_fingerprint, new_run_id};
pub use open_run::{OpenRun, read_run_model};
pub use provenance::MadeFrom;
pub use run_config::{RunConfig, SceneSource, write_json};
