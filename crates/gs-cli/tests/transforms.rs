//! `vagsl convert --to transforms`, `info` and `train` on a transforms.json scene, and the
//! conversion back to COLMAP.

use std::path::{Path, PathBuf};
use std::process::Command;


fn vagsl(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_vagsl")).args(args).output().expect("run vagsl");
    (out.status.success(), String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned())
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The small built-in scene as a COLMAP scene folder (12 views of 120 × 90, 1,500 points),
/// cached under target/.
fn builtin_dir() -> PathBuf {
    gs_testdata::builtin::scene_dir(Path::new(env!("CARGO_TARGET_TMPDIR")), &gs_testdata::builtin::small())
}

/// The built-in scene folder converted to transforms.json in `dir/scene` (photos linked, not
/// copied).
fn convert_scene(dir: &Path) -> PathBuf {
    let out = dir.join("scene");
    let (ok, stdout, err) = vagsl(&["convert", s(&builtin_dir()), "--to", "transforms", "-o", s(&out)]);
    assert!(ok, "{err}");
    assert!(stdout.contains("12 frames") && stdout.contains("1500 points"), "{stdout}");
    assert!(out.join("transforms.json").is_file() && out.join("sparse_pc.ply").is_file());
    assert!(out.join("images").symlink_metadata().unwrap().file_type().is_symlink(), "photos are linked");
    out
}

#[test]
fn a_converted_scene_reports_the_same_scene_and_converts_back() {
    let dir = tempfile::tempdir().unwrap();
    let scene = convert_scene(dir.path());
    let info = |p: &Path| -> serde_json::Value {
        let (ok, stdout, err) = vagsl(&["info", s(p), "--json"]);
        assert!(ok, "{err}");
        serde_json::from_str(&stdout).unwrap()
    };
    let (a, b) = (info(&builtin_dir()), info(&scene));
    assert!(b["format"].as_str().unwrap().starts_with("transforms.json"), "{}", b["format"]);
    for key in ["images", "image_files_found", "points", "resolutions", "camera_models", "neighbours"] {
        assert_eq!(a[key], b[key], "{key}");
    }
    let (ea, eb) = (a["scene_extent"].as_f64().unwrap(), b["scene_extent"].as_f64().unwrap());
    assert!((ea - eb).abs() < 1e-9, "{ea} vs {eb}");
    // Back to a COLMAP text model inside the transforms scene (its default place).
    let (ok, stdout, err) = vagsl(&["convert", s(&scene), "--to", "text"]);
    assert!(ok, "{err}");
    assert!(stdout.contains("1 cameras, 12 images, 1500 points"), "{stdout}");
    assert!(scene.join("sparse/0/images.txt").is_file());
    // The folder now holds both layouts: COLMAP wins.
    assert_eq!(info(&scene)["format"], "text");
    // Converting a transforms scene to transforms is refused in words.
    let blender = dir.path().join("t");
    std::fs::create_dir(&blender).unwrap();
    std::fs::write(blender.join("transforms.json"), "{\"frames\": []}").unwrap();
    let (ok, _, err) = vagsl(&["convert", s(&blender), "--to", "transforms"]);
    assert!(!ok && err.contains("already in the transforms.json layout"), "{err}");
}

#[test]
fn info_and_convert_name_the_problem_of_a_bad_transforms_file() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("transforms.json"), "{\"frames\": [\n  {\"file_path\": 3}\n]}").unwrap();
    for args in [vec!["info", s(dir.path())], vec!["convert", s(dir.path()), "--to", "bin"]] {
        let (ok, _, err) = vagsl(&args);
        assert!(!ok);
        assert!(err.contains("transforms.json") && err.contains("frames[0]") && err.contains("'file_path' must be a string"), "{err}");
    }
    let empty = tempfile::tempdir().unwrap();
    let (ok, _, err) = vagsl(&["train", s(empty.path()), "-o", s(&dir.path().join("o")), "--iterations", "2", "--quiet"]);
    assert!(!ok && err.contains("no COLMAP model and no transforms.json"), "{err}");
}

#[test]
fn trains_end_to_end_on_a_converted_transforms_scene() {
    let dir = tempfile::tempdir().unwrap();
    let scene = convert_scene(dir.path());
    // Without points (no ply_file_path) training starts from random points.
    let json_path = scene.join("transforms.json");
    let mut json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json_path).unwrap()).unwrap();
    json.as_object_mut().unwrap().remove("ply_file_path");
    std::fs::write(&json_path, json.to_string()).unwrap();
    let out = dir.path().join("run");
    let (ok, _, err) = vagsl(&[
        "train", s(&scene), "-o", s(&out), "--iterations", "30", "-r", "2", "--eval", "--backend", "cpu", "--quiet",
    ]);
    assert!(ok, "{err}");
    assert!(out.join("point_cloud.ply").is_file());
    let config: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("config.json")).unwrap()).unwrap();
    assert_eq!(config["test_views"].as_array().unwrap().len(), 2, "every 8th of 12 views held out");
    let (ok, stdout, err) = vagsl(&["eval-images", s(&out), "--no-lpips"]);
    assert!(ok, "{err}");
    assert!(stdout.contains("PSNR"), "{stdout}");
}
