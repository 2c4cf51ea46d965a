//! Undistortion: the new PINHOLE cameras equal real COLMAP's, pixels round-trip between the
//! distorted and the undistorted image, and undistorting an analytically distorted image
//! recovers the pinhole rendering.

use gs_core::Image;
use gs_io::colmap::{CameraModel, ColmapCamera};
use gs_io::undistort::{UndistortMap, UndistortOptions, undistort_camera};

fn cam(model: CameraModel, width: u32, height: u32, params: &[f64]) -> ColmapCamera {
    ColmapCamera { id: 1, model, width, height, params: params.to_vec() }
}

fn fox() -> ColmapCamera {
    cam(
        CameraModel::OpenCv,
        540,
        960,
        &[687.76, 687.245, 277.279, 482.634, 0.0578421, -0.0805099, -0.000980296, 0.00015575],
    )
}

fn opencv() -> ColmapCamera {
    cam(CameraModel::OpenCv, 320, 240, &[310.0, 305.0, 162.0, 117.0, -0.12, 0.02, 0.0015, -0.001])
}

fn full_opencv() -> ColmapCamera {
    cam(
        CameraModel::FullOpenCv,
        320,
        240,
        &[310.0, 305.0, 158.0, 121.0, -0.15, 0.03, 0.001, -0.0007, 0.002, 0.05, -0.01, 0.001],
    )
}

fn radial() -> ColmapCamera {
    cam(CameraModel::Radial, 320, 240, &[300.0, 161.0, 118.5, 0.08, -0.02])
}

fn simple_radial() -> ColmapCamera {
    cam(CameraModel::SimpleRadial, 200, 150, &[180.0, 100.0, 75.0, -0.2])
}

/// Reference values: `pycolmap.undistort_camera(pycolmap.UndistortCameraOptions(), camera)`
/// with pycolmap 4.2.1 (COLMAP's defaults: blank_pixels 0, min_scale 0.2, max_scale 2).
#[test]
fn undistorted_cameras_equal_colmap() {
    let cases: [(ColmapCamera, (u32, u32), [f64; 4]); 5] = [
        (fox(), (533, 948), [687.76, 687.245, 273.6846425925926, 476.601075]),
        (simple_radial(), (214, 154), [180.0, 180.0, 107.0, 77.0]),
        (radial(), (309, 232), [300.0, 300.0, 155.465625, 114.55]),
        (full_opencv(), (336, 247), [310.0, 305.0, 165.9, 124.52916666666667]),
        (opencv(), (329, 243), [310.0, 305.0, 166.55625, 118.4625]),
    ];
    for (c, size, params) in cases {
        let u = undistort_camera(&c, &UndistortOptions::default()).unwrap();
        assert_eq!(u.model, CameraModel::Pinhole);
        assert_eq!((u.width, u.height), size, "{}", c.model);
        for (a, b) in u.params.iter().zip(params) {
            assert!((a - b).abs() < 1e-9, "{}: {:?} vs {params:?}", c.model, u.params);
        }
    }
}

/// Undistorted pixel → ray → distorted pixel → (Newton) → undistorted pixel, and the reverse,
/// over a grid that includes the image corners.
#[test]
fn pixel_round_trip_below_a_thousandth_of_a_pixel() {
    for c in [opencv(), full_opencv(), radial(), simple_radial(), fox()] {
        let u = undistort_camera(&c, &UndistortOptions::default()).unwrap();
        let [fx, fy, cx, cy] = u.pinhole();
        let mut worst: f64 = 0.0;
        for (w, h, forward) in [(u.width, u.height, true), (c.width, c.height, false)] {
            for i in 0..=20 {
                for j in 0..=20 {
                    let p = [w as f64 * i as f64 / 20.0, h as f64 * j as f64 / 20.0];
                    let back = if forward {
                        let ray = [(p[0] - cx) / fx, (p[1] - cy) / fy];
                        let d = c.img_from_cam(ray);
                        let r = c.cam_from_img(d).unwrap();
                        [fx * r[0] + cx, fy * r[1] + cy]
                    } else {
                        let r = c.cam_from_img(p).unwrap();
                        let q = [fx * r[0] + cx, fy * r[1] + cy];
                        c.img_from_cam([(q[0] - cx) / fx, (q[1] - cy) / fy])
                    };
                    worst = worst.max((back[0] - p[0]).hypot(back[1] - p[1]));
                }
            }
        }
        assert!(worst < 1e-3, "{}: worst round trip {worst} px", c.model);
    }
}

