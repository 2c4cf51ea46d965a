//! `vagsl partition` → the blocks trained by their script (one killed by SIGTERM and resumed
//! from its checkpoint) → `vagsl merge` → `eval-images` and `mesh` on the merged run; and the
//! merge's refusals: a block not trained, interrupted, or trained on another scene.
#![cfg(unix)]

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

fn scene() -> PathBuf {
    gs_testdata::builtin::scene_dir(Path::new(env!("CARGO_TARGET_TMPDIR")), &gs_testdata::builtin::small())
}

fn vagsl(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_vagsl")).args(args).env("RAYON_NUM_THREADS", "2").output().unwrap();
    (out.status.success(), String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr))
}

/// Runs `PLAN/run-block.sh INDEX` to its end.
fn train_block(plan: &Path, index: usize) -> String {
    let out = Command::new("bash")
        .arg(plan.join("run-block.sh"))
        .arg(index.to_string())
        .env("VAGSL", env!("CARGO_BIN_EXE_vagsl"))
        .env("RAYON_NUM_THREADS", "2")
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "block {index}:\n{log}");
    log
}

/// Starts block `index`'s script and stops it with SIGTERM once training runs.
fn kill_block(plan: &Path, index: usize) {
    let mut child = Command::new("bash")
        .arg(plan.join("run-block.sh"))
        .arg(index.to_string())
        .env("VAGSL", env!("CARGO_BIN_EXE_vagsl"))
        .env("RAYON_NUM_THREADS", "2")
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (log, code) = common::signal_while_training(&mut child, libc::SIGTERM);
    assert_eq!(code, Some(143), "{log}");
    assert!(log.contains("interrupted at iteration"), "{log}");
}

#[test]
fn partition_train_kill_resume_merge_and_mesh() {
    let tmp = tempfile::tempdir().unwrap();
    let plan = tmp.path().join("plan");
    let p = plan.to_str().unwrap();
    let scene = scene();
    let (ok, log) = vagsl(&["partition", scene.to_str().unwrap(), "-o", p, "--blocks", "2", "--eval", "--", "--iterations", "300", "--backend", "cpu"]);
    assert!(ok, "{log}");
    assert!(log.contains("2 blocks") && log.contains("sbatch --wait") && log.contains("2 views held out"), "{log}");
    for f in ["plan.json", "run-block.sh", "slurm.sbatch", "k8s-job.yaml"] {
        assert!(plan.join(f).is_file(), "{f} missing");
    }
    let sbatch = std::fs::read_to_string(plan.join("slurm.sbatch")).unwrap();
    assert!(sbatch.contains("#SBATCH --array=0-1") && sbatch.contains("#SBATCH --requeue") && sbatch.contains("#SBATCH --mem="), "{sbatch}");

    let merged = tmp.path().join("merged");
    let m = merged.to_str().unwrap();
    let (ok, log) = vagsl(&["merge", p, "-o", m]);
    assert!(!ok && log.contains("block 00: no run in") && log.contains("run-block.sh 0"), "{log}");
    assert!(!merged.exists(), "a refused merge wrote {m}");

    kill_block(&plan, 0);
    let (ok, log) = vagsl(&["merge", p, "-o", m]);
    assert!(!ok && log.contains("block 00") && log.contains("interrupted"), "{log}");
    let resumed = train_block(&plan, 0);
    assert!(resumed.contains("resuming from") && resumed.contains("resuming"), "{resumed}");
    assert!(train_block(&plan, 0).contains("already trained"));
    train_block(&plan, 1);

    // A block run that is not of this plan's block scene.
    let cfg = plan.join("runs/01/config.json");
    let original = std::fs::read_to_string(&cfg).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&original).unwrap();
    v["fingerprint"]["cameras_sha256"] = "0".repeat(64).into();
    std::fs::write(&cfg, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    let (ok, log) = vagsl(&["merge", p, "-o", m]);
    assert!(!ok && log.contains("block 01") && log.contains("not trained on this plan's block scene"), "{log}");
    // ... or trained with other settings than the plan's.
    let mut v: serde_json::Value = serde_json::from_str(&original).unwrap();
    v["train"]["seed"] = 77.into();
    std::fs::write(&cfg, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    let (ok, log) = vagsl(&["merge", p, "-o", m]);
    assert!(!ok && log.contains("block 01") && log.contains("other settings than the plan gives it"), "{log}");
    std::fs::write(&cfg, original).unwrap();

    let (ok, log) = vagsl(&["merge", p, "-o", m]);
    assert!(ok, "{log}");
    assert!(log.contains("from 2 blocks") && log.contains("block 00: kept"), "{log}");
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(merged.join("report.json")).unwrap()).unwrap();
    let kept: u64 = report["blocks"].as_array().unwrap().iter().map(|b| b["gaussians_kept"].as_u64().unwrap()).sum();
    assert_eq!(kept, report["gaussians"].as_u64().unwrap());
    assert!(report["blocks"][0]["peak_memory_bytes"].as_u64().unwrap() > 0);

    let (ok, log) = vagsl(&["eval-images", m, "--backend", "cpu"]);
    assert!(ok && log.contains("mean over 2 views"), "{log}");
    let psnr: f64 = log.split("PSNR").last().unwrap().split_whitespace().next().unwrap().parse().unwrap();
    // A single run of this scene with the same 300 iterations scores 14.7 dB (2-core VM).
    assert!(psnr > 12.0, "merged run held out at {psnr} dB:\n{log}");
    let (ok, log) = vagsl(&["mesh", m, "--backend", "cpu"]);
    assert!(ok && merged.join("mesh.ply").is_file(), "{log}");
    assert!(log.contains("fused block by block: 2 blocks"), "{log}");
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(merged.join("mesh.json")).unwrap()).unwrap();
    assert_eq!(report["pieces"].as_array().map(Vec::len), Some(2), "{report}");
    // Block by block, the surface one volume makes (before the order-dependent simplification).
    let shape = |name: &str, extra: &[&str]| {
        let out = tmp.path().join(name);
        let (ok, log) = vagsl(&[&["mesh", m, "--backend", "cpu", "--no-simplify", "-o", out.to_str().unwrap()], extra].concat());
        assert!(ok, "{log}");
        gs_testdata::MeshShape::of(&gs_io::read_mesh_ply(&out).unwrap())
    };
    let (pieces, whole) = (shape("pieces.ply", &[]), shape("whole.ply", &["--whole"]));
    assert!(whole.triangles.len() > 1000 && pieces == whole, "{} against {} triangles", pieces.triangles.len(), whole.triangles.len());
    // A second merge does not overwrite the run without --force.
    let (ok, log) = vagsl(&["merge", p, "-o", m]);
    assert!(!ok && log.contains("already holds a vagsl run"), "{log}");
}

