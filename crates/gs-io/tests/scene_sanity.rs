//! Models that read fine but would silently train or render the wrong thing are refused at
//! load, naming the image (issue #21): duplicate image names (D8) and absurd poses (D5).

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
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("sparse/0");
    std::fs::create_dir_all(&model).unwrap();
    std::fs::create_dir_all(dir.path().join("images")).unwrap();
    std::fs::write(model.join("cameras.txt"), CAMERAS).unwrap();
    std::fs::write(model.join("images.txt"), images_txt(images)).unwrap();
    std::fs::write(model.join("points3D.txt"), POINTS).unwrap();
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
