#![cfg(feature = "wgpu")]
//! Training on wgpu with the model resident on the device: N + resume N iterations gives the
//! same state bit for bit as 2N (the parameters, the moments and the source-depth memo come
//! back from the device for the checkpoint, between two density-control steps, in the L_p
//! phase; the densifications run on the device), reading the state back mid-run changes
//! nothing of the run, and Adam runs on the device.
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
    let mut densified_on_device = 0;
    straight.run(|_, r| {
        densified_on_device += r.densify.is_some_and(|d| d.on_device) as usize;
        true
    })
    .unwrap();
    assert!(densified_on_device > 0, "clone / split / prune ran on the device");

    // Stopped at 55, after the opacity reset of 50 and before the densification of 60: the
    // parameters, the moments and the gathering statistics live on the device there and come
    // back only when the state is read.
    let mut first = on_wgpu(&scene, None).unwrap();
    first.run(|_, r| r.iteration < 55).unwrap();
    assert!(!first.host_current(), "a device step leaves the host's copy behind");
    let bytes = first.checkpoint(&Default::default()).unwrap();
    assert!(first.host_current());
    let ck = checkpoint::decode(&bytes, std::path::Path::new("checkpoint.bin")).unwrap();
    assert!(ck.state.stats.grad_sum.iter().any(|&g| g > 0.0), "the statistics gather");
    let mut resumed = on_wgpu(&scene, Some(ck.state)).unwrap();
    resumed.run(|_, _| true).unwrap();
    // The run that was read stays resident and goes on as if it had not been.
    first.run(|_, _| true).unwrap();
    assert_eq!(resumed.iteration(), straight.iteration());
    assert!(straight.gaussian_count() != 400, "densification ran");
    let end = straight.state().unwrap().clone();
    assert_eq!(resumed.state().unwrap(), &end, "parameters, optimiser and statistics must match bit for bit");
    assert_eq!(first.state().unwrap(), &end, "a mid-run readback changes nothing");
}

/// L_o reads the opacity logits, which move on the device only: with the host's copy behind,
/// the step reads them back first. Its value must be the entropy of the logits the device
/// holds (read by a twin run), not of the host's stale copy.
#[test]
fn the_opacity_term_reads_the_device_logits() {
    use gs_losses::opacity::entropy_of_logit;
    let scene = small_scene();
    let (train, _) = scene.split(false);
    let cfg = gs_train::TrainConfig { weights: gs_train::LossWeights { lambda_o: 0.01, ..config().weights }, ..config() };
    let at = cfg.warmup_end + 3;
    let start = |scene| -> Option<Trainer> {
        let mut t = Trainer::new(scene, train.clone(), cfg.clone()).unwrap();
        t.set_backend(Backend::Wgpu).ok()?;
        t.run(|_, r| r.iteration < at).unwrap();
        Some(t)
    };
    let Some(mut blind) = start(&scene) else {
        gs_testdata::skip_or_fail!("no wgpu adapter", "install mesa-vulkan-drivers for lavapipe");
        return;
    };
    let mut twin = start(&scene).unwrap();
    let logits = twin.gaussians().unwrap().opacity_logits.clone();
    let expected = logits.iter().map(|x| entropy_of_logit(*x as f64)).sum::<f64>() / logits.len() as f64;
    assert!(!blind.host_current(), "the host's copy is behind before the step");
    let r = blind.step().unwrap();
    let got = r.losses.opacity_entropy.expect("L_o runs after the warm-up");
    assert_eq!(got, expected, "L_o of iteration {} reads the device's logits", r.iteration);
}
