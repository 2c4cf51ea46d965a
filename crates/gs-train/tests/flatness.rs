//! L_s, PGSR's flattening term (docs/method.md §L_s), in training: recorded from the first
//! iteration and counted in the total, and it makes a trained model's Gaussians flatter (the
//! smallest scale a smaller share of the largest), on the CPU and, where an adapter exists, on
//! wgpu, whose device Adam adds the term's gradient (without an adapter the wgpu part prints a
//! SKIPPED line and returns, except in CI).

use gs_train::terms::LossValues;
use gs_train::{LossWeights, TrainConfig, Trainer};

fn small_scene() -> gs_core::Scene {
    let opts = gs_synth::BuiltinOptions { width: 64, height: 48, views: 8, supersample: 1, points: 400, ..Default::default() };
    gs_synth::generate(&opts).unwrap().scene
}

/// The median over the model of smallest scale ÷ largest scale.
fn flatness_ratio(t: &mut Trainer<'_>) -> f32 {
    let mut r: Vec<f32> = t
        .gaussians()
        .unwrap()
        .log_scales
        .iter()
        .map(|l| (l.iter().copied().fold(f32::INFINITY, f32::min) - l.iter().copied().fold(f32::NEG_INFINITY, f32::max)).exp())
        .collect();
    r.sort_by(f32::total_cmp);
    r[r.len() / 2]
}

/// A 120-iteration run with weight `lambda_s`, on wgpu when `wgpu`: its losses and the model's
/// flatness, or `None` without an adapter.
fn run(scene: &gs_core::Scene, lambda_s: f32, wgpu: bool) -> Option<(Vec<LossValues>, f32)> {
    let mut c = TrainConfig::default().scaled(120);
    c.seed = 5;
    c.weights.lambda_s = lambda_s;
    let (train, _) = scene.split(false);
    let mut t = Trainer::new(scene, train, c).unwrap();
    if wgpu {
        #[cfg(feature = "wgpu")]
        if let Err(e) = t.set_backend(gs_raster::Backend::Wgpu) {
            gs_testdata::skip_or_fail!(&format!("no wgpu adapter: {e}"), "install mesa-vulkan-drivers for lavapipe");
            return None;
        }
    }
    let mut losses = Vec::new();
    t.run(|_, r| {
        losses.push(r.losses);
        true
    })
    .unwrap();
    Some((losses, flatness_ratio(&mut t)))
}

#[test]
fn the_flattening_term_is_recorded_and_flattens_the_model() {
    let scene = small_scene();
    let (plain, r_plain) = run(&scene, 0.0, false).unwrap();
    let (flat, r_flat) = run(&scene, 100.0, false).unwrap();
    assert!(plain.iter().all(|v| v.flatness.is_none()));
    assert!(flat.iter().all(|v| v.flatness.is_some_and(|s| s > 0.0 && s.is_finite())), "L_s from the first iteration");
    let v = flat.last().unwrap();
    let without = LossValues { flatness: None, ..*v };
    let weights = LossWeights { lambda_s: 100.0, ..Default::default() };
    assert!((weights.total(v) - weights.total(&without) - 100.0 * v.flatness.unwrap()).abs() < 1e-9);
    assert!(r_flat < 0.7 * r_plain, "median smallest/largest scale {r_flat} with L_s vs {r_plain} without");
    #[cfg(feature = "wgpu")]
    {
        let Some((on_device, r_device)) = run(&scene, 100.0, true) else { return };
        // The same initial model: the first value to the bit; then the device's steps flatten it too.
        assert_eq!(on_device[0].flatness, flat[0].flatness);
        assert!(on_device.iter().all(|v| v.flatness.is_some()));
        assert!(r_device < 0.7 * r_plain, "on wgpu: {r_device} with L_s vs {r_plain} without (CPU)");
    }
}
