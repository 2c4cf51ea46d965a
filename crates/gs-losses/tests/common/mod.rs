//! Shared helpers of the integration tests.
#![allow(dead_code)]

use gs_core::Rng;
use std::path::PathBuf;

/// Path of a file in the shared test data (`VAGSL_TEST_DATA`, see gs-testdata).
pub fn shared(rel: &str) -> PathBuf {
    gs_testdata::root().join(rel)
}

/// Uniform random values in [lo, hi).
pub fn random(rng: &mut Rng, n: usize, lo: f64, hi: f64) -> Vec<f64> {
    (0..n).map(|_| lo + (hi - lo) * rng.uniform_f64()).collect()
}

/// An 8-bit PNG/JPEG as f32 RGB in [0, 1] (value/255), with its size.
pub fn load_rgb(path: &std::path::Path) -> (usize, usize, Vec<f32>) {
    let img = image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgb8();
    let (w, h) = (img.width() as usize, img.height() as usize);
    (
        w,
        h,
        img.into_raw()
            .into_iter()
            .map(|v| v as f32 / 255.0)
            .collect(),
    )
}

/// An 8-bit image's raw RGB bytes, with its size.
pub fn load_rgb8(path: &std::path::Path) -> (usize, usize, Vec<u8>) {
    let img = image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgb8();
    (img.width() as usize, img.height() as usize, img.into_raw())
}
