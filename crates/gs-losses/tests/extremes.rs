//! The extremes of docs/architecture.md §Extremes: constant, saturated and 1×1 images, all-zero depth, NaN-free outputs,
//! and clear errors for invalid input.

use gs_core::{Image, Intrinsics};
use gs_losses::{
    EdgeGuide, ImageLossConfig, LossError, NormalLossConfig, NsGate, image_loss, normal_losses,
    psnr, ssim_metric,
};

fn finite_image_loss(r: &Image, g: &Image) -> f64 {
    let guide = EdgeGuide::from_gt(g).unwrap();
    assert!(guide.gradient.is_finite() && guide.delta.is_finite());
    let out = image_loss(r, g, Some(&guide), &ImageLossConfig::default()).unwrap();
    assert!(out.total.is_finite() && out.ssim.is_finite() && out.edge.unwrap().is_finite());
    assert!(out.grad_rendered.is_finite(), "non-finite gradient");
    out.total
}

#[test]
fn image_loss_finite_at_extremes() {
    for (w, h) in [(1, 1), (2, 2), (3, 3), (1, 17), (40, 30)] {
        for (a, b) in [(0.0, 0.0), (1.0, 1.0), (0.0, 1.0), (0.5, 0.5), (1.0, 0.3)] {
            let r = Image::filled(w, h, 3, a).unwrap();
            let g = Image::filled(w, h, 3, b).unwrap();
            let v = finite_image_loss(&r, &g);
            if a == b {
                assert!(
                    v.abs() < 1e-6,
                    "{w}×{h} identical constant images give L_I = {v}"
                );
            }
        }
        // Binary (saturated) images.
        let bin = |s: usize| {
            Image::from_vec(
                w,
                h,
                3,
                (0..w * h * 3)
                    .map(|i| ((i * 7 + s) % 5 < 2) as u8 as f32)
                    .collect(),
            )
            .unwrap()
        };
        finite_image_loss(&bin(0), &bin(3));
    }
}

