//! Finite-difference (f64, central) gradient checks of every loss w.r.t. every differentiable
//! input, on small random images and at the extremes (constant, saturated, depth with holes).
//! Inputs are drawn away from the |·| / max / ReLU kinks, or the check says how kinks are handled.

mod common;

use common::random;
use gs_core::gradcheck::{GradCheck, check_gradient};
use gs_core::{Image, Intrinsics, Rng};
use gs_losses::gradient::{
    edge_l1, edge_weight, image_gradient, image_gradient_backward, image_gradient_fixed_range,
};
use gs_losses::l1::{l1, l1_backward};
use gs_losses::normal::{depth_normal, depth_normal_backward};
use gs_losses::normal_loss::{normal_consistency, normal_smoothing};
use gs_losses::ssim::{ssim, ssim_backward};
use gs_losses::{Dims, EdgeGuide, ImageLossConfig, NormalLossConfig, NsGate, NsPairs, SsimRegion};

fn opts() -> GradCheck {
    GradCheck {
        eps: 1e-6,
        rtol: 1e-5,
        atol: 1e-9,
        indices: None,
    }
}

fn check(name: &str, f: impl FnMut(&[f64]) -> f64, x: &[f64], analytic: &[f64], o: &GradCheck) {
    match check_gradient(f, x, analytic, o) {
        Ok(_) => {}
        Err(r) => panic!("{name}: gradient check failed: {r:?}"),
    }
    assert!(
        analytic.iter().all(|v| v.is_finite()),
        "{name}: non-finite gradient"
    );
}

/// Two images whose per-value differences stay ≥ 0.05 (away from the L1 kink).
fn pair(rng: &mut Rng, n: usize) -> (Vec<f64>, Vec<f64>) {
    let a = random(rng, n, 0.0, 1.0);
    let b: Vec<f64> = a
        .iter()
        .map(|&v| {
            let d = 0.05 + 0.4 * rng.uniform_f64();
            if v + d <= 1.0 && rng.uniform_f64() < 0.5 {
                v + d
            } else if v - d >= 0.0 {
                v - d
            } else {
                v + d
            }
        })
        .collect();
    (a, b)
}

#[test]
fn l1_gradient() {
    let mut rng = Rng::new(1);
    let (a, b) = pair(&mut rng, 7 * 5 * 3);
    let mut g = vec![0.0; a.len()];
    l1_backward(&a, &b, 0.8, &mut g);
    check("L1", |x| 0.8 * l1(x, &b), &a, &g, &opts());
    // Constant and saturated images (rendered 0.5 / 0 / 1 against a GT on the other side):
    // every difference is away from the kink, so the check is exact.
    let n = 6 * 4 * 3;
    for (name, rendered, gt) in [
        ("L1 constant", vec![0.5; n], random(&mut rng, n, 0.6, 1.0)),
        ("L1 saturated 0", vec![0.0; n], random(&mut rng, n, 0.1, 1.0)),
        ("L1 saturated 1", vec![1.0; n], random(&mut rng, n, 0.0, 0.9)),
    ] {
        let mut g = vec![0.0; n];
        l1_backward(&rendered, &gt, 0.8, &mut g);
        check(name, |x| 0.8 * l1(x, &gt), &rendered, &g, &opts());
    }
}

fn ssim_case(name: &str, a: &[f64], b: &[f64], dims: Dims, region: SsimRegion) {
    let mut g = vec![0.0; a.len()];
    let v = ssim_backward(a, b, dims, region, 1.0, &mut g).unwrap();
    assert!((v - ssim(a, b, dims, region).unwrap()).abs() < 1e-12);
    assert!(v.is_finite() && v <= 1.0 + 1e-12, "{name}: SSIM {v}");
    check(
        name,
        |x| ssim(x, b, dims, region).unwrap(),
        a,
        &g,
        &GradCheck {
            atol: 1e-8,
            ..opts()
        },
    );
}

