//! Bad COLMAP input gives a clear error naming the file, the record and the problem, never a
//! panic and never an allocation driven by a corrupt count.

use gs_io::IoError;
use gs_io::colmap::{
    ColmapModel, parse_cameras_bin, parse_images_bin, parse_points3d_bin, read_binary, read_model, read_text,
    write_binary, write_cameras_bin, write_images_bin, write_points3d_bin, write_text,
};
use std::path::{Path, PathBuf};

const CAMERAS: &str = "# cameras\n1 OPENCV 64 48 60 61 32 24 0.05 -0.01 0.001 0.0005\n2 PINHOLE 64 48 60 60 32 24\n";
const IMAGES: &str = "# images\n\
1 1 0 0 0 0.1 0 2 1 a.png\n10.5 12.25 1 30 20 2 5 5 -1\n\
2 0.9 0.1 0 0 0.2 0 2 2 b.png\n11 13 1 31 21 2\n";
const POINTS: &str = "# points\n1 0.1 0.2 1 10 20 30 0.5 1 0 2 0\n2 0.2 0.2 1 40 50 60 0.25 1 1 2 1\n";

/// A valid text model with the given file contents in a fresh folder.
fn text_model(cameras: &str, images: &str, points: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("cameras.txt"), cameras).unwrap();
    std::fs::write(dir.path().join("images.txt"), images).unwrap();
    std::fs::write(dir.path().join("points3D.txt"), points).unwrap();
    dir
}

fn valid() -> ColmapModel {
    let d = text_model(CAMERAS, IMAGES, POINTS);
    read_text(d.path()).unwrap()
}

fn bytes(write: fn(&ColmapModel, &mut dyn std::io::Write) -> std::io::Result<()>) -> Vec<u8> {
    let mut v = Vec::new();
    write(&valid(), &mut v).unwrap();
    v
}

fn msg(e: &IoError) -> String {
    e.to_string()
}

fn p(name: &str) -> PathBuf {
    PathBuf::from("/model").join(name)
}

#[test]
fn the_valid_model_reads() {
    let m = valid();
    assert_eq!((m.cameras.len(), m.images.len(), m.points3d.len()), (2, 2, 2));
    assert_eq!(m.images[&1].points2d[2].point3d_id, None);
}

#[test]
fn truncated_binary_files() {
    for (name, data) in [
        ("cameras.bin", bytes(write_cameras_bin)),
        ("images.bin", bytes(write_images_bin)),
        ("points3D.bin", bytes(write_points3d_bin)),
    ] {
        // Every strict prefix is an error (never a panic), and names the file.
        for len in 0..data.len() {
            let r = match name {
                "cameras.bin" => parse_cameras_bin(&data[..len], &p(name)).map(|_| ()),
                "images.bin" => parse_images_bin(&data[..len], &p(name)).map(|_| ()),
                _ => parse_points3d_bin(&data[..len], &p(name)).map(|_| ()),
            };
            let e = r.expect_err("a truncated file must not parse");
            assert!(msg(&e).starts_with(&format!("/model/{name}: ")), "{e}");
        }
    }
    // A cut inside the second image names it and the byte offset.
    let data = bytes(write_images_bin);
    let e = parse_images_bin(&data[..data.len() - 10], &p("images.bin")).unwrap_err();
    let m = msg(&e);
    assert!(m.contains("truncated") && m.contains("image 2") && m.contains("byte offset 158"), "{m}");
    // An empty file.
    let e = parse_points3d_bin(&[], &p("points3D.bin")).unwrap_err();
    assert!(msg(&e).contains("truncated at byte offset 0 while reading number of points"), "{e}");
}

#[test]
fn wrong_counts() {
    // A huge count must be rejected before allocating.
    let mut data = bytes(write_points3d_bin);
    data[..8].copy_from_slice(&(u64::MAX / 2).to_le_bytes());
    let e = parse_points3d_bin(&data, &p("points3D.bin")).unwrap_err();
    assert!(msg(&e).contains("wrong count"), "{e}");
    // A huge number of 2D points in the first image.
    let mut data = bytes(write_images_bin);
    let at = 8 + 4 + 56 + 4 + "a.png".len() + 1;
    data[at..at + 8].copy_from_slice(&(1u64 << 60).to_le_bytes());
    let e = parse_images_bin(&data, &p("images.bin")).unwrap_err();
    assert!(msg(&e).contains("image 1") && msg(&e).contains("number of 2D points"), "{e}");
    // A huge track length.
    let mut data = bytes(write_points3d_bin);
    let at = 8 + 8 + 24 + 3 + 8;
    data[at..at + 8].copy_from_slice(&u64::MAX.to_le_bytes());
    let e = parse_points3d_bin(&data, &p("points3D.bin")).unwrap_err();
    assert!(msg(&e).contains("point 1") && msg(&e).contains("track length"), "{e}");
    // A count that is too small leaves trailing bytes.
    let mut data = bytes(write_cameras_bin);
    data[..8].copy_from_slice(&1u64.to_le_bytes());
    let e = parse_cameras_bin(&data, &p("cameras.bin")).unwrap_err();
    assert!(msg(&e).contains("trailing bytes"), "{e}");
    // Text: POINTS2D not a multiple of 3, odd TRACK.
    let d = text_model(CAMERAS, &IMAGES.replace("31 21 2", "31 21"), POINTS);
    let e = read_text(d.path()).unwrap_err();
    assert!(matches!(e, IoError::Parse { line: 5, .. }) && msg(&e).contains("POINTS2D"), "{e}");
    let d = text_model(CAMERAS, IMAGES, &POINTS.replace("0.25 1 1 2 1", "0.25 1 1 2"));
    let e = read_text(d.path()).unwrap_err();
    assert!(matches!(e, IoError::Parse { line: 3, .. }) && msg(&e).contains("TRACK"), "{e}");
    // Wrong number of camera parameters.
    let d = text_model(&CAMERAS.replace(" 0.0005", ""), IMAGES, POINTS);
    let e = read_text(d.path()).unwrap_err();
    assert!(matches!(e, IoError::Parse { line: 2, .. }) && msg(&e).contains("needs 8 parameters, got 7"), "{e}");
}

