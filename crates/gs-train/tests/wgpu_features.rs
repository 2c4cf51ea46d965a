#![cfg(feature = "wgpu")]
//! L_f through the `LossTerm` contract on a wgpu rasterizer: the feature alignment
//! (`gs_mvs::FeatureGpu`) runs on the device, and each view's VGG16 map
//! (`gs_features::Vgg16Gpu`) is made there on a hardware adapter (on lavapipe by the host's
//! faster code), and `parts_on` says so, and the first L_f step of one lent state gives the CPU
//! executor's L_f within 1e-4 relative (the renders of the two backends differ by float
//! error, the maps by their sums' order, the alignment's arithmetic by fused operations, ω by
//! the device's exp), with the sources' depths rendered for the step and from the depth memo;
//! υ/ω made on the device.
//!
//! Without any wgpu adapter the test prints a SKIPPED line and returns, except in CI.

use gs_core::NeighbourRule;
use gs_mvs::{SourceSelection, SourceViewSelector};
use gs_raster::{Backend, Rasterizer};
use gs_train::{ReferenceExecutor, RunInputs, StepExecutor, TermsUsed, TrainConfig, Trainer, plan_step};

mod common;

#[test]
fn the_feature_term_runs_on_the_device_and_matches_the_cpu() {
    // Sources rendered for the step (their depths on the host), and the depth memo (the
    // sources' and the reference's depths stay on the device).
    for max_age in [0, 10] {
        feature_step(max_age);
    }
}

/// The first L_f step of one lent state on both executors with `source_depth_max_age` =
/// `max_age`: L_f within 1e-4 relative; on the device υ/ω are made there, from the sources'
/// depths kept there (rendered for the step, or held by the memo), so a second run of the step
/// reads back less than one plane.
fn feature_step(max_age: u64) {
    let scene = common::small_scene();
    let (train, _) = scene.split(false);
    let cfg = TrainConfig { sh_degree_max: 0, source_depth_max_age: max_age, ..common::busy_config() };
    let cams = scene.cameras_of(&train);
    let selector = SourceViewSelector::new(&cams, &NeighbourRule::default(), cfg.source_views, SourceSelection::RandomN).unwrap();
    // The first iteration of the L_f phase whose view has sources.
    let extent = scene.extent_of(&train).max(1e-9);
    let first_lf = (cfg.photometric_end + 1..=cfg.features_end).find(|&it| !plan_step(&cfg, &train, &selector, extent, it).sources.is_empty()).unwrap();
    let mut trainer = Trainer::new(&scene, train.clone(), cfg.clone()).unwrap();
    trainer.run(|_, r| r.iteration < first_lf - 1).unwrap();
    let state = trainer.state().unwrap().clone();
    let plan = plan_step(&cfg, &train, &selector, trainer.extent(), first_lf);
    assert!(plan.phase.features && !plan.sources.is_empty(), "iteration {first_lf} runs L_f");
    let (budget, raster) = (*trainer.budget(), trainer.raster_config().clone());
    let run = RunInputs { config: &cfg, scene: &scene, train_views: &train, extent: trainer.extent(), raster: &raster, budget: &budget };
    // L_f, where each part ran, and whether the rasterizer's device is a software adapter.
    let lf = |backend: Backend| -> Option<(f64, Vec<gs_train::PartPlace>, bool, gs_gpu::Transfers)> {
        let r = match Rasterizer::new(backend) {
            Ok(r) => r,
            Err(e) => {
                gs_testdata::skip_or_fail!(&format!("no wgpu adapter: {e}"), "install mesa-vulkan-drivers for lavapipe");
                return None;
            }
        };
        let software = r.gpu_context().is_some_and(|c| c.is_software());
        let ctx = r.gpu_context().cloned();
        let mut executor = ReferenceExecutor::new(r, train.len(), TermsUsed::of(&cfg), false);
        let mut s = state.clone();
        let values = executor.execute(&run, &mut s, &plan, &mut gs_train::StepProfile::default()).unwrap();
        // The same step once more, with the run's arrays (photos, maps, grey images) and the
        // model on the device: what a step of a run moves.
        let before = ctx.as_ref().map(|c| c.transfers()).unwrap_or_default();
        executor.execute(&run, &mut s, &plan, &mut gs_train::StepProfile::default()).unwrap();
        let moved = ctx.as_ref().map(|c| c.transfers() - before).unwrap_or_default();
        Some((values.features.expect("L_f ran"), executor.parts_on(), software, moved))
    };
    let (cpu, ..) = lf(Backend::Cpu).unwrap();
    let Some((gpu, parts, software, moved)) = lf(Backend::Wgpu) else { return };
    let align = parts.iter().find(|p| p.part == "L_f: feature alignment").unwrap();
    assert!(align.on.starts_with("wgpu on "), "L_f's alignment runs on {}", align.on);
    // The maps are made on the device only where it is not this CPU (lavapipe: the host).
    let vgg = parts.iter().find(|p| p.part == "L_f: VGG16 features of each view (once a view)").unwrap();
    assert_eq!(vgg.on.starts_with("wgpu on "), !software, "L_f's VGG16 runs on {}", vgg.on);
    let rel = (cpu - gpu).abs() / cpu.abs();
    let plane = 4 * scene.views[train[plan.slot]].camera.width as u64 * scene.views[train[plan.slot]].camera.height as u64;
    eprintln!("max age {max_age}: L_f: CPU {cpu:.8e}, wgpu {gpu:.8e}, relative difference {rel:.2e}; {} bytes read back, a plane {plane}", moved.bytes_down);
    assert!(cpu > 0.0 && rel <= 1e-4, "L_f: CPU {cpu} against wgpu {gpu}");
    // No depth, weight or gradient plane comes back: each loss term's row sums and counts.
    assert!(moved.bytes_down < plane, "{} bytes read back in the step, a plane {plane}", moved.bytes_down);

}
