//! `vagsl train → mesh → render → eval-images → eval-mesh` on the built-in scene and on a
//! shared real scene (a few iterations: this checks the plumbing, files and errors; the
//! accuracy of training is tested in tests/tests/pipeline.rs).

use std::path::{Path, PathBuf};
use std::process::Command;

fn vagsl(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_vagsl")).args(args).output().expect("run vagsl");
    (out.status.success(), String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned())
}

/// A scene of the shared test data (`VAGSL_TEST_DATA`, see gs-testdata).
fn shared(rel: &str) -> PathBuf {
    gs_testdata::root().join("data").join(rel)
}

/// The small built-in scene written as a scene folder (12 views of 120 × 90, 1,500 points),
/// cached under target/.
fn builtin_dir() -> PathBuf {
    gs_testdata::builtin::scene_dir(Path::new(env!("CARGO_TARGET_TMPDIR")), &gs_testdata::builtin::small())
}

fn json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

#[test]
fn builtin_scene_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let o = out.to_str().unwrap();
    let (ok, _, err) = vagsl(&["train", "-o", o, "--iterations", "40", "--eval", "--quiet", "--checkpoint-every", "20"]);
    assert!(ok, "{err}");
    for f in ["config.json", "point_cloud.ply", "report.json", "checkpoint.bin"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let report = json(&out.join("report.json"));
    assert_eq!(report["iterations"], 40);
    assert!(report["gaussians"].as_u64().unwrap() > 0);
    // Where the terms ran (`auto`: the CPU here, wgpu on a hardware GPU) and where the time went.
    let on = report["loss_terms_on"].as_str().unwrap();
    assert!(on.starts_with("every loss term on the CPU") || on.starts_with("L_p, L_I and L_nc/L_ns on wgpu"), "{on}");
    // And each part of the iteration, by name: Adam and the densification statistics where the
    // rasterizer runs (the model is resident on wgpu), and density control and the trim's view
    // counts and the capture path's test too; the training views' floater votes on the CPU either way.
    let parts = report["parts_on"].as_array().unwrap();
    let on_of = |part: &str| parts.iter().find(|p| p["part"] == part).map(|p| p["on"].as_str().unwrap().to_string());
    let raster = on_of("render and backward").unwrap();
    assert!(raster.starts_with("cpu (") || raster.starts_with("wgpu on "), "{raster}");
    assert!(on_of("Adam").unwrap() == raster && on_of("the training views' floater votes").unwrap().starts_with("cpu ("));
    assert_eq!(on_of("the trim's view counts").unwrap(), raster);
    assert_eq!(on_of("the capture path's floater test").unwrap(), raster);
    assert_eq!(on_of("density control (clone, split, prune, opacity reset, trim, floater removal)").unwrap(), raster);
    assert_eq!(on_of("densification statistics").unwrap(), raster);
    assert_eq!(on_of("L_I (L1, D-SSIM, edge term)").unwrap(), raster);
    assert_eq!(parts.len(), 14, "{parts:?}");
    let prof = report["time_by_part"].as_object().unwrap();
    let iterations: u64 = prof.values().map(|p| p["iterations"].as_u64().unwrap()).sum();
    assert_eq!(iterations, 40, "{prof:?}");
    for (phase, p) in prof {
        let ms = p["ms_per_iteration"].as_object().unwrap();
        let parts: f64 = ms.iter().filter(|(k, _)| *k != "whole").map(|(_, v)| v.as_f64().unwrap()).sum();
        let whole = ms["whole"].as_f64().unwrap();
        assert!(whole > 0.0 && (parts - whole).abs() <= 1e-6 * whole + 1e-9, "{phase}: parts {parts} ms, whole {whole} ms");
        assert!(ms["render"].as_f64().unwrap() > 0.0 && ms["backward"].as_f64().unwrap() > 0.0, "{phase}: {ms:?}");
    }
    assert!(prof["photometric"]["ms_per_iteration"]["photometric"].as_f64().unwrap() > 0.0, "L_p ran in its phase: {prof:?}");
    assert_eq!(prof["warm-up"]["ms_per_iteration"]["photometric"].as_f64().unwrap(), 0.0, "and not before: {prof:?}");
    let cfg = json(&out.join("config.json"));
    assert_eq!(cfg["test_views"].as_array().unwrap().len(), 4, "every 8th of 32 views held out");
    assert_eq!(cfg["train"]["iterations"], 40);
    // The PLY opens as a 3DGS model.
    let g = gs_io::read_gaussian_ply(&out.join("point_cloud.ply")).unwrap();
    assert_eq!(g.len() as u64, report["gaussians"].as_u64().unwrap());

    let (ok, stdout, err) = vagsl(&["mesh", o]);
    assert!(ok, "{err}");
    assert!(stdout.contains("triangles"), "{stdout}");
    let mesh = gs_io::read_mesh_ply(&out.join("mesh.ply")).unwrap();
    assert!(!mesh.triangles.is_empty());
    // The mesh report gives the pixel footprint; the note appears exactly when the voxel is finer.
    let mr: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("mesh.json")).unwrap()).unwrap();
    let (voxel, footprint) = (mr["voxel_size"].as_f64().unwrap(), mr["pixel_footprint"].as_f64().unwrap());
    assert!(footprint > 0.0 && footprint < 1.0, "{mr}");
    assert_eq!(err.contains("finer than a training pixel"), voxel < gs_train::FINE_VOXEL_FRACTION * footprint, "{err}");
    // One default-voxel rule: the pixel footprint at the surfaces, clamped to [r/1024, r/256]
    // with r the extent of all the scene's cameras; the default path prints no note.
    let (ok, info, _) = vagsl(&["info", "--json"]);
    assert!(ok);
    let extent = serde_json::from_str::<serde_json::Value>(&info).unwrap()["scene_extent"].as_f64().unwrap();
    assert!(voxel >= extent / 1024.0 && voxel <= extent / 256.0, "voxel {voxel}, scene extent {extent}");
    assert!((voxel / footprint - 1.0).abs() < 0.25 || voxel == extent / 256.0, "voxel {voxel}, footprint {footprint}");
    assert!(!err.contains("finer than a training pixel"), "{err}");
    // mesh.json records what the filters and the simplification did, with their settings.
    assert_eq!(mr["min_alpha"], serde_json::json!(0.5), "{mr}");
    assert!(mr["pixels_below_min_alpha"].is_u64(), "{mr}");
    assert!(mr["components"]["min_share"].as_f64().unwrap() > 0.0, "{mr}");
    let c = &mr["components"];
    assert!(c["removed"].as_u64().unwrap() < c["components"].as_u64().unwrap(), "{mr}");
    assert!(mr["depth_filter"].is_null(), "off by default: {mr}");
    let simp = &mr["simplification"];
    assert_eq!(simp["triangles_after"], mr["triangles"], "{mr}");
    assert!(simp["triangles_before"].as_u64().unwrap() > mr["triangles"].as_u64().unwrap(), "{mr}");
    // Each vertex's bound is the multiple of the footprint at it, never below that of the voxel.
    let bound = simp["error_bound"].as_f64().unwrap();
    assert!(bound / voxel - gs_train::DEFAULT_SIMPLIFY_ERROR > -1e-9, "{mr}");
    let largest = simp["graded"]["largest"].as_f64().unwrap();
    assert!(largest >= bound && largest <= 16.0 * bound, "{mr}");
    assert!(simp["error"].as_f64().unwrap() <= largest, "{mr}");
    // The depth filter on, the simplification off, every component of 50 triangles kept.
    let plain = out.join("plain.ply");
    let (ok, stdout, err) = vagsl(&[
        "mesh", o, "-o", plain.to_str().unwrap(), "--depth-filter", "--no-simplify", "--min-component-share", "0",
    ]);
    assert!(ok, "{err}");
    assert!(stdout.contains("not confirmed by 2 neighbouring views"), "{stdout}");
    let pr = json(&out.join("plain.json"));
    assert!(pr["simplification"].is_null(), "{pr}");
    let f = &pr["depth_filter"];
    assert_eq!(f["min_views"], 2, "{pr}");
    assert!(f["pixels_checked"].as_u64().unwrap() > f["pixels_dropped"].as_u64().unwrap(), "{pr}");
    assert_eq!(pr["components"]["min_share"], serde_json::json!(0.0), "{pr}");
    // A triangle count is an upper bound.
    let (ok, _, err) = vagsl(&["mesh", o, "-o", plain.to_str().unwrap(), "--triangles", "500"]);
    assert!(ok, "{err}");
    assert!(gs_io::read_mesh_ply(&plain).unwrap().triangles.len() <= 500);
    assert!(json(&out.join("plain.json"))["simplification"]["error_bound"].is_null());
    // The front surface by default; blending every Gaussian fuses other depths. Smoothing
    // before simplifying is recorded with its steps.
    assert!((mr["surface_cut"].as_f64().unwrap() - gs_train::DEFAULT_SURFACE_CUT as f64).abs() < 1e-6, "{mr}");
    assert!(mr["smoothing"].is_null(), "off by default: {mr}");
    let (ok, _, err) = vagsl(&["mesh", o, "-o", plain.to_str().unwrap(), "--surface-cut", "0", "--smooth", "5"]);
    assert!(ok, "{err}");
    let br = json(&out.join("plain.json"));
    assert_eq!(br["surface_cut"], serde_json::json!(0.0), "{br}");
    assert_eq!(br["smoothing"]["iterations"], 5, "{br}");
    assert_ne!(gs_io::read_mesh_ply(&plain).unwrap().positions, mesh.positions);
    let (ok, _, err) = vagsl(&["mesh", o, "--surface-cut", "1"]);
    assert!(!ok && err.contains("--surface-cut 1"), "{err}");
    let (ok, _, err) = vagsl(&["mesh", o, "--min-alpha", "2"]);
    assert!(!ok && err.contains("between 0 and 1"), "{err}");
    let mesh_path = out.join("mesh.ply");
    let (ok, _, err) = vagsl(&["render", o, "--split", "test", "--mesh", mesh_path.to_str().unwrap()]);
    assert!(ok, "{err}");
    let renders = out.join("renders/test");
    for f in ["0000.png", "0000_depth.exr", "0000_normal.png", "0000_mesh.png"] {
        assert!(renders.join(f).is_file(), "{f} missing");
    }
    // The mesh screenshot shows the fused surface: most pixels are shaded, not background.
    let shot = image::open(renders.join("0000_mesh.png")).unwrap().to_rgb8();
    let lit = shot.pixels().filter(|p| p[0] > 20).count();
    assert!(lit > shot.len() / 3 / 4, "only {lit} shaded pixels in the mesh screenshot");
    // Probing for a GPU on this headless machine prints nothing alarming: Mesa's device-select
    // layer would print "XDG_RUNTIME_DIR is invalid" twice (vagsl switches it off).
    let out_auto = Command::new(env!("CARGO_BIN_EXE_vagsl"))
        .args(["render", o, "--split", "test", "-o", out.join("auto").to_str().unwrap(), "--backend", "auto"])
        .env_remove("XDG_RUNTIME_DIR")
        .env_remove("WAYLAND_DISPLAY")
        .env_remove("DISPLAY")
        .env_remove("NODEVICE_SELECT")
        .env_remove("MESA_VK_DEVICE_SELECT")
        .output()
        .unwrap();
    let err_auto = String::from_utf8_lossy(&out_auto.stderr);
    assert!(out_auto.status.success() && !err_auto.contains("XDG_RUNTIME_DIR"), "{err_auto}");
    let (ok, _, err) = vagsl(&["render", o, "--mesh", "/nonexistent/m.ply"]);
    assert!(!ok && err.contains("/nonexistent/m.ply"), "{err}");

    let (ok, stdout, err) = vagsl(&["eval-images", o, "--json"]);
    assert!(ok, "{err}");
    let m: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(m["views"].as_array().unwrap().len(), 4);
    let psnr = m["psnr"].as_f64().unwrap();
    assert!(psnr > 10.0 && psnr < 60.0, "PSNR {psnr}");
    assert!(m["lpips"].as_f64().unwrap() > 0.0);
    // The object alone, inside the built-in scene's masks: a different, still sane score.
    let (ok, stdout, err) = vagsl(&["eval-images", o, "--json", "--masked", "--no-lpips"]);
    assert!(ok, "{err}");
    let mm: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(mm["scored"], "object_masks");
    let frac = mm["views"][0]["mask_fraction"].as_f64().unwrap();
    assert!(frac > 0.0 && frac < 1.0, "mask fraction {frac}");
    let masked_psnr = mm["psnr"].as_f64().unwrap();
    assert!(masked_psnr > 10.0 && masked_psnr < 60.0 && masked_psnr != psnr, "masked PSNR {masked_psnr} vs {psnr}");
    assert!(out.join("eval_images_masked.json").is_file());
    // The pixels some training view sees, from the scene's exact depth maps: on the built-in
    // ring nearly all of each held-out view, and a missing map is an error naming the view.
    let built = gs_synth::generate(&gs_synth::BuiltinOptions::default()).unwrap();
    let gt = dir.path().join("gt");
    std::fs::create_dir_all(&gt).unwrap();
    for (v, d) in built.scene.views.iter().zip(&built.gt_depth) {
        gs_io::write_npy(&gt.join(format!("depth_{}.npy", v.name.trim_end_matches(".png"))), d).unwrap();
    }
    let (ok, stdout, err) = vagsl(&["eval-images", o, "--json", "--seen-from", gt.to_str().unwrap(), "--no-lpips"]);
    assert!(ok, "{err}");
    let ms: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(ms["scored"], "seen");
    for v in ms["views"].as_array().unwrap() {
        let frac = v["mask_fraction"].as_f64().unwrap();
        assert!(frac > 0.9 && frac <= 1.0, "{}: {frac} of the image seen", v["name"]);
    }
    let seen_psnr = ms["psnr"].as_f64().unwrap();
    assert!(seen_psnr > 10.0 && seen_psnr < 60.0, "seen PSNR {seen_psnr}");
    assert!(out.join("eval_images_seen.json").is_file());
    std::fs::remove_file(gt.join("depth_0008.npy")).unwrap();
    let (ok, _, err) = vagsl(&["eval-images", o, "--seen-from", gt.to_str().unwrap(), "--no-lpips"]);
    assert!(!ok && err.contains("no depth map for view '0008.png'") && err.contains("depth_0008.npy"), "{err}");
    let (ok, _, err) = vagsl(&["eval-images", o, "--seen-from", gt.to_str().unwrap(), "--masked"]);
    assert!(!ok && err.contains("cannot be used with"), "{err}");

    let (ok, stdout, err) = vagsl(&["eval-mesh", "--pred", out.join("mesh.ply").to_str().unwrap(), "--gt", out.join("mesh.ply").to_str().unwrap(), "--samples", "50000", "--json"]);
    assert!(ok, "{err}");
    let e: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert!(e["chamfer"].as_f64().unwrap() < 0.05);

    // With --checkpoint-every the final state is checkpointed too: resuming it is accepted
    // (same scene options) and has nothing left to do.
    let ck = out.join("checkpoint.bin");
    let report = |p: &std::path::Path| -> serde_json::Value { serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap() };
    let first = report(&out.join("report.json"));
    assert_eq!(first["resumed_from"], serde_json::Value::Null);
    let (ok, _, err) = vagsl(&["train", "-o", o, "--eval", "--quiet", "--resume", ck.to_str().unwrap()]);
    assert!(ok, "{err}");
    assert!(err.contains("resuming"), "{err}");
    // The resumed run's report counts the first segment's time too (carried in the checkpoint).
    let second = report(&out.join("report.json"));
    assert_eq!(second["resumed_from"], first["iterations"]);
    assert_eq!(second["earlier_time_known"], true);
    let (t1, t2) = (first["train_seconds"].as_f64().unwrap(), second["train_seconds"].as_f64().unwrap());
    assert!(t1 > 0.0 && t2 >= t1 && t2 - t1 <= second["segment_seconds"].as_f64().unwrap() + 1e-9, "{t1} then {t2}");

    // A veil injected in front of held-out view 0000 (20 opaque magenta splats 0.1–0.3 in
    // front of its camera) is reported by eval-images and on the report page, with its price.
    let scene = gs_synth::generate(&gs_synth::BuiltinOptions::default()).unwrap().scene;
    let cam = &scene.views.iter().find(|v| v.name == "0000.png").unwrap().camera;
    let ply = out.join("point_cloud.ply");
    let mut g = gs_io::read_gaussian_ply(&ply).unwrap();
    for k in 0..20 {
        let p = cam.camera_to_world(gs_core::glam::DVec3::new(0.04 * (k % 5) as f64 - 0.08, 0.04 * (k / 5) as f64 - 0.06, 0.1 + 0.01 * k as f64));
        let mut sh = [[0.0; 3]; 16];
        sh[0] = [1.0, 0.0, 1.0].map(gs_core::gaussians::rgb_to_sh_dc);
        g.push(p.as_vec3().to_array(), [0.05f32.ln(); 3], [1.0, 0.0, 0.0, 0.0], gs_core::gaussians::inverse_sigmoid(0.99), sh);
    }
    gs_io::write_gaussian_ply(&ply, &g).unwrap();
    // The edited model is no longer the one report.json fingerprints: drop the fingerprint, as
    // reports written before it existed have none.
    let mut rep = json(&out.join("report.json"));
    rep.as_object_mut().unwrap().remove("model_fingerprint").expect("the report fingerprints its model");
    std::fs::write(out.join("report.json"), serde_json::to_string(&rep).unwrap()).unwrap();
    let (ok, stdout, err) = vagsl(&["eval-images", o, "--json", "--no-lpips"]);
    assert!(ok, "{err}");
    let m: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let veil = &m["views"][0]["veil"];
    assert!(veil["splats"].as_u64().unwrap() >= 20 && veil["cover"].as_f64().unwrap() > 0.9, "{veil}");
    let (with, without) = (m["views"][0]["psnr"].as_f64().unwrap(), veil["psnr_without"].as_f64().unwrap());
    assert!(without > with + 3.0, "{with} dB, {without} dB without the veil");
    assert!(m["views"].as_array().unwrap()[1..].iter().all(|v| v.get("veil").is_none()), "{m}");
    let (ok, stdout, err) = vagsl(&["eval-images", o, "--no-lpips"]);
    assert!(ok && stdout.contains("veil: ") && stdout.contains("of the camera"), "{stdout}{err}");
    let (ok, _, err) = vagsl(&["view", o, "--no-lpips"]);
    assert!(ok, "{err}");
    let page = std::fs::read_to_string(out.join("report/data.js")).unwrap();
    assert_eq!(page.matches("veil: ").count(), 1, "one view carries the note");
}

