//! Scene loading: images decoded as value/255 (or /65535), undistorted to PINHOLE, downscaled,
//! masks, views sorted by name, sparse points, and clear errors for missing files.

use gs_io::colmap::{CameraModel, ColmapCamera, ColmapImage, ColmapModel, ColmapPoint3D, write_text};
use gs_io::scene::{LoadOptions, MaskPolicy, Resolution, load_scene, model_summary};
use gs_io::IoError;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

fn shared(rel: &str) -> PathBuf {
    gs_testdata::root().join("data").join(rel)
}

fn only(names: &[&str]) -> LoadOptions {
    LoadOptions { only_images: Some(names.iter().map(|s| s.to_string()).collect()), ..Default::default() }
}

#[test]
fn synth_bunny_views_images_masks_points() {
    if !gs_testdata::needs!("data/synth-bunny") {
        return;
    }
    let scene = load_scene(&shared("synth-bunny"), &only(&["0003.png", "0001.png"])).unwrap();
    // Sorted by name, PINHOLE 480x360 unchanged (no distortion, below 1600 px).
    let names: Vec<&str> = scene.views.iter().map(|v| v.name.as_str()).collect();
    assert_eq!(names, ["0001.png", "0003.png"]);
    let v = &scene.views[0];
    assert_eq!((v.camera.width, v.camera.height), (480, 360));
    assert_eq!(v.camera.intrinsics, gs_core::Intrinsics::new(515.0, 515.0, 240.0, 180.0));
    // Pixels are exactly value/255 of the file.
    let raw = image::open(shared("synth-bunny/images/0001.png")).unwrap().to_rgb8();
    for (x, y) in [(0u32, 0u32), (240, 180), (479, 359), (17, 301)] {
        for c in 0..3 {
            assert_eq!(v.image.get(x as usize, y as usize, c), raw.get_pixel(x, y)[c] as f32 / 255.0);
        }
    }
    // Masks: present, binary, and mostly background.
    let m = v.mask.as_ref().unwrap();
    assert_eq!((m.width(), m.height(), m.channels()), (480, 360, 1));
    assert!(m.data().iter().all(|&x| x == 0.0 || x == 1.0));
    let fg = m.data().iter().filter(|&&x| x == 1.0).count();
    assert!(fg > 1000 && fg < 480 * 360 / 2, "{fg} foreground pixels");
    // Points with colours / 255, in id order.
    assert_eq!(scene.points.len(), 7000);
    let p = scene.points[0];
    assert_eq!(p.color, [190.0 / 255.0, 200.0 / 255.0, 199.0 / 255.0]);
    assert_eq!(p.position.x, -0.266287779);
    // The camera pose is the model's: the centre is far from the origin and the
    // projection of a sparse point seen by this view lies inside the image.
    let (px, depth) = v.camera.project(scene.points[1].position).unwrap();
    assert!(depth > 0.0 && v.camera.contains(px));
}

#[test]
fn downscaling_factors_and_target_width() {
    if !gs_testdata::needs!("data/synth-bunny") {
        return;
    }
    let opts = LoadOptions { resolution: Resolution::Factor(2), masks: MaskPolicy::Ignore, ..only(&["0000.png"]) };
    let s = load_scene(&shared("synth-bunny"), &opts).unwrap();
    let v = &s.views[0];
    assert_eq!((v.image.width(), v.image.height()), (240, 180));
    assert_eq!(v.camera.intrinsics, gs_core::Intrinsics::new(257.5, 257.5, 120.0, 90.0));
    assert!(v.mask.is_none());
    // Area resize: each output pixel is the mean of a 2x2 block.
    let full = load_scene(&shared("synth-bunny"), &LoadOptions { masks: MaskPolicy::Ignore, ..only(&["0000.png"]) }).unwrap();
    let f = &full.views[0].image;
    let mean = (f.get(20, 30, 1) + f.get(21, 30, 1) + f.get(20, 31, 1) + f.get(21, 31, 1)) / 4.0;
    assert!((v.image.get(10, 15, 1) - mean).abs() < 1e-6);
    let opts = LoadOptions { resolution: Resolution::Width(120), ..only(&["0000.png"]) };
    let s = load_scene(&shared("synth-bunny"), &opts).unwrap();
    assert_eq!((s.views[0].camera.width, s.views[0].camera.height), (120, 90));
    assert_eq!(s.views[0].mask.as_ref().unwrap().width(), 120);
}

