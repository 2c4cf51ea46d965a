//! `vagsl convert --to transforms`, `info` and `train` on a transforms.json scene, and the
//! conversion back to COLMAP.

use std::path::{Path, PathBuf};
use std::process::Command;

fn shared(rel: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data")).join(rel)
}

fn vagsl(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_vagsl")).args(args).output().expect("run vagsl");
    (out.status.success(), String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned())
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// synth-bunny converted to transforms.json in `dir/bunny` (photos linked, not copied).
fn convert_bunny(dir: &Path) -> PathBuf {
    let out = dir.join("bunny");
    let (ok, stdout, err) = vagsl(&["convert", s(&shared("synth-bunny")), "--to", "transforms", "-o", s(&out)]);
    assert!(ok, "{err}");
    assert!(stdout.contains("40 frames") && stdout.contains("7000 points"), "{stdout}");
    assert!(out.join("transforms.json").is_file() && out.join("sparse_pc.ply").is_file());
    assert!(out.join("images").symlink_metadata().unwrap().file_type().is_symlink(), "photos are linked");
    out
}

#[test]
fn converted_bunny_reports_the_same_scene_and_converts_back() {
    let dir = tempfile::tempdir().unwrap();
    let scene = convert_bunny(dir.path());
    let info = |p: &Path| -> serde_json::Value {
        let (ok, stdout, err) = vagsl(&["info", s(p), "--json"]);
        assert!(ok, "{err}");
        serde_json::from_str(&stdout).unwrap()
    };
    let (a, b) = (info(&shared("synth-bunny")), info(&scene));
    assert!(b["format"].as_str().unwrap().starts_with("transforms.json"), "{}", b["format"]);
    for key in ["images", "image_files_found", "points", "resolutions", "camera_models", "neighbours"] {
        assert_eq!(a[key], b[key], "{key}");
    }
    let (ea, eb) = (a["scene_extent"].as_f64().unwrap(), b["scene_extent"].as_f64().unwrap());
    assert!((ea - eb).abs() < 1e-9, "{ea} vs {eb}");
    // Back to a COLMAP text model inside the transforms scene (its default place).
    let (ok, stdout, err) = vagsl(&["convert", s(&scene), "--to", "text"]);
    assert!(ok, "{err}");
    assert!(stdout.contains("1 cameras, 40 images, 7000 points"), "{stdout}");
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
    let scene = convert_bunny(dir.path());
    // Without points (no ply_file_path) training starts from random points.
    let json_path = scene.join("transforms.json");
    let mut json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json_path).unwrap()).unwrap();
    json.as_object_mut().unwrap().remove("ply_file_path");
    std::fs::write(&json_path, json.to_string()).unwrap();
    let out = dir.path().join("run");
    let (ok, _, err) = vagsl(&[
        "train", s(&scene), "-o", s(&out), "--iterations", "30", "-r", "4", "--eval", "--backend", "cpu", "--quiet",
    ]);
    assert!(ok, "{err}");
    assert!(out.join("point_cloud.ply").is_file());
    let config: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("config.json")).unwrap()).unwrap();
    assert_eq!(config["test_views"].as_array().unwrap().len(), 5, "every 8th of 40 views held out");
    let (ok, stdout, err) = vagsl(&["eval-images", s(&out), "--no-lpips"]);
    assert!(ok, "{err}");
    assert!(stdout.contains("PSNR"), "{stdout}");
}
