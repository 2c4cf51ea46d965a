//! Benchmarks: generating the built-in scene, and BVH ray-casting throughput.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use gs_synth::{BuiltinOptions, Bvh, generate, pixel_ray, ring_cameras};
use std::hint::black_box;
use std::time::Duration;

fn bench_generate(c: &mut Criterion) {
    let mut g = c.benchmark_group("generate");
    g.sample_size(10).measurement_time(Duration::from_secs(20));
    g.bench_function("default_32x200x150_ss2", |b| {
        b.iter(|| generate(black_box(&BuiltinOptions::default())).unwrap())
    });
    let small = BuiltinOptions {
        width: 64,
        height: 48,
        views: 8,
        ..Default::default()
    };
    g.bench_function("small_8x64x48_ss2", |b| {
        b.iter(|| generate(black_box(&small)).unwrap())
    });
    g.finish();
}

fn bench_rays(c: &mut Criterion) {
    let built = generate(&BuiltinOptions {
        width: 32,
        height: 24,
        views: 1,
        points: 10,
        ..Default::default()
    })
    .unwrap();
    let bvh = Bvh::new(&built.scene_mesh).unwrap();
    let cams = ring_cameras(200, 150, 4, 1).unwrap();
    let rays: Vec<_> = cams
        .iter()
        .flat_map(|cam| {
            (0..150u32).flat_map(move |y| {
                (0..200u32).map(move |x| pixel_ray(cam, x as f64 + 0.5, y as f64 + 0.5))
            })
        })
        .collect();
    let mut g = c.benchmark_group("bvh");
    g.throughput(Throughput::Elements(rays.len() as u64));
    g.bench_function("closest_hit_1thread", |b| {
        b.iter(|| {
            let mut s = 0.0;
            for &(o, d) in &rays {
                if let Some(h) = bvh.intersect(o, d, 0.0, f64::INFINITY) {
                    s += h.t;
                }
            }
            black_box(s)
        })
    });
    g.bench_function("cast_view_4x200x150", |b| {
        b.iter(|| {
            for cam in &cams {
                black_box(bvh.cast_view(cam).unwrap());
            }
        })
    });
    g.finish();
}

criterion_group!(benches, bench_generate, bench_rays);
criterion_main!(benches);