/// A target width beyond the photos is refused, naming the photo, before anything is upscaled.
#[test]
fn a_width_beyond_the_photos_is_refused() {
    if !gs_testdata::needs!("data/synth-bunny") {
        return;
    }
    let opts = LoadOptions { resolution: Resolution::Width(3000), ..only(&["0000.png"]) };
    let e = load_scene(&shared("synth-bunny"), &opts).unwrap_err().to_string();
    assert!(e.contains("0000.png") && e.contains("3000 px is wider than the photo (480 × 360 px"), "{e}");
    let opts = LoadOptions { resolution: Resolution::Width(480), ..only(&["0000.png"]) };
    assert_eq!(load_scene(&shared("synth-bunny"), &opts).unwrap().views[0].camera.width, 480);
}

/// Fox: OPENCV → PINHOLE 533x948, fx 687.76, fy 687.245, cx 273.6846, cy 476.6011 (the values
/// `pycolmap.undistort_camera` gives, see colmap_undistort.rs).
#[test]
fn fox_is_undistorted_to_pinhole() {
    if !gs_testdata::needs!("data/fox") {
        return;
    }
    let s = load_scene(&shared("fox"), &only(&["0001.jpg", "0002.jpg"])).unwrap();
    for v in &s.views {
        assert_eq!((v.camera.width, v.camera.height), (533, 948));
        assert_eq!((v.image.width(), v.image.height()), (533, 948));
        let k = v.camera.intrinsics;
        assert_eq!((k.fx, k.fy), (687.76, 687.245));
        assert!((k.cx - 273.6846425925926).abs() < 1e-9 && (k.cy - 476.601075).abs() < 1e-9);
        assert!(v.mask.is_none());
        assert!(v.image.is_finite() && v.image.data().iter().all(|&x| (0.0..=1.0).contains(&x)));
    }
    // Every sparse point observed by a view reprojects near its undistorted observation:
    // compare with the model's observations undistorted by the camera model.
    let model = gs_io::read_model(&shared("fox/sparse/0")).unwrap();
    let img = model.images.values().find(|i| i.name == "0002.jpg").unwrap();
    let view = s.views.iter().find(|v| v.name == "0002.jpg").unwrap();
    let cam = &model.cameras[&img.camera_id];
    let k = view.camera.intrinsics;
    let mut errs = Vec::new();
    for obs in img.points2d.iter().filter(|p| p.point3d_id.is_some()) {
        let p = model.points3d[&obs.point3d_id.unwrap()].xyz;
        let (px, _) = view.camera.project(gs_core::glam::DVec3::from_array(p)).unwrap();
        let n = cam.cam_from_img(obs.xy).unwrap();
        let undistorted = [k.fx * n[0] + k.cx, k.fy * n[1] + k.cy];
        errs.push((px.x - undistorted[0]).hypot(px.y - undistorted[1]));
    }
    errs.sort_by(f64::total_cmp);
    let median = errs[errs.len() / 2];
    assert!(median < 1.0, "median reprojection error {median} px");
}

/// A synthetic scene folder: one camera, images written by `make_image`, optional masks.
fn synthetic_scene(camera: ColmapCamera, names: &[&str], make_image: impl Fn(&Path, u32, u32)) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (camera.width, camera.height);
    let mut images = BTreeMap::new();
    for (k, name) in names.iter().enumerate() {
        let id = k as u32 + 1;
        images.insert(id, ColmapImage {
            id,
            qvec: [1.0, 0.0, 0.0, 0.0],
            tvec: [0.1 * k as f64, 0.0, 2.0],
            camera_id: camera.id,
            name: name.to_string(),
            points2d: vec![],
        });
    }
    let mut points3d = BTreeMap::new();
    points3d.insert(1, ColmapPoint3D { id: 1, xyz: [0.0, 0.0, 1.0], rgb: [255, 0, 51], error: -1.0, track: vec![] });
    let model = ColmapModel { cameras: BTreeMap::from([(camera.id, camera)]), images, points3d };
    write_text(&model, &dir.path().join("sparse/0")).unwrap();
    std::fs::create_dir_all(dir.path().join("images")).unwrap();
    for name in names {
        make_image(&dir.path().join("images").join(name), w, h);
    }
    dir
}

