//! Test-only readers for synth-bunny: `.npy` float32 depth, binary PLY meshes, COLMAP text poses.
//! (The library does not depend on gs-io; these minimal readers only serve the tests.)
#![allow(dead_code)]

use gs_core::{Camera, Image, Intrinsics, TriangleMesh};
use std::path::{Path, PathBuf};

/// synth-bunny in the shared test data (`VAGSL_TEST_DATA`, see gs-testdata).
pub fn bunny_dir() -> PathBuf {
    gs_testdata::root().join("data/synth-bunny")
}

/// Reads a little-endian float32 C-order 2-D `.npy` as a 1-channel image.
pub fn read_npy_f32(path: &Path) -> Image {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(&bytes[..6], b"\x93NUMPY", "{}: not an npy file", path.display());
    let (header_len, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        _ => (u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize, 12),
    };
    let header = std::str::from_utf8(&bytes[start..start + header_len]).unwrap();
    assert!(header.contains("'<f4'") && header.contains("'fortran_order': False"), "{header}");
    let shape = &header[header.find("'shape': (").unwrap() + 10..];
    let dims: Vec<usize> =
        shape[..shape.find(')').unwrap()].split(',').filter_map(|s| s.trim().parse().ok()).collect();
    let (h, w) = (dims[0], dims[1]);
    let data: Vec<f32> = bytes[start + header_len..]
        .chunks_exact(4)
        .take(w * h)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    Image::from_vec(w, h, 1, data).unwrap()
}

/// Reads a binary little-endian PLY with float `x y z` vertices (other vertex properties must be
/// absent) and `uchar int vertex_indices` triangle faces.
pub fn read_ply(path: &Path) -> TriangleMesh {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let end = bytes.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    let header = std::str::from_utf8(&bytes[..end]).unwrap();
    assert!(header.contains("binary_little_endian"));
    let count = |el: &str| -> usize {
        header.lines().find(|l| l.starts_with(&format!("element {el} "))).unwrap().split_whitespace().nth(2).unwrap().parse().unwrap()
    };
    let (nv, nf) = (count("vertex"), count("face"));
    let mut off = end;
    let f = |o: usize| f32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
    let mut positions = Vec::with_capacity(nv);
    for _ in 0..nv {
        positions.push([f(off), f(off + 4), f(off + 8)]);
        off += 12;
    }
    let mut triangles = Vec::with_capacity(nf);
    for _ in 0..nf {
        assert_eq!(bytes[off], 3, "only triangles");
        let i = |k: usize| u32::from_le_bytes(bytes[off + 1 + 4 * k..off + 5 + 4 * k].try_into().unwrap());
        triangles.push([i(0), i(1), i(2)]);
        off += 13;
    }
    TriangleMesh { positions, triangles, colors: None }
}

/// The cameras of `sparse/0` (PINHOLE, text) with their image names, in file order.
pub fn read_cameras(dir: &Path) -> Vec<(String, Camera)> {
    let cams = std::fs::read_to_string(dir.join("sparse/0/cameras.txt")).unwrap();
    let c: Vec<f64> = cams
        .lines()
        .find(|l| !l.starts_with('#') && !l.trim().is_empty())
        .unwrap()
        .split_whitespace()
        .skip(2)
        .map(|s| s.parse().unwrap())
        .collect();
    let (w, h) = (c[0] as u32, c[1] as u32);
    let k = Intrinsics::new(c[2], c[3], c[4], c[5]);
    let imgs = std::fs::read_to_string(dir.join("sparse/0/images.txt")).unwrap();
    let lines: Vec<&str> = imgs.lines().filter(|l| !l.starts_with('#')).collect();
    lines
        .chunks(2)
        .filter_map(|p| {
            let f: Vec<&str> = p[0].split_whitespace().collect();
            if f.len() < 10 {
                return None;
            }
            let n: Vec<f64> = f[1..8].iter().map(|s| s.parse().unwrap()).collect();
            let cam = Camera::from_quaternion(w, h, k, [n[0], n[1], n[2], n[3]], [n[4], n[5], n[6]]).unwrap();
            Some((f[9].to_string(), cam))
        })
        .collect()
}

/// `(camera, depth)` of every view with a GT depth map.
pub fn bunny_views() -> Vec<(Camera, Image)> {
    let dir = bunny_dir();
    read_cameras(&dir)
        .into_iter()
        .filter_map(|(name, cam)| {
            let stem = name.trim_end_matches(".png");
            let p = dir.join(format!("gt/depth_{stem}.npy"));
            p.exists().then(|| (cam, read_npy_f32(&p)))
        })
        .collect()
}
