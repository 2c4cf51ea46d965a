//! L_o, the opacity entropy (docs/method.md §L_o), in training: off during the colour warm-up
//! and bit for bit without effect there, recorded and counted in the total after it, and it
//! drives the opacities of a trained model towards 0 or 1.

use gs_losses::opacity::entropy_of_logit;
use gs_train::terms::LossValues;
use gs_train::{LossWeights, TrainConfig, Trainer};

fn small_scene() -> gs_core::Scene {
    let opts = gs_synth::BuiltinOptions { width: 64, height: 48, views: 8, supersample: 1, points: 400, ..Default::default() };
    gs_synth::generate(&opts).unwrap().scene
}

fn run(scene: &gs_core::Scene, lambda_o: f32) -> (Vec<LossValues>, f64, u64) {
    let mut c = TrainConfig::default().scaled(120);
    c.seed = 5;
    c.weights.lambda_o = lambda_o;
    let warmup_end = c.warmup_end;
    let (train, _) = scene.split(false);
    let mut t = Trainer::new(scene, train, c).unwrap();
    let mut losses = Vec::new();
    t.run(|_, r| {
        losses.push(r.losses);
        true
    })
    .unwrap();
    let logits = &t.gaussians().unwrap().opacity_logits;
    let mean_entropy = logits.iter().map(|x| entropy_of_logit(*x as f64)).sum::<f64>() / logits.len() as f64;
    (losses, mean_entropy, warmup_end)
}

#[test]
fn the_opacity_entropy_runs_after_the_warm_up_and_sharpens_the_opacities() {
    let scene = small_scene();
    let (plain, h_plain, warmup_end) = run(&scene, 0.0);
    let (sharp, h_sharp, _) = run(&scene, 1.0);
    let w = warmup_end as usize;
    assert!(w > 0 && w < plain.len());
    // The warm-up is untouched: the same losses to the bit, and no L_o recorded.
    assert_eq!(&plain[..w], &sharp[..w]);
    assert!(sharp[..w].iter().chain(&plain).all(|v| v.opacity_entropy.is_none()));
    // After it, L_o is recorded and counted in the total (λ_o = 1).
    let after = &sharp[w..];
    assert!(after.iter().all(|v| v.opacity_entropy.is_some_and(|h| h > 0.0 && h <= std::f64::consts::LN_2)));
    let v = after.last().unwrap();
    let without = LossValues { opacity_entropy: None, ..*v };
    let weights = LossWeights { lambda_o: 1.0, ..Default::default() };
    assert!((weights.total(v) - weights.total(&without) - v.opacity_entropy.unwrap()).abs() < 1e-12);
    // The model's opacities end nearer 0 or 1 than without the term.
    assert!(h_sharp < 0.8 * h_plain, "mean entropy {h_sharp} with L_o vs {h_plain} without");
}
