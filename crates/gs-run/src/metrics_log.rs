//! `OUT/metrics.jsonl`: the training curves of a run, one JSON object per line, written as
//! training goes (so `tail -f` shows them), read by `vagsl view`.
//!
//! Every [`LOSS_EVERY`] iterations a line `{"iteration", "seconds", "gaussians", "loss": {…}}`
//! gives the loss terms averaged over those iterations (one view per iteration makes single
//! values noisy). With held-out views, [`HELDOUT_POINTS`] times per run (and at the end) a
//! line `{"iteration", "seconds", "heldout_psnr", "heldout_ssim"}` scores them; a point that
//! falls on an opacity reset is taken half an interval later. `seconds` is training time (earlier segments of a resumed run included, the held-out scoring excluded),
//! so curves of different runs share a time axis. A resumed run keeps the lines up to its
//! checkpoint and appends.
//!
//! With `--track-gt GT_MESH`, the same points also mesh the model (TSDF of the training views'
//! plane depths, `vagsl mesh`'s defaults, fused only inside the crop when one is given) and
//! score it against the ground truth as `vagsl eval-mesh` does: a line `{"iteration", "seconds", "chamfer", "f1", "accuracy",
//! "completeness", "triangles"}` — the Chamfer-against-wall-time curve of a run, with the
//! meshing excluded from training time like the held-out scoring. (docs/architecture.md §Runs)

use crate::error::{Context, Result, refuse};
use gs_core::TriangleMesh;
use gs_train::{MeshOptions, StepReport, Trainer, extract_mesh};
use gs_tsdf::{Aabb, EvalOptions, evaluate_meshes};
use serde_json::{Value, json};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Iterations per loss line.
pub const LOSS_EVERY: u64 = 10;
/// Held-out scorings per run (besides the last iteration's).
pub const HELDOUT_POINTS: u64 = 10;

/// The loss terms of one line, summed over its iterations.
#[derive(Default)]
struct Sums {
    n: u32,
    terms: [(f64, u32); 9],
}

const TERMS: [&str; 9] =
    ["total", "l1", "edge", "normal_consistency", "normal_smoothing", "photometric", "features", "opacity_entropy", "flatness"];

impl Sums {
    fn add(&mut self, r: &StepReport) {
        let l = &r.losses;
        let values = [
            Some(l.total),
            Some(l.l1),
            l.edge,
            l.normal_consistency,
            l.normal_smoothing,
            l.photometric,
            l.features,
            l.opacity_entropy,
            l.flatness,
        ];
        for (slot, v) in self.terms.iter_mut().zip(values) {
            if let Some(v) = v {
                slot.0 += v;
                slot.1 += 1;
            }
        }
        self.n += 1;
    }

    fn means(&self) -> Value {
        let mut m = serde_json::Map::new();
        for (name, (sum, n)) in TERMS.iter().zip(self.terms) {
            if n > 0 {
                m.insert((*name).into(), json!(sum / n as f64));
            }
        }
        Value::Object(m)
    }
}

/// The ground truth and settings of the mesh curve.
pub struct MeshTrack {
    gt: TriangleMesh,
    eval: EvalOptions,
    mesh: MeshOptions,
}

impl MeshTrack {
    /// The mesh curve against the ground-truth mesh `gt` (read from `gt_path`): with
    /// `crop_to_gt`, only the GT's box grown by that fraction per side (and above `min_z`) is
    /// fused and scored, as `vagsl eval-mesh --crop-to-gt`; the meshes are fused under
    /// `max_memory` bytes, as `vagsl mesh`.
    pub fn new(gt_path: &Path, gt: TriangleMesh, crop_to_gt: Option<f64>, min_z: Option<f64>, max_memory: u64) -> Result<Self> {
        let b = Aabb::of_mesh(&gt).with_context(|| format!("{}: the ground-truth mesh has no vertices", gt_path.display()))?;
        if let Some(f) = crop_to_gt
            && !(f.is_finite() && f >= 0.0)
        {
            refuse!("--track-crop-to-gt {f}: expected a fraction ≥ 0");
        }
        let crop = crop_to_gt.map(|f| b.grown(f, min_z));
        let eval = EvalOptions::for_gt(&b, crop);
        // Only the cropped region is scored, so only it is fused (a room's walls at a fine voxel
        // can need more memory than the machine has, and the time goes to the object).
        let mesh = MeshOptions { bounds: crop, max_memory: Some(max_memory), ..Default::default() };
        Ok(Self { gt, eval, mesh })
    }

    /// Meshes the trainer's model and scores it: the fields of one curve line.
    fn score(&self, tr: &mut Trainer, rasterizer: &mut gs_raster::Rasterizer) -> Result<Value> {
        let (mesh, report) = extract_mesh(&tr.model()?, rasterizer, &self.mesh)?;
        let m = evaluate_meshes(&mesh, &self.gt, &self.eval)?.metrics;
        Ok(json!({ "chamfer": m.chamfer, "f1": m.f1, "accuracy": m.accuracy, "completeness": m.completeness, "triangles": report.triangles }))
    }
}

