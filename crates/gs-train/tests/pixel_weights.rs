//! Pixel-GS's pixel-weighted densification statistics (`densify.pixel_weighted`) on the
//! built-in scene: before the first densification the model is the same bit for bit (the
//! statistics feed nothing else), each view adds the Gaussian's pixels in front instead of 1,
//! and density control then grows from the weighted means.

use gs_train::{TrainConfig, Trainer};

mod common;

fn run_to<'s>(cfg: &TrainConfig, scene: &'s gs_core::Scene, iteration: u64) -> Trainer<'s> {
    let (train, _) = scene.split(false);
    let mut t = Trainer::new(scene, train, cfg.clone()).unwrap();
    while t.state().unwrap().iteration < iteration {
        t.step().unwrap();
    }
    t
}

#[test]
fn pixel_weights_count_pixels_and_change_only_the_growth() {
    let scene = common::small_scene();
    let plain = TrainConfig { sh_degree_max: 0, ..common::busy_config() };
    let mut weighted = plain.clone();
    weighted.densify.pixel_weighted = true;
    let first = plain.densify.from + plain.densify.interval - plain.densify.from % plain.densify.interval;
    let (mut a, mut b) = (run_to(&plain, &scene, first - 1), run_to(&weighted, &scene, first - 1));
    assert_eq!(a.gaussians().unwrap(), b.gaussians().unwrap(), "the statistics change nothing before density control");
    let (sa, sb) = (&a.state().unwrap().stats, &b.state().unwrap().stats);
    assert!(sa.visible_count.iter().all(|&v| u64::from(v) < first), "one count per view");
    let (views, pixels): (u64, u64) = (sa.visible_count.iter().map(|&v| u64::from(v)).sum(), sb.visible_count.iter().map(|&v| u64::from(v)).sum());
    assert!(pixels > 4 * views, "pixels in front outnumber views: {pixels} against {views}");
    assert!(sb.visible_count.iter().zip(&sa.visible_count).all(|(&p, &v)| v > 0 || p == 0), "weights only where visible");
    assert_eq!(sa.max_radius, sb.max_radius, "radii are counted as before");
    let (mut a, mut b) = (run_to(&plain, &scene, first), run_to(&weighted, &scene, first));
    assert_ne!(a.gaussians().unwrap(), b.gaussians().unwrap(), "the weighted means grow another model");
    b.gaussians().unwrap().validate().unwrap();
}
