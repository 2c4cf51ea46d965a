//! gs-tsdf benches (2 threads is the reference setting: `RAYON_NUM_THREADS=2`):
//! - integration of 49 depth maps at 800×600 (DTU's view count and size) of an analytic
//!   sphere-and-box scene, voxel 1/256 of the object size;
//! - marching cubes over the resulting volume;
//! - simplification of that mesh with a bound per vertex (0.3 of the pixel footprint at it);
//! - Chamfer / F1 metrics on 1M + 1M points.

use criterion::{Criterion, criterion_group, criterion_main};
use gs_core::glam::DVec3;
use gs_tsdf::analytic_depth::{Primitive, orbit_cameras, render_depth};
use gs_tsdf::{TsdfConfig, TsdfVolume, point_metrics};

fn scene() -> Vec<Primitive> {
    vec![Primitive::Sphere { center: DVec3::new(0.0, 0.0, 0.0), radius: 0.8 }]
}

fn bench(c: &mut Criterion) {
    let prims = scene();
    let cams = orbit_cameras(49, 800, 600, DVec3::ZERO, 3.0);
    let depths: Vec<_> = cams.iter().map(|cam| render_depth(cam, &prims)).collect();
    let config = TsdfConfig { with_color: false, ..TsdfConfig::with_voxel_size(2.0 / 256.0) };
    let fuse = || {
        let mut v = TsdfVolume::new(config.clone()).unwrap();
        for (i, (cam, d)) in cams.iter().zip(&depths).enumerate() {
            v.integrate_view(i, cam, d, None, None, None).unwrap();
        }
        v
    };
    let mut g = c.benchmark_group("tsdf");
    g.sample_size(10);
    g.bench_function("integrate_49_views_800x600", |b| b.iter(fuse));
    let volume = fuse();
    eprintln!("{} blocks, {:.1} MB", volume.block_count(), volume.memory_bytes() as f64 / 1e6);
    g.bench_function("extract_mesh", |b| b.iter(|| volume.extract_mesh().unwrap()));
    let mesh = volume.extract_mesh().unwrap();
    let cam_refs: Vec<&gs_core::Camera> = cams.iter().collect();
    let voxel = config.voxel_size;
    let bounds: Vec<f64> =
        gs_tsdf::pixel_footprints(&mesh.positions, &cam_refs).into_iter().map(|f| 0.3 * f.unwrap_or(voxel).max(voxel)).collect();
    eprintln!("{} triangles to simplify", mesh.triangles.len());
    g.bench_function("simplify_graded", |b| b.iter(|| gs_tsdf::simplify_mesh_graded(&mesh, &bounds).unwrap()));
    let pred = gs_tsdf::sample_surface(&mesh, 1_000_000, 1).unwrap();
    let gt = gs_tsdf::sample_surface(&mesh, 1_000_000, 2).unwrap();
    g.bench_function("metrics_1M_vs_1M", |b| b.iter(|| point_metrics(&pred, &gt, 0.01, None).unwrap()));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
