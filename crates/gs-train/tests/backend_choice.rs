#![cfg(feature = "wgpu")]
//! `--backend auto` by measurement (`Trainer::choose_backend`): with a wgpu adapter at hand
//! (lavapipe here, allowed as a software adapter) one step of the run, the first with L_p, is
//! timed on each backend and the faster is kept; the timing leaves the run as it was, so the
//! run that follows is byte for byte the run of the backend named outright. Without a
//! hardware adapter and without leave for a software one, the CPU, with no timing.
//!
//! Without any wgpu adapter the test prints a SKIPPED line and returns, except in CI.

use gs_core::NeighbourRule;
use gs_mvs::{SourceSelection, SourceViewSelector};
use gs_raster::Backend;
use gs_train::{TrainConfig, Trainer, plan_step};

mod common;

#[test]
fn auto_times_a_step_on_each_backend_and_keeps_the_faster() {
    let scene = common::small_scene();
    let (train, _) = scene.split(false);
    let cfg = TrainConfig { sh_degree_max: 0, ..common::busy_config() };
    let mut auto = Trainer::new(&scene, train.clone(), cfg.clone()).unwrap();
    let choice = auto.choose_backend(true).unwrap();
    let Some(probe) = choice.probe else {
        gs_testdata::skip_or_fail!(&format!("no step timed on a wgpu adapter ({})", choice.in_words()), "install mesa-vulkan-drivers for lavapipe");
        return;
    };
    eprintln!("{}", choice.in_words());
    assert!(probe.cpu_ms > 0.0 && probe.wgpu_ms > 0.0, "{probe:?}");
    assert_eq!(choice.chosen, if probe.wgpu_ms < probe.cpu_ms { "wgpu" } else { "cpu" }, "the faster: {probe:?}");
    assert_eq!(auto.rasterizer().backend_name(), choice.chosen);
    // The step timed is the first of the L_p phase, on the initial model.
    let cams = scene.cameras_of(&train);
    let selector = SourceViewSelector::new(&cams, &NeighbourRule::default(), cfg.source_views, SourceSelection::RandomN).unwrap();
    let plan = plan_step(&cfg, &train, &selector, auto.extent(), probe.iteration);
    assert!(plan.photometric.is_some() && probe.iteration == cfg.warmup_end + 1, "iteration {}", probe.iteration);
    assert_eq!((probe.gaussians, auto.iteration()), (auto.gaussian_count(), 0), "the run's state as it was");
    // The run is the chosen backend's, byte for byte.
    let until = cfg.warmup_end + 6;
    auto.run(|_, r| r.iteration < until).unwrap();
    let mut named = Trainer::new(&scene, train.clone(), cfg.clone()).unwrap();
    named.set_backend(if choice.chosen == "wgpu" { Backend::Wgpu } else { Backend::Cpu }).unwrap();
    named.run(|_, r| r.iteration < until).unwrap();
    assert_eq!(auto.state().unwrap().gaussians, named.state().unwrap().gaussians, "the same model as the backend named outright");
    // Without leave for a software adapter, and no hardware one: the CPU, untimed.
    if !gs_gpu::hardware_adapter_available() {
        let mut cpu_only = Trainer::new(&scene, train.clone(), cfg.clone()).unwrap();
        let choice = cpu_only.choose_backend(false).unwrap();
        assert_eq!((choice.chosen.as_str(), choice.probe), ("cpu", None));
        assert!(choice.in_words().contains("no GPU"), "{}", choice.in_words());
    }
}
