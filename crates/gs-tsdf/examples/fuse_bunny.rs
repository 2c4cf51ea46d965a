//! Fuses synth-bunny's GT depth maps and prints timings and metrics as JSON (for the workspace BENCHMARKS.md).
//! `cargo run -p gs-tsdf --release --example fuse_bunny -- [voxel] [max_tsdf_jump]`

#[path = "../tests/common/mod.rs"]
mod common;

use gs_tsdf::{EvalOptions, ExtractOptions, TsdfConfig, TsdfVolume, evaluate_meshes};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let voxel: f64 = args.get(1).map(|s| s.parse().unwrap()).unwrap_or(0.008);
    let jump: Option<f32> = args.get(2).map(|s| s.parse().unwrap());
    let dir = common::bunny_dir();
    let views = common::bunny_views();
    let cfg = TsdfConfig { depth_trunc: 20.0, with_color: false, ..TsdfConfig::with_voxel_size(voxel) };
    let t0 = std::time::Instant::now();
    let mut vol = TsdfVolume::new(cfg).unwrap();
    for (i, (cam, depth)) in views.iter().enumerate() {
        vol.integrate_view(i, cam, depth, None, None, None).unwrap();
    }
    let t1 = std::time::Instant::now();
    let mesh = vol.extract_mesh_with(&ExtractOptions { min_weight: 0.0, max_tsdf_jump: jump }).unwrap();
    let t2 = std::time::Instant::now();
    let gt = common::read_ply(&dir.join("gt_mesh.ply"));
    let opts = EvalOptions::object_protocol(&gt).unwrap();
    let r = evaluate_meshes(&mesh, &gt, &opts).unwrap();
    let t3 = std::time::Instant::now();
    let scene = common::read_ply(&dir.join("gt_scene_mesh.ply"));
    let s = evaluate_meshes(&mesh, &scene, &EvalOptions { crop: None, ..opts.clone() }).unwrap();
    println!(
        "{{\"voxel\": {voxel}, \"views\": {}, \"threads\": {}, \"blocks\": {}, \"integrate_s\": {:.3}, \"extract_s\": {:.3}, \"eval_s\": {:.3}, \"vertices\": {}, \"triangles\": {}, \"bunny\": {}, \"scene\": {}}}",
        views.len(),
        rayon::current_num_threads(),
        vol.block_count(),
        (t1 - t0).as_secs_f64(),
        (t2 - t1).as_secs_f64(),
        (t3 - t2).as_secs_f64(),
        mesh.positions.len(),
        mesh.triangles.len(),
        serde_json::to_string(&r.metrics).unwrap(),
        serde_json::to_string(&s.metrics).unwrap()
    );
}