#[test]
fn options_that_belong_to_the_plan_are_refused_after_the_separator() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = scene();
    for (extra, words) in [("-o", "the plan sets it"), ("--eval", "the plan sets it"), ("--resume", "the plan sets it"), ("--no-such-flag", "the training options after `--`")] {
        let out = tmp.path().join("p");
        let (ok, log) = vagsl(&["partition", scene.to_str().unwrap(), "-o", out.to_str().unwrap(), "--blocks", "2", "--", extra, "x"]);
        assert!(!ok && log.contains(words), "{extra}: {log}");
        assert!(!out.exists());
    }
    let (ok, log) = vagsl(&["partition", scene.to_str().unwrap(), "-o", tmp.path().join("q").to_str().unwrap()]);
    assert!(!ok && log.contains("--blocks"), "{log}");
}

/// The plan's Kubernetes manifest passes the batch/v1 Job schema (strict, offline validator).
#[test]
fn the_kubernetes_manifest_is_a_valid_indexed_job() {
    let Some(k8s) = gs_testdata::k8s_validator!() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let plan = tmp.path().join("plan with space");
    let (ok, log) = vagsl(&["partition", scene().to_str().unwrap(), "-o", plan.to_str().unwrap(), "--blocks", "2", "--image", "registry.example/vagsl:1", "--", "--iterations", "50"]);
    assert!(ok, "{log}");
    let yaml = std::fs::read_to_string(plan.join("k8s-job.yaml")).unwrap();
    assert!(yaml.contains("completionMode: Indexed") && yaml.contains("completions: 2"), "{yaml}");
    k8s.check(&plan.join("k8s-job.yaml")).unwrap_or_else(|e| panic!("{e}\n{yaml}"));
}