#[test]
fn ssim_gradient_random_and_extremes() {
    let mut rng = Rng::new(2);
    let dims = Dims::new(13, 12, 3);
    let n = dims.len();
    let (a, b) = pair(&mut rng, n);
    ssim_case("SSIM random", &a, &b, dims, SsimRegion::Full);
    ssim_case("SSIM random interior", &a, &b, dims, SsimRegion::Interior);
    // Constant rendered image, constant target, both constant.
    ssim_case(
        "SSIM constant rendered",
        &vec![0.4; n],
        &b,
        dims,
        SsimRegion::Full,
    );
    ssim_case(
        "SSIM constant target",
        &a,
        &vec![0.7; n],
        dims,
        SsimRegion::Full,
    );
    ssim_case(
        "SSIM both constant",
        &vec![0.3; n],
        &vec![0.3; n],
        dims,
        SsimRegion::Full,
    );
    // Saturated: all 0, all 1, binary 0/1 images.
    ssim_case(
        "SSIM all zero",
        &vec![0.0; n],
        &vec![0.0; n],
        dims,
        SsimRegion::Full,
    );
    ssim_case(
        "SSIM all one vs random",
        &vec![1.0; n],
        &b,
        dims,
        SsimRegion::Full,
    );
    let bin: Vec<f64> = (0..n)
        .map(|_| if rng.uniform() < 0.5 { 0.0 } else { 1.0 })
        .collect();
    ssim_case("SSIM binary", &bin, &a, dims, SsimRegion::Full);
    // Images smaller than the window, 1×1, one channel.
    let d1 = Dims::new(1, 1, 3);
    ssim_case(
        "SSIM 1x1",
        &[0.2, 0.5, 0.9],
        &[0.1, 0.6, 0.3],
        d1,
        SsimRegion::Full,
    );
    let d2 = Dims::new(4, 3, 1);
    let (a2, b2) = pair(&mut rng, d2.len());
    ssim_case("SSIM 4x3 grey", &a2, &b2, d2, SsimRegion::Full);
}

/// Edge term β2·L1(∇Ĩ, ∇I) through the gradient map with min/max frozen.
fn edge_case(name: &str, a: &[f64], gt: &[f64], dims: Dims, atol: f64) {
    let ggt = image_gradient(gt, dims);
    let gr = image_gradient(a, dims);
    let mut up = vec![0.0; dims.pixels()];
    let v = edge_l1(&gr.map, &ggt.map, 0.03, Some(&mut up));
    assert!(v.is_finite());
    let mut g = vec![0.0; a.len()];
    image_gradient_backward(a, dims, &gr, &up, &mut g);
    let (lo, hi) = (gr.min, gr.max);
    check(
        name,
        |x| {
            0.03 * edge_l1(
                &image_gradient_fixed_range(x, dims, lo, hi),
                &ggt.map,
                0.0,
                None,
            )
        },
        a,
        &g,
        &GradCheck { atol, ..opts() },
    );
}

#[test]
fn edge_term_gradient() {
    let mut rng = Rng::new(3);
    let dims = Dims::new(9, 8, 3);
    let (a, b) = pair(&mut rng, dims.len());
    edge_case("edge random", &a, &b, dims, 1e-8);
    // Constant rendered image: every |difference| sits at the kink 0, where both the analytic
    // subgradient and the symmetric central difference are 0 (up to the rounding of the
    // 1/(max − min + 1e-6) = 1e6 normalisation, hence the looser atol).
    edge_case(
        "edge constant rendered",
        &vec![0.5; dims.len()],
        &b,
        dims,
        1e-7,
    );
    edge_case(
        "edge grey",
        &random(&mut rng, 36, 0.0, 1.0),
        &random(&mut rng, 36, 0.0, 1.0),
        Dims::new(6, 6, 1),
        1e-8,
    );
    // Saturated ground truths (all 0, all 1): ∇I is 0 inside, the rendered image is random.
    for (name, v) in [("edge GT saturated 0", 0.0), ("edge GT saturated 1", 1.0)] {
        edge_case(name, &a, &vec![v; dims.len()], dims, 1e-8);
    }
    // Too small for an interior: ∇I = 1 everywhere, zero loss and gradient.
    edge_case(
        "edge 2x5",
        &random(&mut rng, 30, 0.0, 1.0),
        &random(&mut rng, 30, 0.0, 1.0),
        Dims::new(2, 5, 3),
        1e-8,
    );
}

