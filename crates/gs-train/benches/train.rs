//! Time of one training iteration on synth-bunny (480×360, 35 training views), initialised
//! from its 7,000 SfM points: the colour warm-up (L1 + D-SSIM, comparable to plain 3DGS and
//! to OpenSplat's 0.39 s/iteration at 7k Gaussians, docs/architecture.md §Targets), the L_p phase (edge, L_nc,
//! L_ns, L_p with 3 source renders) and the L_f phase (VGG features cached beforehand).
//! Densification is off so the Gaussian count stays fixed. Needs synth-bunny from the shared test
//! data (`VAGSL_TEST_DATA`, see gs-testdata); prints SKIPPED without it.

use criterion::{Criterion, criterion_group, criterion_main};
use gs_train::{TrainConfig, Trainer};

fn bench(c: &mut Criterion) {
    if !gs_testdata::needs!("data/synth-bunny") {
        return;
    }
    let dir = gs_testdata::root().join("data/synth-bunny");
    let scene = gs_io::load_scene(&dir, &Default::default()).expect("synth-bunny loads");
    let (train, _) = scene.split(true);
    let mut group = c.benchmark_group("train_iteration_synth_bunny_480x360_7k");
    group.sample_size(20);
    for (name, start) in [("warmup_colour_only", 0u64), ("photometric_phase", 7_000), ("feature_phase", 15_000)] {
        let mut cfg = TrainConfig::default();
        cfg.densify.until = 0; // fixed Gaussian count
        let mut trainer = Trainer::new(&scene, train.clone(), cfg.clone()).expect("trainer");
        let mut state = trainer.state().unwrap().clone();
        state.iteration = start;
        trainer = Trainer::with_state(&scene, train.clone(), cfg, state).expect("trainer");
        // Warm the per-view caches (guides, grey images, features) outside the measurement.
        for _ in 0..train.len() {
            trainer.step().expect("step");
        }
        group.bench_function(name, |b| b.iter(|| trainer.step().expect("step")));
    }
    group.finish();

    // The same at the Gaussian count a full run reaches (~300k): every SfM point replaced by 43
    // copies jittered by up to 0.5 % of the scene radius, so per-Gaussian work (Adam, projection,
    // sorting, densification statistics) weighs as it does late in training.
    let mut big = scene.clone();
    let mut rng = gs_core::Rng::new(7);
    let radius = scene.extent();
    big.points = scene
        .points
        .iter()
        .flat_map(|p| std::iter::repeat_n(p, 43))
        .map(|p| {
            let mut q = p.clone();
            q.position += glam::DVec3::new(rng.uniform_f64() - 0.5, rng.uniform_f64() - 0.5, rng.uniform_f64() - 0.5) * (0.01 * radius);
            q
        })
        .collect();
    let mut group = c.benchmark_group("train_iteration_synth_bunny_480x360_301k");
    group.sample_size(10);
    for (name, start) in [("warmup_colour_only", 0u64), ("photometric_phase", 7_000)] {
        let mut cfg = TrainConfig::default();
        cfg.densify.until = 0;
        let mut trainer = Trainer::new(&big, train.clone(), cfg.clone()).expect("trainer");
        let mut state = trainer.state().unwrap().clone();
        state.iteration = start;
        let mut trainer = Trainer::with_state(&big, train.clone(), cfg, state).expect("trainer");
        for _ in 0..if start == 0 { 3 } else { train.len() } {
            trainer.step().expect("step");
        }
        group.bench_function(name, |b| b.iter(|| trainer.step().expect("step")));
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
