//! transforms.json scenes: shared COLMAP scenes converted to transforms.json load with the
//! same cameras (to 1e-6) and convert back to the same model; a Blender-synthetic fixture
//! loads with the focal of `camera_angle_x`, its poses and its test split.

use gs_core::Camera;
use gs_core::glam::DVec3;
use gs_io::colmap::{ColmapModel, read_model, read_text, write_text};
use gs_io::scene::{LoadOptions, MaskPolicy, load_scene};
use gs_io::transforms::write_transforms;
use gs_io::{SceneLayout, read_scene_model};
use std::path::{Path, PathBuf};

fn shared(rel: &str) -> PathBuf {
    gs_testdata::root().join("data").join(rel)
}

/// `scene`'s COLMAP model written as transforms.json into a temporary folder whose `images`
/// links to the scene's photos.
fn converted(scene: &Path) -> (tempfile::TempDir, ColmapModel) {
    let model = read_model(&scene.join("sparse/0")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    write_transforms(&model, dir.path(), "images").unwrap();
    std::os::unix::fs::symlink(scene.join("images"), dir.path().join("images")).unwrap();
    (dir, model)
}

/// Largest difference between two views' cameras: intrinsics, size, rotation, translation and
/// centre (panics on a size difference).
fn camera_difference(a: &Camera, b: &Camera) -> f64 {
    assert_eq!((a.width, a.height), (b.width, b.height));
    let (ka, kb) = (&a.intrinsics, &b.intrinsics);
    let k = [ka.fx - kb.fx, ka.fy - kb.fy, ka.cx - kb.cx, ka.cy - kb.cy].map(f64::abs);
    let r = (a.rotation - b.rotation).to_cols_array().map(f64::abs);
    let t = (a.translation - b.translation).abs().max_element();
    let c = (a.center() - b.center()).abs().max_element();
    k.into_iter().chain(r).fold(t.max(c), f64::max)
}

/// Largest difference between two models' cameras (projection of a grid of rays, with
/// distortion, in pixels) and poses (rotation entries, translation), matched by image name;
/// the models must have the same names and image sizes.
fn model_difference(a: &ColmapModel, b: &ColmapModel) -> f64 {
    let mut names_a: Vec<&str> = a.images.values().map(|i| i.name.as_str()).collect();
    let mut names_b: Vec<&str> = b.images.values().map(|i| i.name.as_str()).collect();
    names_a.sort();
    names_b.sort();
    assert_eq!(names_a, names_b);
    let mut worst = 0.0f64;
    for ia in a.images.values() {
        let ib = b.images.values().find(|i| i.name == ia.name).unwrap();
        let (ca, cb) = (&a.cameras[&ia.camera_id], &b.cameras[&ib.camera_id]);
        assert_eq!((ca.width, ca.height), (cb.width, cb.height), "{}", ia.name);
        for u in [-0.4, 0.0, 0.3] {
            for v in [-0.3, 0.1, 0.5] {
                let (pa, pb) = (ca.img_from_cam([u, v]), cb.img_from_cam([u, v]));
                worst = worst.max((pa[0] - pb[0]).abs()).max((pa[1] - pb[1]).abs());
            }
        }
        let r = (ia.rotation().unwrap() - ib.rotation().unwrap()).to_cols_array().map(f64::abs);
        let t = (DVec3::from_array(ia.tvec) - DVec3::from_array(ib.tvec)).abs().max_element();
        worst = r.into_iter().fold(worst.max(t), f64::max);
    }
    worst
}

fn check_round_trip(path: &Path, load_images: bool) {
    let scene = path.file_name().unwrap().to_string_lossy();
    let (dir, model) = converted(path);
    let sm = read_scene_model(dir.path(), None).unwrap();
    assert!(matches!(sm.layout, SceneLayout::Transforms(_)));
    let d_model = model_difference(&model, &sm.model);
    assert!(d_model < 1e-6, "{scene}: transforms model differs by {d_model:e}");
    // Points: float32 positions, exact colours.
    assert_eq!(sm.model.points3d.len(), model.points3d.len());
    for (p, q) in model.points3d.values().zip(sm.model.points3d.values()) {
        let scale = 1.0 + DVec3::from_array(p.xyz).abs().max_element();
        assert!((DVec3::from_array(p.xyz) - DVec3::from_array(q.xyz)).abs().max_element() < 1e-6 * scale);
        assert_eq!(p.rgb, q.rgb);
    }
    let mut d_views = 0.0f64;
    if load_images {
        let opts = LoadOptions { masks: MaskPolicy::Ignore, ..Default::default() };
        let a = load_scene(path, &opts).unwrap();
        let b = load_scene(dir.path(), &opts).unwrap();
        assert_eq!(a.views.len(), b.views.len());
        for (va, vb) in a.views.iter().zip(&b.views) {
            assert_eq!(va.name, vb.name);
            d_views = d_views.max(camera_difference(&va.camera, &vb.camera));
            assert_eq!((vb.image.width(), vb.image.height()), (va.image.width(), va.image.height()));
        }
        assert_eq!(a.views[0].image.data(), b.views[0].image.data(), "{scene}: same photo, same pixels");
        assert!(d_views < 1e-6, "{scene}: loaded views differ by {d_views:e}");
        assert_eq!(b.held_out, None);
    }
    // Back to COLMAP: the same cameras and poses.
    let back = tempfile::tempdir().unwrap();
    write_text(&sm.model, back.path()).unwrap();
    let d_back = model_difference(&model, &read_text(back.path()).unwrap());
    assert!(d_back < 1e-6, "{scene}: COLMAP → transforms → COLMAP differs by {d_back:e}");
    eprintln!("{scene}: max difference model {d_model:.2e}, loaded views {d_views:.2e}, round trip {d_back:.2e}");
}

#[test]
fn the_builtin_scene_converts_to_transforms_and_back() {
    let dir = gs_testdata::builtin::scene_dir(Path::new(env!("CARGO_TARGET_TMPDIR")), &gs_testdata::builtin::small());
    check_round_trip(&dir, true);
}

#[test]
fn synth_bunny_converts_to_transforms_and_back() {
    if !gs_testdata::needs!("data/synth-bunny") {
        return;
    }
    check_round_trip(&shared("synth-bunny"), true);
}

#[test]
fn fox_with_opencv_distortion_converts_to_transforms_and_back() {
    if !gs_testdata::needs!("data/fox") {
        return;
    }
    check_round_trip(&shared("fox"), true);
}

#[test]
fn dtu_with_a_camera_per_image_converts_to_transforms_and_back() {
    if !gs_testdata::needs!("data/dtu-scan24") {
        return;
    }
    // 49 cameras: intrinsics written per frame.
    check_round_trip(&shared("dtu-scan24"), false);
}

/// A Blender-synthetic-style scene: 8×6 PNGs, `camera_angle_x` = 90° (f = 4 px), frames
/// without extensions, a train and a test file.
fn blender_fixture() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    for sub in ["train", "test"] {
        std::fs::create_dir(dir.path().join(sub)).unwrap();
    }
    for (i, name) in ["train/r_0.png", "train/r_1.png", "test/r_0.png"].iter().enumerate() {
        let img = image::RgbImage::from_pixel(8, 6, image::Rgb([40 * i as u8, 100, 200]));
        img.save(dir.path().join(name)).unwrap();
    }
    let angle = std::f64::consts::FRAC_PI_2;
    // r_0: OpenGL identity at (0, 0, 4), looking down −z. r_1: at (4, 0, 0) looking down −x
    // (camera x = world −z, y = world y, z = world x). Test r_0: at (0, 0, 5) like r_0.
    let train = format!(
        r#"{{"camera_angle_x": {angle}, "frames": [
        {{"file_path": "./train/r_0", "rotation": 0.0, "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]}},
        {{"file_path": "./train/r_1", "transform_matrix": [[0,0,1,4],[0,1,0,0],[-1,0,0,0],[0,0,0,1]]}}]}}"#
    );
    let test = format!(
        r#"{{"camera_angle_x": {angle}, "frames": [
        {{"file_path": "./test/r_0", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,5],[0,0,0,1]]}}]}}"#
    );
    std::fs::write(dir.path().join("transforms_train.json"), train).unwrap();
    std::fs::write(dir.path().join("transforms_test.json"), test).unwrap();
    std::fs::write(dir.path().join("transforms_val.json"), "not read").unwrap();
    dir
}

