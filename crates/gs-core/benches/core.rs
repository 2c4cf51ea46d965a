//! Criterion benches of the gs-core hot spots: SH colour forward/backward per Gaussian and an
//! Adam step over a 1M-scalar group.

use criterion::{Criterion, Throughput, black_box, criterion_group, criterion_main};
use gs_core::optim::{Adam, AdamConfig};
use gs_core::sh::{SH_COEFFS, eval_sh_backward, sh_to_color};
use gs_core::Rng;

fn bench_sh(c: &mut Criterion) {
    let mut rng = Rng::new(1);
    let n = 100_000;
    let coeffs: Vec<[[f32; 3]; SH_COEFFS]> =
        (0..n).map(|_| std::array::from_fn(|_| [rng.normal(), rng.normal(), rng.normal()])).collect();
    let dirs: Vec<[f32; 3]> = (0..n)
        .map(|_| {
            let v = [rng.normal(), rng.normal(), rng.normal()];
            let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            [v[0] / l, v[1] / l, v[2] / l]
        })
        .collect();
    let mut g = c.benchmark_group("sh_degree3");
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("forward_100k", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for (c, d) in coeffs.iter().zip(&dirs) {
                acc += sh_to_color(3, c, *d).0[0];
            }
            black_box(acc)
        })
    });
    g.bench_function("backward_100k", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for (c, d) in coeffs.iter().zip(&dirs) {
                acc += eval_sh_backward(3, c, *d, [1.0, 0.5, 0.25]).1[0];
            }
            black_box(acc)
        })
    });
    g.finish();
}

fn bench_adam(c: &mut Criterion) {
    let n = 1_000_000;
    let mut adam = Adam::new(AdamConfig::default());
    adam.add_group("p", 1e-3, n, 1).unwrap();
    let mut params = vec![0.5f32; n];
    let grads: Vec<f32> = (0..n).map(|i| (i as f32 * 1e-3).sin()).collect();
    let mut g = c.benchmark_group("adam");
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("step_1M_scalars", |b| b.iter(|| adam.step("p", black_box(&mut params), &grads).unwrap()));
    g.finish();
}

criterion_group!(benches, bench_sh, bench_adam);
criterion_main!(benches);