/// The open curve file of a training run.
pub struct MetricsLog {
    path: PathBuf,
    file: BufWriter<File>,
    sums: Sums,
    heldout_every: u64,
    rasterizer: Option<gs_raster::Rasterizer>,
    mesh_track: Option<MeshTrack>,
    /// A scoring point moved off an opacity reset (see [`MetricsLog::record`]).
    deferred: Option<u64>,
}

impl MetricsLog {
    /// Opens `OUT/metrics.jsonl`: a fresh run starts it empty; a run resumed at iteration
    /// `resumed_from` keeps the lines up to it (a line cut short by a kill is dropped).
    /// Held-out scoring (when `test` views exist) and the mesh curve render on the CPU.
    pub fn open(out: &Path, resumed_from: Option<u64>, iterations: u64, has_test: bool, mesh_track: Option<MeshTrack>) -> Result<Self> {
        let path = out.join("metrics.jsonl");
        let kept = match resumed_from {
            Some(from) => kept_lines(&path, from),
            None => String::new(),
        };
        gs_io::write_atomic(&path, |w| w.write_all(kept.as_bytes()))?;
        let file = std::fs::OpenOptions::new()
            .append(true)
            .open(&path)
            .with_context(|| format!("{}: cannot open the training curves for writing", path.display()))?;
        let rasterizer =
            if has_test || mesh_track.is_some() { Some(gs_raster::Rasterizer::new(gs_raster::Backend::Cpu)?) } else { None };
        Ok(Self {
            path,
            file: BufWriter::new(file),
            sums: Sums::default(),
            heldout_every: (iterations / HELDOUT_POINTS).max(1),
            rasterizer,
            mesh_track,
            deferred: None,
        })
    }

    /// Records iteration `r` at `seconds` of training; scores the held-out views `test` when
    /// one is due. Returns the time the scoring took (to leave out of the training time).
    pub fn record(&mut self, tr: &mut Trainer, r: &StepReport, seconds: f64, test: &[usize], last: bool) -> Result<Duration> {
        self.sums.add(r);
        if r.iteration % LOSS_EVERY == 0 || last {
            let line = json!({ "iteration": r.iteration, "seconds": seconds, "gaussians": r.gaussians, "loss": self.sums.means() });
            self.write(&line)?;
            self.sums = Sums::default();
        }
        let t0 = Instant::now();
        // A point that falls on an opacity reset would score a transparent model (4.6 dB and
        // no mesh on synth-bunny's default run): it moves half an interval later, once the
        // opacities have come back. (A resume in between drops that one point.)
        let on_grid = r.iteration % self.heldout_every == 0;
        if on_grid && r.opacity_reset && !last {
            self.deferred = Some(r.iteration + (self.heldout_every / 2).max(1));
        }
        let due = (on_grid && !r.opacity_reset) || self.deferred == Some(r.iteration) || last;
        if let Some(rasterizer) = self.rasterizer.as_mut()
            && due
        {
            let mut lines = Vec::new();
            if !test.is_empty() {
                let m = gs_train::evaluate_images(&tr.model()?, rasterizer, test, None, gs_train::PixelMasks::None)?;
                lines.push(json!({ "iteration": r.iteration, "seconds": seconds, "heldout_psnr": m.psnr, "heldout_ssim": m.ssim }));
            }
            if let Some(track) = &self.mesh_track {
                // An early model may have no surface to mesh yet: the curve says so and goes on.
                let mut line = track.score(tr, rasterizer).unwrap_or_else(|e| json!({ "mesh_error": crate::error::chain_text(&e) }));
                line["iteration"] = json!(r.iteration);
                line["seconds"] = json!(seconds);
                lines.push(line);
            }
            for line in &lines {
                self.write(line)?;
            }
        }
        Ok(t0.elapsed())
    }

    fn write(&mut self, line: &Value) -> Result<()> {
        writeln!(self.file, "{line}").and_then(|_| self.file.flush()).with_context(|| format!("{}: cannot write the training curves", self.path.display()))
    }
}

/// The whole lines of `path` whose iteration is at most `from` (nothing if it is missing).
fn kept_lines(path: &Path, from: u64) -> String {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let mut kept = String::new();
    for line in text.lines() {
        let it = serde_json::from_str::<Value>(line).ok().and_then(|v| v.get("iteration").and_then(Value::as_u64));
        if it.is_some_and(|it| it <= from) {
            kept.push_str(line);
            kept.push('\n');
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_resume_keeps_the_lines_up_to_its_checkpoint_and_drops_a_cut_line() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("metrics.jsonl");
        std::fs::write(&p, "{\"iteration\":10}\n{\"iteration\":20}\n{\"iteration\":30}\n{\"itera").unwrap();
        assert_eq!(kept_lines(&p, 20), "{\"iteration\":10}\n{\"iteration\":20}\n");
        assert_eq!(kept_lines(&dir.path().join("missing"), 20), "");
    }
}
