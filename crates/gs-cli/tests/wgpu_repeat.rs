#![cfg(feature = "wgpu")]
//! Two `--backend wgpu` runs with one seed write the same bytes: the wgpu backward sums every
//! gradient in a fixed order (no float atomics), and the device's L_I, L_p and L_nc/L_ns
//! kernels leave their sums to the host, so a GPU run repeats like a CPU run.
//!
//! Kept small for lavapipe (software Vulkan on the CPU, seconds per iteration): the built-in
//! scene (200×150), 30 iterations of the default schedule scaled to that length. Without
//! any wgpu adapter the test prints SKIPPED and returns, except in CI (`CI=true`), where a
//! missing adapter is a failure.

use std::path::Path;
use std::process::Command;

fn train(out: &Path) {
    let o = out.to_str().unwrap();
    let args = ["train", "-o", o, "--iterations", "30", "--seed", "3", "--backend", "wgpu", "--quiet"];
    let run = Command::new(env!("CARGO_BIN_EXE_vagsl")).args(args).env("RAYON_NUM_THREADS", "2").output().expect("run vagsl");
    assert!(run.status.success(), "vagsl {args:?} failed:\n{}", String::from_utf8_lossy(&run.stderr));
}

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn two_wgpu_runs_with_one_seed_write_the_same_model() {
    match gs_raster::probe_adapter() {
        Some(a) => eprintln!("wgpu adapter: {a}"),
        None if std::env::var("CI").is_ok_and(|v| v == "true" || v == "1") => {
            panic!("CI=true but no wgpu adapter (install mesa-vulkan-drivers)")
        }
        None => {
            eprintln!("SKIPPED: no wgpu adapter; install mesa-vulkan-drivers for lavapipe");
            return;
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    train(&a);
    train(&b);
    let model = read(&a.join("point_cloud.ply"));
    assert!(model.len() > 1000, "a model of {} bytes", model.len());
    assert!(model == read(&b.join("point_cloud.ply")), "point_cloud.ply differs between the two wgpu runs");
    // The loss kernels ran on the device in these runs, and L_p and the normal terms ran at all.
    let report: serde_json::Value = serde_json::from_slice(&read(&a.join("report.json"))).unwrap();
    let on = report["loss_terms_on"].as_str().unwrap();
    assert!(on.starts_with("L_p, L_I and L_nc/L_ns on wgpu"), "{on}");
    let lp_phase = &report["time_by_part"]["photometric"]["ms_per_iteration"];
    assert!(lp_phase["photometric"].as_f64().unwrap() > 0.0, "{report}");
    assert!(lp_phase["normal_losses"].as_f64().unwrap() > 0.0, "{report}");
}