/// A smooth pattern on the plane z = 1 (normalised camera coordinates), period ≈ 25 px.
fn pattern(x: f64, y: f64) -> f32 {
    (0.5 + 0.25 * (x * 25.0).sin() * (y * 21.0).cos() + 0.2 * ((x + 2.0 * y) * 9.0).sin()) as f32
}

#[test]
fn undistorting_a_distorted_rendering_recovers_the_pinhole_rendering() {
    for c in [opencv(), full_opencv(), radial()] {
        // The distorted image: each distorted pixel centre sees the ray cam_from_img(pixel).
        let (w, h) = (c.width as usize, c.height as usize);
        let mut distorted = Image::new(w, h, 1).unwrap();
        for y in 0..h {
            for x in 0..w {
                let r = c.cam_from_img([x as f64 + 0.5, y as f64 + 0.5]).unwrap();
                distorted.set(x, y, 0, pattern(r[0], r[1]));
            }
        }
        let u = undistort_camera(&c, &UndistortOptions::default()).unwrap();
        let out = UndistortMap::new(&c, &u).apply(&distorted).unwrap();
        assert_eq!((out.width(), out.height()), (u.width as usize, u.height as usize));
        let [fx, fy, cx, cy] = u.pinhole();
        let (mut err, mut naive_err, mut max_err) = (0.0f64, 0.0f64, 0.0f64);
        for y in 0..out.height() {
            for x in 0..out.width() {
                let truth = pattern((x as f64 + 0.5 - cx) / fx, (y as f64 + 0.5 - cy) / fy);
                let e = (out.get(x, y, 0) - truth).abs() as f64;
                err += e;
                max_err = max_err.max(e);
                // Control: the distorted image read as if it were already pinhole.
                let (dx, dy) = ((x as f32 + 0.5) * w as f32 / out.width() as f32, (y as f32 + 0.5) * h as f32 / out.height() as f32);
                naive_err += (distorted.sample_bilinear(dx, dy, 0) - truth).abs() as f64;
            }
        }
        let n = (out.width() * out.height()) as f64;
        let (mean, naive) = (err / n, naive_err / n);
        eprintln!("{}: mean {mean:.5}, max {max_err:.5}, control {naive:.5}", c.model);
        assert!(mean < 0.005 && max_err < 0.03, "{}: mean {mean}, max {max_err}", c.model);
        assert!(naive > 10.0 * mean, "{}: control {naive} vs {mean}", c.model);
    }
}

#[test]
fn straight_lines_stay_straight() {
    // Points of a world line seen by the distorted camera: their distorted pixels are on a
    // curve; after undistortion (cam_from_img then the PINHOLE camera) they are collinear.
    let c = fox();
    let u = undistort_camera(&c, &UndistortOptions::default()).unwrap();
    let [fx, fy, cx, cy] = u.pinhole();
    // Along the top of the image, where the fox lens distorts most.
    let (a, b) = ([-0.38, -0.67, 1.0], [0.37 * 1.3, -0.66 * 1.3, 1.3]);
    let pts: Vec<[f64; 2]> = (0..=30)
        .map(|k| {
            let t = k as f64 / 30.0;
            let p: Vec<f64> = (0..3).map(|i| a[i] + t * (b[i] - a[i])).collect();
            let distorted = c.img_from_cam([p[0] / p[2], p[1] / p[2]]);
            let r = c.cam_from_img(distorted).unwrap();
            [fx * r[0] + cx, fy * r[1] + cy]
        })
        .collect();
    let distance = |p: [f64; 2], q0: [f64; 2], q1: [f64; 2]| {
        let (dx, dy) = (q1[0] - q0[0], q1[1] - q0[1]);
        ((p[0] - q0[0]) * dy - (p[1] - q0[1]) * dx).abs() / dx.hypot(dy)
    };
    let worst = pts.iter().map(|&p| distance(p, pts[0], pts[30])).fold(0.0, f64::max);
    assert!(worst < 1e-6, "undistorted line deviates by {worst} px");
    // Control: the distorted pixels themselves are visibly curved.
    let dpts: Vec<[f64; 2]> = pts
        .iter()
        .map(|p| c.img_from_cam([(p[0] - cx) / fx, (p[1] - cy) / fy]))
        .collect();
    let curved = dpts.iter().map(|&p| distance(p, dpts[0], dpts[30])).fold(0.0, f64::max);
    eprintln!("line: undistorted {worst:e} px, distorted {curved} px");
    assert!(curved > 1.0, "distorted line deviates by only {curved} px");
}