#[test]
fn bad_inputs_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let o = dir.path().join("x");
    let o = o.to_str().unwrap();
    let (ok, _, err) = vagsl(&["train", "/nonexistent/scene", "-o", o]);
    assert!(!ok && err.contains("/nonexistent/scene"), "{err}");
    let (ok, _, err) = vagsl(&["train", "-o", o, "--patch-size", "4"]);
    assert!(!ok && err.contains("patch_size"), "{err}");
    let (ok, _, err) = vagsl(&["train", "-o", o, "--ncc-scale", "5"]);
    assert!(!ok && err.contains("ncc_scale"), "{err}");
    // Grey images wider than the photos would only be upsampled: refused.
    let (ok, _, err) = vagsl(&["train", builtin_dir().to_str().unwrap(), "-o", o, "-r", "1", "--ncc-scale", "2"]);
    assert!(!ok && err.contains("--ncc-scale 2") && err.contains("wider than the originals"), "{err}");
    let (ok, _, err) = vagsl(&["train", "-o", o, "--sh-policy", "adaptive", "--sh-min-gain", "1.5"]);
    assert!(!ok && err.contains("sh_min_gain"), "{err}");
    let (ok, _, err) = vagsl(&["train", "-o", o, "--sh-degree", "4"]);
    assert!(!ok && err.contains("sh_degree_max"), "{err}");
    let (ok, _, err) = vagsl(&["train", "-o", o, "--iterations", "0"]);
    assert!(!ok && err.contains("iterations"), "{err}");
    let (ok, _, err) = vagsl(&["mesh", dir.path().to_str().unwrap()]);
    assert!(!ok && err.contains("config.json"), "{err}");
    let bad = dir.path().join("bad.bin");
    std::fs::write(&bad, b"garbage").unwrap();
    let (ok, _, err) = vagsl(&["train", "-o", o, "--resume", bad.to_str().unwrap()]);
    assert!(!ok && err.contains("bad.bin") && err.contains("magic"), "{err}");
    let (ok, _, err) = vagsl(&["eval-mesh", "--pred", "/nonexistent/p.ply", "--gt", "/nonexistent/g.ply"]);
    assert!(!ok && err.contains("/nonexistent/p.ply"), "{err}");
}