fn pinhole(w: u32, h: u32) -> ColmapCamera {
    ColmapCamera { id: 3, model: CameraModel::SimplePinhole, width: w, height: h, params: vec![w as f64, w as f64 / 2.0, h as f64 / 2.0] }
}

#[test]
fn sixteen_bit_grey_and_rgba_images() {
    let d = synthetic_scene(pinhole(4, 3), &["a.png", "b.png"], |p, w, h| {
        if p.ends_with("a.png") {
            let img = image::ImageBuffer::from_fn(w, h, |x, y| image::Luma([(x * 20000 + y * 1000) as u16]));
            img.save(p).unwrap();
        } else {
            let img = image::ImageBuffer::from_fn(w, h, |x, y| image::Rgba([x as u8 * 60, y as u8 * 100, 7, 0]));
            img.save(p).unwrap();
        }
    });
    let s = load_scene(d.path(), &LoadOptions::default()).unwrap();
    assert_eq!(s.views.len(), 2);
    let a = &s.views[0].image;
    assert_eq!(a.channels(), 3);
    for c in 0..3 {
        assert_eq!(a.get(3, 2, c), (3.0 * 20000.0 + 2000.0) / 65535.0);
    }
    let b = &s.views[1].image;
    assert_eq!([b.get(2, 1, 0), b.get(2, 1, 1), b.get(2, 1, 2)], [120.0 / 255.0, 100.0 / 255.0, 7.0 / 255.0]);
    // SIMPLE_PINHOLE → PINHOLE fx = fy.
    assert_eq!(s.views[0].camera.intrinsics, gs_core::Intrinsics::new(4.0, 4.0, 2.0, 1.5));
    assert_eq!(s.points[0].color, [1.0, 0.0, 0.2]);
}

#[test]
fn wide_images_default_to_1600_pixels() {
    let cam = ColmapCamera {
        id: 1,
        model: CameraModel::SimpleRadial,
        width: 2000,
        height: 40,
        params: vec![1500.0, 1000.0, 20.0, -0.01],
    };
    let d = synthetic_scene(cam.clone(), &["w.png"], |p, w, h| {
        image::ImageBuffer::from_fn(w, h, |x, _| image::Rgb([(x % 256) as u8, 0, 0])).save(p).unwrap();
    });
    let s = load_scene(d.path(), &LoadOptions::default()).unwrap();
    let und = gs_io::undistort::undistort_camera(&cam, &Default::default()).unwrap();
    let v = &s.views[0];
    assert_eq!(v.camera.width, 1600);
    assert_eq!(v.camera.height, (und.height as f64 * 1600.0 / und.width as f64).round() as u32);
    assert!((v.camera.intrinsics.fx - 1500.0 * 1600.0 / und.width as f64).abs() < 1e-9);
    // -r 1 keeps the full undistorted size.
    let s = load_scene(d.path(), &LoadOptions { resolution: Resolution::Factor(1), ..Default::default() }).unwrap();
    assert_eq!((s.views[0].camera.width, s.views[0].camera.height), (und.width, und.height));
}

#[test]
fn half_size_image_folder_rescales_the_camera() {
    let d = synthetic_scene(pinhole(8, 6), &["a.png"], |p, _, _| {
        image::ImageBuffer::from_fn(4, 3, |_, _| image::Rgb([10u8, 20, 30])).save(p).unwrap();
    });
    let s = load_scene(d.path(), &LoadOptions::default()).unwrap();
    assert_eq!(s.views[0].camera.intrinsics, gs_core::Intrinsics::new(4.0, 4.0, 2.0, 1.5));
    // A non-uniform mismatch is an error naming the image.
    let d = synthetic_scene(pinhole(8, 6), &["a.png"], |p, _, _| {
        image::ImageBuffer::from_fn(8, 3, |_, _| image::Rgb([10u8, 20, 30])).save(p).unwrap();
    });
    let e = load_scene(d.path(), &LoadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("a.png") && e.to_string().contains("not a uniform rescale"), "{e}");
}

