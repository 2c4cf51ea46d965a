//! Malformed PLY files give clear errors naming the file and the problem, never a panic.

use gs_core::Gaussians;
use gs_io::ply::gaussian::write_gaussian_ply_to;
use gs_io::{IoError, parse_gaussian_ply, parse_mesh_ply, read_gaussian_ply, read_mesh_ply};
use std::path::Path;

fn good_gaussians(n: usize) -> Vec<u8> {
    let mut g = Gaussians::with_len(n).unwrap();
    for i in 0..n {
        g.means[i] = [i as f32, 1.0, 2.0];
    }
    g.sh_degree = 3;
    let mut buf = Vec::new();
    write_gaussian_ply_to(&mut buf, &g).unwrap();
    buf
}

fn err_gauss(bytes: &[u8]) -> String {
    parse_gaussian_ply(bytes, Path::new("bad/model.ply")).unwrap_err().to_string()
}

fn assert_has(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "error {msg:?} lacks {p:?}");
    }
}

#[test]
fn truncated_gaussian_file() {
    let bytes = good_gaussians(10);
    let e = err_gauss(&bytes[..bytes.len() - 5]);
    assert_has(&e, &["bad/model.ply", "element 'vertex' declares 10 records", "can hold (truncated", "the cap for a PLY file is"]);
    // Cut inside the header.
    let e = err_gauss(&bytes[..40]);
    assert_has(&e, &["bad/model.ply", "end_header"]);
}

#[test]
fn wrong_counts() {
    let bytes = good_gaussians(3);
    let text = String::from_utf8_lossy(&bytes[..200]).into_owned();
    assert!(text.contains("element vertex 3\n"));
    // Count larger than the data.
    let mut more = bytes.clone();
    let at = more.windows(16).position(|w| w == b"element vertex 3").unwrap();
    more[at + 15] = b'4';
    assert_has(&err_gauss(&more), &["bad/model.ply", "element 'vertex' declares 4 records", "can hold"]);
    // Absurd count: rejected before allocating.
    let s = String::from_utf8_lossy(&bytes).replacen("element vertex 3", "element vertex 18446744073709551615", 1);
    let absurd = [s.as_bytes()].concat();
    let e = parse_gaussian_ply(&absurd, Path::new("x.ply")).unwrap_err().to_string();
    assert_has(&e, &["x.ply", "element 'vertex' declares 18446744073709551615 records", "(more than 16 EiB)", "the cap for a PLY file is 11.5 GiB"]);
    // Wrong number of f_rest fields.
    let hdr = "ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float f_rest_0\nend_header\n";
    assert_has(&err_gauss(hdr.as_bytes()), &["bad/model.ply", "1 f_rest", "0, 9, 24 or 45"]);
}

#[test]
fn missing_property_and_bad_types() {
    let hdr = "ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\nproperty float y\nend_header\n";
    assert_has(&err_gauss(hdr.as_bytes()), &["bad/model.ply", "lacks the property 'z'"]);
    let bytes = good_gaussians(1);
    let s = String::from_utf8_lossy(&bytes[..100]).into_owned();
    let changed = s.replacen("property float x", "property int x", 1);
    let bytes2 = [changed.as_bytes(), &bytes[100..]].concat();
    assert_has(&err_gauss(&bytes2), &["'x'", "float or double"]);
    let no_vertex = "ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n";
    assert_has(&err_gauss(no_vertex.as_bytes()), &["no 'vertex' element"]);
}

#[test]
fn wrong_magic_and_unknown_format() {
    let mut bytes = good_gaussians(1);
    bytes[0] = b'P';
    assert_has(&err_gauss(&bytes), &["bad/model.ply", "not a PLY file"]);
    let s = "ply\nformat binary_middle_endian 1.0\nend_header\n";
    assert_has(&err_gauss(s.as_bytes()), &["bad/model.ply:2", "unknown PLY format 'binary_middle_endian'"]);
    let e = parse_mesh_ply(s.as_bytes(), Path::new("m.ply")).unwrap_err();
    assert!(matches!(e, IoError::Parse { line: 2, .. }), "{e:?}");
}

