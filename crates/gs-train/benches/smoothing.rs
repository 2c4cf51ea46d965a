//! The 3D smoothing filter's cost per iteration at the Gaussian count of a full synth-bunny run
//! (150k): applying it (the filtered log-scales and opacity logits), carrying a gradient back
//! and reverting; and computing the variances over 35 training views (every 100 iterations).
//! Synthetic Gaussians on a camera ring; needs no data.

use criterion::{Criterion, criterion_group, criterion_main};
use gs_core::{Gaussians, Rng};
use gs_train::smoothing::{Smoothing, variances};

const N: usize = 150_000;

fn gaussians() -> Gaussians {
    let mut rng = Rng::new(3);
    let mut g = Gaussians::default();
    for _ in 0..N {
        let m = [rng.uniform() - 0.5, rng.uniform() - 0.5, rng.uniform() - 0.5];
        g.means.push(m);
        g.log_scales.push([-4.0 - 3.0 * rng.uniform(), -4.0 - 3.0 * rng.uniform(), -7.0 - 3.0 * rng.uniform()]);
        g.rotations.push([1.0, 0.0, 0.0, 0.0]);
        g.opacity_logits.push(8.0 * rng.uniform() - 4.0);
        g.sh.push([[0.0; 3]; gs_core::sh::SH_COEFFS]);
    }
    g
}

fn bench(c: &mut Criterion) {
    let mut g = gaussians();
    let cams = gs_core::camera::camera_ring(35);
    let refs: Vec<&gs_core::Camera> = cams.iter().collect();
    let mut group = c.benchmark_group("smoothing_3d_150k");
    group.sample_size(20);
    group.bench_function("variances_35_views", |b| b.iter(|| variances(&g, &refs, 0.01, 0.2)));
    let mut s = Smoothing::new(variances(&g, &refs, 0.01, 0.2)).unwrap();
    let mut grads = gs_raster::GaussianGradients {
        log_scales: vec![[1e-3, -2e-3, 5e-4]; N],
        opacity_logits: vec![1e-3; N],
        ..gs_raster::GaussianGradients::zeros(N)
    };
    group.bench_function("apply_chain_revert", |b| {
        b.iter(|| {
            s.apply(&mut g).unwrap();
            s.chain(&mut grads).unwrap();
            s.revert(&mut g);
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