#[test]
fn missing_image_and_mask_files() {
    let d = synthetic_scene(pinhole(4, 3), &["a.png", "b.png"], |p, w, h| {
        if p.ends_with("a.png") {
            image::ImageBuffer::from_fn(w, h, |_, _| image::Rgb([1u8, 2, 3])).save(p).unwrap();
        }
    });
    let e = load_scene(d.path(), &LoadOptions::default()).unwrap_err();
    assert!(matches!(e, IoError::Invalid { .. }), "{e}");
    assert!(e.to_string().contains("images/b.png: missing image file"), "{e}");
    // An unknown name in only_images.
    let e = load_scene(d.path(), &only(&["c.png"])).unwrap_err();
    assert!(e.to_string().contains("'c.png' is not in the model"), "{e}");
    // Required masks.
    let opts = LoadOptions { masks: MaskPolicy::Require, ..only(&["a.png"]) };
    let e = load_scene(d.path(), &opts).unwrap_err();
    assert!(e.to_string().contains("masks/a.png: missing mask file"), "{e}");
    // A corrupt image file.
    std::fs::write(d.path().join("images/b.png"), b"not a png").unwrap();
    let e = load_scene(d.path(), &LoadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("images/b.png"), "{e}");
    // No model at all.
    let empty = tempfile::tempdir().unwrap();
    assert!(load_scene(empty.path(), &LoadOptions::default()).unwrap_err().to_string().contains("no COLMAP model"));
}

#[test]
fn model_summary_of_the_datasets() {
    if !gs_testdata::needs!("data/dtu-scan24", "data/fox") {
        return;
    }
    let s = model_summary(&shared("dtu-scan24")).unwrap();
    assert_eq!((s.cameras.len(), s.num_images, s.num_points, s.num_observations), (49, 49, 6885, 37099));
    assert!((s.mean_reprojection_error.unwrap() - 0.4994026631792447).abs() < 1e-9);
    let text = s.to_string();
    assert!(text.contains("49 × PINHOLE 800x600 (no distortion)"), "{text}");
    let s = model_summary(&shared("fox/sparse/0")).unwrap();
    assert_eq!(s.cameras[0].model, "OPENCV");
    assert!(!s.cameras[0].undistorted);
    assert!((s.mean_track_length - 6.672355788955445).abs() < 1e-9);
}

/// Whole scenes (release only: decoding 50 JPEGs is slow in debug).
#[test]
#[cfg_attr(debug_assertions, ignore)]
fn full_scenes_load() {
    if !gs_testdata::needs!("data/dtu-scan24", "data/fox", "data/synth-bunny") {
        return;
    }
    for (name, n, size) in [("dtu-scan24", 49, (800, 600)), ("fox", 50, (533, 948)), ("synth-bunny", 40, (480, 360))] {
        let t = std::time::Instant::now();
        let s = load_scene(&shared(name), &LoadOptions::default()).unwrap();
        eprintln!("{name}: {} views loaded in {:.2} s", s.views.len(), t.elapsed().as_secs_f64());
        assert_eq!(s.views.len(), n);
        assert!(s.views.iter().all(|v| (v.camera.width, v.camera.height) == size));
        assert!(s.views.windows(2).all(|w| w[0].name < w[1].name));
        assert_eq!(s.views.iter().all(|v| v.mask.is_some()), name != "fox");
        // A normal capture: no outlier camera, the extent comes from the cameras.
        let report = s.extent_report();
        assert_eq!((report.basis, report.outliers.len()), (gs_core::ExtentBasis::Cameras, 0), "{name}");
        assert!(s.check_extent().unwrap().is_empty(), "{name}");
    }
}
