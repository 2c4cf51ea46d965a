//! Truncated or corrupt photos and masks are refused with an error naming the file, never
//! decoded with missing rows filled in (issue #21, D4).

use gs_io::scene::{LoadOptions, decode_mask, decode_rgb, load_scene};
use std::path::{Path, PathBuf};

fn shared(rel: &str) -> PathBuf {
    gs_testdata::root().join("data").join(rel)
}

/// A file of a two-view built-in scene folder (PNG photos and masks of 240 × 180; large enough
/// that a mask cut to 5 % still holds the PNG header).
fn builtin(rel: &str) -> PathBuf {
    let opts = gs_synth::BuiltinOptions { width: 240, height: 180, views: 2, supersample: 1, points: 100, ..Default::default() };
    gs_testdata::builtin::scene_dir(Path::new(env!("CARGO_TARGET_TMPDIR")), &opts).join(rel)
}

/// `src` copied to `dir/name`, cut to `fraction` of its bytes.
fn cut_copy(src: &Path, dir: &Path, name: &str, fraction: f64) -> PathBuf {
    let bytes = std::fs::read(src).unwrap();
    let keep = (bytes.len() as f64 * fraction) as usize;
    let p = dir.join(name);
    std::fs::write(&p, &bytes[..keep]).unwrap();
    p
}

#[test]
fn truncated_jpeg_photos_are_refused() {
    if !gs_testdata::needs!("data/fox") {
        return;
    }
    let src = shared("fox/images/0001.jpg");
    let dir = tempfile::tempdir().unwrap();
    // The lenient decoder alone accepts a cut JPEG: this is what the check guards against.
    let half = cut_copy(&src, dir.path(), "half.jpg", 0.5);
    assert!(image::open(&half).is_ok(), "the image crate now refuses cut JPEGs itself");
    for (k, fraction) in [0.05, 0.3, 0.5, 0.9, 0.999].into_iter().enumerate() {
        let p = cut_copy(&src, dir.path(), &format!("cut{k}.jpg"), fraction);
        let e = decode_rgb(&p).map(|_| ()).unwrap_err().to_string();
        assert!(e.contains(&format!("cut{k}.jpg")) && e.contains("truncated JPEG"), "{fraction}: {e}");
    }
    let full = decode_rgb(&src).unwrap();
    assert_eq!((full.width(), full.height()), (540, 960));
}

#[test]
fn truncated_png_photos_and_masks_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    for (src, decode) in [
        (builtin("images/0000.png"), decode_rgb as fn(&Path) -> gs_io::Result<gs_core::Image>),
        (builtin("masks/0000.png"), decode_mask),
    ] {
        for (k, fraction) in [0.05, 0.3, 0.5, 0.99].into_iter().enumerate() {
            let p = cut_copy(&src, dir.path(), &format!("cut{k}.png"), fraction);
            let e = decode(&p).map(|_| ()).unwrap_err().to_string();
            assert!(e.contains(&format!("cut{k}.png")) && e.contains("truncated PNG"), "{fraction}: {e}");
        }
        assert_eq!(decode(&src).unwrap().width(), 240);
    }
}

#[test]
fn corrupt_png_data_is_refused() {
    let src = builtin("images/0000.png");
    let mut bytes = std::fs::read(&src).unwrap();
    // Flip bytes inside the compressed data: the chunk checksum no longer matches.
    let mid = bytes.len() / 2;
    for b in &mut bytes[mid..mid + 16] {
        *b ^= 0x5A;
    }
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("flipped.png");
    std::fs::write(&p, &bytes).unwrap();
    let e = decode_rgb(&p).map(|_| ()).unwrap_err().to_string();
    assert!(e.contains("flipped.png") && e.contains("cannot decode image"), "{e}");
}

/// A scene whose photo was cut short fails to load, naming the photo.
#[test]
fn scene_with_a_truncated_photo_fails_to_load() {
    if !gs_testdata::needs!("data/fox") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path();
    std::fs::create_dir_all(scene.join("sparse")).unwrap();
    std::fs::create_dir_all(scene.join("images")).unwrap();
    for f in ["cameras.txt", "images.txt", "points3D.txt"] {
        std::fs::copy(shared("fox/sparse/0").join(f), scene.join("sparse").join(f)).unwrap();
    }
    let names = ["0001.jpg", "0002.jpg"];
    for n in names {
        std::fs::copy(shared("fox/images").join(n), scene.join("images").join(n)).unwrap();
    }
    let opts = LoadOptions { only_images: Some(names.iter().map(|s| s.to_string()).collect()), ..Default::default() };
    assert_eq!(load_scene(scene, &opts).unwrap().views.len(), 2);
    cut_copy(&shared("fox/images/0002.jpg"), &scene.join("images"), "0002.jpg", 0.3);
    let e = load_scene(scene, &opts).map(|_| ()).unwrap_err().to_string();
    assert!(e.contains("images/0002.jpg") && e.contains("truncated JPEG"), "{e}");
}
