//! The jobs of a plan (docs/architecture.md §Partitioned training): one script that trains a
//! block — a fresh run, the resume of a killed one from its checkpoint, or nothing when the
//! block is done — and the two scheduler files that run it once per block: a Slurm job array
//! (`slurm.sbatch`) and a Kubernetes Indexed Job (`k8s-job.yaml`). Any other runner (a shell
//! loop, GNU parallel) calls the script with the block's index.

use crate::plan::Plan;
use std::fmt::Write as _;
use std::path::Path;

/// How often a failed block task is requeued by the Slurm script before it gives up.
pub const RETRIES: u32 = 3;

/// The block script in a plan folder.
pub const BLOCK_SCRIPT: &str = "run-block.sh";
/// The Slurm batch script in a plan folder.
pub const SLURM_SCRIPT: &str = "slurm.sbatch";
/// The Kubernetes manifest in a plan folder.
pub const K8S_MANIFEST: &str = "k8s-job.yaml";

/// A block's checkpoint is written this often (iterations; `VAGSL_CHECKPOINT_EVERY` overrides
/// it when the job runs), so a killed job loses at most this much work.
pub const CHECKPOINT_EVERY: u64 = 500;

/// What the job files need besides the plan.
#[derive(Debug, Clone)]
pub struct RunnerOptions {
    /// The `vagsl` binary the jobs run (absolute; the `VAGSL` variable overrides it at run time).
    pub vagsl: String,
    /// The plan folder, absolute (the scheduler files name it).
    pub plan_dir: String,
    /// CPU cores per block job.
    pub cpus: u32,
    /// Memory requested per job, bytes (the largest block estimate with headroom).
    pub memory_bytes: u64,
    /// Time limit per job, seconds.
    pub time_seconds: u64,
    /// Container image of the Kubernetes job.
    pub image: String,
    /// The folder the Kubernetes volume is mounted at: it must hold the plan and the scene at
    /// the same paths as here.
    pub data_root: String,
}

/// Memory requested per job: the largest block estimate plus a quarter (the estimate is an
/// upper bound within 1.25× of the measured peak, RELIABILITY.md §Training memory, and a job
/// over its request is killed by the scheduler).
pub fn job_memory(plan: &Plan) -> u64 {
    let worst = plan.blocks.iter().map(|b| b.memory_bytes).max().unwrap_or(0);
    worst.saturating_add(worst / 4).max(256 << 20)
}

/// Shell-quotes `s` for bash (single quotes).
fn quote(s: &str) -> String {
    if !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c)) {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', "'\\''"))
    }
}

