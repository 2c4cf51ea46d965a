//! The small scene and busy configuration shared by the tests that follow a run's state step
//! by step (resume, the executor contract).

use gs_train::TrainConfig;

/// The built-in scene at 64×48, 24 views (12 a ring, 30° apart: each has source views for L_p
/// and L_f), 400 points.
pub fn small_scene() -> gs_core::Scene {
    let opts = gs_synth::BuiltinOptions { width: 64, height: 48, views: 24, supersample: 1, points: 400, ..Default::default() };
    gs_synth::generate(&opts).unwrap().scene
}

/// 120 iterations in which every mechanism fires: each loss phase, densification, opacity
/// reset and trim (also around iteration 60), exposure compensation and its optimiser, and the
/// memo of source-view plane depths that L_p and L_f reuse.
pub fn busy_config() -> TrainConfig {
    let mut c = TrainConfig::default().scaled(120);
    c.densify.from = 10;
    c.densify.interval = 20;
    c.densify.opacity_reset_interval = 50;
    c.densify.trim_interval = 40;
    c.seed = 7;
    c.exposure = true;
    c.source_depth_max_age = 15;
    // Two sources a step keep L_p and L_f cheap on lavapipe (the wgpu runs of wgpu_resume).
    c.source_views = 2;
    c
}