#[test]
fn unknown_and_unsupported_camera_models() {
    let mut data = bytes(write_cameras_bin);
    data[8 + 4..8 + 8].copy_from_slice(&99i32.to_le_bytes());
    let e = parse_cameras_bin(&data, &p("cameras.bin")).unwrap_err();
    assert!(matches!(e, IoError::Format { .. }) && msg(&e).contains("unknown camera model id 99"), "{e}");
    data[8 + 4..8 + 8].copy_from_slice(&5i32.to_le_bytes());
    let e = parse_cameras_bin(&data, &p("cameras.bin")).unwrap_err();
    assert!(matches!(e, IoError::Unsupported { .. }) && msg(&e).contains("OPENCV_FISHEYE"), "{e}");
    assert!(msg(&e).contains("cameras.bin") && msg(&e).contains("camera 1"), "{e}");

    let d = text_model(&CAMERAS.replace("2 PINHOLE", "2 SIMPLE_RADIAL_FISHEYE"), IMAGES, POINTS);
    let e = read_text(d.path()).unwrap_err();
    assert!(matches!(e, IoError::Unsupported { .. }), "{e}");
    assert!(msg(&e).contains("cameras.txt") && msg(&e).contains("SIMPLE_RADIAL_FISHEYE") && msg(&e).contains("line 3"), "{e}");
    let d = text_model(&CAMERAS.replace("2 PINHOLE", "2 PINHOLY"), IMAGES, POINTS);
    let e = read_text(d.path()).unwrap_err();
    assert!(matches!(e, IoError::Parse { line: 3, .. }) && msg(&e).contains("unknown camera model 'PINHOLY'"), "{e}");
}

#[test]
fn image_referencing_a_missing_camera() {
    let d = text_model(CAMERAS, &IMAGES.replace("0.2 0 2 2 b.png", "0.2 0 2 7 b.png"), POINTS);
    let e = read_text(d.path()).unwrap_err();
    assert!(matches!(e, IoError::Invalid { .. }), "{e}");
    assert!(msg(&e).contains("images.txt") && msg(&e).contains("image 2 (b.png) references missing camera 7"), "{e}");
    // The same through the binary reader.
    let mut m = valid();
    m.images.get_mut(&2).unwrap().camera_id = 7;
    let dir = tempfile::tempdir().unwrap();
    write_binary(&m, dir.path()).unwrap();
    let e = read_binary(dir.path()).unwrap_err();
    assert!(msg(&e).contains("images.bin") && msg(&e).contains("missing camera 7"), "{e}");
}

#[test]
fn inconsistent_tracks() {
    let d = text_model(CAMERAS, IMAGES, &POINTS.replace("0.5 1 0 2 0", "0.5 1 0 3 0"));
    let e = read_text(d.path()).unwrap_err();
    assert!(msg(&e).contains("points3D.txt") && msg(&e).contains("point 1: track references missing image 3"), "{e}");
    let d = text_model(CAMERAS, IMAGES, &POINTS.replace("0.5 1 0 2 0", "0.5 1 0 2 9"));
    let e = read_text(d.path()).unwrap_err();
    assert!(msg(&e).contains("point2D 9 of image 2"), "{e}");
    let d = text_model(CAMERAS, &IMAGES.replace("30 20 2", "30 20 5"), POINTS);
    let e = read_text(d.path()).unwrap_err();
    assert!(msg(&e).contains("references missing 3D point 5"), "{e}");
}

