//! Packing a model for the report page: the cost `vagsl view` adds before the renders
//! (covariances, base64 of the geometry and SH textures).

use criterion::{Criterion, criterion_group, criterion_main};
use gs_core::Gaussians;
use gs_report::SplatData;

fn model(n: usize) -> Gaussians {
    let mut g = Gaussians::default();
    for i in 0..n {
        let f = i as f32 / n as f32;
        g.push([f, 1.0 - f, 0.5 * f], [-3.0, -3.5, -4.0], [1.0, f, 0.0, 0.2], 0.5, [[0.1 * f; 3]; 16]);
    }
    g.sh_degree = 3;
    g
}

fn bench(c: &mut Criterion) {
    let g = model(100_000);
    c.bench_function("splat_data_100k_sh3", |b| b.iter(|| SplatData::from_gaussians(&g, &gs_raster::RasterConfig::default()).unwrap()));
}

criterion_group!(benches, bench);
criterion_main!(benches);
