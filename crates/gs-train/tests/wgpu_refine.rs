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

/// Trains `cfg` on the device to iteration 36 with the run's own density control (densified
/// at 10 and 30), from the initial state as `prepare` leaves it, and hands the executor, the
/// run, the state and iteration 36's plan to `body`.
fn trained(
    cfg: &TrainConfig,
    prepare: impl FnOnce(&mut TrainState, &[&gs_core::Camera]),
    body: impl FnOnce(&mut ReferenceExecutor, &RunInputs<'_>, &mut TrainState, StepPlan, &SourceViewSelector),
) {
    let scene = common::small_scene();
    let (train, _) = scene.split(false);
    let mut trainer = Trainer::new(&scene, train.clone(), cfg.clone()).unwrap();
    let mut state: TrainState = trainer.state().unwrap().clone();
    prepare(&mut state, &scene.cameras_of(&train));
    let cams = scene.cameras_of(&train);
    let selector = SourceViewSelector::new(&cams, &NeighbourRule::default(), cfg.source_views, SourceSelection::RandomN).unwrap();
    let Some(mut device) = on_wgpu(train.len(), cfg, false) else { return };
    let (budget, raster) = (*trainer.budget(), trainer.raster_config().clone());
    let run = RunInputs { config: cfg, scene: &scene, train_views: &train, extent: trainer.extent(), raster: &raster, budget: &budget };
    let mut profile = gs_train::StepProfile::default();
    let mut step = |device: &mut ReferenceExecutor, state: &mut TrainState, it: u64| {
        let plan = plan_step(cfg, &train, &selector, run.extent, it);
        device.execute(&run, state, &plan, &mut profile).unwrap();
        state.iteration = it;
        plan
    };
    for it in 1..=35 {
        let plan = step(&mut device, &mut state, it);
        device.refine(&run, &mut state, &plan).unwrap();
    }
    let plan = step(&mut device, &mut state, 36);
    body(&mut device, &run, &mut state, plan, &selector);
}

#[test]
fn density_control_on_the_device_matches_the_hosts() {
    let cfg = config();
    trained(&cfg, |_, _| {}, |device, run, state, mut plan, selector| {
        (plan.refine.densify, plan.refine.remove_floaters, plan.refine.reset_opacity, plan.refine.trim) = (true, true, true, true);
        let before = state.gaussians.len();
        let report = refine_both(device, run, state, &plan);
        let (d, f) = (report.densify.unwrap(), report.floaters.unwrap());
        assert!(d.on_device && d.cloned + d.split > 0 && report.opacity_reset, "{report:?}");
        assert!(f.removed() > 0 && report.trimmed.unwrap() > 0, "the floater rule and the trim removed Gaussians: {report:?}");
        assert_ne!(state.gaussians.len(), before);

        // A trim that would remove every Gaussian keeps the most opaque one.
        let strict = TrainConfig { densify: gs_train::DensifyConfig { trim_min_views: 1000, ..cfg.densify.clone() }, ..cfg.clone() };
        let run = RunInputs { config: &strict, ..*run };
        let mut plan = plan_step(&strict, run.train_views, selector, run.extent, 37);
        plan.refine = gs_train::RefinePlan { trim: true, ..Default::default() };
        let before = state.gaussians.len();
        let report = refine_both(device, &run, state, &plan);
        assert_eq!((report.trimmed, state.gaussians.len()), (Some(before - 1), 1));
    });
}

/// The capture-path rule alone (the default floater rule), after a densification that left
/// the host's copy behind: tested where the model lives, with the host's report and bits, and
/// without the model crossing (less read back than a byte a Gaussian). Splats planted beside
/// the first training camera, just in front of its image plane and outside every view, stay
/// there untouched until the rule removes them.
#[test]
fn the_capture_path_alone_removes_on_the_device_without_reading_the_model() {
    let mut cfg = config();
    cfg.densify.floaters.enabled = false;
    let plant = |state: &mut TrainState, cams: &[&gs_core::Camera]| {
        let (c, spacing) = (cams[0].center(), cams[0].center().distance(cams[1].center()));
        let forward = cams[0].rotation.transpose() * gs_core::glam::DVec3::Z;
        let side = forward.cross(gs_core::glam::DVec3::Z).normalize();
        let mut sh = [[0.0; 3]; 16];
        sh[0] = [0.5; 3];
        for k in 0..5 {
            let at = c + side * spacing * (0.2 + 0.05 * k as f64) + forward * spacing * 0.05;
            state.gaussians.push(at.as_vec3().to_array(), [-6.0; 3], [1.0, 0.0, 0.0, 0.0], 0.0, sh);
        }
        state.adam.extend_rows(5);
        state.stats = gs_core::DensifyStats::new(state.gaussians.len());
    };
    trained(&cfg, plant, |device, run, state, plan, _| {
        let ctx = device.rasterizer().gpu_context().cloned().expect("on wgpu");
        let mut host = on_wgpu(run.train_views.len(), run.config, true).unwrap();
        device.pull(state).unwrap();
        let mut host_state = state.clone();
        let [densify, floaters] = [
            StepPlan { refine: gs_train::RefinePlan { densify: true, ..Default::default() }, ..plan.clone() },
            StepPlan { refine: gs_train::RefinePlan { remove_floaters: true, ..Default::default() }, ..plan },
        ];
        device.refine(run, state, &densify).unwrap();
        host.refine(run, &mut host_state, &densify).unwrap();
        // The floater rule's traffic alone, the host's copy behind the device's after the densification.
        let before = ctx.transfers();
        let on_device = device.refine(run, state, &floaters).unwrap();
        let moved = ctx.transfers() - before;
        let on_host = host.refine(run, &mut host_state, &floaters).unwrap();
        device.pull(state).unwrap();
        let f = on_device.floaters.unwrap();
        eprintln!("capture path on the device: {f:?}; {} bytes read back, {} waits, for {} Gaussians", moved.bytes_down, moved.syncs, state.gaussians.len());
        assert!(f.on_capture_path > 0 && f.see_through + f.outside_all_frusta == 0, "{f:?}");
        assert_eq!(on_host.floaters, on_device.floaters, "the same report");
        assert!(state.gaussians == host_state.gaussians && state.adam == host_state.adam && state.stats == host_state.stats, "the host's model, bit for bit");
        assert!(moved.bytes_down <= 16, "{} bytes read back", moved.bytes_down);
    });
}