#[test]
fn blender_synthetic_fixture_loads_with_focal_poses_and_split() {
    let dir = blender_fixture();
    let scene = load_scene(dir.path(), &LoadOptions::default()).unwrap();
    let names: Vec<&str> = scene.views.iter().map(|v| v.name.as_str()).collect();
    assert_eq!(names, ["test/r_0.png", "train/r_0.png", "train/r_1.png"]);
    let k = &scene.views[1].camera.intrinsics;
    assert!((k.fx - 4.0).abs() < 1e-12 && (k.fy - 4.0).abs() < 1e-12, "{k:?}");
    assert_eq!((k.cx, k.cy), (4.0, 3.0));
    // A known point projects where the OpenGL → COLMAP conversion says.
    let p = DVec3::new(0.5, 0.25, 0.0);
    let (px, depth) = scene.views[1].camera.project(p).unwrap();
    assert!((px.x - 4.5).abs() < 1e-12 && (px.y - 2.75).abs() < 1e-12 && (depth - 4.0).abs() < 1e-12, "{px} {depth}");
    let (px, depth) = scene.views[2].camera.project(p).unwrap();
    assert!((px.x - 4.0).abs() < 1e-12 && (px.y - (3.0 - 1.0 / 3.5)).abs() < 1e-12 && (depth - 3.5).abs() < 1e-12, "{px}");
    assert!((scene.views[2].camera.center() - DVec3::new(4.0, 0.0, 0.0)).length() < 1e-12);
    // The test file's frames are the held-out views of --eval; without --eval all train.
    assert_eq!(scene.held_out.as_deref(), Some(&["test/r_0.png".to_string()][..]));
    assert_eq!(scene.split(true), (vec![1, 2], vec![0]));
    assert_eq!(scene.split(false), (vec![0, 1, 2], vec![]));
    assert!((scene.views[0].image.get(0, 0, 1) - 100.0 / 255.0).abs() < 1e-7);
}

