//! `.npy` reading on the built-in scene's ground truth (written by gs-testdata), round trips,
//! rejected layouts, and the shared VGG16 `.npz`.

use gs_core::Image;
use gs_io::npy::parse_npy;
use gs_io::{IoError, read_npy, write_npy};
use std::path::{Path, PathBuf};

mod common;
use common::npy;

/// A ground-truth file of the small built-in scene folder (120 × 90).
fn gt(name: &str) -> PathBuf {
    gs_testdata::builtin::scene_dir(Path::new(env!("CARGO_TARGET_TMPDIR")), &gs_testdata::builtin::small()).join("gt").join(name)
}

#[test]
fn ground_truth_depth_is_positive_where_hit() {
    let d = read_npy(&gt("depth_0000.npy")).unwrap();
    assert_eq!((d.width(), d.height(), d.channels()), (120, 90, 1));
    assert!(d.data().iter().all(|v| v.is_finite() && *v >= 0.0));
    let hits = d.data().iter().filter(|v| **v > 0.0).count();
    assert!(hits > d.data().len() / 2, "only {hits} pixels hit");
}

#[test]
fn ground_truth_normals_are_unit() {
    let n = read_npy(&gt("normal_0000.npy")).unwrap();
    assert_eq!((n.width(), n.height(), n.channels()), (120, 90, 3));
    let mut unit = 0;
    for px in n.data().chunks_exact(3) {
        let len = (px[0] * px[0] + px[1] * px[1] + px[2] * px[2]).sqrt();
        if len == 0.0 {
            continue; // miss
        }
        assert!((len - 1.0).abs() < 1e-3, "normal {px:?} has length {len}");
        unit += 1;
    }
    assert!(unit > 1000);
    // Where depth is 0 (miss), the normal is 0 too.
    let d = read_npy(&gt("depth_0000.npy")).unwrap();
    for (dv, px) in d.data().iter().zip(n.data().chunks_exact(3)) {
        assert_eq!(*dv == 0.0, px == [0.0, 0.0, 0.0]);
    }
}

#[test]
fn write_read_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    for c in [1, 3, 4] {
        let img = Image::from_vec(5, 3, c, (0..15 * c).map(|i| i as f32 - 0.25).collect()).unwrap();
        let p = dir.path().join(format!("a{c}.npy"));
        write_npy(&p, &img).unwrap();
        assert_eq!(read_npy(&p).unwrap(), img);
    }
}


#[test]
fn rejected_layouts_are_clear() {
    let p = Path::new("g/x.npy");
    assert!(parse_npy(&npy("<f4", "False", "(2, 3)", 24), p).is_ok());
    assert!(parse_npy(&npy("<f2", "False", "(2, 3, 2)", 24), p).is_ok());
    let cases: [(Vec<u8>, &str); 8] = [
        (npy(">f4", "False", "(2, 3)", 24), "dtype '>f4'"),
        (npy("<f8", "False", "(2, 3)", 48), "dtype '<f8'"),
        (npy("<i4", "False", "(2, 3)", 24), "dtype '<i4'"),
        (npy("<f4", "True", "(2, 3)", 24), "Fortran"),
        (npy("<f4", "False", "(6,)", 24), "only 2-D"),
        (npy("<f4", "False", "(1, 2, 3, 1)", 24), "only 2-D"),
        (npy("<f4", "False", "(2, 3)", 20), "shape [2, 3] of <f4 declares 6 values of at least 4 bytes each (24 bytes), more than the 20 bytes left in the file can hold (truncated"),
        (b"PK\x03\x04 not npy".to_vec(), "magic"),
    ];
    for (bytes, expect) in cases {
        let e = parse_npy(&bytes, p).unwrap_err();
        let s = e.to_string();
        assert!(s.contains("g/x.npy") && s.contains(expect), "{s:?} lacks {expect:?}");
        if expect.starts_with("dtype") || expect == "Fortran" || expect == "only 2-D" {
            assert!(matches!(e, IoError::Unsupported { .. }), "{e:?}");
        }
    }
    // Absurd shape: no allocation, clear error.
    let e = parse_npy(&npy("<f4", "False", "(100000000000, 100000000000)", 8), p).unwrap_err().to_string();
    assert!(e.contains("g/x.npy: shape [100000000000, 100000000000] declares more than 2^64 values; the cap for a NumPy file is 2 GiB"), "{e}");
}

fn weights(name: &str) -> PathBuf {
    gs_testdata::root().join("weights").join(name)
}

#[test]
fn npz_reads_the_shared_vgg16_weights() {
    if !gs_testdata::needs!("weights/vgg16_imagenet_conv1_1-conv3_3.npz") {
        return;
    }
    let arrays = gs_io::read_npz(&weights("vgg16_imagenet_conv1_1-conv3_3.npz")).unwrap();
    let names: Vec<&str> = arrays.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names.len(), 16);
    assert_eq!(&names[..4], &["conv1_1_weight", "conv1_1_bias", "conv1_2_weight", "conv1_2_bias"]);
    let get = |n: &str| &arrays.iter().find(|(k, _)| k == n).unwrap().1;
    assert_eq!(get("conv3_3_weight").shape, vec![256, 256, 3, 3]);
    assert_eq!(get("conv1_1_bias").shape, vec![64]);
    assert_eq!(get("conv1_1_weight").data.len(), 64 * 3 * 9);
    let mean = &get("input_mean").data;
    assert!((mean[0] - 0.485).abs() < 1e-7 && (mean[2] - 0.406).abs() < 1e-7);
}

#[test]
fn npz_truncated_or_not_a_zip_is_a_clear_error() {
    if !gs_testdata::needs!("weights/vgg16_imagenet_conv1_1-conv3_3.npz") {
        return;
    }
    let bytes = std::fs::read(weights("vgg16_imagenet_conv1_1-conv3_3.npz")).unwrap();
    let p = Path::new("w.npz");
    let msg = gs_io::npy::parse_npz(&bytes[..100_000], p).unwrap_err().to_string();
    assert!(msg.contains("w.npz") && msg.contains("truncated"), "{msg}");
    let msg = gs_io::npy::parse_npz(b"hello", p).unwrap_err().to_string();
    assert!(msg.contains("not an .npz"), "{msg}");
    // A compressed member (method 8) is refused, naming it.
    let mut compressed = bytes.clone();
    compressed[8] = 8;
    let msg = gs_io::npy::parse_npz(&compressed, p).unwrap_err().to_string();
    assert!(msg.contains("conv1_1_weight.npy") && msg.contains("compressed"), "{msg}");
    let missing = gs_io::read_npz(Path::new("/nonexistent/w.npz")).unwrap_err().to_string();
    assert!(missing.contains("/nonexistent/w.npz"), "{missing}");
}
