//! LPIPS-alex v0.1 with the bundled f16 weights against the published and reference values
//! listed with the shared reference images (`weights/README.md` of the shared test data, found
//! through `VAGSL_TEST_DATA`; without them those tests print SKIPPED).

mod common;

use common::shared;
use gs_core::Image;
use gs_losses::{LossError, Lpips};

/// A shared reference image (`weights/REL`); the test checked with `needs!` that it exists.
fn load(rel: &str) -> Image {
    let (w, h, v) = common::load_rgb(&shared(&format!("weights/{rel}")));
    Image::from_vec(w, h, 3, v).unwrap()
}

#[test]
fn upstream_examples_give_published_values() {
    if !gs_testdata::needs!("weights/ref/upstream/ex_ref.png", "weights/ref/upstream/ex_p0.png", "weights/ref/upstream/ex_p1.png") {
        return;
    }
    let m = Lpips::bundled().unwrap();
    let (r, p0, p1) = (load("ref/upstream/ex_ref.png"), load("ref/upstream/ex_p0.png"), load("ref/upstream/ex_p1.png"));
    let d0 = m.distance(&r, &p0).unwrap();
    let d1 = m.distance(&r, &p1).unwrap();
    // Published (PerceptualSimilarity issue #120): 0.722 and 0.138; f32 reference 0.721881, 0.137566.
    assert!((d0 - 0.722).abs() <= 0.002, "ex_ref vs ex_p0: {d0}");
    assert!((d1 - 0.138).abs() <= 0.002, "ex_ref vs ex_p1: {d1}");
    assert!(
        (d0 - 0.721881).abs() < 5e-4 && (d1 - 0.137566).abs() < 5e-4,
        "{d0} {d1}"
    );
    let per = m.distance_per_layer(&r, &p0).unwrap();
    let expect = [0.01813, 0.28697, 0.15986, 0.11900, 0.13792];
    for (k, (a, b)) in per.iter().zip(expect).enumerate() {
        assert!((a - b).abs() < 3e-4, "layer {k}: {a} vs {b}");
    }
    assert_eq!(m.distance(&r, &r).unwrap(), 0.0);
    assert!(
        (m.distance(&p0, &r).unwrap() - d0).abs() < 1e-9,
        "symmetric"
    );
}

#[test]
fn reference_pairs_256() {
    if !gs_testdata::needs!("weights/ref/img1_astronaut.png", "weights/ref/img2_chelsea.png", "weights/ref/img3_astronaut_blur1.png") {
        return;
    }
    let m = Lpips::bundled().unwrap();
    let (a, b, c) = (load("ref/img1_astronaut.png"), load("ref/img2_chelsea.png"), load("ref/img3_astronaut_blur1.png"));
    let d1 = m.distance(&a, &b).unwrap();
    let d2 = m.distance(&a, &c).unwrap();
    assert!((d1 - 0.712265).abs() < 1e-3, "pair 1: {d1}");
    assert!((d2 - 0.185121).abs() < 1e-3, "pair 2: {d2}");
}

#[test]
fn rejects_bad_input_and_corrupt_weights() {
    let m = Lpips::bundled().unwrap();
    let small = Image::filled(30, 40, 3, 0.5).unwrap();
    assert!(matches!(
        m.distance(&small, &small),
        Err(LossError::InvalidParameter(_))
    ));
    let grey = Image::filled(64, 64, 1, 0.5).unwrap();
    assert!(matches!(
        m.distance(&grey, &grey),
        Err(LossError::Channels(_))
    ));
    let (a, b) = (
        Image::filled(64, 64, 3, 0.5).unwrap(),
        Image::filled(64, 65, 3, 0.5).unwrap(),
    );
    assert!(matches!(
        m.distance(&a, &b),
        Err(LossError::ShapeMismatch(_))
    ));
    let mut nan = a.clone();
    nan.set(3, 3, 0, f32::NAN);
    assert!(m.distance(&nan, &a).is_err());
    // Minimum size and constant / saturated images are finite.
    let (z, o) = (
        Image::filled(31, 31, 3, 0.0).unwrap(),
        Image::filled(31, 31, 3, 1.0).unwrap(),
    );
    let d = m.distance(&z, &o).unwrap();
    assert!(d.is_finite() && d >= 0.0);
    // Corrupt weights: one flipped byte, truncation, wrong magic.
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/weights/lpips_alex_v0.1.f16.bin"
    );
    let bytes = std::fs::read(path).unwrap();
    let mut bad = bytes.clone();
    bad[1000] ^= 1;
    let e = Lpips::from_bytes(&bad, "flipped", None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("checksum") && e.contains("flipped"), "{e}");
    assert!(Lpips::from_bytes(&bytes[..bytes.len() - 9], "cut", None).is_err());
    assert!(Lpips::from_bytes(&bytes, "sized", Some(bytes.len() + 1)).is_err());
    let mut magic = bytes.clone();
    magic[0] = b'X';
    assert!(
        Lpips::from_bytes(&magic, "magic", None)
            .unwrap_err()
            .to_string()
            .contains("magic")
    );
    assert!(Lpips::from_file(std::path::Path::new("/nonexistent/w.bin")).is_err());
    assert!(Lpips::from_file(std::path::Path::new(path)).is_ok());
}