#[test]
fn gradient_map_definition() {
    // 4×3 grey image: the single-row interior (1,1), (2,1).
    let img: [f64; 12] = [0.0, 0.1, 0.5, 0.2, 0.3, 0.0, 0.9, 0.4, 0.6, 0.2, 0.3, 0.8];
    let d = Dims::new(4, 3, 1);
    let g = image_gradient(&img, d);
    // (1,1): gx = |0.9 − 0.3| = 0.6, gy = |0.2 − 0.1| = 0.1 → 0.6; (2,1): gx = |0.4 − 0| = 0.4,
    // gy = |0.3 − 0.5| = 0.2 → 0.4. min 0.4, max 0.6.
    assert!((g.min - 0.4).abs() < 1e-12 && (g.max - 0.6).abs() < 1e-12);
    assert!((g.map[5] - 0.2 / (0.2 + 1e-6)).abs() < 1e-12);
    assert_eq!(g.map[6], 0.0);
    for i in [0, 1, 2, 3, 4, 7, 8, 9, 10, 11] {
        assert_eq!(g.map[i], 1.0, "border pixel {i}");
    }
    let delta = edge_weight(&g.map);
    assert_eq!(delta[0], 0.0);
    assert!((delta[6] - 1.0).abs() < 1e-12);
}

/// A smooth depth surface seen from the front (no two neighbour normals equal).
fn surface(rng: &mut Rng, w: usize, h: usize) -> Vec<f64> {
    let (a, b, c) = (
        rng.uniform_f64() * 0.3,
        rng.uniform_f64() * 0.3,
        rng.uniform_f64(),
    );
    (0..h)
        .flat_map(|j| (0..w).map(move |i| (i, j)))
        .map(|(i, j)| {
            let (x, y) = (i as f64 / w as f64, j as f64 / h as f64);
            2.0 + a * x
                + b * y
                + 0.3 * (3.0 * x + c).sin() * (2.0 * y).cos()
                + 0.05 * rng.uniform_f64()
        })
        .collect()
}

fn intrinsics(w: usize, h: usize) -> Intrinsics {
    Intrinsics::new(
        1.2 * w as f64,
        1.1 * h as f64,
        0.45 * w as f64,
        0.55 * h as f64,
    )
}

/// Ñ near N̂ but not equal (away from the L1 kink), unit-ish, facing the camera.
fn rendered_normals(rng: &mut Rng, nhat: &[f64]) -> Vec<f64> {
    nhat.chunks(3)
        .flat_map(|n| {
            let base = if n.iter().all(|&v| v == 0.0) {
                [0.1, -0.2, -0.9]
            } else {
                [n[0], n[1], n[2]]
            };
            let mut v = [0.0; 3];
            for k in 0..3 {
                let d = 0.02 + 0.1 * rng.uniform_f64();
                v[k] = base[k] + if rng.uniform() < 0.5 { d } else { -d };
            }
            v
        })
        .collect()
}

