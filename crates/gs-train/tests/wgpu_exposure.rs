#![cfg(feature = "wgpu")]
//! Exposure compensation through the executor on a wgpu rasterizer: the rendered colour stays
//! on the device, is corrected there (`gs_losses::ExposureGpu`) for L_I there, and L_I's
//! gradient goes back through the correction there; view k's (a, b) take their Adam step on
//! the host from the device's sums. One lent state, one step of the L_p phase on each executor
//! (the view's exposure moved away from the identity first): L1 within 1e-4 relative, and the
//! view's (a, b) after the step within 1e-6 of the CPU executor's (Adam's first steps move
//! each by the learning rate against its gradient's sign, which the two agree on); where each
//! part ran.
//!
//! Without any wgpu adapter the test prints a SKIPPED line and returns, except in CI.

use gs_core::NeighbourRule;
use gs_mvs::{SourceSelection, SourceViewSelector};
use gs_raster::{Backend, Rasterizer};
use gs_train::{ReferenceExecutor, RunInputs, StepExecutor, TermsUsed, TrainConfig, Trainer, plan_step};

mod common;

#[test]
fn the_exposure_correction_runs_on_the_device_and_matches_the_cpu() {
    let scene = common::small_scene();
    let (train, _) = scene.split(false);
    let cfg = TrainConfig { sh_degree_max: 0, exposure: true, ..common::busy_config() };
    let cams = scene.cameras_of(&train);
    let selector = SourceViewSelector::new(&cams, &NeighbourRule::default(), cfg.source_views, SourceSelection::RandomN).unwrap();
    let it = cfg.warmup_end + 2;
    let mut trainer = Trainer::new(&scene, train.clone(), cfg.clone()).unwrap();
    trainer.run(|_, r| r.iteration < it - 1).unwrap();
    let mut state = trainer.state().unwrap().clone();
    let plan = plan_step(&cfg, &train, &selector, trainer.extent(), it);
    // The view's correction away from the identity, so that both the gain and the bias act.
    state.exposure.as_mut().expect("exposure on").params[plan.slot] = [0.1, -0.05, 0.02, 0.01, -0.02, 0.03];
    let (budget, raster) = (*trainer.budget(), trainer.raster_config().clone());
    let run = RunInputs { config: &cfg, scene: &scene, train_views: &train, extent: trainer.extent(), raster: &raster, budget: &budget };
    let step = |backend: Backend| -> Option<(f64, [f32; 6], Vec<gs_train::PartPlace>)> {
        let r = match Rasterizer::new(backend) {
            Ok(r) => r,
            Err(e) => {
                gs_testdata::skip_or_fail!(&format!("no wgpu adapter: {e}"), "install mesa-vulkan-drivers for lavapipe");
                return None;
            }
        };
        let mut executor = ReferenceExecutor::new(r, train.len(), TermsUsed::of(&cfg), false);
        let mut s = state.clone();
        let values = executor.execute(&run, &mut s, &plan, &mut gs_train::StepProfile::default()).unwrap();
        Some((values.l1, s.exposure.unwrap().params[plan.slot], executor.parts_on()))
    };
    let (cpu_l1, cpu_e, _) = step(Backend::Cpu).unwrap();
    let Some((gpu_l1, gpu_e, parts)) = step(Backend::Wgpu) else { return };
    let on = |part: &str| parts.iter().find(|p| p.part == part).unwrap().on.clone();
    assert!(on("exposure compensation").starts_with("wgpu on "), "{parts:?}");
    assert!(on("L_I (L1, D-SSIM, edge term)").starts_with("wgpu on "), "{parts:?}");
    let rel = (cpu_l1 - gpu_l1).abs() / cpu_l1;
    eprintln!("L1: CPU {cpu_l1:.8e}, wgpu {gpu_l1:.8e}; (a, b): CPU {cpu_e:?}, wgpu {gpu_e:?}");
    assert!(rel <= 1e-4, "L1 {cpu_l1} against {gpu_l1}");
    for k in 0..6 {
        assert!((cpu_e[k] - gpu_e[k]).abs() <= 1e-6, "(a, b)[{k}]: {} against {}", cpu_e[k], gpu_e[k]);
    }
    assert_ne!(gpu_e, [0.1, -0.05, 0.02, 0.01, -0.02, 0.03], "the step moved the correction");
}
