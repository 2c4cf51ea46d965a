#![cfg(feature = "wgpu")]
//! Training on wgpu with the model resident on the device: N + resume N iterations gives the
//! same state bit for bit as 2N (the moments come back from the device for the checkpoint,
//! between two density-control steps), and Adam runs on the device.
//!
//! Without any wgpu adapter the test prints a SKIPPED line and returns, except in CI.

use gs_raster::Backend;
use gs_train::{Trainer, checkpoint};

mod common;
use common::{busy_config as config, small_scene};

/// A trainer on wgpu, or `None` (skipped) without an adapter.
fn on_wgpu<'s>(scene: &'s gs_core::Scene, state: Option<gs_train::TrainState>) -> Option<Trainer<'s>> {
    let (train, _) = scene.split(false);
    let mut t = match state {
        Some(s) => Trainer::with_state(scene, train, config(), s).unwrap(),
        None => Trainer::new(scene, train, config()).unwrap(),
    };
    match t.set_backend(Backend::Wgpu) {
        Ok(()) => Some(t),
        Err(e) => {
            gs_testdata::skip_or_fail!(&format!("no wgpu adapter: {e}"), "install mesa-vulkan-drivers for lavapipe");
            None
        }
    }
}

#[test]
fn a_resident_run_resumes_bit_identically() {
    let scene = small_scene();
    let Some(mut straight) = on_wgpu(&scene, None) else { return };
    let parts = straight.parts_on();
    let adam = parts.iter().find(|p| p.part == "Adam").unwrap();
    assert!(adam.on.starts_with("wgpu on "), "Adam runs on {}", adam.on);
    straight.run(|_, _| true).unwrap();

    // Stopped at 65, between the densification steps of 60 and 80: the moments live on the
    // device there and come back only through the sync.
    let mut first = on_wgpu(&scene, None).unwrap();
    first.run(|_, r| r.iteration < 65).unwrap();
    first.sync().unwrap();
    let bytes = checkpoint::encode(first.config(), first.state(), &Default::default());
    drop(first);
    let ck = checkpoint::decode(&bytes, std::path::Path::new("checkpoint.bin")).unwrap();
    let mut resumed = on_wgpu(&scene, Some(ck.state)).unwrap();
    resumed.run(|_, _| true).unwrap();
    assert_eq!(resumed.iteration(), straight.iteration());
    assert!(straight.gaussians().len() != 400, "densification ran");
    assert_eq!(resumed.state(), straight.state(), "parameters, optimiser and statistics must match bit for bit");
}