#[test]
fn trains_on_a_real_distorted_scene() {
    if !gs_testdata::needs!("data/fox") {
        return;
    }
    // fox: OPENCV with distortion, 50 photos; undistorted and downscaled on load, with L_p's
    // grey images loaded again at twice the training width (--ncc-scale 2).
    let dir = tempfile::tempdir().unwrap();
    let o = dir.path().join("fox");
    let (ok, _, err) = vagsl(&[
        "train", shared("fox").to_str().unwrap(), "-o", o.to_str().unwrap(), "--width", "135",
        "--iterations", "20", "--quiet", "--eval", "--ncc-scale", "2",
    ]);
    assert!(ok, "{err}");
    let (ok, stdout, err) = vagsl(&["eval-images", o.to_str().unwrap(), "--no-lpips"]);
    assert!(ok, "{err}");
    assert!(stdout.contains("PSNR"), "{stdout}");
    // fox has no masks: masked evaluation names the first view that lacks one.
    let (ok, _, err) = vagsl(&["eval-images", o.to_str().unwrap(), "--no-lpips", "--masked"]);
    assert!(!ok && err.contains("has no mask"), "{err}");
}

#[test]
fn mesh_from_given_depth_maps_matches_the_open3d_floor() {
    if !gs_testdata::needs!("data/synth-bunny") {
        return;
    }
    // synth-bunny's exact GT depth maps fused by `vagsl mesh --depth-dir`, scored by
    // `vagsl eval-mesh` with the object protocol. Open3D 0.19's raw mesh gives Chamfer 0.0057,
    // F1 0.945 (gs-tsdf's own test matches it); `vagsl mesh` also drops components under 50
    // triangles, which costs a little completeness: measured 0.005774 / 0.9432.
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("gt_fused.ply");
    let bunny = shared("synth-bunny");
    // The raw fusion, without simplification.
    let (ok, stdout, err) = vagsl(&[
        "mesh", bunny.to_str().unwrap(), "--depth-dir", bunny.join("gt").to_str().unwrap(),
        "--voxel-size", "0.008", "--depth-trunc", "20", "-o", mesh.to_str().unwrap(), "--no-simplify",
    ]);
    assert!(ok, "{err}");
    assert!(stdout.contains("40 depth maps"), "{stdout}");
    let (ok, stdout, err) = vagsl(&[
        "eval-mesh", "--pred", mesh.to_str().unwrap(), "--gt", bunny.join("gt_mesh.ply").to_str().unwrap(),
        "--crop-to-gt", "0.05", "--min-z", "0.005", "--json",
    ]);
    assert!(ok, "{err}");
    let m: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert!(m["chamfer"].as_f64().unwrap() <= 0.0059, "{m}");
    assert!(m["f1"].as_f64().unwrap() >= 0.94, "{m}");
    // `--bounds` around the bunny (its GT box grown by 5 %, floor dropped) fuses the object
    // alone: the same scores, a fraction of the triangles.
    let (lo, hi) = gs_io::read_mesh_ply(&bunny.join("gt_mesh.ply")).unwrap().bounds().unwrap();
    let g = |k: usize, s: f32| (if s < 0.0 { lo[k] } else { hi[k] } + s * 0.05 * (hi[k] - lo[k])) as f64;
    let bounds = format!("{},{},0.005,{},{},{}", g(0, -1.0), g(1, -1.0), g(0, 1.0), g(1, 1.0), g(2, 1.0));
    let boxed = dir.path().join("gt_boxed.ply");
    let (ok, stdout, err) = vagsl(&[
        "mesh", bunny.to_str().unwrap(), "--depth-dir", bunny.join("gt").to_str().unwrap(),
        "--voxel-size", "0.008", "--depth-trunc", "20", "-o", boxed.to_str().unwrap(), "--bounds", &bounds,
        "--no-simplify",
    ]);
    assert!(ok, "{err}");
    let triangles = |s: &str| s.split(" triangles").next().unwrap().rsplit(' ').next().unwrap().parse::<u64>().unwrap();
    let all = gs_io::read_mesh_ply(&mesh).unwrap().triangles.len() as u64;
    assert!(triangles(&stdout) * 4 < all, "{stdout} vs {all} triangles");
    let (ok, out2, err) = vagsl(&[
        "eval-mesh", "--pred", boxed.to_str().unwrap(), "--gt", bunny.join("gt_mesh.ply").to_str().unwrap(),
        "--crop-to-gt", "0.05", "--min-z", "0.005", "--json",
    ]);
    assert!(ok, "{err}");
    let b: serde_json::Value = serde_json::from_str(&out2).unwrap();
    assert!((b["chamfer"].as_f64().unwrap() - m["chamfer"].as_f64().unwrap()).abs() < 2e-4, "{b} vs {m}");
    let (ok, _, err) = vagsl(&["mesh", bunny.to_str().unwrap(), "--bounds", "1,2,3"]);
    assert!(!ok && err.contains("six finite numbers"), "{err}");
    // A depth folder without the views' maps is a clear error naming the view.
    let (ok, _, err) = vagsl(&["mesh", bunny.to_str().unwrap(), "--depth-dir", dir.path().to_str().unwrap()]);
    assert!(!ok && err.contains("0000"), "{err}");
}

