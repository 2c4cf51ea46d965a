//! `.npy` reading on the synth-bunny ground truth, round trips and rejected layouts.

use gs_core::Image;
use gs_io::npy::parse_npy;
use gs_io::{IoError, read_npy, write_npy};
use std::path::{Path, PathBuf};

fn gt(name: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data/synth-bunny/gt")).join(name)
}

#[test]
fn synth_bunny_depth_is_positive_where_hit() {
    let d = read_npy(&gt("depth_0000.npy")).unwrap();
    assert_eq!((d.width(), d.height(), d.channels()), (480, 360, 1));
    assert!(d.data().iter().all(|v| v.is_finite() && *v >= 0.0));
    let hits = d.data().iter().filter(|v| **v > 0.0).count();
    assert!(hits > d.data().len() / 2, "only {hits} pixels hit");
}

#[test]
fn synth_bunny_normals_are_unit() {
    let n = read_npy(&gt("normal_0000.npy")).unwrap();
    assert_eq!((n.width(), n.height(), n.channels()), (480, 360, 3));
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

fn npy(descr: &str, fortran: &str, shape: &str, data_len: usize) -> Vec<u8> {
    let mut h = format!("{{'descr': '{descr}', 'fortran_order': {fortran}, 'shape': {shape}, }}");
    while (h.len() + 11) % 64 != 0 {
        h.push(' ');
    }
    h.push('\n');
    let mut b = b"\x93NUMPY\x01\x00".to_vec();
    b.extend_from_slice(&(h.len() as u16).to_le_bytes());
    b.extend_from_slice(h.as_bytes());
    b.extend(std::iter::repeat_n(0u8, data_len));
    b
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
        (npy("<f4", "False", "(2, 3)", 20), "truncated"),
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
    assert!(e.contains("overflows") || e.contains("truncated"), "{e}");
}
