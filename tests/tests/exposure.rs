//! Exposure compensation (issue 9) on the built-in scene: the training photos get a different
//! per-channel gain each (as auto-exposure / white balance would), the held-out photos keep the
//! true exposure. With `exposure` on, the learned per-view gains follow the applied ones and the
//! held-out PSNR (after fitting each held-out photo's gain) is clearly higher than without.
//! Release only (two short trainings).

use gs_core::{Image, Rng};
use gs_train::{LossSwitches, TrainConfig, Trainer};

/// Held-out PSNR after fitting each view's per-channel gain (least squares): the model keeps
/// one reference exposure, which a held-out photo need not share, so the comparison fits that
/// exposure (as NeRF-W-style evaluations fit a test image's appearance).
fn psnr_after_gain_fit(g: &gs_core::Gaussians, scene: &gs_core::Scene, views: &[usize], raster: &gs_raster::RasterConfig) -> f64 {
    let mut total = 0.0;
    for &v in views {
        let out = gs_raster::render(g, &scene.views[v].camera, &gs_raster::RenderRequest::default(), raster).unwrap();
        let (r, t) = (out.color.unwrap(), &scene.views[v].image);
        let (mut rt, mut rr) = ([0.0f64; 3], [0.0f64; 3]);
        for (k, (&a, &b)) in r.data().iter().zip(t.data()).enumerate() {
            rt[k % 3] += a as f64 * b as f64;
            rr[k % 3] += a as f64 * a as f64;
        }
        let gain: Vec<f64> = (0..3).map(|c| rt[c] / rr[c].max(1e-12)).collect();
        let mse = r.data().iter().zip(t.data()).enumerate().map(|(k, (&a, &b))| ((a as f64 * gain[k % 3]).clamp(0.0, 1.0) - b as f64).powi(2)).sum::<f64>()
            / r.data().len() as f64;
        total += -10.0 * mse.max(1e-12).log10();
    }
    total / views.len() as f64
}

/// Trains colour-only for `iterations`; returns (held-out PSNR as rendered, after the gain fit,
/// learned log-gains per view).
fn train_colour(scene: &gs_core::Scene, train: &[usize], test: &[usize], exposure: bool, iterations: u64) -> (f64, f64, Vec<[f32; 3]>) {
    let base = TrainConfig::default().scaled(iterations);
    let config = TrainConfig {
        exposure,
        losses: LossSwitches::image_only(),
        warmup_end: iterations,
        photometric_end: iterations,
        features_end: iterations,
        ..base
    };
    let mut trainer = Trainer::new(scene, train.to_vec(), config).unwrap();
    trainer.run(|_, _| true).unwrap();
    let m = trainer.evaluate_images(test, None).unwrap();
    let state = trainer.state().unwrap().clone();
    let fitted = psnr_after_gain_fit(&state.gaussians, scene, test, trainer.raster_config());
    let gains = state.exposure.as_ref().map(|e| e.params.iter().map(|p| [p[0], p[1], p[2]]).collect()).unwrap_or_default();
    (m.psnr, fitted, gains)
}

#[test]
#[cfg_attr(debug_assertions, ignore = "release only: cargo test --release")]
fn exposure_compensation_recovers_per_view_gains() {
    let built = gs_synth::generate(&gs_synth::BuiltinOptions { width: 120, height: 90, views: 24, supersample: 1, ..Default::default() })
        .unwrap();
    let mut scene = built.scene;
    let (train, test) = scene.split(true);
    // Per training view and channel, a gain in [0.4, 1.0] (no clipping).
    let mut rng = Rng::new(11);
    let mut applied = Vec::new();
    for &v in &train {
        let g = [0.4 + 0.6 * rng.uniform_f64() as f32, 0.4 + 0.6 * rng.uniform_f64() as f32, 0.4 + 0.6 * rng.uniform_f64() as f32];
        let img = &scene.views[v].image;
        let data = img.data().iter().enumerate().map(|(k, &c)| c * g[k % 3]).collect();
        scene.views[v].image = Image::from_vec(img.width(), img.height(), 3, data).unwrap();
        applied.push(g);
    }
    let iterations = 600;
    let (raw_off, psnr_off, _) = train_colour(&scene, &train, &test, false, iterations);
    let (raw_on, psnr_on, learned) = train_colour(&scene, &train, &test, true, iterations);
    // The model settles on one reference exposure, so compare log-gains up to a per-channel
    // offset: correlation across views.
    let mut corr = [0.0f64; 3];
    for (c, corr_c) in corr.iter_mut().enumerate() {
        let a: Vec<f64> = applied.iter().map(|g| (g[c] as f64).ln()).collect();
        let l: Vec<f64> = learned.iter().map(|g| g[c] as f64).collect();
        let (ma, ml) = (a.iter().sum::<f64>() / a.len() as f64, l.iter().sum::<f64>() / l.len() as f64);
        let cov: f64 = a.iter().zip(&l).map(|(x, y)| (x - ma) * (y - ml)).sum();
        let va: f64 = a.iter().map(|x| (x - ma).powi(2)).sum();
        let vl: f64 = l.iter().map(|y| (y - ml).powi(2)).sum();
        *corr_c = cov / (va * vl).sqrt().max(1e-12);
    }
    println!(
        "held-out PSNR as rendered: {raw_off:.2} dB without exposure, {raw_on:.2} dB with; after the per-view gain fit: {psnr_off:.2} vs {psnr_on:.2} dB; log-gain correlation {corr:?}"
    );
    assert!(corr.iter().all(|&c| c > 0.9), "learned gains do not follow the applied ones: {corr:?}");
    assert!(psnr_on > psnr_off + 1.0, "exposure compensation: {psnr_on:.2} dB vs {psnr_off:.2} dB without");
}
