#![cfg(feature = "wgpu")]
//! Training on wgpu (issue #34; docs/architecture.md §GPU), on the built-in scene (200×150):
//! - two `--backend wgpu` runs with one seed write the same bytes: the wgpu backward sums
//!   every gradient in a fixed order (no float atomics), and the device's L_I, L_p and
//!   L_nc/L_ns kernels leave their sums to the host, so a GPU run repeats like a CPU run;
//! - the two executors train alike: a short run with one seed on the CPU and on wgpu reaches
//!   the same held-out PSNR within 0.2 dB.
//!
//! Kept small for lavapipe (software Vulkan on the CPU, about a second per iteration here).
//! Without any wgpu adapter each test prints one SKIPPED line and returns, except in CI
//! (`CI=true`), where a missing adapter is a failure.

use std::path::Path;
use std::process::Command;

/// Runs `vagsl ARGS` on 2 threads; panics with its stderr when it fails.
fn vagsl(args: &[&str]) {
    let run = Command::new(env!("CARGO_BIN_EXE_vagsl")).args(args).env("RAYON_NUM_THREADS", "2").output().expect("run vagsl");
    assert!(run.status.success(), "vagsl {args:?} failed:\n{}", String::from_utf8_lossy(&run.stderr));
}

/// Trains the built-in scene into `out` on `backend`: `iterations` of the default schedule
/// scaled to that length, seed 3, `extra` flags.
fn train(out: &Path, backend: &str, iterations: &str, extra: &[&str]) {
    let o = out.to_str().unwrap();
    vagsl(&[&["train", "-o", o, "--iterations", iterations, "--seed", "3", "--backend", backend, "--quiet"], extra].concat());
}

/// Whether a wgpu adapter exists; where none does, the test's one SKIPPED line (a failure
/// under `CI=true`).
fn adapter() -> bool {
    match gs_raster::probe_adapter() {
        Some(a) => {
            eprintln!("wgpu adapter: {a}");
            true
        }
        None => {
            gs_testdata::skip_or_fail!("no wgpu adapter", "install mesa-vulkan-drivers for lavapipe");
            false
        }
    }
}

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn two_wgpu_runs_with_one_seed_write_the_same_model() {
    if !adapter() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    train(&a, "wgpu", "30", &[]);
    train(&b, "wgpu", "30", &[]);
    let model = read(&a.join("point_cloud.ply"));
    assert!(model.len() > 1000, "a model of {} bytes", model.len());
    assert!(model == read(&b.join("point_cloud.ply")), "point_cloud.ply differs between the two wgpu runs");
    // The loss kernels, Adam and density control with the trim's counts and the capture path's
    // test (but the training views' floater votes) ran on the
    // device in these runs, and L_p and the normal terms ran at all.
    let report: serde_json::Value = serde_json::from_slice(&read(&a.join("report.json"))).unwrap();
    let on = report["loss_terms_on"].as_str().unwrap();
    assert!(on.starts_with("L_p, L_I and L_nc/L_ns on wgpu"), "{on}");
    let parts = report["parts_on"].as_array().unwrap();
    let on_device: Vec<&str> = parts.iter().filter(|p| p["on"].as_str().unwrap().starts_with("wgpu on ")).map(|p| p["part"].as_str().unwrap()).collect();
    assert_eq!(on_device, ["render and backward", "L_I (L1, D-SSIM, edge term)", "L_nc and L_ns", "L_p: NCC of the patches", "L_p: pixel selection, visibility υ and weight ω", "Adam", "densification statistics", "density control (clone, split, prune, opacity reset, trim, floater removal)", "the trim's view counts", "the capture path's floater test"], "{parts:?}");
    let lp_phase = &report["time_by_part"]["photometric"]["ms_per_iteration"];
    assert!(lp_phase["photometric"].as_f64().unwrap() > 0.0, "{report}");
    assert!(lp_phase["normal_losses"].as_f64().unwrap() > 0.0, "{report}");
}

/// Trains with held-out views on `backend` and returns the held-out PSNR `eval-images` reports.
fn held_out_psnr(dir: &Path, backend: &str) -> f64 {
    let out = dir.join(backend);
    train(&out, backend, AGREEMENT_ITERATIONS, &["--eval"]);
    vagsl(&["eval-images", out.to_str().unwrap(), "--no-lpips"]);
    let scores: serde_json::Value = serde_json::from_slice(&read(&out.join("eval_images.json"))).unwrap();
    scores["psnr"].as_f64().unwrap()
}

/// Iterations of the agreement run: every phase of the schedule, scaled (L_I, L_nc, L_ns, L_p
/// and density control all act; L_f is off by default).
const AGREEMENT_ITERATIONS: &str = "300";

#[test]
fn cpu_and_wgpu_training_reach_the_same_held_out_psnr() {
    if !adapter() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cpu = held_out_psnr(dir.path(), "cpu");
    let gpu = held_out_psnr(dir.path(), "wgpu");
    eprintln!("held-out PSNR after {AGREEMENT_ITERATIONS} iterations: {cpu:.3} dB on the CPU, {gpu:.3} dB on wgpu");
    assert!(cpu > 15.0 && gpu > 15.0, "both runs learnt the scene: {cpu} and {gpu} dB");
    assert!((cpu - gpu).abs() <= 0.2, "the executors differ by {:.3} dB ({cpu:.3} on the CPU, {gpu:.3} on wgpu)", cpu - gpu);
}
