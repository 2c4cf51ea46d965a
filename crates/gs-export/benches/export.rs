//! Encode and decode of 100k Gaussians in each compressed format.

use criterion::{Criterion, criterion_group, criterion_main};
use gs_core::sh::SH_COEFFS;
use gs_core::{Gaussians, Rng};
use std::path::Path;

fn gaussians(n: usize) -> Gaussians {
    let mut rng = Rng::new(1);
    let mut g = Gaussians::default();
    for _ in 0..n {
        let sh: [[f32; 3]; SH_COEFFS] = std::array::from_fn(|_| [0.3 * rng.normal(), 0.3 * rng.normal(), 0.3 * rng.normal()]);
        let q = [rng.normal(), rng.normal(), rng.normal(), rng.normal()];
        g.push([rng.normal(), rng.normal(), rng.normal()], [rng.normal() - 4.0; 3], q, rng.normal(), sh);
    }
    g.sh_degree = 3;
    g
}

fn bench(c: &mut Criterion) {
    let g = gaussians(100_000);
    let p = Path::new("bench");
    c.bench_function("splat encode 100k", |b| b.iter(|| gs_export::splat::encode_splat(&g, p).unwrap()));
    c.bench_function("spz encode 100k", |b| b.iter(|| gs_export::spz::encode_spz(&g, false, p).unwrap()));
    c.bench_function("compressed-ply encode 100k", |b| b.iter(|| gs_export::compressed_ply::encode_compressed_ply(&g)));
    let spz = gs_export::spz::encode_spz(&g, false, p).unwrap();
    c.bench_function("spz decode 100k", |b| b.iter(|| gs_export::spz::decode_spz(&spz, p).unwrap()));
    let cply = gs_export::compressed_ply::encode_compressed_ply(&g);
    c.bench_function("compressed-ply decode 100k", |b| b.iter(|| gs_export::compressed_ply::decode_compressed_ply(&cply, p).unwrap()));
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