/// `run-block.sh`: trains block INDEX (the first argument, else `SLURM_ARRAY_TASK_ID`, else
/// `JOB_COMPLETION_INDEX`).
pub fn block_script(plan: &Plan, o: &RunnerOptions) -> String {
    let mut scene_args = Vec::new();
    if let Some(r) = plan.scene.resolution_factor {
        scene_args.push(format!("-r {r}"));
    }
    if let Some(w) = plan.scene.width {
        scene_args.push(format!("--width {w}"));
    }
    let mut cases = String::new();
    for b in &plan.blocks {
        let args: Vec<String> = crate::block_train_args(&plan.train_args, b.train.iterations, b.train.densify.region.as_ref()).iter().map(|a| quote(a)).collect();
        let _ = writeln!(cases, "  {}) args=({}) ;;", b.name(), args.join(" "));
    }
    let last = plan.blocks.len() - 1;
    format!(
        r#"#!/usr/bin/env bash
# Trains one block of the plan in this folder (made by `vagsl partition`): block INDEX is the
# first argument, else $SLURM_ARRAY_TASK_ID (Slurm job array), else $JOB_COMPLETION_INDEX
# (Kubernetes Indexed Job). A block already trained is left alone; a block whose job was
# killed resumes from its checkpoint (written every $VAGSL_CHECKPOINT_EVERY iterations, default
# {CHECKPOINT_EVERY}); otherwise a new run starts (replacing what a killed run left before its
# first checkpoint).
set -euo pipefail
plan="$(cd "$(dirname "${{BASH_SOURCE[0]}}")" && pwd)"
vagsl="${{VAGSL:-{vagsl}}}"
every="${{VAGSL_CHECKPOINT_EVERY:-{CHECKPOINT_EVERY}}}"
index="${{1:-${{SLURM_ARRAY_TASK_ID:-${{JOB_COMPLETION_INDEX:-}}}}}}"
if ! [[ "$index" =~ ^[0-9]+$ ]] || (( 10#$index > {last} )); then
  echo "run-block.sh: give a block index from 0 to {last} (got '$index')" >&2
  exit 2
fi
name="$(printf '%02d' "$((10#$index))")"
scene="$plan/blocks/$name"
run="$plan/runs/$name"
# Each block's training options: the plan's, with its share of the iterations.
case "$name" in
{cases}esac
if [[ -f "$run/point_cloud.ply" && -f "$run/report.json" ]] && grep -q '"interrupted": false' "$run/report.json"; then
  echo "block $name: already trained ($run)"
  exit 0
fi
if [[ -f "$run/checkpoint.bin" ]]; then
  echo "block $name: resuming from $run/checkpoint.bin"
  exec "$vagsl" train --resume "$run/checkpoint.bin" -o "$run" --checkpoint-every "$every" --quiet
fi
force=()
if [[ -e "$run/config.json" || -e "$run/point_cloud.ply" ]]; then force=(--force); fi
echo "block $name: training $scene"
exec "$vagsl" train "$scene" -o "$run" {scene_args}"${{args[@]}}" --checkpoint-every "$every" --quiet "${{force[@]}}"
"#,
        vagsl = o.vagsl,
        scene_args = scene_args.iter().map(|a| format!("{a} ")).collect::<String>(),
    )
}

/// `hh:mm:ss` (Slurm's `--time`).
fn clock(seconds: u64) -> String {
    format!("{}:{:02}:{:02}", seconds / 3600, seconds / 60 % 60, seconds % 60)
}

/// `slurm.sbatch`: a job array of one task per block, with the memory and time per task,
/// requeued when a node fails, the job is preempted, or the task fails ([`RETRIES`] times).
pub fn slurm_script(plan: &Plan, o: &RunnerOptions) -> String {
    let mib = o.memory_bytes.div_ceil(1 << 20);
    let dir = &o.plan_dir;
    format!(
        r#"#!/usr/bin/env bash
# Trains every block of the plan in {dir} as one task of a Slurm job array:
#   sbatch {dir}/{SLURM_SCRIPT}            (add --wait to block until all tasks end)
# then: vagsl merge {dir} -o MERGED && vagsl mesh MERGED
# Memory per task: the largest block's training estimate plus a quarter. Time: an upper bound
# from the iterations and image size; raise it here if tasks time out (a task killed at its
# limit and requeued resumes from its checkpoint).
#SBATCH --job-name=vagsl-blocks
#SBATCH --array=0-{last}
#SBATCH --cpus-per-task={cpus}
#SBATCH --mem={mib}M
#SBATCH --time={time}
#SBATCH --requeue
#SBATCH --open-mode=append
#SBATCH --output={dir}/logs/block-%a.log
export RAYON_NUM_THREADS="${{SLURM_CPUS_PER_TASK:-{cpus}}}"
bash {script} "$SLURM_ARRAY_TASK_ID" && exit 0
status=$?
# --requeue covers node failures and preemption; a task that fails is requeued here, up to
# {RETRIES} times (a killed block resumes from its checkpoint).
if (( ${{SLURM_RESTART_COUNT:-0}} < {RETRIES} )); then
  echo "block $SLURM_ARRAY_TASK_ID failed (exit $status): requeued (restart ${{SLURM_RESTART_COUNT:-0}} of {RETRIES})" >&2
  scontrol requeue "${{SLURM_ARRAY_JOB_ID}}_${{SLURM_ARRAY_TASK_ID}}"
fi
exit "$status"
"#,
        last = plan.blocks.len() - 1,
        cpus = o.cpus,
        time = clock(o.time_seconds),
        script = quote(&format!("{dir}/{BLOCK_SCRIPT}")),
    )
}

/// `k8s-job.yaml`: an Indexed Job (one completion per block, all in parallel), each pod running
/// the block script on a volume that holds the plan and the scene at their paths here.
pub fn k8s_manifest(plan: &Plan, o: &RunnerOptions) -> String {
    let n = plan.blocks.len();
    let mib = o.memory_bytes.div_ceil(1 << 20);
    let mut y = String::new();
    let _ = write!(
        y,
        r#"# Trains every block of the plan in {dir} as one completion of a Kubernetes Indexed Job:
#   kubectl apply -f {dir}/{K8S_MANIFEST}
# The volume "vagsl-data" (a PersistentVolumeClaim) must hold the plan and the scene at the
# same paths as on the machine that partitioned them; it is mounted at {root}. The image must
# provide bash and vagsl.
apiVersion: batch/v1
kind: Job
metadata:
  name: vagsl-blocks
spec:
  completionMode: Indexed
  completions: {n}
  parallelism: {n}
  backoffLimit: {retries}
  template:
    spec:
      restartPolicy: OnFailure
      containers:
        - name: block
          image: {image}
          command: ["bash", {script}]
          env:
            - name: VAGSL
              value: vagsl
            - name: RAYON_NUM_THREADS
              value: "{cpus}"
          resources:
            requests:
              cpu: "{cpus}"
              memory: {mib}Mi
            limits:
              memory: {mib}Mi
          volumeMounts:
            - name: vagsl-data
              mountPath: {root}
      volumes:
        - name: vagsl-data
          persistentVolumeClaim:
            claimName: vagsl-data
"#,
        dir = o.plan_dir,
        root = json_string(&o.data_root),
        retries = RETRIES as usize * n,
        image = json_string(&o.image),
        script = json_string(&format!("{}/{BLOCK_SCRIPT}", o.plan_dir)),
        cpus = o.cpus,
    );
    y
}

/// `s` as a JSON string, which is also a valid YAML scalar.
fn json_string(s: &str) -> String {
    serde_json::Value::String(s.to_string()).to_string()
}

/// Writes the three job files into the plan folder `dir` (the script executable).
pub fn write_runners(dir: &Path, plan: &Plan, o: &RunnerOptions) -> crate::Result<()> {
    use crate::error::Context;
    std::fs::create_dir_all(dir.join("logs")).with_context(|| format!("{}: cannot create the logs folder", dir.display()))?;
    for (name, text) in [(BLOCK_SCRIPT, block_script(plan, o)), (SLURM_SCRIPT, slurm_script(plan, o)), (K8S_MANIFEST, k8s_manifest(plan, o))] {
        let path = dir.join(name);
        gs_io::write_atomic(&path, |w| w.write_all(text.as_bytes()))?;
        #[cfg(unix)]
        if name != K8S_MANIFEST {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).with_context(|| format!("{}: cannot make it executable", path.display()))?;
        }
    }
    Ok(())
}

/// The time limit of every block job of `plan`, seconds: an upper bound of the most iterations a
/// block trains on views as large as its largest, at a conservative
/// [`SECONDS_PER_MEGAPIXEL_ITERATION`] per core (with L_p and L_f rendering source views), at
/// least half an hour.
pub fn time_limit(plan: &Plan, cpus: u32) -> u64 {
    let iterations = plan.blocks.iter().map(|b| b.train.iterations).max().unwrap_or(0);
    let pixels = plan.blocks.iter().map(|b| b.largest_view_pixels).max().unwrap_or(0);
    let work = iterations as f64 * pixels as f64 / 1e6 * SECONDS_PER_MEGAPIXEL_ITERATION / (cpus.max(1) as f64).sqrt();
    (3.0 * work).max(1800.0).min(7.0 * 86400.0) as u64
}

/// Seconds one training iteration takes per megapixel of the view, on one core of the 2-core
/// development VM: the street scene's block 00 (200×150, 1,189 iterations of the default) took
/// 228 s on one thread, 6.4 s per megapixel-iteration (BENCHMARKS.md §Partitioned training).
pub const SECONDS_PER_MEGAPIXEL_ITERATION: f64 = 6.4;