#[test]
fn nerfstudio_fixture_with_per_frame_intrinsics_distortion_points_and_applied_transform() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("images")).unwrap();
    for name in ["a.jpg", "b.jpg", "c.jpg"] {
        image::RgbImage::from_pixel(16, 12, image::Rgb([9, 9, 9])).save(dir.path().join("images").join(name)).unwrap();
    }
    // Points at the world positions the frames see after undoing applied_transform (a swap
    // of y and z with a sign, nerfstudio's COLMAP default) and a shift.
    let applied = [[1.0, 0.0, 0.0, 0.5], [0.0, 0.0, 1.0, 0.0], [0.0, -1.0, 0.0, 0.0]];
    let cloud = gs_core::TriangleMesh { positions: vec![[1.5, 2.0, -3.0]], triangles: vec![], colors: Some(vec![[1, 2, 3]]) };
    gs_io::write_mesh_ply(&dir.path().join("sparse_pc.ply"), &cloud).unwrap();
    let json = serde_json::json!({
        "camera_model": "OPENCV", "fl_x": 20.0, "fl_y": 21.0, "cx": 8.0, "cy": 6.0, "w": 16, "h": 12,
        "k1": 0.01, "k2": -0.002, "p1": 0.0, "p2": 0.0, "aabb_scale": 16,
        "applied_transform": applied, "ply_file_path": "sparse_pc.ply",
        "frames": [
            {"file_path": "images/a.jpg", "transform_matrix": [[1,0,0,0.5],[0,0,1,0],[0,-1,0,2],[0,0,0,1]]},
            {"file_path": "images/b.jpg", "fl_x": 30.0, "fl_y": 30.0, "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,3],[0,0,0,1]]},
            {"file_path": "images/c.jpg", "k3": 0.001, "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]}
        ],
        "test_filenames": ["images/b.jpg"]
    });
    std::fs::write(dir.path().join("transforms.json"), json.to_string()).unwrap();
    let sm = read_scene_model(dir.path(), None).unwrap();
    let cams: Vec<_> = sm.model.cameras.values().collect();
    assert_eq!(cams.len(), 3, "a shared camera, one with its own focal, one with k3");
    assert_eq!(cams[0].model.name(), "OPENCV");
    assert_eq!(cams[0].params, [20.0, 21.0, 8.0, 6.0, 0.01, -0.002, 0.0, 0.0]);
    assert_eq!(cams[1].params[..2], [30.0, 30.0]);
    assert_eq!(cams[2].model.name(), "FULL_OPENCV");
    assert_eq!(sm.held_out, Some(vec!["b.jpg".to_string()]));
    // applied_transform undone: frame a's centre (0.5, 0, 2) maps back to (0, −2, 0); its
    // COLMAP-world rotation is the identity in OpenGL terms.
    let a = sm.model.images.values().find(|i| i.name == "a.jpg").unwrap();
    let r = a.rotation().unwrap();
    let centre = -(r.transpose() * DVec3::from_array(a.tvec));
    assert!((centre - DVec3::new(0.0, -2.0, 0.0)).length() < 1e-12, "{centre}");
    let d = r - gs_core::glam::DMat3::from_diagonal(DVec3::new(1.0, -1.0, -1.0));
    assert!(d.to_cols_array().iter().all(|x| x.abs() < 1e-12), "{r}");
    let p = sm.model.points3d.values().next().unwrap();
    assert_eq!(p.rgb, [1, 2, 3]);
    assert!((DVec3::from_array(p.xyz) - DVec3::new(1.0, 3.0, 2.0)).length() < 1e-6, "{:?}", p.xyz);
    // The whole scene loads (undistorted to PINHOLE) and --eval holds out b.jpg.
    let scene = load_scene(dir.path(), &LoadOptions::default()).unwrap();
    assert_eq!(scene.split(true).1, vec![1]);
    assert_eq!(scene.points.len(), 1);
}
