//! Models that read fine but would silently train or render the wrong thing are refused at
//! load, naming the image, or reported (issue #21): duplicate image names (D8), absurd poses
//! (D5), outlier and coincident cameras in the scene extent (D6).

use gs_core::ExtentBasis;
use gs_io::colmap::{read_binary, read_model, read_text, write_binary};
use gs_io::scene::{LoadOptions, load_scene, model_summary};
use std::path::Path;

const CAMERAS: &str = "# cameras\n1 PINHOLE 8 6 8 8 4 3\n";
const POINTS: &str = "# points\n1 0.1 0.2 1 10 20 30 0.5\n";

/// `images.txt` with one line pair per `(name, tx, ty, tz)`, identity rotations.
fn images_txt(images: &[(&str, f64, f64, f64)]) -> String {
    let mut s = String::from("# images\n");
    for (k, (name, tx, ty, tz)) in images.iter().enumerate() {
        s += &format!("{} 1 0 0 0 {tx:e} {ty:e} {tz:e} 1 {name}\n\n", k + 1);
    }
    s
}

/// A scene folder with a text model in `sparse/0` and an 8×6 PNG per distinct image name.
fn scene(images: &[(&str, f64, f64, f64)]) -> tempfile::TempDir {
    scene_with_points(images, POINTS)
}

fn scene_with_points(images: &[(&str, f64, f64, f64)], points: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("sparse/0");
    std::fs::create_dir_all(&model).unwrap();
    std::fs::create_dir_all(dir.path().join("images")).unwrap();
    std::fs::write(model.join("cameras.txt"), CAMERAS).unwrap();
    std::fs::write(model.join("images.txt"), images_txt(images)).unwrap();
    std::fs::write(model.join("points3D.txt"), points).unwrap();
    for (name, ..) in images {
        image::RgbImage::from_pixel(8, 6, image::Rgb([90, 120, 30])).save(dir.path().join("images").join(name)).unwrap();
    }
    dir
}

fn load_err(dir: &Path) -> String {
    load_scene(dir, &LoadOptions::default()).map(|_| ()).unwrap_err().to_string()
}

#[test]
fn duplicate_image_names_are_refused() {
    let d = scene(&[("a.png", 0.0, 0.0, 2.0), ("b.png", 0.1, 0.0, 2.0), ("a.png", 0.2, 0.0, 2.0)]);
    let e = load_err(d.path());
    assert!(
        e.contains("images.txt") && e.contains("images 1 and 3 have the same name 'a.png'"),
        "{e}"
    );
    // The model readers and `info` refuse it too, in both formats.
    let model_dir = d.path().join("sparse/0");
    assert!(read_text(&model_dir).is_err());
    assert!(model_summary(d.path()).map(|_| ()).unwrap_err().to_string().contains("same name 'a.png'"));
    // The same duplicate in a binary model (a valid model, edited, written as binary).
    let ok = scene(&[("a.png", 0.0, 0.0, 2.0), ("b.png", 0.1, 0.0, 2.0)]);
    let mut model = read_model(&ok.path().join("sparse/0")).unwrap();
    model.images.get_mut(&2).unwrap().name = "a.png".into();
    let bin = tempfile::tempdir().unwrap();
    write_binary(&model, bin.path()).unwrap();
    let e = read_binary(bin.path()).map(|_| ()).unwrap_err().to_string();
    assert!(e.contains("images.bin") && e.contains("images 1 and 2 have the same name 'a.png'"), "{e}");
    // Distinct names load.
    assert_eq!(load_scene(ok.path(), &LoadOptions::default()).unwrap().views.len(), 2);
    // Selecting the same image twice is refused as well.
    let opts = LoadOptions { only_images: Some(vec!["b.png".into(), "b.png".into()]), ..Default::default() };
    let e = load_scene(ok.path(), &opts).map(|_| ()).unwrap_err().to_string();
    assert!(e.contains("image 'b.png' is selected twice"), "{e}");
}

