//! Jobs too large for the machine are refused with a message instead of running out of memory,
//! and bad output paths or options are refused before the work (issue #21).

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

fn vagsl(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_vagsl")).args(args).output().expect("run vagsl");
    (out.status.success(), String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned())
}

/// A 4-iteration run of the built-in scene in `dir`/run.
fn tiny_run(dir: &Path) -> String {
    let run = dir.join("run");
    let o = run.to_str().unwrap().to_string();
    let (ok, _, err) = vagsl(&["train", "-o", &o, "--iterations", "4", "--backend", "cpu", "--quiet"]);
    assert!(ok, "{err}");
    o
}

#[test]
fn mesh_memory_is_estimated_before_fusing() {
    let dir = tempfile::tempdir().unwrap();
    let run = tiny_run(dir.path());
    // A voxel of 1e-9: refused from the probe views, quickly, naming estimate, limit and flags.
    let t = Instant::now();
    let (ok, _, err) = vagsl(&["mesh", &run, "--backend", "cpu", "--voxel-size", "1e-9"]);
    assert!(!ok, "{err}");
    assert!(t.elapsed() < Duration::from_secs(60), "took {:?}", t.elapsed());
    assert!(err.contains("needs about") && err.contains("GiB") && err.contains("TSDF blocks"), "{err}");
    assert!(err.contains("memory limit of") && err.contains("--voxel-size") && err.contains("--max-memory"), "{err}");
    assert!(!Path::new(&run).join("mesh.ply").exists());
    // The default mesh fits the default limit; a 1 MB limit refuses it.
    let (ok, stdout, err) = vagsl(&["mesh", &run, "--backend", "cpu"]);
    assert!(ok && stdout.contains("triangles"), "{err}");
    let (ok, _, err) = vagsl(&["mesh", &run, "--backend", "cpu", "--max-memory", "1MB", "-o", dir.path().join("m.ply").to_str().unwrap()]);
    assert!(!ok && err.contains("memory limit of 976.6 KiB"), "{err}");
    // Sizes with units only.
    let (ok, _, err) = vagsl(&["mesh", &run, "--max-memory", "3 parsecs"]);
    assert!(!ok && err.contains("unknown size unit"), "{err}");
}

#[test]
fn training_memory_is_estimated_before_training() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let o = out.to_str().unwrap();
    // 10 MiB cannot hold even the photos: refused before any training, naming the estimate,
    // its parts, the limit and the flags to change; no output folder is created.
    let t = Instant::now();
    let (ok, _, err) = vagsl(&["train", "-o", o, "--preset", "dtu", "--backend", "cpu", "--quiet", "--max-memory", "10MiB"]);
    assert!(!ok, "{err}");
    assert!(t.elapsed() < Duration::from_secs(60), "took {:?}", t.elapsed());
    assert!(err.contains("training needs about") && err.contains("more than the memory limit of 10.0 MiB"), "{err}");
    assert!(err.contains("Gaussians (the scene's budget)") && err.contains("VGG feature maps of L_f"), "{err}");
    assert!(err.contains("--max-memory") && err.contains("--no-features") && err.contains("-r 2"), "{err}");
    assert!(!out.exists(), "a refused start created its output folder");
    // Without L_f (switched off, or the default schedule with no L_f phase) its maps leave the
    // estimate; a roomy limit lets the run go on and print it.
    let (ok, _, err) = vagsl(&["train", "-o", o, "--preset", "dtu", "--backend", "cpu", "--quiet", "--max-memory", "10MiB", "--no-features"]);
    assert!(!ok && !err.contains("VGG") && !err.contains("--no-features"), "{err}");
    let (ok, _, err) = vagsl(&["train", "-o", o, "--backend", "cpu", "--quiet", "--max-memory", "10MiB"]);
    assert!(!ok && !err.contains("VGG") && err.contains("per-view caches"), "{err}");
    let (ok, _, err) = vagsl(&["train", "-o", o, "--iterations", "2", "--backend", "cpu", "--quiet", "--max-memory", "8GiB"]);
    assert!(ok && err.contains("memory estimate: about") && err.contains("limit 8.0 GiB"), "{err}");
}

#[test]
fn tradeoff_meshes_go_through_the_mesh_memory_check() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ladder");
    let o = out.to_str().unwrap();
    let (ok, _, err) = vagsl(&["tradeoff", "-o", o, "--iterations", "2", "--backend", "cpu", "--max-memory", "1MB"]);
    assert!(!ok, "{err}");
    assert!(err.contains("meshing the '") && err.contains("more than the memory limit of") && err.contains("--max-memory"), "{err}");
}

#[test]
fn bad_outputs_and_options_are_refused_before_the_work() {
    let dir = tempfile::tempdir().unwrap();
    let o = dir.path().join("x");
    let (ok, _, err) = vagsl(&["train", "-o", o.to_str().unwrap(), "--checkpoint-every", "0"]);
    assert!(!ok && err.contains("--checkpoint-every") && err.contains("0 is not in 1.."), "{err}");
    assert!(!o.exists(), "nothing trained");
    let run = dir.path().join("run");
    let r = run.to_str().unwrap();
    let (ok, _, err) = vagsl(&["train", "-o", r, "--iterations", "4", "--backend", "cpu", "--quiet", "--eval"]);
    assert!(ok, "{err}");
    // mesh -o into a missing folder: refused before rendering or fusing.
    let bad = dir.path().join("missing").join("m.ply");
    let (ok, stdout, err) = vagsl(&["mesh", r, "--backend", "cpu", "-o", bad.to_str().unwrap()]);
    assert!(!ok && err.contains("m.ply") && err.contains("does not exist"), "{err}");
    assert!(!stdout.contains("triangles") && !err.contains("rasterizer"), "{stdout}{err}");
    // eval-images whose result file is a folder: refused before scoring (issue #35; a folder
    // that turns read-only later still gets the scores printed, then the error).
    std::fs::create_dir(run.join("eval_images.json")).unwrap();
    let (ok, stdout, err) = vagsl(&["eval-images", r, "--backend", "cpu", "--no-lpips"]);
    assert!(!ok && !stdout.contains("mean over"), "{stdout}");
    assert!(err.contains("folder, not a file") && err.contains("eval_images.json"), "{err}");
}