#[test]
fn the_mesh_curve_scores_each_point_against_the_ground_truth() {
    if !gs_testdata::needs!("data/synth-bunny") {
        return;
    }
    // `train --track-gt`: at each of the 10 scoring points the model is meshed and scored with
    // the object protocol; the curve must fall as training goes (SfM points → a surface).
    let dir = tempfile::tempdir().unwrap();
    let bunny = shared("synth-bunny");
    let gt = bunny.join("gt_mesh.ply");
    let out = dir.path().join("run");
    let track = ["--track-gt", gt.to_str().unwrap(), "--track-crop-to-gt", "0.05", "--track-min-z", "0.005"];
    // Opacity resets every 30 iterations (until densification ends at 112): the points that
    // fall on one (30, 60, 90) move half an interval later instead of scoring a transparent model.
    // 3DGS' screen filter: with the compensated Mip filter of the CPU presets the model is still
    // below the mesh's opacity 7 iterations after a reset, and those points record a mesh error.
    let mut args = vec![
        "train", bunny.to_str().unwrap(), "-o", out.to_str().unwrap(), "-r", "4", "--iterations", "150",
        "--set", "densify.opacity_reset_interval=30", "--set", "antialiased=false", "--set", "low_pass=0.3",
    ];
    args.extend(track);
    let (ok, _, err) = vagsl(&args);
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(out.join("metrics.jsonl")).unwrap();
    let points: Vec<serde_json::Value> =
        text.lines().map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()).filter(|v| v.get("chamfer").is_some()).collect();
    let its: Vec<u64> = points.iter().map(|p| p["iteration"].as_u64().unwrap()).collect();
    assert_eq!(its, [15, 37, 45, 67, 75, 97, 105, 120, 135, 150], "{text}");
    let chamfer = |p: &serde_json::Value| p["chamfer"].as_f64().unwrap();
    assert!(points.windows(2).all(|w| w[1]["seconds"].as_f64() >= w[0]["seconds"].as_f64()));
    // The last point beats the first by 30 % and every point of the curve's first half. (Since
    // meshes fuse the front surface, stop 43, the first point is 0.081 where it was 0.145, and
    // the last 0.051 where it was 0.069.)
    assert!(chamfer(&points[9]) < 0.7 * chamfer(&points[0]), "{text}");
    assert!(points[..5].iter().all(|p| chamfer(&points[9]) < chamfer(p)), "{text}");
    assert!(points.iter().all(|p| (0.0..=1.0).contains(&p["f1"].as_f64().unwrap()) && p["triangles"].as_u64().unwrap() > 0));
    // Training time leaves the meshing out: the last point's seconds are the run's.
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert!((points[9]["seconds"].as_f64().unwrap() - report["train_seconds"].as_f64().unwrap()).abs() < 1.0, "{report}");
    // A missing ground truth is refused before the output folder is made.
    let missing = dir.path().join("nope.ply");
    let out2 = dir.path().join("run2");
    let (ok, _, err) = vagsl(&["train", bunny.to_str().unwrap(), "-o", out2.to_str().unwrap(), "-r", "4", "--iterations", "20", "--track-gt", missing.to_str().unwrap()]);
    assert!(!ok && err.contains("nope.ply"), "{err}");
    assert!(!out2.exists());
}
