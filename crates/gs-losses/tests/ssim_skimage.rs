//! SSIM against independent Python values (`scripts/ssim_crosscheck.py`, output kept in
//! `tests/fixtures/ssim_skimage.json`): scikit-image's `structural_similarity(gaussian_weights=True,
//! sigma=1.5, use_sample_covariance=False, data_range=1, channel_axis=-1)` equals
//! `SsimRegion::Interior`, and a scipy zero-padded implementation of 3DGS's SSIM equals
//! `SsimRegion::Full`; both to 1e-4 (observed: ~1e-7, f32 rounding). JPEG pairs are decoded by a
//! different library here (image-rs) than in the script (PIL/libjpeg), which the tolerance covers.

mod common;

use gs_core::Image;
use gs_losses::{SsimRegion, ssim_metric_with};

#[test]
fn matches_scikit_image_and_zero_padded_reference() {
    let fixture: serde_json::Value =
        serde_json::from_str(include_str!("fixtures/ssim_skimage.json")).unwrap();
    let pairs = fixture["pairs"].as_array().unwrap();
    let files: Vec<&str> = pairs.iter().flat_map(|p| [p["a"].as_str().unwrap(), p["b"].as_str().unwrap()]).collect();
    if !gs_testdata::needs(&gs_testdata::test_name(env!("CARGO_CRATE_NAME")), &files) {
        return;
    }
    for p in pairs {
        let (pa, pb) = (
            common::shared(p["a"].as_str().unwrap()),
            common::shared(p["b"].as_str().unwrap()),
        );
        let (w, h, a) = common::load_rgb(&pa);
        let (_, _, b) = common::load_rgb(&pb);
        let (a, b) = (
            Image::from_vec(w, h, 3, a).unwrap(),
            Image::from_vec(w, h, 3, b).unwrap(),
        );
        let interior = ssim_metric_with(&a, &b, SsimRegion::Interior).unwrap();
        let full = ssim_metric_with(&a, &b, SsimRegion::Full).unwrap();
        let (sk, zp) = (
            p["skimage"].as_f64().unwrap(),
            p["zero_padded"].as_f64().unwrap(),
        );
        eprintln!(
            "{}: interior {interior:.8} skimage {sk:.8} | full {full:.8} zero-padded {zp:.8}",
            pa.display()
        );
        assert!(
            (interior - sk).abs() < 1e-4,
            "{}: interior {interior} vs skimage {sk}",
            pa.display()
        );
        assert!(
            (full - zp).abs() < 1e-4,
            "{}: full {full} vs zero-padded {zp}",
            pa.display()
        );
        // The two regions really differ on these images, so the test tells them apart.
        assert!((sk - zp).abs() > 1e-3);
    }
}

#[test]
fn interior_needs_11_pixels() {
    let a = Image::filled(10, 20, 3, 0.5).unwrap();
    assert!(ssim_metric_with(&a, &a, SsimRegion::Interior).is_err());
    assert_eq!(ssim_metric_with(&a, &a, SsimRegion::Full).unwrap(), 1.0);
}
