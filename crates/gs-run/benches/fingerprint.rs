//! Benchmarks of the fingerprints every run command computes: the model fingerprint over
//! 100k Gaussians (all 59 parameters each; a run opens, records and checks it) and the scene
//! fingerprint over the small built-in scene's pixels (computed at every open of a run).

use criterion::{Criterion, criterion_group, criterion_main};
use gs_core::Gaussians;

fn gaussians(n: usize) -> Gaussians {
    gs_testdata::random_gaussians(n)
}

fn bench(c: &mut Criterion) {
    let g = gaussians(100_000);
    c.bench_function("model_fingerprint 100k Gaussians", |b| b.iter(|| gs_run::model_fingerprint(std::hint::black_box(&g))));
    let scene = gs_synth::generate(&gs_synth::BuiltinOptions { width: 320, height: 240, views: 24, supersample: 1, ..Default::default() })
        .expect("the built-in scene")
        .scene;
    c.bench_function("SceneFingerprint 24 views 320x240", |b| b.iter(|| gs_run::SceneFingerprint::of(std::hint::black_box(&scene))));
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