/// L_nc w.r.t. z and Ñ, L_ns w.r.t. z, for a depth map (optionally with alpha).
fn normal_case(name: &str, z: &[f64], w: usize, h: usize, alpha: Option<&[f64]>, rng: &mut Rng) {
    let k = intrinsics(w, h);
    let nhat = depth_normal(z, w, h, &k, alpha);
    let nt = rendered_normals(rng, &nhat);
    let delta: Vec<f64> = (0..w * h).map(|_| 0.2 + 0.8 * rng.uniform_f64()).collect();
    // L_nc w.r.t. z and Ñ.
    let mut g_nhat = vec![0.0; w * h * 3];
    let mut g_nt = vec![0.0; w * h * 3];
    normal_consistency(&nhat, &nt, &delta, 1.0, Some(&mut g_nhat), Some(&mut g_nt));
    let mut g_z = vec![0.0; w * h];
    depth_normal_backward(z, w, h, &k, alpha, &g_nhat, &mut g_z);
    let o = GradCheck {
        atol: 1e-8,
        rtol: 1e-5,
        ..opts()
    };
    check(
        &format!("{name}: dL_nc/dz"),
        |x| {
            normal_consistency(
                &depth_normal(x, w, h, &k, alpha),
                &nt,
                &delta,
                0.0,
                None,
                None,
            )
        },
        z,
        &g_z,
        &o,
    );
    check(
        &format!("{name}: dL_nc/dÑ"),
        |x| normal_consistency(&nhat, x, &delta, 0.0, None, None),
        &nt,
        &g_nt,
        &o,
    );
    // L_ns w.r.t. z, both gates and pair rules (τ chosen so that both gates select pairs).
    for gate in [NsGate::Above, NsGate::Below] {
        for pairs in [NsPairs::Interior, NsPairs::All] {
            let tau = 0.15;
            let mut g_nhat = vec![0.0; w * h * 3];
            let (v, _) = normal_smoothing(
                &nhat,
                &nt,
                &delta,
                w,
                h,
                tau,
                gate,
                pairs,
                1.0,
                Some(&mut g_nhat),
            );
            assert!(v.is_finite());
            let mut g_z = vec![0.0; w * h];
            depth_normal_backward(z, w, h, &k, alpha, &g_nhat, &mut g_z);
            check(
                &format!("{name}: dL_ns/dz {gate:?} {pairs:?}"),
                |x| {
                    normal_smoothing(
                        &depth_normal(x, w, h, &k, alpha),
                        &nt,
                        &delta,
                        w,
                        h,
                        tau,
                        gate,
                        pairs,
                        0.0,
                        None,
                    )
                    .0
                },
                z,
                &g_z,
                &o,
            );
        }
    }
}

