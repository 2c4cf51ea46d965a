//! What `vagsl train` tells the user about bad scene folders (issue #21): a truncated photo, a
//! duplicate image name, an outlier camera (a warning naming it; training goes on) and
//! coincident cameras with nothing else to set the scale (refused).

use std::path::Path;
use std::process::Command;

fn vagsl(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_vagsl")).args(args).env("RAYON_NUM_THREADS", "2").output().expect("run vagsl");
    (out.status.success(), String::from_utf8_lossy(&out.stderr).into_owned())
}

/// A scene folder: one 64×48 PINHOLE camera, identity rotations, the image centres at `-t`
/// for each `(name, t)`, one textured PNG per distinct name, and `points` as `points3D.txt`.
fn scene(images: &[(String, [f64; 3])], points: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("sparse/0");
    std::fs::create_dir_all(&model).unwrap();
    std::fs::create_dir_all(dir.path().join("images")).unwrap();
    std::fs::write(model.join("cameras.txt"), "1 PINHOLE 64 48 60 60 32 24\n").unwrap();
    let mut txt = String::new();
    for (k, (name, [x, y, z])) in images.iter().enumerate() {
        txt += &format!("{} 1 0 0 0 {x:e} {y:e} {z:e} 1 {name}\n\n", k + 1);
        let img = image::RgbImage::from_fn(64, 48, |u, v| image::Rgb([(u * 4) as u8, (v * 5) as u8, (k * 20) as u8]));
        img.save(dir.path().join("images").join(name)).unwrap();
    }
    std::fs::write(model.join("images.txt"), txt).unwrap();
    std::fs::write(model.join("points3D.txt"), points).unwrap();
    dir
}

const POINTS: &str = "1 0 0 1 200 100 50 0.5\n2 0.5 0 1 200 100 50 0.5\n3 0 0.5 1.5 200 100 50 0.5\n";

/// Twelve cameras on a circle of radius 3 around the points.
fn ring() -> Vec<(String, [f64; 3])> {
    (0..12)
        .map(|k| {
            let a = k as f64 / 12.0 * std::f64::consts::TAU;
            (format!("{k:02}.png"), [3.0 * a.cos(), 3.0 * a.sin(), 2.0])
        })
        .collect()
}

fn train(scene: &Path) -> (bool, String) {
    let out = scene.join("run");
    vagsl(&["train", scene.to_str().unwrap(), "-o", out.to_str().unwrap(), "--iterations", "2", "--backend", "cpu", "--quiet"])
}

#[test]
fn an_outlier_camera_is_named_and_training_goes_on() {
    let mut images = ring();
    images.push(("stray.png".into(), [0.0, 0.0, 1e6]));
    let d = scene(&images, POINTS);
    let (ok, err) = train(d.path());
    assert!(ok, "{err}");
    assert!(err.contains("warning: ") && err.contains("left out of the scene extent") && err.contains(": stray.png"), "{err}");
    // The same ring without the stray camera trains without a warning.
    let d = scene(&ring(), POINTS);
    let (ok, err) = train(d.path());
    assert!(ok && !err.contains("warning"), "{err}");
}

#[test]
fn coincident_cameras_without_spread_points_are_refused() {
    let images: Vec<(String, [f64; 3])> = (0..5).map(|k| (format!("{k}.png"), [0.0, 0.0, 2.0])).collect();
    let d = scene(&images, "1 0 0 1 200 100 50 0.5\n");
    let (ok, err) = train(d.path());
    assert!(!ok && err.contains("camera centres coincide") && err.contains("nothing sets the scene's scale"), "{err}");
}

#[test]
fn duplicate_names_and_truncated_photos_are_refused() {
    let mut images = ring();
    images[5].0 = "00.png".into();
    let d = scene(&images, POINTS);
    let (ok, err) = train(d.path());
    assert!(!ok && err.contains("images 1 and 6 have the same name '00.png'"), "{err}");

    let d = scene(&ring(), POINTS);
    let p = d.path().join("images/03.png");
    let bytes = std::fs::read(&p).unwrap();
    std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
    let (ok, err) = train(d.path());
    assert!(!ok && err.contains("images/03.png: truncated PNG"), "{err}");
}

/// Two photos with one stem (`00.png`, `00.jpg`) train, but `render` refuses to write both as
/// `00.png` (it once said "rendered 13 views" and wrote 12 files).
#[test]
fn render_refuses_two_views_that_would_share_a_file() {
    let mut images = ring();
    images.push(("00.jpg".into(), [3.0, 0.5, 2.0]));
    let d = scene(&images, POINTS);
    let (ok, err) = train(d.path());
    assert!(ok, "{err}");
    let run = d.path().join("run");
    let (ok, err) = vagsl(&["render", run.to_str().unwrap(), "--split", "all", "--backend", "cpu"]);
    assert!(!ok && err.contains("views '00.jpg' and '00.png' would both be written as 00.png"), "{err}");
    assert!(!run.join("renders/all").exists(), "the output folder was made before refusing");
    // Distinct stems render one file each.
    let d = scene(&ring(), POINTS);
    assert!(train(d.path()).0);
    let run = d.path().join("run");
    let (ok, err) = vagsl(&["render", run.to_str().unwrap(), "--split", "all", "--backend", "cpu"]);
    assert!(ok, "{err}");
    assert_eq!(std::fs::read_dir(run.join("renders/all")).unwrap().filter(|e| e.as_ref().unwrap().path().extension().is_some_and(|x| x == "exr")).count(), 12);
}

#[test]
fn info_takes_the_extent_of_coincident_cameras_from_the_sparse_points_as_training_does() {
    let images: Vec<(String, [f64; 3])> = (0..5).map(|k| (format!("{k}.png"), [0.0, 0.0, 2.0])).collect();
    let d = scene(&images, POINTS);
    let info = Command::new(env!("CARGO_BIN_EXE_vagsl")).args(["info", d.path().to_str().unwrap()]).output().unwrap();
    let text = String::from_utf8_lossy(&info.stdout).into_owned();
    let line = text.lines().find(|l| l.starts_with("scene extent r")).unwrap_or_else(|| panic!("{text}"));
    assert!(line.contains("(from the sparse points: the camera centres coincide)"), "{line}");
    let r: f64 = line.split_whitespace().nth(3).unwrap().parse().unwrap();
    let (ok, err) = train(d.path());
    assert!(ok, "{err}");
    let trained: f64 = err.split("scene extent r = ").nth(1).and_then(|t| t.split_whitespace().next()).unwrap().parse().unwrap();
    assert!((trained - r).abs() < 1e-4, "info says r = {r}, training r = {trained}");
}
