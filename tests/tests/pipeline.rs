//! End to end on the built-in scene: train (full VA-GS and the only-L_I ablation) → mesh →
//! Chamfer / F1 against the exact object mesh, beside the floor a depth-fusion method can
//! reach (the TSDF of the exact GT depth maps at the same voxel size). Release only.

use gs_core::{Scene, TriangleMesh};
use gs_train::{LossSwitches, MeshOptions, MeshReport, TrainConfig, Trainer};
use gs_tsdf::{EvalOptions, PointMetrics, TsdfConfig, TsdfVolume, evaluate_meshes};

/// Iterations of both runs (`VAGSL_PIPELINE_ITERATIONS` overrides, for longer experiments).
fn iterations() -> u64 {
    std::env::var("VAGSL_PIPELINE_ITERATIONS").ok().and_then(|v| v.parse().ok()).unwrap_or(1500)
}

fn score(mesh: &TriangleMesh, gt: &TriangleMesh) -> PointMetrics {
    let opts = EvalOptions { samples: 100_000, ..EvalOptions::object_protocol(gt).unwrap() };
    evaluate_meshes(mesh, gt, &opts).unwrap().metrics
}

fn train_and_mesh(scene: &Scene, train: &[usize], config: TrainConfig) -> (TriangleMesh, MeshReport, usize, f64) {
    let t0 = std::time::Instant::now();
    let mut trainer = Trainer::new(scene, train.to_vec(), config).unwrap();
    trainer.run(|_, _| true).unwrap();
    let (mesh, report) = trainer.extract_mesh(&MeshOptions::default()).unwrap();
    (mesh, report, trainer.gaussian_count(), t0.elapsed().as_secs_f64())
}

#[test]
#[cfg_attr(debug_assertions, ignore = "release only: two training runs")]
fn full_pipeline_beats_image_only_and_approaches_the_gt_depth_floor() {
    let built = gs_synth::generate(&gs_synth::BuiltinOptions::default()).unwrap();
    let scene = &built.scene;
    let (train, _test) = scene.split(true);
    let gt = &built.object_mesh;

    // The floor: exact GT depth of the training views fused at the same voxel size.
    let cams: Vec<&gs_core::Camera> = train.iter().map(|&i| &scene.views[i].camera).collect();
    let extent = gs_core::scene_extent(&cams);
    let voxel = extent / 512.0;
    let mut vol = TsdfVolume::new(TsdfConfig { depth_trunc: 3.0 * extent, with_color: false, ..TsdfConfig::with_voxel_size(voxel) }).unwrap();
    for &i in &train {
        vol.integrate_view(i, &scene.views[i].camera, &built.gt_depth[i], None, None, None).unwrap();
    }
    let floor = score(&vol.extract_mesh().unwrap(), gt);

    let full_cfg = TrainConfig::default().scaled(iterations());
    let (full_mesh, full_report, full_n, full_s) = train_and_mesh(scene, &train, full_cfg.clone());
    let full = score(&full_mesh, gt);
    let li_cfg = TrainConfig { losses: LossSwitches::image_only(), ..full_cfg };
    let (li_mesh, _, li_n, li_s) = train_and_mesh(scene, &train, li_cfg);
    let li = score(&li_mesh, gt);
    eprintln!("voxel {voxel:.5}");
    eprintln!("GT-depth floor: {}", serde_json::to_string(&floor).unwrap());
    eprintln!("full VA-GS ({full_n} Gaussians, {full_s:.0}s): {}", serde_json::to_string(&full).unwrap());
    eprintln!("only L_I   ({li_n} Gaussians, {li_s:.0}s): {}", serde_json::to_string(&li).unwrap());
    // Measured at 1500 iterations, seed 0, 2 threads (2026-11-23): floor Chamfer 0.00691 / F1
    // 0.949; full VA-GS 0.01856 / 0.715 (77k Gaussians, 171 s); only L_I 0.0400 / 0.267 (88k,
    // 89 s). With today's training and mesher (2026-11-27, stop 46: the depth on each voxel's
    // ray, simplification per vertex): floor 0.00686 / 0.948; full 0.01310 / 0.844 (28k);
    // only L_I 0.0332 / 0.601 (33k). The bounds keep a margin for other CPUs (the VGG kernels
    // pick AVX2 at run time, so features differ in the last bits) while still failing if a
    // term stops helping: the full method must more than halve-ish the only-L_I error (paper:
    // ~4× on DTU at 20k iterations), gain F1, and stay within 4× of what fusing the exact
    // depth maps gives.
    assert!(full.chamfer < 0.6 * li.chamfer, "full {} vs only-L_I {}", full.chamfer, li.chamfer);
    assert!(full.f1 > li.f1 + 0.15, "F1 full {} vs only-L_I {}", full.f1, li.f1);
    assert!(full.chamfer < 4.0 * floor.chamfer, "full {} vs GT-depth floor {}", full.chamfer, floor.chamfer);
    assert!(floor.chamfer < 0.01 && floor.f1 > 0.9, "floor {floor:?}");

    // The pixel footprint the mesh report gives (which `vagsl mesh` compares with the voxel)
    // matches the one of the exact depth maps: median over views of median GT depth / fx.
    let mut per_view: Vec<f64> = train
        .iter()
        .filter_map(|&i| {
            let fx = scene.views[i].camera.intrinsics.fx;
            let mut d: Vec<f64> = built.gt_depth[i].data().iter().filter(|&&z| z > 0.0).map(|&z| z as f64 / fx).collect();
            d.sort_by(f64::total_cmp);
            d.get(d.len() / 2).copied()
        })
        .collect();
    per_view.sort_by(f64::total_cmp);
    let gt_footprint = per_view[per_view.len() / 2];
    let footprint = full_report.pixel_footprint.expect("depths were fused");
    eprintln!("pixel footprint {footprint:.5} (GT depth: {gt_footprint:.5}), voxel {voxel:.5}");
    assert!((footprint / gt_footprint - 1.0).abs() < 0.1, "footprint {footprint} vs GT {gt_footprint}");
}