#[test]
fn an_absurd_camera_translation_is_refused() {
    let d = scene(&[("a.png", 0.0, 0.0, 2.0), ("b.png", 0.1, 1e300, 2.0)]);
    let e = load_err(d.path());
    assert!(
        e.contains("images.txt:4: image 2 (b.png): camera centre lies about 1e300 from the origin, beyond the limit"),
        "{e}"
    );
    // A far but sane translation loads.
    let d = scene(&[("a.png", 0.0, 0.0, 2.0), ("b.png", 0.1, 6.4e6, 2.0)]);
    assert_eq!(load_scene(d.path(), &LoadOptions::default()).unwrap().views.len(), 2);
    // An absurd sparse point too.
    let d = scene_with_points(&[("a.png", 0.0, 0.0, 2.0)], "1 0.1 -1e200 1 10 20 30 0.5\n");
    let e = load_err(d.path());
    assert!(e.contains("points3D.txt") && e.contains("point 1: position lies about 1e200"), "{e}");
}

/// Twelve cameras on a circle of radius 3 (identity rotations, so the centre is -t).
fn ring() -> Vec<(String, f64, f64, f64)> {
    (0..12)
        .map(|k| {
            let a = k as f64 / 12.0 * std::f64::consts::TAU;
            (format!("{k:02}.png"), 3.0 * a.cos(), 3.0 * a.sin(), 2.0)
        })
        .collect()
}

fn refs(images: &[(String, f64, f64, f64)]) -> Vec<(&str, f64, f64, f64)> {
    images.iter().map(|(n, x, y, z)| (n.as_str(), *x, *y, *z)).collect()
}

#[test]
fn an_outlier_camera_is_left_out_of_the_extent_and_named() {
    let normal = load_scene(scene(&refs(&ring())).path(), &LoadOptions::default()).unwrap();
    let mut images = ring();
    images.push(("stray.png".into(), 0.0, 0.0, 1e6));
    let s = load_scene(scene(&refs(&images)).path(), &LoadOptions::default()).unwrap();
    let report = s.extent_report();
    assert_eq!(report.outliers, [12]);
    assert_eq!(s.views[12].name, "stray.png");
    // Exactly the extent of the ring alone (3.3), not ~1e6.
    assert_eq!(s.extent().to_bits(), normal.extent().to_bits());
    assert!((s.extent() - 3.3).abs() < 1e-9);
    let w = s.check_extent().unwrap();
    assert_eq!(w.len(), 1);
    assert!(w[0].contains("left out of the scene extent") && w[0].ends_with(": stray.png"), "{w:?}");
    assert!(normal.check_extent().unwrap().is_empty());
}

#[test]
fn coincident_cameras_use_the_points_or_are_refused() {
    let images: Vec<(String, f64, f64, f64)> = (0..6).map(|k| (format!("{k}.png"), 0.5, 0.5, 2.0)).collect();
    // One sparse point: no spread anywhere, nothing sets the scale.
    let s = load_scene(scene(&refs(&images)).path(), &LoadOptions::default()).unwrap();
    assert_eq!(s.extent_report().basis, ExtentBasis::Unscaled);
    let e = s.check_extent().unwrap_err().to_string();
    assert!(e.contains("camera centres coincide") && e.contains("nothing sets the scene's scale"), "{e}");
    // Spread-out points set it.
    let points = "1 -1 0 0 1 1 1 0.5\n2 1 0 0 1 1 1 0.5\n3 0 -1 0 1 1 1 0.5\n4 0 1 0 1 1 1 0.5\n5 0 0 0 1 1 1 0.5\n";
    let s = load_scene(scene_with_points(&refs(&images), points).path(), &LoadOptions::default()).unwrap();
    let report = s.extent_report();
    assert_eq!((report.basis, report.radius), (ExtentBasis::SparsePoints, 1.1));
    assert!(s.check_extent().unwrap()[0].contains("comes from the sparse points"));
}
