#![cfg(feature = "wgpu")]
//! Density control through the executor on a resident model against the host's: a run trained
//! on the device to just before a step whose plan takes every part (densification, floater
//! removal, opacity reset, multi-view trim), refined once where the model lives and once by an
//! executor that refines on the host (its renders on the same device, the model uploaded from
//! the host's copy). The same report, and the same parameters, moments and statistics bit for
//! bit; the device's run stays resident throughout (its floater votes read the device's
//! records back, the densification before them having left the host's copy behind). Then a trim that would remove every
//! Gaussian keeps the most opaque one on both.
//!
//! Without any wgpu adapter the test prints a SKIPPED line and returns, except in CI.

use gs_core::NeighbourRule;
use gs_mvs::{SourceSelection, SourceViewSelector};
use gs_raster::{Backend, Rasterizer};
use gs_train::{ReferenceExecutor, RunInputs, StepExecutor, StepPlan, TrainConfig, TrainState, Trainer, plan_step};

mod common;

fn config() -> TrainConfig {
    let mut c = TrainConfig { sh_degree_max: 0, ..common::busy_config() };
    // Both floater rules: the votes of every view and the capture path.
    c.densify.floaters.enabled = true;
    c.densify.floaters.capture_path = true;
    // A trim that removes some: seen in at least half of the 21 training views.
    c.densify.trim_min_views = 10;
    c
}

/// An executor on wgpu, or `None` (skipped) without an adapter; `host_refine` keeps Adam and
/// density control on the host (as the 3D filter does).
fn on_wgpu(views: usize, cfg: &TrainConfig, host_refine: bool) -> Option<ReferenceExecutor> {
    match Rasterizer::new(Backend::Wgpu) {
        Ok(r) => Some(ReferenceExecutor::new(r, views, gs_train::TermsUsed::of(cfg), host_refine)),
        Err(e) => {
            gs_testdata::skip_or_fail!(&format!("no wgpu adapter: {e}"), "install mesa-vulkan-drivers for lavapipe");
            None
        }
    }
}

/// Refines `state` by `plan` on `device` (resident) and on a host-refining twin; compares.
fn refine_both(device: &mut ReferenceExecutor, run: &RunInputs<'_>, state: &mut TrainState, plan: &StepPlan) -> gs_train::RefineReport {
    device.pull(state).unwrap();
    let mut host_state = state.clone();
    let mut host = on_wgpu(run.train_views.len(), run.config, true).unwrap();
    let on_host = host.refine(run, &mut host_state, plan).unwrap();
    let on_device = device.refine(run, state, plan).unwrap();
    assert!(device.rasterizer().is_resident(), "the device refined the model where it lives");
    device.pull(state).unwrap();
    // The same report, but where the densification ran.
    assert_eq!(on_host.densify.map(|d| d.on_device), on_host.densify.map(|_| false));
    let said = |r: gs_train::RefineReport| gs_train::RefineReport { densify: r.densify.map(|d| gs_train::DensifyReport { on_device: false, ..d }), ..r };
    assert_eq!(said(on_device), said(on_host), "the same report");
    assert_eq!(state.gaussians, host_state.gaussians, "the parameters bit for bit");
    assert_eq!(state.adam, host_state.adam, "the moments bit for bit");
    assert_eq!(state.stats, host_state.stats, "the statistics bit for bit");
    on_device
}

#[test]
fn density_control_on_the_device_matches_the_hosts() {
    let scene = common::small_scene();
    let (train, _) = scene.split(false);
    let cfg = config();
    let mut trainer = Trainer::new(&scene, train.clone(), cfg.clone()).unwrap();
    let mut state: TrainState = trainer.state().unwrap().clone();
    let cams = scene.cameras_of(&train);
    let selector = SourceViewSelector::new(&cams, &NeighbourRule::default(), cfg.source_views, SourceSelection::RandomN).unwrap();
    let Some(mut device) = on_wgpu(train.len(), &cfg, false) else { return };
    let (budget, raster) = (*trainer.budget(), trainer.raster_config().clone());
    let run = RunInputs { config: &cfg, scene: &scene, train_views: &train, extent: trainer.extent(), raster: &raster, budget: &budget };
    let mut profile = gs_train::StepProfile::default();
    // Up to iteration 35 with the run's own density control (densified at 10, 30), on the device.
    let mut step = |device: &mut ReferenceExecutor, state: &mut TrainState, it: u64| {
        let plan = plan_step(&cfg, &train, &selector, run.extent, it);
        device.execute(&run, state, &plan, &mut profile).unwrap();
        state.iteration = it;
        plan
    };
    for it in 1..=35 {
        let plan = step(&mut device, &mut state, it);
        device.refine(&run, &mut state, &plan).unwrap();
    }
    let mut plan = step(&mut device, &mut state, 36);
    (plan.refine.densify, plan.refine.remove_floaters, plan.refine.reset_opacity, plan.refine.trim) = (true, true, true, true);
    let before = state.gaussians.len();
    let report = refine_both(&mut device, &run, &mut state, &plan);
    let (d, f) = (report.densify.unwrap(), report.floaters.unwrap());
    assert!(d.on_device && d.cloned + d.split > 0 && report.opacity_reset, "{report:?}");
    assert!(f.removed() > 0 && report.trimmed.unwrap() > 0, "the floater rule and the trim removed Gaussians: {report:?}");
    assert_ne!(state.gaussians.len(), before);

    // A trim that would remove every Gaussian keeps the most opaque one.
    let strict = TrainConfig { densify: gs_train::DensifyConfig { trim_min_views: 1000, ..cfg.densify.clone() }, ..cfg.clone() };
    let run = RunInputs { config: &strict, ..run };
    let mut plan = plan_step(&strict, &train, &selector, run.extent, 37);
    plan.refine = gs_train::RefinePlan { trim: true, ..Default::default() };
    let before = state.gaussians.len();
    let report = refine_both(&mut device, &run, &mut state, &plan);
    assert_eq!((report.trimmed, state.gaussians.len()), (Some(before - 1), 1));
}