#[test]
fn nan_and_inf_in_points_and_poses() {
    let d = text_model(CAMERAS, IMAGES, &POINTS.replace("1 0.1 0.2 1", "1 nan 0.2 1"));
    let e = read_text(d.path()).unwrap_err();
    assert!(matches!(e, IoError::Parse { line: 2, .. }) && msg(&e).contains("point 1 coordinate 0"), "{e}");
    let d = text_model(CAMERAS, &IMAGES.replace("0.2 0 2 2 b.png", "inf 0 2 2 b.png"), POINTS);
    let e = read_text(d.path()).unwrap_err();
    assert!(matches!(e, IoError::Parse { line: 4, .. }) && msg(&e).contains("image 2 translation"), "{e}");
    // Binary: NaN in the first image's qw, infinity in the first point's z.
    let mut data = bytes(write_images_bin);
    data[12..20].copy_from_slice(&f64::NAN.to_le_bytes());
    let e = parse_images_bin(&data, &p("images.bin")).unwrap_err();
    assert!(msg(&e).contains("image 1") && msg(&e).contains("quaternion component 0") && msg(&e).contains("byte offset 12"), "{e}");
    let mut data = bytes(write_points3d_bin);
    data[32..40].copy_from_slice(&f64::INFINITY.to_le_bytes());
    let e = parse_points3d_bin(&data, &p("points3D.bin")).unwrap_err();
    assert!(msg(&e).contains("point 1") && msg(&e).contains("coordinate 2"), "{e}");
    // A model built in code is checked by validate().
    let mut m = valid();
    m.points3d.get_mut(&2).unwrap().xyz[1] = f64::NAN;
    let dir = tempfile::tempdir().unwrap();
    write_text(&m, dir.path()).unwrap();
    assert!(read_text(dir.path()).is_err());
}

#[test]
fn non_utf8_text() {
    let d = text_model(CAMERAS, IMAGES, POINTS);
    let mut raw = IMAGES.as_bytes().to_vec();
    let at = IMAGES.find("b.png").unwrap();
    raw[at] = 0xff;
    std::fs::write(d.path().join("images.txt"), raw).unwrap();
    let e = read_text(d.path()).unwrap_err();
    assert!(matches!(e, IoError::Parse { line: 4, .. }) && msg(&e).contains("not valid UTF-8"), "{e}");
    // Binary image names must be UTF-8 too.
    let mut data = bytes(write_images_bin);
    data[8 + 4 + 56 + 4] = 0xc3;
    let e = parse_images_bin(&data, &p("images.bin")).unwrap_err();
    assert!(msg(&e).contains("not valid UTF-8"), "{e}");
}

#[test]
fn empty_model() {
    let d = text_model(CAMERAS, "# no images\n", "");
    let e = read_text(d.path()).unwrap_err();
    assert!(matches!(e, IoError::Invalid { .. }) && msg(&e).contains("empty model"), "{e}");
    let dir = tempfile::tempdir().unwrap();
    write_binary(&ColmapModel::default(), dir.path()).unwrap();
    let e = read_binary(dir.path()).unwrap_err();
    assert!(msg(&e).contains("empty model"), "{e}");
    // A folder without a model at all.
    let empty = tempfile::tempdir().unwrap();
    let e = read_model(empty.path()).unwrap_err();
    assert!(msg(&e).contains("no COLMAP model"), "{e}");
    let e = read_model(Path::new("/nonexistent/sparse/0")).unwrap_err();
    assert!(msg(&e).contains("does not exist"), "{e}");
}

#[test]
fn zero_norm_quaternion() {
    let d = text_model(CAMERAS, &IMAGES.replace("1 1 0 0 0 0.1", "1 0 0 0 0 0.1"), POINTS);
    let e = read_text(d.path()).unwrap_err();
    assert!(matches!(e, IoError::Parse { line: 2, .. }) && msg(&e).contains("quaternion has zero norm"), "{e}");
    let mut data = bytes(write_images_bin);
    data[12..20].copy_from_slice(&0f64.to_le_bytes());
    let e = parse_images_bin(&data, &p("images.bin")).unwrap_err();
    assert!(msg(&e).contains("image 1") && msg(&e).contains("zero norm"), "{e}");
}

#[test]
fn bad_camera_values() {
    for (from, to, what) in [
        ("2 PINHOLE 64 48 60 60", "2 PINHOLE 64 48 -60 60", "focal lengths must be positive"),
        ("2 PINHOLE 64 48", "2 PINHOLE 0 48", "is empty"),
        ("2 PINHOLE 64 48 60 60", "2 PINHOLE 64 48 NaN 60", "must be finite"),
        ("2 PINHOLE 64", "2 PINHOLE -64", "cannot parse width"),
    ] {
        let d = text_model(&CAMERAS.replace(from, to), IMAGES, POINTS);
        let e = read_text(d.path()).unwrap_err();
        assert!(matches!(e, IoError::Parse { line: 3, .. }) && msg(&e).contains(what), "{e}");
    }
    let d = text_model(&format!("{CAMERAS}1 PINHOLE 8 8 1 1 1 1\n"), IMAGES, POINTS);
    assert!(msg(&read_text(d.path()).unwrap_err()).contains("duplicate camera id 1"));
}
