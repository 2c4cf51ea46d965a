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
