//! Bad transforms.json input gives a clear error naming the file, the frame and the problem,
//! never a panic.

use gs_io::transforms::parse_transforms;
use gs_io::{read_scene_model, IoError};
use std::path::Path;

const IDENTITY_AT_4: &str = "[[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]";

/// The error message of parsing `json` as `bad.json`.
fn parse_error(json: &str) -> String {
    let e: IoError = parse_transforms(json.as_bytes(), Path::new("bad.json")).unwrap_err();
    let m = e.to_string();
    assert!(m.starts_with("bad.json: "), "{m}");
    assert!(!m.contains("Some(") && !m.contains("Error {"), "Debug output in {m}");
    m
}

fn one_frame(global: &str, frame: &str) -> String {
    format!(r#"{{{global} "frames": [{{"file_path": "./r_0", {frame}}}]}}"#)
}

#[test]
fn malformed_json_names_line_and_column() {
    let m = parse_error("{\n  \"fl_x\": 500,\n  \"frames\": [\n    {\"file_path\": \"a.png\",,}\n]}");
    assert!(m.contains("malformed JSON") && m.contains("line 4") && m.contains("column"), "{m}");
    let m = parse_error("[1, 2]");
    assert!(m.contains("JSON object"), "{m}");
    assert!(parse_error("").contains("malformed JSON"));
}

#[test]
fn missing_fields_are_named() {
    assert!(parse_error(r#"{"fl_x": 500}"#).contains("missing 'frames'"));
    let m = parse_error(r#"{"frames": [{"transform_matrix": []}]}"#);
    assert!(m.contains("frames[0]") && m.contains("missing 'file_path'"), "{m}");
    let m = parse_error(&one_frame(r#""fl_x": 5,"#, r#""fl_y": 5"#));
    assert!(m.contains("frames[0] ('./r_0')") && m.contains("missing 'transform_matrix'"), "{m}");
    let m = parse_error(&one_frame("", r#""fl_x": "500", "transform_matrix": []"#));
    assert!(m.contains("'fl_x' must be a finite number, got \"500\""), "{m}");
}

#[test]
fn non_finite_and_non_rigid_matrices_are_refused() {
    let m = parse_error(&one_frame("", r#""transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,"nan"],[0,0,0,1]]"#));
    assert!(m.contains("frames[0] ('./r_0')") && m.contains("row 2 column 3 must be a finite number"), "{m}");
    // JSON has no NaN; a number beyond f64 is malformed JSON.
    assert!(parse_error(&one_frame("", r#""transform_matrix": [[1e999,0,0,0],[0,1,0,0],[0,0,1,0]]"#)).contains("malformed JSON"));
    let m = parse_error(&one_frame("", r#""transform_matrix": [[2,0,0,0],[0,2,0,0],[0,0,2,4],[0,0,0,1]]"#));
    assert!(m.contains("frames[0] ('./r_0')") && m.contains("not a rigid transform") && m.contains("orthonormal"), "{m}");
    let m = parse_error(&one_frame("", r#""transform_matrix": [[1,0.1,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]"#));
    assert!(m.contains("not a rigid transform"), "{m}");
    let m = parse_error(&one_frame("", r#""transform_matrix": [[-1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]"#));
    assert!(m.contains("reflection"), "{m}");
    let m = parse_error(&one_frame("", r#""transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,1,1]]"#));
    assert!(m.contains("last row must be 0 0 0 1"), "{m}");
    let m = parse_error(&one_frame("", r#""transform_matrix": [[1,0,0],[0,1,0],[0,0,1]]"#));
    assert!(m.contains("row 0 must hold 4 numbers"), "{m}");
    let m = parse_error(&format!(r#"{{"applied_transform": [[1,0,0,0],[0,1,0,0],[0,0,3,0]], "frames": [{{"file_path": "a", "transform_matrix": {IDENTITY_AT_4}}}]}}"#));
    assert!(m.contains("'applied_transform' is not a rigid transform"), "{m}");
}

#[test]
fn bad_intrinsics_are_refused() {
    let t = format!(r#""transform_matrix": {IDENTITY_AT_4}"#);
    let m = parse_error(&one_frame(r#""fl_x": 0,"#, &t));
    assert!(m.contains("focal length 'fl_x' must be positive, got 0"), "{m}");
    let m = parse_error(&one_frame("", &format!(r#""fl_y": -3, {t}"#)));
    assert!(m.contains("frames[0] ('./r_0')") && m.contains("'fl_y' must be positive, got -3"), "{m}");
    let m = parse_error(&one_frame(r#""camera_angle_x": 0,"#, &t));
    assert!(m.contains("'camera_angle_x' must lie between 0 and π"), "{m}");
    let m = parse_error(&one_frame(r#""w": 10.5,"#, &t));
    assert!(m.contains("'w' must be a whole number"), "{m}");
    let m = parse_error(&one_frame(r#""camera_model": "OPENCV_FISHEYE","#, &t));
    assert!(m.contains("unsupported camera_model OPENCV_FISHEYE"), "{m}");
    let m = parse_error(&one_frame(r#""camera_model": "KANNALA","#, &t));
    assert!(m.contains("unknown camera_model 'KANNALA'"), "{m}");
    assert!(parse_error(&one_frame(r#""aabb_scale": -1,"#, &t)).contains("aabb_scale"));
}

/// A folder with `transforms.json` = `json` and a 4×3 `a.png`.
fn scene_with(json: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    image::RgbImage::new(4, 3).save(dir.path().join("a.png")).unwrap();
    std::fs::write(dir.path().join("transforms.json"), json).unwrap();
    dir
}

fn scene_error(json: &str) -> String {
    let dir = scene_with(json);
    let m = read_scene_model(dir.path(), None).unwrap_err().to_string();
    assert!(m.contains("transforms.json"), "{m}");
    m
}

#[test]
fn scene_level_problems_name_the_frame_and_file() {
    let frame = |path: &str| format!(r#"{{"file_path": "{path}", "transform_matrix": {IDENTITY_AT_4}}}"#);
    let m = scene_error(&format!(r#"{{"fl_x": 5, "frames": [{}, {}]}}"#, frame("a.png"), frame("missing/b")));
    assert!(m.contains("frames[1] ('missing/b')") && m.contains("missing image file") && m.contains("also tried .png"), "{m}");
    let m = scene_error(&format!(r#"{{"frames": [{}]}}"#, frame("./a")));
    assert!(m.contains("frames[0] ('./a')") && m.contains("no focal length"), "{m}");
    let m = scene_error(&format!(r#"{{"fl_x": 5, "k4": 0.1, "frames": [{}]}}"#, frame("a")));
    assert!(m.contains("'k4'") && m.contains("no COLMAP camera model"), "{m}");
    let m = scene_error(&format!(r#"{{"fl_x": 5, "frames": [{}, {}]}}"#, frame("a.png"), frame("./a")));
    assert!(m.contains("frames[1] ('./a')") && m.contains("view name 'a.png' is already taken"), "{m}");
    let m = scene_error(r#"{"fl_x": 5, "frames": []}"#);
    assert!(m.contains("no frames"), "{m}");
    let m = scene_error(&format!(r#"{{"fl_x": 5, "ply_file_path": "pc.ply", "frames": [{}]}}"#, frame("a")));
    assert!(m.contains("'ply_file_path' names") && m.contains("pc.ply"), "{m}");
    let m = scene_error(&format!(r#"{{"fl_x": 5, "test_filenames": ["z.png"], "frames": [{}]}}"#, frame("a")));
    assert!(m.contains("'test_filenames' names 'z.png'"), "{m}");
    // Sizes in the JSON win over the file's (a uniform rescale is then accepted on load).
    let dir = scene_with(&format!(r#"{{"fl_x": 5, "w": 8, "h": 6, "frames": [{}]}}"#, frame("a")));
    let sm = read_scene_model(dir.path(), None).unwrap();
    assert_eq!(sm.model.cameras[&1].width, 8);
}

#[test]
fn a_folder_with_neither_layout_names_both() {
    let dir = tempfile::tempdir().unwrap();
    let m = read_scene_model(dir.path(), None).unwrap_err().to_string();
    assert!(m.contains("no COLMAP model") && m.contains("transforms.json") && m.contains("transforms_train.json"), "{m}");
    let m = read_scene_model(&dir.path().join("nope"), None).unwrap_err().to_string();
    assert!(m.contains("does not exist"), "{m}");
}

#[test]
fn absurd_cameras_are_refused_with_the_number() {
    let frame = format!(r#"{{"file_path": "a.png", "transform_matrix": {IDENTITY_AT_4}}}"#);
    for (lens, says) in [
        (r#""camera_angle_x": 3.14159"#, "focal length fx = 2.654e-6 px gives a field of view of 179.9998° across 4 px, outside 0.01°–170°"),
        (r#""fl_x": 1e-30"#, "focal length fx = 1.000e-30 px gives a field of view of 180°"),
        (r#""fl_x": 1e30"#, "focal length fx = 1.000e30 px gives a field of view of 2.292e-28°"),
        (r#""fl_x": 5, "cx": -1e9"#, "principal point cx = -1.000e9 px lies more than the image's size (4 px) outside the image"),
        (r#""fl_x": 5, "k1": 1e6"#, "its distortion (1.000e6 0 0 0) moves the image corner (0, 0) to 250001 times its distance from the centre"),
    ] {
        let m = scene_error(&format!(r#"{{{lens}, "frames": [{frame}]}}"#));
        assert!(m.contains(says), "{lens}: {m}");
    }
    // A real wide lens and a real barrel distortion pass.
    let ok = scene_with(&format!(r#"{{"camera_angle_x": 2.0, "k1": -0.3, "k2": 0.1, "frames": [{frame}]}}"#));
    read_scene_model(ok.path(), None).unwrap();
}

#[test]
fn a_nan_in_the_json_names_its_key() {
    let m = parse_error("{\n  \"fl_x\": NaN,\n  \"frames\": []\n}");
    assert!(m.contains("'fl_x' at line 2") && m.contains("is NaN: it must be a finite number"), "{m}");
}
