//! The Slurm features a partition plan's job array relies on, checked on a real cluster
//! (`scripts/slurm-local.sh start`): an array with --mem, --time, --requeue, --cpus-per-task,
//! --chdir and --output %A_%a runs every task under `sbatch --wait`; a failing task makes
//! `sbatch --wait` fail; a --mem or --cpus-per-task no node has is refused at submit; a
//! requeued task runs again.

use std::path::{Path, PathBuf};
use std::process::Output;

/// A fresh folder for one test's job files (jobs write there through --chdir).
fn job_dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("slurm").join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// `sbatch --wait --parsable` of `script` in `dir` with `args`.
fn submit(slurm: &gs_testdata::Slurm, dir: &Path, args: &[&str], script: &str) -> Output {
    let path = dir.join("job.sbatch");
    std::fs::write(&path, script).unwrap();
    slurm.command("sbatch").current_dir(dir).args(["--wait", "--parsable"]).args(args).arg(&path).output().unwrap()
}

fn text(o: &Output) -> String {
    format!("stdout: {}\nstderr: {}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

/// The job id `sbatch --parsable` printed.
fn job_id(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).trim().split(';').next().unwrap().to_string()
}

#[test]
fn an_array_runs_every_task_with_the_plan_directives() {
    let Some(slurm) = gs_testdata::slurm!() else { return };
    let dir = job_dir("array");
    let chdir = format!("--chdir={}", dir.display());
    let script = "#!/bin/sh\n#SBATCH --array=0-2\n#SBATCH --mem=100M\n#SBATCH --time=5\n#SBATCH --requeue\n\
                  #SBATCH --cpus-per-task=1\n#SBATCH --output=task-%A_%a.out\n\
                  echo \"task $SLURM_ARRAY_TASK_ID cpus $SLURM_CPUS_PER_TASK mem $SLURM_MEM_PER_NODE in $(pwd)\"\n";
    let o = submit(&slurm, &dir, &[&chdir], script);
    assert!(o.status.success(), "{}", text(&o));
    let id = job_id(&o);
    for t in 0..3 {
        let out = dir.join(format!("task-{id}_{t}.out"));
        let got = std::fs::read_to_string(&out).unwrap_or_else(|e| panic!("{}: {e}", out.display()));
        assert_eq!(got.trim(), format!("task {t} cpus 1 mem 100 in {}", dir.display()));
    }
}

#[test]
fn a_failing_task_fails_the_wait() {
    let Some(slurm) = gs_testdata::slurm!() else { return };
    let dir = job_dir("failing");
    let script = "#!/bin/sh\n#SBATCH --array=0-1\n#SBATCH --mem=50M\n#SBATCH --time=2\n#SBATCH --output=%A_%a.out\n\
                  exit $((SLURM_ARRAY_TASK_ID * 3))\n";
    let o = submit(&slurm, &dir, &[], script);
    // sbatch --wait exits with the highest exit code of the array's tasks.
    assert_eq!(o.status.code(), Some(3), "{}", text(&o));
}

#[test]
fn requests_no_node_can_meet_are_refused_at_submit() {
    let Some(slurm) = gs_testdata::slurm!() else { return };
    let dir = job_dir("too-large");
    // Refused at once rather than left pending for ever (sbatch --wait would never return).
    for (args, message) in [
        (["--mem=64T", "--time=1"], "Memory specification can not be satisfied"),
        (["--cpus-per-task=4096", "--time=1"], "More processors requested than permitted"),
    ] {
        let o = submit(&slurm, &dir, &args, "#!/bin/sh\ntrue\n");
        assert!(!o.status.success(), "{args:?}: {}", text(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(message), "{args:?}: {err}");
    }
}

#[test]
fn a_requeued_task_runs_again() {
    let Some(slurm) = gs_testdata::slurm!() else { return };
    let dir = job_dir("requeue");
    // The task requeues itself on its first run, as a block job does when it fails; Slurm
    // starts it again (after the cluster's requeue delay) with SLURM_RESTART_COUNT=1.
    let script = "#!/bin/sh\n#SBATCH --array=0-1\n#SBATCH --mem=50M\n#SBATCH --time=5\n#SBATCH --requeue\n\
                  #SBATCH --open-mode=append\n#SBATCH --output=%A_%a.out\n\
                  echo \"run ${SLURM_RESTART_COUNT:-0}\"\n\
                  if [ \"$SLURM_ARRAY_TASK_ID\" = 1 ] && [ \"${SLURM_RESTART_COUNT:-0}\" = 0 ]; then\n\
                    scontrol requeue \"${SLURM_ARRAY_JOB_ID}_${SLURM_ARRAY_TASK_ID}\"; sleep 60; exit 1\n\
                  fi\n";
    let o = submit(&slurm, &dir, &[], script);
    assert!(o.status.success(), "{}", text(&o));
    let id = job_id(&o);
    let runs = |t: u32| std::fs::read_to_string(dir.join(format!("{id}_{t}.out"))).unwrap();
    assert_eq!(runs(0).trim(), "run 0");
    let task1 = runs(1);
    assert!(task1.contains("run 0") && task1.contains("run 1"), "{task1}");
}
