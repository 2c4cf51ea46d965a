//! Test helpers: shared-data paths, PNG loading and cropping, a tiny `.npy` reader and the few
//! COLMAP text lines the cross-view test needs.
#![allow(dead_code)]

use gs_core::{Camera, Image, Intrinsics};
use std::path::PathBuf;

/// The shared test data (`VAGSL_TEST_DATA`, see gs-testdata).
pub fn shared() -> PathBuf {
    gs_testdata::root()
}

pub fn fixture(name: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures")).join(name)
}

/// An 8-bit RGB PNG as value/255 (docs/architecture.md §Conventions, no gamma conversion).
pub fn load_rgb(path: &std::path::Path) -> Image {
    let img = image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())).to_rgb8();
    let (w, h) = img.dimensions();
    let data = img.into_raw().into_iter().map(|v| v as f32 / 255.0).collect();
    Image::from_vec(w as usize, h as usize, 3, data).unwrap()
}

/// The first view of the built-in scene at its default size (200 × 150).
pub fn builtin_image() -> Image {
    let opts = gs_synth::BuiltinOptions { views: 2, points: 10, ..Default::default() };
    gs_synth::generate(&opts).unwrap().scene.views.swap_remove(0).image
}

pub fn crop(img: &Image, x0: usize, y0: usize, w: usize, h: usize) -> Image {
    let c = img.channels();
    let mut data = Vec::with_capacity(w * h * c);
    for y in y0..y0 + h {
        data.extend_from_slice(&img.row(y)[x0 * c..(x0 + w) * c]);
    }
    Image::from_vec(w, h, c, data).unwrap()
}

/// Little-endian f32 values of a raw fixture file.
pub fn read_f32(path: &std::path::Path) -> Vec<f32> {
    let b = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    b.chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect()
}

/// A `.npy` array (gs-io's reader): (shape, values).
pub fn read_npy_f32(path: &std::path::Path) -> (Vec<usize>, Vec<f32>) {
    let a = gs_io::read_npy_array(path).unwrap_or_else(|e| panic!("{e}"));
    (a.shape, a.data)
}

/// (image name, camera) of a COLMAP TEXT model with PINHOLE cameras.
pub fn read_colmap(dir: &std::path::Path) -> Vec<(String, Camera)> {
    let cams = std::fs::read_to_string(dir.join("cameras.txt")).unwrap();
    let cam_line: Vec<&str> =
        cams.lines().find(|l| !l.starts_with('#') && !l.trim().is_empty()).unwrap().split_whitespace().collect();
    assert_eq!(cam_line[1], "PINHOLE");
    let p: Vec<f64> = cam_line[2..8].iter().map(|s| s.parse().unwrap()).collect();
    let (w, h) = (p[0] as u32, p[1] as u32);
    let k = Intrinsics::new(p[2], p[3], p[4], p[5]);
    let imgs = std::fs::read_to_string(dir.join("images.txt")).unwrap();
    let lines: Vec<&str> = imgs.lines().filter(|l| !l.starts_with('#')).collect();
    let mut out = Vec::new();
    for pair in lines.chunks(2) {
        let f: Vec<&str> = pair[0].split_whitespace().collect();
        if f.len() < 10 {
            continue;
        }
        let v: Vec<f64> = f[1..8].iter().map(|s| s.parse().unwrap()).collect();
        let cam = Camera::from_quaternion(w, h, k, [v[0], v[1], v[2], v[3]], [v[4], v[5], v[6]]).unwrap();
        out.push((f[9].to_string(), cam));
    }
    out
}

/// Mean of a slice.
pub fn mean(v: &[f32]) -> f32 {
    v.iter().sum::<f32>() / v.len().max(1) as f32
}