#[test]
fn normal_losses_gradient() {
    let mut rng = Rng::new(4);
    let (w, h) = (9, 7);
    let z = surface(&mut rng, w, h);
    normal_case("smooth depth", &z, w, h, None, &mut rng);
    let alpha: Vec<f64> = (0..w * h).map(|_| 0.3 + 0.7 * rng.uniform_f64()).collect();
    normal_case("smooth depth with alpha", &z, w, h, Some(&alpha), &mut rng);
    // Depth with isolated holes (z = 0: "no depth").
    let mut holes = z.clone();
    for p in [w + 2, 3 * w + 5, 5 * w + 3, 0, w * h - 1] {
        holes[p] = 0.0;
    }
    normal_case("depth with holes", &holes, w, h, None, &mut rng);
    // Random (non-smooth) depth.
    let zr = random(&mut rng, w * h, 1.0, 3.0);
    normal_case("random depth", &zr, w, h, None, &mut rng);
    // A planar depth (a tilted plane n·X = d, so N̂ = n everywhere inside). Tilted, because a
    // fronto-parallel plane puts N̂'s x, y components exactly on the kink of ‖·‖₁ in L_ns.
    let k = intrinsics(w, h);
    let n = [0.3f64, -0.2, -1.0];
    let d = -2.0; // z ≈ 2 at the principal point
    let plane: Vec<f64> = (0..w * h)
        .map(|p| {
            let (u, v) = ((p % w) as f64 + 0.5, (p / w) as f64 + 0.5);
            let r = [(u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0];
            d / (n[0] * r[0] + n[1] * r[1] + n[2] * r[2])
        })
        .collect();
    assert!(plane.iter().all(|&z| z > 0.5 && z < 5.0), "plane in front of the camera");
    normal_case("planar depth", &plane, w, h, None, &mut rng);
}

#[test]
fn all_zero_depth_gives_zero_normals_and_finite_gradients() {
    let (w, h) = (6, 5);
    let k = intrinsics(w, h);
    let z = vec![0.0f64; w * h];
    let nhat = depth_normal(&z, w, h, &k, None);
    assert!(nhat.iter().all(|&v| v == 0.0));
    let up = vec![1.0; w * h * 3];
    let mut g = vec![0.0; w * h];
    depth_normal_backward(&z, w, h, &k, None, &up, &mut g);
    assert!(g.iter().all(|v| v.is_finite()));
}

/// The f32 Image-level APIs agree with the f64 kernels they are built from.
#[test]
fn f32_apis_match_f64_kernels() {
    let mut rng = Rng::new(5);
    let dims = Dims::new(17, 13, 3);
    let (a, b) = pair(&mut rng, dims.len());
    let img = |v: &[f64], c| {
        Image::from_vec(
            dims.width,
            dims.height,
            c,
            v.iter().map(|&x| x as f32).collect(),
        )
        .unwrap()
    };
    let (ra, gb) = (img(&a, 3), img(&b, 3));
    let guide = EdgeGuide::from_gt(&gb).unwrap();
    let out = gs_losses::image_loss(&ra, &gb, Some(&guide), &ImageLossConfig::default()).unwrap();
    // f64 composition.
    let ggt = image_gradient(&b, dims);
    let gr = image_gradient(&a, dims);
    let mut g = vec![0.0; dims.len()];
    let l1v = l1(&a, &b);
    l1_backward(&a, &b, 0.8, &mut g);
    let s = ssim_backward(&a, &b, dims, SsimRegion::Full, -0.2, &mut g).unwrap();
    let mut up = vec![0.0; dims.pixels()];
    let e = edge_l1(&gr.map, &ggt.map, 0.03, Some(&mut up));
    image_gradient_backward(&a, dims, &gr, &up, &mut g);
    let total = 0.8 * l1v + 0.2 * (1.0 - s) + 0.03 * e;
    assert!((out.total - total).abs() < 1e-6, "{} vs {total}", out.total);
    for (x, y) in out.grad_rendered.data().iter().zip(&g) {
        assert!((*x as f64 - y).abs() < 1e-7 + 1e-4 * y.abs(), "{x} vs {y}");
    }
    // Normal losses.
    let (w, h) = (dims.width, dims.height);
    let z = surface(&mut rng, w, h);
    let k = intrinsics(w, h);
    let nhat = depth_normal(&z, w, h, &k, None);
    let nt = rendered_normals(&mut rng, &nhat);
    let cfg = NormalLossConfig {
        tau: 0.1,
        ..Default::default()
    };
    let out = gs_losses::normal_losses(&img(&z, 1), &img(&nt, 3), None, &guide, &k, &cfg).unwrap();
    let delta: Vec<f64> = guide.delta.data().iter().map(|&v| v as f64).collect();
    let mut g_nhat = vec![0.0; w * h * 3];
    let mut g_nt = vec![0.0; w * h * 3];
    let lnc = normal_consistency(
        &nhat,
        &nt,
        &delta,
        0.015,
        Some(&mut g_nhat),
        Some(&mut g_nt),
    );
    let (lns, _) = normal_smoothing(
        &nhat,
        &nt,
        &delta,
        w,
        h,
        0.1,
        NsGate::Above,
        NsPairs::Interior,
        0.3,
        Some(&mut g_nhat),
    );
    let mut g_z = vec![0.0; w * h];
    depth_normal_backward(&z, w, h, &k, None, &g_nhat, &mut g_z);
    assert!(
        (out.l_nc - lnc).abs() < 1e-5 && (out.l_ns - lns).abs() < 1e-5,
        "{} {lnc} {} {lns}",
        out.l_nc,
        out.l_ns
    );
    let scale = g_z.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (x, y) in out.grad_plane_depth.data().iter().zip(&g_z) {
        assert!((*x as f64 - y).abs() < 1e-3 * scale, "{x} vs {y}");
    }
    for (x, y) in out.grad_normal.data().iter().zip(&g_nt) {
        assert!((*x as f64 - y).abs() < 1e-7 + 1e-4 * y.abs());
    }
}