#[test]
fn nan_is_rejected_with_the_vertex_index() {
    let mut bytes = good_gaussians(5);
    let h = gs_io::ply::parse_header(&bytes, Path::new("m")).unwrap();
    // Vertex 3, property opacity (field 54).
    let at = h.data_offset + 3 * 62 * 4 + 54 * 4;
    bytes[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    assert_has(&err_gauss(&bytes), &["bad/model.ply", "vertex 3", "'opacity'", "NaN"]);
    // Infinity in a mean.
    let mut bytes = good_gaussians(5);
    let at = h.data_offset + 62 * 4 + 4;
    bytes[at..at + 4].copy_from_slice(&f32::INFINITY.to_le_bytes());
    assert_has(&err_gauss(&bytes), &["vertex 1", "'y'", "inf"]);
    // ASCII nan in a mesh.
    let m = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n1 nan 0\n";
    let e = parse_mesh_ply(m.as_bytes(), Path::new("n.ply")).unwrap_err().to_string();
    assert_has(&e, &["n.ply", "vertex 1", "y", "NaN"]);
}

#[test]
fn non_utf8_header() {
    let mut bytes = good_gaussians(1);
    bytes[30] = 0xff;
    let e = parse_gaussian_ply(&bytes, Path::new("u.ply")).unwrap_err();
    assert!(matches!(e, IoError::Parse { .. }), "{e:?}");
    assert_has(&e.to_string(), &["u.ply", "not valid UTF-8"]);
}

#[test]
fn mesh_bad_inputs() {
    let base = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    let mut bytes = base.as_bytes().to_vec();
    for v in [0f32, 0., 0., 1., 0., 0., 0., 1., 0.] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    let mut good = bytes.clone();
    good.push(3);
    for i in [0i32, 1, 2] {
        good.extend_from_slice(&i.to_le_bytes());
    }
    assert_eq!(parse_mesh_ply(&good, Path::new("ok.ply")).unwrap().triangles, vec![[0, 1, 2]]);
    // Truncated inside the face list.
    let e = parse_mesh_ply(&good[..good.len() - 2], Path::new("t.ply")).unwrap_err().to_string();
    assert_has(&e, &["t.ply", "face 0", "truncated"]);
    // Index out of range.
    let mut bad = good.clone();
    let n = bad.len();
    bad[n - 4..].copy_from_slice(&7i32.to_le_bytes());
    assert_has(&parse_mesh_ply(&bad, Path::new("o.ply")).unwrap_err().to_string(), &["o.ply", "face 0", "index 7"]);
    // A face list of floats.
    let s = String::from_utf8_lossy(&good).replacen("list uchar int", "list uchar float", 1);
    let e = parse_mesh_ply(&s.into_bytes(), Path::new("f.ply")).unwrap_err().to_string();
    assert_has(&e, &["f.ply", "list of integers"]);
    // Huge list length in a skipped element cannot allocate or loop forever.
    let skip = "ply\nformat binary_little_endian 1.0\nelement junk 1\nproperty list uint uchar data\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    let skip = [skip.as_bytes(), &[0xff; 4]].concat();
    let e = parse_mesh_ply(&skip, Path::new("j.ply")).unwrap_err().to_string();
    assert_has(&e, &["j.ply", "junk 0", "truncated"]);
}

#[test]
fn missing_files_name_the_path() {
    let e = read_gaussian_ply(Path::new("/nonexistent/g.ply")).unwrap_err();
    assert!(matches!(e, IoError::Io { .. }) && e.to_string().contains("/nonexistent/g.ply"));
    let e = read_mesh_ply(Path::new("/nonexistent/m.ply")).unwrap_err();
    assert!(e.to_string().contains("/nonexistent/m.ply"));
}