/// On a real scheduler: the plan's job array trains both blocks (`sbatch --wait`); block 01's
/// training is killed (SIGTERM, as a node's OOM killer or an admin would) and its task is
/// requeued by the script and resumes from the checkpoint the kill left; then the merge and the
/// mesh run on the merged run.
#[test]
fn slurm_trains_the_blocks_of_a_plan() {
    let Some(slurm) = gs_testdata::slurm!() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let plan = tmp.path().join("plan");
    let p = plan.to_str().unwrap();
    let (ok, log) = vagsl(&["partition", scene().to_str().unwrap(), "-o", p, "--blocks", "2", "--eval", "--", "--iterations", "300", "--backend", "cpu"]);
    assert!(ok, "{log}");
    let sbatch =
        slurm.command("sbatch").current_dir(&plan).args(["--wait", "--parsable"]).arg(plan.join("slurm.sbatch")).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let block_log = |i: usize| std::fs::read_to_string(plan.join(format!("logs/block-{i}.log"))).unwrap_or_default();
    let started = std::time::Instant::now();
    while !block_log(1).contains("Gaussian budget") {
        assert!(started.elapsed().as_secs() < 300, "block 01 did not start training in 5 minutes:\n{}", block_log(1));
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let run = plan.join("runs/01");
    let pids = Command::new("pgrep").args(["-f", &format!("train .*{}", run.display())]).output().unwrap();
    let pids: Vec<i32> = String::from_utf8_lossy(&pids.stdout).split_whitespace().filter_map(|s| s.parse().ok()).collect();
    assert!(!pids.is_empty(), "no training process of block 01 found:\n{}", block_log(1));
    for pid in pids {
        // SAFETY: kill(2) on a process of this test's own block job.
        unsafe { libc::kill(pid, libc::SIGTERM) };
    }
    let out = sbatch.wait_with_output().unwrap();
    let logs = block_log(0) + &block_log(1);
    assert!(out.status.success(), "sbatch: {}\n{}\n{logs}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(logs.contains("block 00: training") && logs.contains("block 01: training"), "{logs}");
    let second = block_log(1);
    assert!(second.contains("requeued (restart 0") && second.contains("block 01: resuming from"), "{second}");
    let merged = tmp.path().join("merged");
    let (ok, log) = vagsl(&["merge", p, "-o", merged.to_str().unwrap()]);
    assert!(ok && log.contains("from 2 blocks"), "{log}");
    let (ok, log) = vagsl(&["mesh", merged.to_str().unwrap(), "--backend", "cpu"]);
    assert!(ok && log.contains("fused block by block"), "{log}");
}

/// The street scene (`vagsl synth --street`) is larger than one block: partitioned into 4
/// strips along the street, no block trains on more than 60 % of its views (a quarter of the
/// street plus its margins and the views that look into it: 29–40 of 70 measured), and together
/// they cover every training view.
#[test]
fn the_street_scene_partitions_into_strips_of_its_own_views() {
    let tmp = tempfile::tempdir().unwrap();
    let street = tmp.path().join("street");
    let (ok, log) = vagsl(&["synth", "--street", "--quick", "-o", street.to_str().unwrap()]);
    assert!(ok && log.contains("80 views"), "{log}");
    let (ok, log) = vagsl(&["info", street.to_str().unwrap()]);
    assert!(ok, "{log}");
    let plan = tmp.path().join("plan");
    let (ok, log) = vagsl(&["partition", street.to_str().unwrap(), "-o", plan.to_str().unwrap(), "--blocks", "4", "--eval"]);
    assert!(ok && log.contains("4 blocks") && log.contains("10 views held out"), "{log}");
    let p: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(plan.join("plan.json")).unwrap()).unwrap();
    let blocks = p["blocks"].as_array().unwrap();
    // Strips across the street's axis (+x): the ground frame's first axis follows it.
    assert!(p["frame"]["u"][0].as_f64().unwrap().abs() > 0.99, "{}", p["frame"]);
    let mut covered = std::collections::BTreeSet::new();
    for b in blocks {
        let views = b["views"].as_array().unwrap();
        assert!(views.len() <= 42, "block {} trains {} of 70 views", b["index"], views.len());
        covered.extend(views.iter().map(|v| v.as_str().unwrap().to_string()));
    }
    assert_eq!(covered.len(), 70, "every training view is in a block");
}
