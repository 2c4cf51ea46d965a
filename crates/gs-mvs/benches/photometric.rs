//! L_p forward + backward at 800×600 with 3 source views (textured ground plane seen from 4
//! cameras, analytic depth), with the default 102,400-pixel cap and uncapped; L_f with a
//! synthetic 64-channel stride-2 feature grid.

use criterion::{Criterion, criterion_group, criterion_main};
use gs_core::glam::DVec3;
use gs_core::{Camera, Intrinsics, Rng};
use gs_mvs::analytic_scene::{AnalyticMaps, AnalyticScene};
use gs_mvs::{
    FeatureReference, FeatureSource, GridFeatureMaps, PhotometricConfig, PhotometricReference,
    PhotometricSource, feature_loss, photometric_loss,
};

fn setup() -> (Vec<Camera>, Vec<AnalyticMaps>) {
    let (w, h) = (800u32, 600u32);
    let k = Intrinsics::new(700.0, 700.0, 400.0, 300.0);
    let scene = AnalyticScene {
        boxes: vec![],
        frequency: 14.0,
    };
    let eyes = [
        DVec3::new(0.0, -2.5, 2.0),
        DVec3::new(0.4, -2.5, 2.0),
        DVec3::new(-0.4, -2.45, 2.1),
        DVec3::new(0.1, -2.2, 2.3),
    ];
    let cams: Vec<Camera> = eyes
        .iter()
        .map(|&e| Camera::look_at(w, h, k, e, DVec3::ZERO, DVec3::Z).unwrap())
        .collect();
    let maps = cams.iter().map(|c| scene.render(c)).collect();
    (cams, maps)
}

fn bench(c: &mut Criterion) {
    let (cams, maps) = setup();
    let m = &maps[0];
    let reference = PhotometricReference {
        camera: &cams[0],
        normal: (&m.normal).into(),
        distance: (&m.distance).into(),
        plane_depth: (&m.plane_depth).into(),
        grey: (&m.grey).into(),
    };
    let sources: Vec<PhotometricSource<f32>> = (1..4)
        .map(|k| PhotometricSource {
            camera: &cams[k],
            plane_depth: (&maps[k].plane_depth).into(),
            grey: (&maps[k].grey).into(),
        })
        .collect();
    let mut g = c.benchmark_group("photometric_800x600_3src");
    g.sample_size(10);
    let capped = PhotometricConfig::default();
    let out = photometric_loss(&reference, &sources, &capped).unwrap();
    eprintln!(
        "capped: L_p = {:.5}, per source {:?}",
        out.loss,
        out.per_source
            .iter()
            .map(|s| (s.n_candidates, s.n_sampled, s.n_valid))
            .collect::<Vec<_>>()
    );
    g.bench_function("L_p fwd+bwd, cap 102400", |b| {
        b.iter(|| photometric_loss(&reference, &sources, &capped).unwrap())
    });
    let uncapped = PhotometricConfig {
        max_pixels_per_source: None,
        ..Default::default()
    };
    g.bench_function("L_p fwd+bwd, uncapped", |b| {
        b.iter(|| photometric_loss(&reference, &sources, &uncapped).unwrap())
    });

    let mut rng = Rng::new(3);
    let (fw, fh, ch) = (400, 300, 64);
    let feats: Vec<GridFeatureMaps<f32>> = (0..4)
        .map(|_| {
            GridFeatureMaps::new(
                fw,
                fh,
                ch,
                2,
                (0..fw * fh * ch).map(|_| rng.uniform()).collect(),
            )
            .unwrap()
        })
        .collect();
    let fr = FeatureReference {
        camera: &cams[0],
        plane_depth: (&m.plane_depth).into(),
        features: &feats[0],
    };
    let fs: Vec<FeatureSource<f32>> = (1..4)
        .map(|k| FeatureSource {
            camera: &cams[k],
            plane_depth: (&maps[k].plane_depth).into(),
            features: &feats[k],
        })
        .collect();
    g.bench_function("L_f fwd+bwd, 64 ch stride 2", |b| {
        b.iter(|| feature_loss(&fr, &fs).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
