//! synth-bunny GT depth fusion vs the Open3D 0.19 ScalableTSDFVolume anchor
//! (release only: `cargo test -p gs-tsdf --release --test bunny`).

mod common;

use gs_tsdf::{EvalOptions, TsdfConfig, TsdfVolume, evaluate_meshes};

#[test]
#[cfg_attr(debug_assertions, ignore = "release only: fuses 40 views of 480x360")]
fn bunny_gt_depth_at_voxel_0008_matches_open3d() {
    if !gs_testdata::needs!("data/synth-bunny") {
        return;
    }
    let dir = common::bunny_dir();
    let views = common::bunny_views();
    assert_eq!(views.len(), 40);
    let cfg = TsdfConfig { depth_trunc: 20.0, with_color: false, ..TsdfConfig::with_voxel_size(0.008) };
    let t0 = std::time::Instant::now();
    let mut vol = TsdfVolume::new(cfg).unwrap();
    for (i, (cam, depth)) in views.iter().enumerate() {
        vol.integrate_view(i, cam, depth, None, None, None).unwrap();
    }
    let t1 = std::time::Instant::now();
    let mesh = vol.extract_mesh().unwrap();
    let t2 = std::time::Instant::now();
    eprintln!(
        "blocks {} integrate {:.2}s extract {:.2}s, {} vertices {} triangles",
        vol.block_count(),
        (t1 - t0).as_secs_f64(),
        (t2 - t1).as_secs_f64(),
        mesh.positions.len(),
        mesh.triangles.len()
    );
    let gt = common::read_ply(&dir.join("gt_mesh.ply"));
    let opts = EvalOptions::object_protocol(&gt).unwrap();
    assert!((opts.tau - 0.0081).abs() < 1e-4);
    let r = evaluate_meshes(&mesh, &gt, &opts).unwrap();
    eprintln!("bunny protocol: {}", serde_json::to_string(&r.metrics).unwrap());
    // Open3D 0.19 at voxel 0.008: Chamfer 0.0057, F1 0.945. Measured 2026-11-27: 0.00571,
    // 0.9442. Open3D reads each voxel's depth at the nearest pixel; vagsl interpolates it on
    // the voxel's ray (flat planes, docs/method.md §TSDF), which leaves the visible bunny as
    // it was (GT → mesh distances at heights 0.2–1 equal or lower) and changes the crevice
    // where the bunny meets the floor (z < 0.2, seen by no view: +0.0003 on average there).
    assert!(r.metrics.chamfer <= 0.0057 * 1.01, "Chamfer {}", r.metrics.chamfer);
    assert!(r.metrics.f1 >= 0.943, "F1 {}", r.metrics.f1);
    // The whole scene against gt_scene_mesh.ply (no crop).
    let scene = common::read_ply(&dir.join("gt_scene_mesh.ply"));
    let so = EvalOptions { crop: None, tau: 0.01, ..opts };
    let s = evaluate_meshes(&mesh, &scene, &so).unwrap();
    eprintln!("scene: {}", serde_json::to_string(&s.metrics).unwrap());
    // Open3D 0.19 on the same inputs (same protocol, 200k samples each, 2026-11-23): scene
    // accuracy 0.01185, completeness 0.06212, Chamfer 0.03698 (unobserved wall backs and
    // floor under the bunny dominate completeness). Allow 0.5 % for the sampling noise.
    assert!(s.metrics.accuracy <= 0.01185 * 1.005, "scene accuracy {}", s.metrics.accuracy);
    assert!(s.metrics.chamfer <= 0.03698 * 1.005, "scene Chamfer {}", s.metrics.chamfer);
}
