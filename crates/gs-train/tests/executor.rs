//! The executor contract: a [`ReferenceExecutor`] driven from outside the trainer, on a
//! [`TrainState`] the caller owns and passes in, reaches the same state bit for bit as
//! [`Trainer::step`] — across every loss phase, densification, opacity reset, trim, exposure and
//! the source-depth memo. So the state an executor sees is exactly what it is lent.

use gs_core::NeighbourRule;
use gs_mvs::{SourceSelection, SourceViewSelector};
use gs_raster::{Backend, Rasterizer};
use gs_train::{ReferenceExecutor, RunInputs, StepExecutor, TrainConfig, TrainState, Trainer, plan_step};

mod common;

/// The busy run with a fixed SH degree: the degree is the trainer's own business (it may judge
/// bands on its rasterizer), so the step is left to the executor alone.
fn config() -> TrainConfig {
    TrainConfig { sh_degree_max: 0, ..common::busy_config() }
}

#[test]
fn an_executor_on_a_lent_state_matches_the_trainer_bit_for_bit() {
    let scene = common::small_scene();
    let (train, _) = scene.split(false);
    let cfg = config();
    assert!(cfg.warmup_end < cfg.photometric_end && cfg.photometric_end < cfg.iterations);

    let mut trainer = Trainer::new(&scene, train.clone(), cfg.clone()).unwrap();
    let mut state: TrainState = trainer.state().unwrap().clone();
    let cams = scene.cameras_of(&train);
    let selector = SourceViewSelector::new(&cams, &NeighbourRule::default(), cfg.source_views, SourceSelection::RandomN).unwrap();
    let mut executor = ReferenceExecutor::new(Rasterizer::new(Backend::Cpu).unwrap(), train.len(), gs_train::TermsUsed::of(&cfg), false);
    let budget = *trainer.budget();
    let raster = trainer.raster_config().clone();
    let run = RunInputs { config: &cfg, scene: &scene, train_views: &train, extent: trainer.extent(), raster: &raster, budget: &budget };
    let mut profile = gs_train::StepProfile::default();
    let (mut densified, mut trimmed, mut reset, mut photometric, mut features) = (0, 0, 0, 0, 0);
    while !trainer.finished() {
        let report = trainer.step().unwrap();
        let plan = plan_step(&cfg, &train, &selector, run.extent, state.iteration + 1);
        let losses = executor.execute(&run, &mut state, &plan, &mut profile).unwrap();
        let refined = executor.refine(&run, &mut state, &plan).unwrap();
        state.iteration = plan.iteration;
        assert_eq!(losses, report.losses, "iteration {}", plan.iteration);
        assert_eq!((refined.densify, refined.trimmed), (report.densify, report.trimmed), "iteration {}", plan.iteration);
        densified += refined.densify.is_some() as u32;
        trimmed += refined.trimmed.is_some() as u32;
        reset += refined.opacity_reset as u32;
        photometric += losses.photometric.is_some() as u32;
        features += losses.features.is_some() as u32;
        assert!(state == *trainer.state().unwrap(), "the states part at iteration {}", plan.iteration);
    }
    assert!(densified > 0 && trimmed > 0 && reset > 0, "the run covers the density control: {densified} {trimmed} {reset}");
    assert!(photometric > 10 && features > 10, "the run covers L_p ({photometric} steps) and L_f ({features})");
    assert_ne!(state.gaussians.len(), 0);
}
