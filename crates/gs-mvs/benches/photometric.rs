//! L_p forward + backward at 800×600 with 3 source views (textured ground plane seen from 4
//! cameras, analytic depth), with the default 102,400-pixel cap and uncapped; L_f with a
//! synthetic 64-channel stride-2 feature grid. With the `wgpu` feature and an adapter, L_p on
//! the device with υ/ω and the selection made on the host and made on the device (on
//! lavapipe these measure the kernels' work on this CPU, not GPU speed).

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
    #[cfg(feature = "wgpu")]
    device(c, &reference, &sources);
}

/// L_p on the device, when there is a wgpu adapter: υ/ω and the selection on the host (`loss`,
/// the plane uploaded) and on the device (`start_on_device`, the plane and the depths held
/// there), at the default cap (the device draws from the candidate counts: two waits) and
/// under a cap no source reaches (one wait).
#[cfg(feature = "wgpu")]
fn device(c: &mut Criterion, reference: &PhotometricReference<'_, f32>, sources: &[PhotometricSource<'_, f32>]) {
    let ctx = match gs_gpu::GpuContext::new(&gs_gpu::GpuOptions::default()) {
        Ok(ctx) => ctx,
        Err(e) => {
            eprintln!("SKIPPED: the device rows: {e}");
            return;
        }
    };
    let mut gpu = gs_mvs::PhotometricGpu::new(&ctx).unwrap();
    let (w, h) = (reference.camera.width as usize, reference.camera.height as usize);
    let surface = gs_mvs::upload_surface(&ctx, reference).unwrap();
    let on_device = gs_mvs::SurfaceReference { camera: reference.camera, surface: &surface, plane_depth: Some(reference.plane_depth), grey: reference.grey };
    let views: Vec<u64> = (0..=sources.len() as u64).collect();
    let versions = vec![0; sources.len()];
    let keys = gs_mvs::ViewKeys { views: &views, depth_versions: &versions, keep_reference_depth: None };
    let held: Vec<gs_mvs::DeviceSource<'_>> = sources.iter().map(|&s| s.into()).collect();
    let mut g = c.benchmark_group("photometric_800x600_3src_device");
    eprintln!("device: {}", ctx.description());
    g.sample_size(10);
    for (label, cap) in [("cap 102400", Some(102_400)), ("no source capped", Some(w * h))] {
        let config = PhotometricConfig { max_pixels_per_source: cap, ..Default::default() };
        g.bench_function(format!("L_p, selection on the host, {label}"), |b| {
            b.iter(|| gpu.loss_of_views(reference, sources, &views, &config).unwrap())
        });
        g.bench_function(format!("L_p, selection on the device, {label}"), |b| {
            b.iter(|| {
                let started = gpu.start_on_device(&on_device, &held, Some(keys), &config).unwrap();
                gpu.finish_on_device(started).unwrap()
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