#[test]
fn normal_losses_finite_at_extremes() {
    for (w, h) in [(1, 1), (2, 3), (3, 3), (24, 18)] {
        let k = Intrinsics::new(30.0, 30.0, w as f64 / 2.0, h as f64 / 2.0);
        let guide = EdgeGuide::from_gt(&Image::filled(w, h, 3, 0.5).unwrap()).unwrap();
        let mut holes = Image::filled(w, h, 1, 2.0).unwrap();
        for p in (0..w * h).step_by(3) {
            holes.data_mut()[p] = 0.0;
        }
        let depths = [
            Image::new(w, h, 1).unwrap(),
            Image::filled(w, h, 1, 1e-6).unwrap(),
            Image::filled(w, h, 1, 1e6).unwrap(),
            holes,
        ];
        let normals = [
            Image::new(w, h, 3).unwrap(),
            Image::filled(w, h, 3, 0.577).unwrap(),
        ];
        for z in &depths {
            for n in &normals {
                for gate in [NsGate::Above, NsGate::Below] {
                    let alpha = Image::filled(w, h, 1, 0.0).unwrap();
                    for a in [None, Some(&alpha)] {
                        let cfg = NormalLossConfig {
                            gate,
                            ..Default::default()
                        };
                        let o = normal_losses(z, n, a, &guide, &k, &cfg).unwrap();
                        assert!(o.l_nc.is_finite() && o.l_ns.is_finite() && o.total.is_finite());
                        assert!(
                            o.depth_normal.is_finite()
                                && o.grad_plane_depth.is_finite()
                                && o.grad_normal.is_finite()
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn invalid_input_is_an_error() {
    let a = Image::filled(8, 8, 3, 0.5).unwrap();
    let b = Image::filled(8, 9, 3, 0.5).unwrap();
    assert!(matches!(
        image_loss(&a, &b, None, &ImageLossConfig::default()),
        Err(LossError::ShapeMismatch(_))
    ));
    // Edge term on but no guide.
    assert!(matches!(
        image_loss(&a, &a, None, &ImageLossConfig::default()),
        Err(LossError::InvalidParameter(_))
    ));
    let no_edge = ImageLossConfig {
        edge: false,
        ..Default::default()
    };
    assert!(image_loss(&a, &a, None, &no_edge).unwrap().edge.is_none());
    let bad = ImageLossConfig {
        beta1: f32::NAN,
        ..Default::default()
    };
    assert!(image_loss(&a, &a, None, &bad).is_err());
    let guide = EdgeGuide::from_gt(&a).unwrap();
    let k = Intrinsics::new(10.0, 10.0, 4.0, 4.0);
    let z = Image::filled(8, 8, 1, 1.0).unwrap();
    assert!(matches!(
        normal_losses(&z, &a, None, &guide, &k, &NormalLossConfig::default()).map(|_| ()),
        Ok(())
    ));
    assert!(matches!(
        normal_losses(&a, &a, None, &guide, &k, &NormalLossConfig::default()),
        Err(LossError::Channels(_))
    ));
    let n9 = Image::filled(8, 9, 3, 0.0).unwrap();
    assert!(matches!(
        normal_losses(&z, &n9, None, &guide, &k, &NormalLossConfig::default()),
        Err(LossError::ShapeMismatch(_))
    ));
    let neg = NormalLossConfig {
        tau: -1.0,
        ..Default::default()
    };
    assert!(normal_losses(&z, &a, None, &guide, &k, &neg).is_err());
    let k0 = Intrinsics::new(0.0, 10.0, 4.0, 4.0);
    assert!(normal_losses(&z, &a, None, &guide, &k0, &NormalLossConfig::default()).is_err());
    assert!(psnr(&a, &b).is_err() && ssim_metric(&a, &b).is_err());
}

#[test]
fn metrics_definitions() {
    let a = Image::filled(16, 16, 3, 0.5).unwrap();
    let b = Image::filled(16, 16, 3, 0.6).unwrap();
    // MSE = 0.01 → 20 dB.
    assert!((psnr(&a, &b).unwrap() - 20.0).abs() < 1e-4);
    assert_eq!(psnr(&a, &a).unwrap(), gs_losses::metrics::PSNR_MAX_DB);
    assert_eq!(ssim_metric(&a, &a).unwrap(), 1.0);
    let one = Image::filled(1, 1, 3, 1.0).unwrap();
    let zero = Image::filled(1, 1, 3, 0.0).unwrap();
    assert!((psnr(&one, &zero).unwrap()).abs() < 1e-12);
    assert!(ssim_metric(&one, &zero).unwrap().is_finite());
}

#[test]
#[cfg_attr(debug_assertions, ignore = "release only: 4000×3000 images")]
fn losses_finite_at_4000x3000() {
    // docs/architecture.md §Extremes (5): the largest image size, a saturated/textured pair and a tilted plane.
    let (w, h) = (4000, 3000);
    let r = Image::from_vec(w, h, 3, (0..w * h * 3).map(|i| ((i * 31) % 97) as f32 / 96.0).collect()).unwrap();
    let g = Image::from_vec(w, h, 3, (0..w * h * 3).map(|i| ((i / 3) % 2) as f32).collect()).unwrap();
    finite_image_loss(&r, &g);
    let guide = EdgeGuide::from_gt(&g).unwrap();
    let k = Intrinsics::new(3500.0, 3500.0, 2000.0, 1500.0);
    let z = Image::from_vec(w, h, 1, (0..w * h).map(|p| 2.0 + (p % w) as f32 * 1e-4).collect()).unwrap();
    let mut n = Image::new(w, h, 3).unwrap();
    for p in n.data_mut().chunks_mut(3) {
        p.copy_from_slice(&[0.1, -0.1, -0.99]);
    }
    let out = normal_losses(&z, &n, None, &guide, &k, &NormalLossConfig::default()).unwrap();
    assert!(out.l_nc.is_finite() && out.l_ns.is_finite());
    assert!(out.grad_plane_depth.is_finite() && out.grad_normal.is_finite());
}
