//! The output folder of a training run (docs/architecture.md §Errors and files): a run
//! already there is never overwritten silently, `--force` replaces exactly the files vagsl
//! writes into a run folder (and nothing a user put beside them) only once the new model is
//! written, a second `train` into the same folder is locked out, and every command's output
//! file is checked before any work ([`check_output_file`]).

use crate::error::{Context, Result, RunError, refuse};
use std::path::Path;

/// The files vagsl writes into a run folder: `train` (configuration, model, report,
/// checkpoint, exposure, curves), `mesh` (mesh and its report), `eval-images` (its six score
/// files), `eval-mesh` (its scores of the run's mesh), `view` (the report page) and `export`
/// (its index of the run's exports, [`crate::provenance::EXPORTS_INDEX`]).
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
    "eval_images_seen.json",
    "eval_images_train_seen.json",
    "eval_mesh.json",
    "report.html",
    "exports.json",
];

/// The folders vagsl writes into a run folder: `render`'s default output and the report
/// page's images and data.
pub const RUN_FOLDERS: &[&str] = &["renders", "report"];

/// Whether `dir` holds a training run (its configuration or its model).
pub fn holds_run(dir: &Path) -> bool {
    dir.join("config.json").exists() || dir.join("point_cloud.ply").exists()
}

/// Refuses, before any work, an output folder that is a file or holds a run, unless the run is
/// to be replaced (`--force`) or continued (`--resume`). Made again under the run's lock by
/// [`prepare`].
pub fn check(out: &Path, force: bool, resume: bool) -> Result<()> {
    if out.exists() && !out.is_dir() {
        refuse!("{}: exists and is not a folder; give an output folder with -o", out.display());
    }
    if holds_run(out) && !force && !resume {
        refuse!(
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

/// The output folder of a training run that has started, held until the run ends: the lock
/// that keeps a second `train -o` of the same folder out, and the folder the run writes into
/// (`work`): the output folder itself, or with `--force` over a previous run a staging folder
/// inside it, `.train.PID.tmp/`, moved in place of the previous run by [`Prepared::commit`]
/// once the new model is written. An error before that drops the staging folder and leaves
/// the previous run whole.
pub struct Prepared {
    /// Where the run writes its files.
    pub work: std::path::PathBuf,
    out: std::path::PathBuf,
    staged: bool,
    /// With `resume`: the previous model's derived files removed, in words for the user
    /// (`None` when there were none).
    pub resume_note: Option<String>,
    _lock: std::fs::File,
}

/// The lock file in a run folder, held (an exclusive advisory lock) by the `train` writing it.
pub const LOCK_FILE: &str = ".vagsl-train.lock";

/// Makes `out` ready when training really starts: creates it, takes its lock (a second
/// `train` into the same folder is refused while this one runs), checks again under the lock
/// that no run has appeared there meanwhile, removes staging folders of killed runs; with
/// `resume` the outputs derived from the model being continued ([`derived_files`],
/// [`RUN_FOLDERS`]) are removed (they would describe an older model); with `force` over a
/// previous run the new run is staged (see [`Prepared`]), nothing of the old run is removed yet.
pub fn prepare(out: &Path, force: bool, resume: bool) -> Result<Prepared> {
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create the output folder", out.display()))?;
    let lock_path = out.join(LOCK_FILE);
    let lock = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&lock_path)
        .with_context(|| format!("{}: cannot create the run's lock file", lock_path.display()))?;
    if let Err(e) = lock.try_lock() {
        match e {
            std::fs::TryLockError::WouldBlock => refuse!(
                "{}: another `vagsl train` is writing this run folder now (it holds {LOCK_FILE}); wait for it to end, or give another output folder with -o",
                out.display()
            ),
            std::fs::TryLockError::Error(e) => {
                return Err(RunError::Context { context: format!("{}: cannot lock the run folder", lock_path.display()), source: Box::new(e) });
            }
        }
    }
    check(out, force, resume)?;
    gs_io::remove_stale_temps(out, "train");
    let mut resume_note = None;
    if resume {
        let removed = remove_listed(out, &derived_files())?;
        if !removed.is_empty() {
            resume_note = Some(format!(
                "--resume: removed the previous model's {} from {} (made from the model this run replaces)",
                removed.join(", "),
                out.display()
            ));
        }
    }
    let staged = force && (RUN_FILES.iter().chain(RUN_FOLDERS).any(|f| out.join(f).exists()));
    let work = if staged { out.join(format!(".train.{}.tmp", std::process::id())) } else { out.to_path_buf() };
    if staged {
        std::fs::create_dir(&work).with_context(|| format!("{}: cannot create the staging folder of the new run", work.display()))?;
    }
    Ok(Prepared { work, out: out.to_path_buf(), staged, resume_note, _lock: lock })
}

impl Prepared {
    /// Puts a staged run in place of the previous one: each new file is renamed over the old
    /// (atomic per file), then the previous run's other files and folders are removed. Returns
    /// what was replaced and removed, in words; nothing to do (`None`) when the run was not staged.
    pub fn commit(&mut self) -> Result<Option<String>> {
        if !self.staged {
            return Ok(None);
        }
        let mut replaced = Vec::new();
        for entry in std::fs::read_dir(&self.work).with_context(|| format!("{}: cannot list the new run", self.work.display()))? {
            let entry = entry.with_context(|| format!("{}: cannot list the new run", self.work.display()))?;
            let to = self.out.join(entry.file_name());
            std::fs::rename(entry.path(), &to).with_context(|| format!("{}: cannot move the new run's file in place", to.display()))?;
            replaced.push(entry.file_name().to_string_lossy().into_owned());
        }
        let old: Vec<&str> = RUN_FILES.iter().copied().filter(|f| !replaced.iter().any(|r| r == f)).collect();
        let removed = remove_listed(&self.out, &old)?;
        std::fs::remove_dir(&self.work).with_context(|| format!("{}: cannot remove the staging folder", self.work.display()))?;
        self.staged = false;
        replaced.sort();
        Ok(Some(format!(
            "--force: the new run's {} replaced the previous run's in {}{}",
            replaced.join(", "),
            self.out.display(),
            if removed.is_empty() { String::new() } else { format!("; removed the previous run's {}", removed.join(", ")) }
        )))
    }
}

impl Drop for Prepared {
    /// A run that failed before [`Prepared::commit`] leaves the previous run as it was.
    fn drop(&mut self) {
        if self.staged {
            let _ = std::fs::remove_dir_all(&self.work);
        }
    }
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

/// The one output-file check of every command, before any work: the path is a regular file or
/// new, never a link, device or folder, in a folder that exists and accepts a new file
/// ([`gs_io::check_output_writable`]); and it is none of a run's own files ([`RUN_FILES`] in a
/// folder that [`holds_run`]) unless it is one of `own`, the command's own outputs (e.g.
/// `mesh`'s RUN/mesh.ply and RUN/mesh.json of the run it meshes). `what` names the output.
pub fn check_output_file(path: &Path, what: &str, own: &[std::path::PathBuf]) -> Result<()> {
    gs_io::check_output_writable(path).with_context(|| format!("cannot write {what}"))?;
    let Some(name) = path.file_name().and_then(|n| n.to_str()) else { return Ok(()) };
    let dir = gs_io::output::folder_of(path);
    if !RUN_FILES.contains(&name) || !holds_run(dir) {
        return Ok(());
    }
    let same = |a: &Path, b: &Path| match (std::fs::canonicalize(gs_io::output::folder_of(a)), std::fs::canonicalize(gs_io::output::folder_of(b))) {
        (Ok(x), Ok(y)) => x == y && a.file_name() == b.file_name(),
        _ => false,
    };
    if own.iter().any(|o| same(o, path)) {
        return Ok(());
    }
    refuse!(
        "{}: this is the run's own {name}, which {what} would replace (every later command on the run reads it); give another output file with -o",
        path.display()
    )
}
