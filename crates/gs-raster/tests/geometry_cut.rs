//! The geometry cut (`RenderRequest::geometry_cut`): normal and distance blend only while the
//! transmittance exceeds the cut, so the plane depth is the front surface's. Exact values on two
//! layers, tiled == naive, colour untouched, and the forward-only contract.

use gs_core::glam::DVec3;
use gs_core::{Camera, Gaussians, Image, Intrinsics, Rng};
use gs_raster::{OutputGradients, RasterConfig, RasterError, RenderRequest, render, render_naive};

const W: u32 = 33;
const H: u32 = 25;

/// The camera at (0, 0, −3) looking along +z (camera depth = world z + 3).
fn camera() -> Camera {
    Camera::look_at(W, H, Intrinsics::new(30.0, 30.0, 16.5, 12.5), DVec3::new(0.0, 0.0, -3.0), DVec3::ZERO, DVec3::new(0.0, -1.0, 0.0))
        .unwrap()
}

fn logit(p: f32) -> f32 {
    (p / (1.0 - p)).ln()
}

/// Two huge flat Gaussians facing the camera: a semi-transparent front layer (opacity `front`)
/// at depth 3 and an opaque one at depth 4.
fn two_layers(front: f32) -> Gaussians {
    let mut g = Gaussians::with_len(0).unwrap();
    let mut sh = [[0.0f32; 3]; 16];
    sh[0] = [0.5, -0.2, 0.1];
    g.push([0.0, 0.0, 0.0], [3.0, 3.0, -9.0], [1.0, 0.0, 0.0, 0.0], logit(front), sh);
    sh[0] = [-0.4, 0.3, 0.6];
    g.push([0.0, 0.0, 1.0], [3.0, 3.0, -9.0], [1.0, 0.0, 0.0, 0.0], 8.0, sh);
    g
}

fn geometry(cut: f32) -> RenderRequest {
    RenderRequest { normal: true, distance: true, plane_depth: true, geometry_cut: cut, ..RenderRequest::default() }
}

/// The plane depth at the centre pixel.
fn centre_depth(g: &Gaussians, cut: f32) -> f64 {
    let out = render(g, &camera(), &geometry(cut), &RasterConfig::default()).unwrap();
    out.plane_depth.unwrap().get(16, 12, 0) as f64
}

#[test]
fn the_cut_keeps_the_front_layer_of_two() {
    // Front α1 = 0.6 (T 1 → 0.4), back α2 = 0.99 (the cap; T 0.4 → 0.004). Both planes face
    // the camera, so the plane depth is the weighted mean of 3 and 4.
    let g = two_layers(0.6);
    let mean = |w1: f64, w2: f64| (3.0 * w1 + 4.0 * w2) / (w1 + w2);
    let cases = [
        (0.0, mean(0.6, 0.4 * 0.99)), // every contribution
        (0.15, mean(0.6, 0.4 - 0.15)), // the back layer down to T = 0.15
        (0.5, 3.0),                    // the front layer alone, in part (1 − 0.5)
        (0.9, 3.0),
    ];
    for (cut, want) in cases {
        let got = centre_depth(&g, cut);
        assert!((got - want).abs() < 2e-4, "cut {cut}: plane depth {got}, want {want}");
    }
    // A front layer more transparent than the cut leaves the back layer its share.
    let got = centre_depth(&two_layers(0.3), 0.5);
    let want = mean(0.3, 0.7 - 0.5);
    assert!((got - want).abs() < 2e-4, "plane depth {got}, want {want}");
}

#[test]
fn the_cut_changes_only_the_geometry_and_tiles_match_the_naive_render() {
    let mut rng = Rng::new(5);
    let mut g = Gaussians::with_len(0).unwrap();
    for _ in 0..300 {
        let mut sh = [[0.0f32; 3]; 16];
        sh[0] = [rng.normal(), rng.normal(), rng.normal()];
        let q = [rng.normal(), rng.normal(), rng.normal(), rng.normal()];
        let mean = [rng.uniform_range(-1.0, 1.0), rng.uniform_range(-0.8, 0.8), rng.uniform_range(-0.5, 1.5)];
        g.push(mean, [rng.uniform_range(-3.0, -1.5), rng.uniform_range(-3.0, -1.5), -6.0], q, rng.uniform_range(-1.0, 3.0), sh);
    }
    let cam = camera();
    let cfg = RasterConfig::default();
    let all = RenderRequest { geometry_cut: 0.0, ..RenderRequest::all() };
    let full = render(&g, &cam, &all, &cfg).unwrap();
    let cut = render(&g, &cam, &RenderRequest { geometry_cut: 0.3, ..all }, &cfg).unwrap();
    let naive = render_naive(&g, &cam, &RenderRequest { geometry_cut: 0.3, ..all }, &cfg).unwrap();
    let data = |im: &Option<Image>| im.as_ref().unwrap().data().to_vec();
    // Colour, alpha and expected depth do not see the cut.
    assert_eq!(data(&full.color), data(&cut.color));
    assert_eq!(data(&full.alpha), data(&cut.alpha));
    assert_eq!(data(&full.expected_depth), data(&cut.expected_depth));
    assert_ne!(data(&full.plane_depth), data(&cut.plane_depth));
    for (name, a, b) in [("plane depth", &cut.plane_depth, &naive.plane_depth), ("normal", &cut.normal, &naive.normal)] {
        for (x, y) in data(a).iter().zip(data(b)) {
            assert!((x - y).abs() <= 1e-5 * (1.0 + y.abs()), "{name}: tiled {x}, naive {y}");
        }
    }
}

#[test]
fn the_cut_is_forward_only_and_checked() {
    let (g, cam, cfg) = (two_layers(0.6), camera(), RasterConfig::default());
    let req = RenderRequest { color: true, ..geometry(0.2) };
    let out = render(&g, &cam, &req, &cfg).unwrap();
    let ones = |c: usize| Image::filled(W as usize, H as usize, c, 1.0).unwrap();
    let (gc, gz) = (ones(3), ones(1));
    let colour_only = OutputGradients { color: Some(&gc), ..OutputGradients::default() };
    assert!(gs_raster::backward(&g, &cam, &cfg, &out, &colour_only).is_ok());
    let depth = OutputGradients { plane_depth: Some(&gz), ..OutputGradients::default() };
    match gs_raster::backward(&g, &cam, &cfg, &out, &depth) {
        Err(RasterError::InvalidGradients(m)) => assert!(m.contains("geometry_cut"), "{m}"),
        other => panic!("geometry gradients of a cut render: {other:?}"),
    }
    for bad in [-0.1, 1.0, f32::NAN, f32::INFINITY] {
        match render(&g, &cam, &geometry(bad), &cfg) {
            Err(RasterError::InvalidConfig(m)) => assert!(m.contains("geometry_cut"), "{m}"),
            other => panic!("cut {bad}: {:?}", other.map(|_| ())),
        }
    }
}
