#![cfg(feature = "wgpu")]
//! The source-depth memo on the device (docs/architecture.md §GPU): in the L_p phase of a wgpu
//! run each step's reference depth, and every source depth rendered for a step, stays in L_p's
//! arena (`StoredDepth::Device`) and serves later steps there; so do L_f's steps, whose υ/ω are
//! made there from those depths (stop 68; they read them back before); `StepExecutor::pull` brings every one
//! back, with the values a render of the same model reads back. The run's values do not move
//! with the memo's place: gs-raster tests/wgpu_device_images.rs and gs-mvs tests/held_depths.rs
//! prove the bits, and wgpu_resume.rs a resume across a checkpoint taken in this phase.
//!
//! Without any wgpu adapter the test prints a SKIPPED line and returns, except in CI.

use gs_core::NeighbourRule;
use gs_mvs::{SourceSelection, SourceViewSelector};
use gs_raster::{Backend, RenderRequest, Rasterizer};
use gs_train::{ReferenceExecutor, RunInputs, StepExecutor, StoredDepth, TrainConfig, TrainState, Trainer, plan_step};

mod common;

#[test]
fn the_depth_memo_stays_on_the_device_until_the_host_reads_it() {
    let scene = common::small_scene();
    let (train, _) = scene.split(false);
    let cfg = TrainConfig { sh_degree_max: 0, ..common::busy_config() };
    let rasterizer = match Rasterizer::new(Backend::Wgpu) {
        Ok(r) => r,
        Err(e) => {
            gs_testdata::skip_or_fail!(&format!("no wgpu adapter: {e}"), "install mesa-vulkan-drivers for lavapipe");
            return;
        }
    };
    let mut executor = ReferenceExecutor::new(rasterizer, train.len(), gs_train::TermsUsed::of(&cfg), false);
    let mut trainer = Trainer::new(&scene, train.clone(), cfg.clone()).unwrap();
    assert!(cfg.warmup_end + 5 < cfg.photometric_end, "an L_p phase to watch");
    let mut state: TrainState = trainer.state().unwrap().clone();
    let cams = scene.cameras_of(&train);
    let selector = SourceViewSelector::new(&cams, &NeighbourRule::default(), cfg.source_views, SourceSelection::RandomN).unwrap();
    let (budget, raster) = (*trainer.budget(), trainer.raster_config().clone());
    let run = RunInputs { config: &cfg, scene: &scene, train_views: &train, extent: trainer.extent(), raster: &raster, budget: &budget };
    let mut profile = gs_train::StepProfile::default();
    let (mut kept, mut most, mut read_for_features, mut compared) = (0, 0, 0, false);
    while state.iteration < cfg.photometric_end + 10 {
        let plan = plan_step(&cfg, &train, &selector, run.extent, state.iteration + 1);
        // Once in the L_p phase: the depth this step keeps must be the plane depth a render of
        // the model it renders reads back (the host's copy brought up to date first).
        let want = match !compared && plan.photometric.is_some() && plan.weights.lambda_f == 0.0 && plan.scale == 1 && plan.iteration > cfg.warmup_end + 5 {
            true => {
                executor.pull(&mut state).unwrap();
                let request = RenderRequest { color: false, alpha: false, plane_depth: true, ..RenderRequest::default() };
                let mut other = Rasterizer::new(Backend::Wgpu).unwrap();
                Some(other.render(&state.gaussians, &scene.views[plan.view].camera, &request, &raster).unwrap().plane_depth.unwrap())
            }
            false => None,
        };
        let losses = executor.execute(&run, &mut state, &plan, &mut profile).unwrap();
        let on_device = state.source_depths.on_device(None);
        if let Some(want) = want {
            executor.pull(&mut state).unwrap();
            let (at, depth) = state.source_depths.entries()[plan.slot].as_ref().unwrap();
            let got = depth.host().expect("read back by the pull");
            assert_eq!(*at, plan.iteration);
            assert!(got.data().iter().zip(want.data()).all(|(a, b)| a.to_bits() == b.to_bits()), "the rendered depth, bit for bit");
            assert!(want.data().iter().filter(|z| **z > 0.0).count() > 100, "a surface in view");
            compared = true;
        }
        executor.refine(&run, &mut state, &plan).unwrap();
        state.iteration = plan.iteration;
        if losses.photometric.is_some() && plan.scale == 1 {
            assert!(on_device.contains(&plan.slot), "iteration {}: the reference's depth stays on the device", plan.iteration);
            kept += 1;
        }
        if losses.features.is_some() {
            // L_f's υ/ω were made on the device from its sources' depths there: they stayed.
            assert!(plan.sources.iter().all(|s| on_device.contains(s)), "iteration {}", plan.iteration);
            assert!(on_device.contains(&plan.slot), "iteration {}: the reference's depth stays on the device", plan.iteration);
            read_for_features += 1;
        }
        most = most.max(on_device.len());
    }
    assert!(kept > 10 && read_for_features > 5, "the run covers L_p ({kept} steps) and L_f ({read_for_features})");
    assert!(most >= train.len() / 2, "at most {most} of {} depths were on the device at once", train.len());

    assert!(compared, "a kept depth was compared");
    // A pull brings the rest back.
    let before = state.source_depths.on_device(None).len();
    executor.pull(&mut state).unwrap();
    assert!(before > 0 && state.source_depths.on_device(None).is_empty(), "{before} depths came back");
    assert!(state.source_depths.entries().iter().flatten().all(|(_, d)| matches!(d, StoredDepth::Host(_))));
}
