//! Refactors must not change training: short CPU runs on the built-in scene produce exactly the
//! bytes recorded here. The digests are SHA-256 of the written files.
//!
//! - The paper's path: 60 iterations of the `dtu` schedule with the scene budget and floater
//!   removal off (`densify.gaussians_per_surface_pixel=0`, `densify.floaters.enabled=false`,
//!   `densify.floaters.capture_path=false`)
//!   still give the bytes of commit 2c307d5, from before issues #19 and #18. They cover every
//!   phase: colour warm-up to 21, edge + L_nc + L_ns + L_p to 45 (one densification at 25),
//!   L_f to 60. The second run adds per-view exposure compensation and the adaptive SH policy
//!   (one band judged and dropped).
//! - The budget, floater and CPU-schedule paths, recorded at issue #18 and re-recorded when
//!   `standard` took its CPU schedule (L_p to the end, no opacity reset) and again when it took
//!   source-view depths up to 10 iterations old (stop 31), and when the floater rule took the
//!   capture path (stop 33: one more splat removed, in front of the path), and when the capture
//!   path became a default at κ = 1.0 (stop 43: 117 removed, was 115; the same bytes at 1 and 2
//!   threads), and when the CPU presets took Mip-Splatting's screen filter (stop 45: 0.1 px²
//!   with opacity compensation; 90 removed; the same bytes at 1 and 2 threads), and when they
//!   took five L_p sources at 61,440 pixels each (stop 48: 101 removed; the same bytes at 1
//!   and 2 threads), and when `standard` took twice the paper's L_p weight (stop 51: 85
//!   removed; the same bytes at 1 and 2 threads): the default
//!   schedule with a budget
//!   small enough to bound the densification step (ρ = 0.15, B = 5,205) and the final floater
//!   removal switched on; colour warm-up to 21, then edge + L_nc + L_ns + L_p to 60.
//!
//! Results do not depend on the thread count (checked at 1 and 2 threads when recorded); the
//! runs use 2, as CI's machine has.
//!
//! If a change is *meant* to alter training, re-record the digests and say so in the commit.

use sha2::{Digest, Sha256};
use std::path::Path;
use std::process::Command;

fn sha256(path: &Path) -> String {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    Sha256::digest(&bytes).iter().map(|b| format!("{b:02x}")).collect()
}

fn train(out: &Path, extra: &[&str]) {
    let o = out.to_str().unwrap();
    let mut args = vec!["train", "-o", o, "--iterations", "60", "--backend", "cpu", "--quiet"];
    args.extend_from_slice(extra);
    let run = Command::new(env!("CARGO_BIN_EXE_vagsl")).args(&args).env("RAYON_NUM_THREADS", "2").output().expect("run vagsl");
    assert!(run.status.success(), "vagsl {args:?} failed:\n{}", String::from_utf8_lossy(&run.stderr));
}

#[test]
fn sixty_iterations_are_byte_identical_to_the_reference() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    train(&out, &PAPER_PATH);
    assert_eq!(
        sha256(&out.join("point_cloud.ply")),
        "2c1c9a1bfa1f502708cc3c7f3708a5094b41c98b6a8029bb4f3c7fd0c408072f",
        "point_cloud.ply of the 60-iteration reference run changed"
    );
}

/// The paper's density control: no scene budget, no floater removal.
const PAPER_PATH: [&str; 8] = [
    "--preset",
    "dtu",
    "--set",
    "densify.gaussians_per_surface_pixel=0",
    "--set",
    "densify.floaters.enabled=false",
    "--set",
    "densify.floaters.capture_path=false",
];

#[test]
fn the_budget_and_floater_paths_are_byte_identical_to_their_record() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    train(&out, &["--set", "densify.gaussians_per_surface_pixel=0.15", "--set", "densify.floaters.enabled=true"]);
    assert_eq!(
        sha256(&out.join("point_cloud.ply")),
        "376264560355f54d18f1dbd910b469d571809ec6dbd7b01ac353c085868a09bb",
        "point_cloud.ply of the 60-iteration budget + floater run changed"
    );
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["floaters_removed"].as_u64(), Some(85));
    assert!(report["growth_stopped"].as_str().unwrap().contains("budget"), "{report}");
}

#[test]
fn exposure_and_adaptive_sh_are_byte_identical_to_the_reference() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let mut args = PAPER_PATH.to_vec();
    args.extend(["--exposure", "--sh-policy", "adaptive", "--seed", "7"]);
    train(&out, &args);
    assert_eq!(
        sha256(&out.join("point_cloud.ply")),
        "e5d7d6d0bdd920beb22745404cf8a0ca79109a920521a14b6863a7eb09807447",
        "point_cloud.ply of the exposure + adaptive-SH reference run changed"
    );
    assert_eq!(
        sha256(&out.join("exposure.json")),
        "6519e824e5917be052a799bc8c0eca73212c25600e58fd88bfe7b1828bd2de56",
        "exposure.json of the reference run changed"
    );
}
