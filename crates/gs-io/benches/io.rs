//! Benchmarks of the gs-io writers and readers: a 1M-Gaussian 3DGS PLY and a 1M-triangle mesh
//! PLY, written to and read from a temporary folder.

use criterion::{Criterion, criterion_group, criterion_main};
use gs_core::{Gaussians, TriangleMesh};
use gs_io::{read_gaussian_ply, read_mesh_ply, write_gaussian_ply, write_mesh_ply};

fn gaussians(n: usize) -> Gaussians {
    gs_testdata::random_gaussians(n)
}

fn mesh(grid: usize) -> TriangleMesh {
    let mut m = TriangleMesh::default();
    for y in 0..=grid {
        for x in 0..=grid {
            m.positions.push([x as f32, y as f32, ((x * y) % 7) as f32 * 0.1]);
        }
    }
    let id = |x: usize, y: usize| (y * (grid + 1) + x) as u32;
    for y in 0..grid {
        for x in 0..grid {
            m.triangles.push([id(x, y), id(x + 1, y), id(x + 1, y + 1)]);
            m.triangles.push([id(x, y), id(x + 1, y + 1), id(x, y + 1)]);
        }
    }
    m.colors = Some(vec![[200, 100, 50]; m.positions.len()]);
    m
}

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let g = gaussians(1_000_000);
    let gp = dir.path().join("g.ply");
    let mut group = c.benchmark_group("gaussian_ply_1M");
    group.sample_size(10);
    group.bench_function("write", |b| b.iter(|| write_gaussian_ply(&gp, &g).unwrap()));
    group.bench_function("read", |b| b.iter(|| read_gaussian_ply(&gp).unwrap()));
    group.finish();

    let m = mesh(707); // 1,000,000 triangles, 501,264 vertices
    let mp = dir.path().join("m.ply");
    let mut group = c.benchmark_group("mesh_ply_1M_triangles");
    group.sample_size(10);
    group.bench_function("write", |b| b.iter(|| write_mesh_ply(&mp, &m).unwrap()));
    group.bench_function("read", |b| b.iter(|| read_mesh_ply(&mp).unwrap()));
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
