#![cfg(feature = "wgpu")]
//! Parity of VGG16's trunk on the device ([`Vgg16Gpu`]) with the CPU extractor ([`Vgg16`]) on
//! a crop of the built-in scene's first view (a rendered photograph), at both feature levels,
//! with odd sizes so that the floor pools drop a row and a column; the same input checks and
//! errors; options (grey input, channel projection, f16 storage) finished as the host finishes
//! them; one map for one image on one device; the host's map where the activations exceed one
//! storage binding. Without a wgpu adapter the tests print one SKIPPED line (a failure under
//! `CI=true`, where `.ci/run` installs lavapipe).
//!
//! Tolerance: the device sums each convolution in another order than the host's GEMM (and may
//! fuse a·b + c), so every value is within 2e-5 of the map's largest magnitude (lavapipe:
//! see the printed figure); the layout and the pools are exact.

mod common;

use gs_core::Image;
use gs_features::{ExtractOptions, FeatureError, FeatureLevel, FeatureMap, StoragePrecision, Vgg16, Vgg16Gpu};
use gs_gpu::GpuOptions;

const TOLERANCE: f32 = 2e-5;

/// The host's extractor and the device's on a context made with `options` (`None`: no adapter,
/// after the SKIPPED line).
fn extractors(options: &GpuOptions) -> Option<(Vgg16, Vgg16Gpu)> {
    let ctx = gs_testdata::wgpu_context!(options)?;
    let net = Vgg16::bundled().unwrap();
    let gpu = Vgg16Gpu::new(&ctx, &net).unwrap();
    Some((net, gpu))
}

/// A 61 × 43 crop of the built-in scene's first view (200 × 150), where the object and the
/// walls meet.
fn photo() -> Image {
    common::crop(&common::builtin_image(), 70, 50, 61, 43)
}

/// The largest |device − host| over the map's largest magnitude, after checking the layout.
fn relative_error(device: &FeatureMap, host: &FeatureMap) -> f32 {
    assert_eq!((device.width(), device.height(), device.channels()), (host.width(), host.height(), host.channels()));
    assert_eq!((device.stride(), device.precision()), (host.stride(), host.precision()));
    let (d, h) = (device.to_f32_vec(), host.to_f32_vec());
    let scale = h.iter().fold(0f32, |m, v| m.max(v.abs()));
    assert!(scale > 0.0, "an all-zero map tests nothing");
    d.iter().zip(&h).map(|(a, b)| (a - b).abs()).fold(0f32, f32::max) / scale
}

#[test]
fn device_features_match_the_host_at_both_levels() {
    let Some((net, mut gpu)) = extractors(&GpuOptions::default()) else { return };
    let img = photo();
    for level in [FeatureLevel::Conv2_2, FeatureLevel::Conv3_3] {
        let host = net.extract(&img, level).unwrap();
        let device = gpu.extract(&img, level).unwrap();
        let err = relative_error(&device, &host);
        eprintln!("VGG16 {level:?}: relative error, max |device − host| / max |host| = {err:.2e}");
        assert!(err <= TOLERANCE, "{level:?}: {err}");
        // The sums have one order: the same image gives the same bits again.
        assert_eq!(gpu.extract(&img, level).unwrap(), device, "{level:?} repeats");
    }
}

#[test]
fn options_are_finished_as_the_host_finishes_them() {
    let Some((net, mut gpu)) = extractors(&GpuOptions::default()) else { return };
    let img = photo();
    let grey = img.to_grey().unwrap();
    let opts = ExtractOptions { reduce_to: Some(24), precision: StoragePrecision::F16, ..ExtractOptions::at(FeatureLevel::Conv2_2) };
    for input in [&img, &grey] {
        let host = net.extract_with(input, &opts).unwrap();
        let device = gpu.extract_with(input, &opts).unwrap();
        assert_eq!(device.channels(), 24);
        // f16 storage rounds both maps: allow one f16 step of the largest value besides.
        let err = relative_error(&device, &host);
        assert!(err <= TOLERANCE + 1e-3, "{} channel(s): {err}", input.channels());
    }
}

#[test]
fn bad_images_get_the_host_errors() {
    let Some((net, mut gpu)) = extractors(&GpuOptions::default()) else { return };
    let img = photo();
    let mut nan = img.clone();
    nan.set(3, 2, 1, f32::NAN);
    let bad = [
        nan,
        Image::filled(3, 3, 1, 0.5).unwrap(),
        Image::filled(8, 8, 2, 0.5).unwrap(),
    ];
    for img in &bad {
        let want = net.extract(img, FeatureLevel::Conv3_3).unwrap_err();
        let got = gpu.extract(img, FeatureLevel::Conv3_3).unwrap_err();
        assert!(matches!(got, FeatureError::InvalidImage(_)), "{got}");
        assert_eq!(got, want);
    }
    let capped = ExtractOptions { max_pixels: 100, ..ExtractOptions::default() };
    assert_eq!(gpu.extract_with(&img, &capped).unwrap_err(), net.extract_with(&img, &capped).unwrap_err());
}

#[test]
fn activations_beyond_one_binding_are_extracted_on_the_host() {
    // conv1's padded 63 × 45 × 64 activation is 726 KB: a 256 KiB binding cannot hold it.
    let Some((net, mut gpu)) = extractors(&GpuOptions { max_storage_binding: Some(256 << 10), ..Default::default() }) else { return };
    let img = photo();
    assert_eq!(gpu.extract(&img, FeatureLevel::Conv2_2).unwrap(), net.extract(&img, FeatureLevel::Conv2_2).unwrap());
}
