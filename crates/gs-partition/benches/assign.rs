//! Criterion benchmark of the view/point assignment, the part of `vagsl partition` that grows
//! with the capture (views × points projections): 400 cameras along a 40 m street, 50,000
//! points, 8 blocks.

use criterion::{Criterion, criterion_group, criterion_main};
use glam::DVec3;
use gs_core::{Camera, Intrinsics, Rng};
use gs_partition::{GroundFrame, Rect, assign};

fn street() -> (Vec<Camera>, Vec<DVec3>) {
    let k = Intrinsics::new(300.0, 300.0, 320.0, 240.0);
    let cams = (0..400)
        .map(|i| {
            let eye = DVec3::new(i as f64 * 0.1 - 20.0, 0.0, 1.5);
            let side = if i % 2 == 0 { 1.0 } else { -1.0 };
            Camera::look_at(640, 480, k, eye, eye + DVec3::new(0.0, side, -0.2), DVec3::Z).unwrap()
        })
        .collect();
    let mut rng = Rng::new(7);
    let pts = (0..50_000)
        .map(|_| {
            let side = if rng.uniform() < 0.5 { -3.0 } else { 3.0 };
            DVec3::new(rng.uniform_range(-21.0, 21.0) as f64, side, rng.uniform_range(0.0, 3.0) as f64)
        })
        .collect();
    (cams, pts)
}

fn bench(c: &mut Criterion) {
    let (cams, pts) = street();
    let frame = GroundFrame::of(&cams, &pts).unwrap();
    let regions: Vec<Rect> = (0..8).map(|b| Rect { min: [b as f64 * 5.0 - 21.0, -4.0], max: [b as f64 * 5.0 - 15.0, 4.0] }).collect();
    c.bench_function("assign 400 views x 50k points, 8 blocks", |b| b.iter(|| assign(&frame, &regions, &cams, &pts, 0.25)));
}

criterion_group! { name = benches; config = Criterion::default().sample_size(10); targets = bench }
criterion_main!(benches);
