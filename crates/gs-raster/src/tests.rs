//! Tests of the CPU rasterizer: gradient checks (f64 central differences on the f32 render),
//! tiled == naive, determinism, conventions, image-level checks and extremes.
//!
//! Gradient-check tolerances: the render is f32, so checks use steps of 1e-3 (1e-2 for the
//! linear SH coefficients and for the plane/expected-depth ratios), a lowered alpha threshold (1e-9, making the render continuous:
//! the 1/255 cut is a jump of up to 1/255·T per pixel, far above what central differences can
//! absorb), opacities in [0.2, 0.7] (no 0.99 cap, no saturation), and per coordinate
//! |a − n| ≤ 3e-3·max|a|(group) + floor + 3e-2·max(|a|, |n|), with the f32 rounding floor
//! 1e-6·‖w ⊙ output‖₂ / eps (w the random loss weights).

use super::*;
use crate::cpu::project::{self, CamParams, Features, Splat, SplatGrad};
use crate::cpu::raster;
use gs_core::{Camera, Gaussians, Image};
use gs_core::glam::{DMat3, DVec3};
use gs_core::gradcheck::{GradCheck, check_gradient};
use gs_core::{Intrinsics, Rng};

fn camera(w: u32, h: u32, f: f64) -> Camera {
    Camera::look_at(
        w,
        h,
        Intrinsics::new(f, f * 1.05, w as f64 * 0.5 + 0.3, h as f64 * 0.5 - 0.2),
        DVec3::new(0.4, -0.3, -4.0),
        DVec3::new(0.1, 0.05, 0.0),
        DVec3::new(0.1, -1.0, 0.0),
    )
    .unwrap()
}

fn random_quat(rng: &mut Rng) -> [f32; 4] {
    [rng.normal(), rng.normal(), rng.normal(), rng.normal()]
}

/// `n` Gaussians near the origin (seen by [`camera`]), with distinct scales (smallest axis well
/// defined), normals not edge-on, opacities in [0.2, 0.7].
fn random_scene(n: usize, degree: u32, seed: u64, spread: f32) -> Gaussians {
    let mut rng = Rng::new(seed);
    let cam = camera(32, 32, 40.0);
    let mut g = Gaussians::with_len(0).unwrap();
    g.sh_degree = degree;
    while g.len() < n {
        let mean = [
            rng.uniform_range(-spread, spread),
            rng.uniform_range(-spread, spread),
            rng.uniform_range(-0.5, 0.5),
        ];
        let ls = [
            rng.uniform_range(-2.0, -1.4),
            rng.uniform_range(-2.0, -1.4),
            rng.uniform_range(-3.5, -2.8),
        ];
        let q = random_quat(&mut rng);
        // Reject normals close to edge-on (the flip is a discontinuity) and near-tied scales.
        let r = gs_core::gaussians::rotation_matrix(q);
        let n_w = r.col(2).as_dvec3();
        let to_cam =
            (cam.center() - DVec3::new(mean[0] as f64, mean[1] as f64, mean[2] as f64)).normalize();
        if n_w.dot(to_cam).abs() < 0.3 || (ls[0] - ls[1]).abs() < 0.05 {
            continue;
        }
        let o: f32 = rng.uniform_range(0.2, 0.7);
        let mut sh = [[0.0f32; 3]; 16];
        for (k, c) in sh.iter_mut().enumerate() {
            for v in c.iter_mut() {
                *v = if k == 0 {
                    rng.uniform_range(-0.8, 1.2)
                } else {
                    0.3 * rng.normal()
                };
            }
        }
        g.push(mean, ls, q, gs_core::gaussians::inverse_sigmoid(o), sh);
    }
    g
}

fn test_config() -> RasterConfig {
    RasterConfig {
        alpha_threshold: 1e-9,
        background: [0.2, 0.5, 0.9],
        ..RasterConfig::default()
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Channel {
    Color,
    Alpha,
    Normal,
    Distance,
    PlaneDepth,
    ExpectedDepth,
}

#[derive(Clone, Copy, Debug)]
enum Group {
    Means,
    LogScales,
    Rotations,
    Opacity,
    Sh,
}

fn get_group(g: &Gaussians, group: Group) -> Vec<f64> {
    let f = |v: &[f32]| v.iter().map(|&x| x as f64).collect::<Vec<_>>();
    match group {
        Group::Means => f(g.means.as_flattened()),
        Group::LogScales => f(g.log_scales.as_flattened()),
        Group::Rotations => f(g.rotations.as_flattened()),
        Group::Opacity => f(&g.opacity_logits),
        Group::Sh => f(g.sh_flat()),
    }
}

fn set_group(g: &mut Gaussians, group: Group, x: &[f64]) {
    let dst: &mut [f32] = match group {
        Group::Means => g.means.as_flattened_mut(),
        Group::LogScales => g.log_scales.as_flattened_mut(),
        Group::Rotations => g.rotations.as_flattened_mut(),
        Group::Opacity => &mut g.opacity_logits,
        Group::Sh => g.sh_flat_mut(),
    };
    for (d, &v) in dst.iter_mut().zip(x) {
        *d = v as f32;
    }
}

fn grad_group(gr: &GaussianGradients, group: Group) -> Vec<f64> {
    let f = |v: &[f32]| v.iter().map(|&x| x as f64).collect::<Vec<_>>();
    match group {
        Group::Means => f(gr.means.as_flattened()),
        Group::LogScales => f(gr.log_scales.as_flattened()),
        Group::Rotations => f(gr.rotations.as_flattened()),
        Group::Opacity => f(&gr.opacity_logits),
        Group::Sh => f(gr.sh.as_flattened().as_flattened()),
    }
}

fn request_for(ch: Channel) -> RenderRequest {
    let mut r = RenderRequest {
        color: false,
        alpha: true,
        ..RenderRequest::default()
    };
    match ch {
        Channel::Color => r.color = true,
        Channel::Alpha => {}
        Channel::Normal => r.normal = true,
        Channel::Distance => r.distance = true,
        Channel::PlaneDepth => r.plane_depth = true,
        Channel::ExpectedDepth => r.expected_depth = true,
    }
    r
}

fn channel_image(out: &RenderOutput, ch: Channel) -> &Image {
    match ch {
        Channel::Color => out.color.as_ref(),
        Channel::Alpha => out.alpha.as_ref(),
        Channel::Normal => out.normal.as_ref(),
        Channel::Distance => out.distance.as_ref(),
        Channel::PlaneDepth => out.plane_depth.as_ref(),
        Channel::ExpectedDepth => out.expected_depth.as_ref(),
    }
    .unwrap()
}

/// Random loss weights for a channel; plane and expected depth only where the pixel is well
/// covered (the depth guard is a discontinuity and 1/A is steep near A = 0).
fn weights(out: &RenderOutput, ch: Channel, seed: u64) -> Image {
    let img = channel_image(out, ch);
    let alpha = out.alpha.as_ref().unwrap();
    let max_a = alpha.data().iter().fold(0.0f32, |m, &v| m.max(v));
    let mut rng = Rng::new(seed);
    let mut wimg = Image::new(img.width(), img.height(), img.channels()).unwrap();
    for y in 0..img.height() {
        for x in 0..img.width() {
            let ok = match ch {
                Channel::PlaneDepth => alpha.get(x, y, 0) > 0.3 * max_a,
                Channel::ExpectedDepth => alpha.get(x, y, 0) > 0.05 * max_a,
                _ => true,
            };
            for c in 0..img.channels() {
                wimg.set(x, y, c, if ok { rng.normal() } else { 0.0 });
            }
        }
    }
    wimg
}

fn loss(out: &RenderOutput, ch: Channel, w: &Image) -> f64 {
    let img = channel_image(out, ch);
    img.data()
        .iter()
        .zip(w.data())
        .map(|(&a, &b)| a as f64 * b as f64)
        .sum()
}

fn gradcheck_scene(g: &Gaussians, cam: &Camera, channels: &[Channel], groups: &[Group], seed: u64) {
    let cfg = test_config();
    for &ch in channels {
        let req = request_for(ch);
        let out = render(g, cam, &req, &cfg).unwrap();
        let w = weights(&out, ch, seed);
        let mut og = OutputGradients::default();
        match ch {
            Channel::Color => og.color = Some(&w),
            Channel::Alpha => og.alpha = Some(&w),
            Channel::Normal => og.normal = Some(&w),
            Channel::Distance => og.distance = Some(&w),
            Channel::PlaneDepth => og.plane_depth = Some(&w),
            Channel::ExpectedDepth => og.expected_depth = Some(&w),
        }
        let grads = backward(g, cam, &cfg, &out, &og).unwrap();
        for &group in groups {
            let x = get_group(g, group);
            let analytic = grad_group(&grads, group);
            let max_a = analytic.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(analytic.iter().all(|v| v.is_finite()));
            let mut gg = g.clone();
            let f = |x: &[f64]| {
                set_group(&mut gg, group, x);
                let o = render(&gg, cam, &req, &cfg).unwrap();
                loss(&o, ch, &w)
            };
            // Plane and expected depth are ratios of f32 sums (noisier): larger steps.
            let eps = if matches!(group, Group::Sh)
                || matches!(ch, Channel::PlaneDepth | Channel::ExpectedDepth)
            {
                1e-2
            } else {
                1e-3
            };
            // f32 rounding floor: ~1e-7 relative error per pixel term, random across pixels, over
            // a central difference of step eps (×16 margin over f32 epsilon: ratios amplify it).
            let l2 = channel_image(&out, ch)
                .data()
                .iter()
                .zip(w.data())
                .map(|(&a, &b)| (a as f64 * b as f64).powi(2))
                .sum::<f64>()
                .sqrt();
            let floor = 1e-6 * l2 / eps;
            let opts = GradCheck {
                eps,
                rtol: 3e-2,
                atol: 3e-3 * max_a + floor,
                indices: None,
            };
            let report = check_gradient(f, &x, &analytic, &opts);
            assert!(
                report.is_ok(),
                "{ch:?} / {group:?} (n = {}): {report:?}, floor {floor}",
                g.len()
            );
            // Guard against vacuous checks: the group must have a non-zero gradient unless the
            // channel cannot depend on it.
            let independent = matches!(
                (ch, group),
                (
                    Channel::Alpha
                        | Channel::Normal
                        | Channel::Distance
                        | Channel::PlaneDepth
                        | Channel::ExpectedDepth,
                    Group::Sh
                ) | (Channel::Normal, Group::Means)
                    | (
                        Channel::Normal | Channel::Distance | Channel::PlaneDepth,
                        Group::LogScales
                    )
                    | (Channel::PlaneDepth, Group::Opacity)
            );
            if !independent {
                assert!(max_a > 1e-6, "{ch:?} / {group:?}: zero gradient");
            }
        }
    }
}

const ALL_CHANNELS: [Channel; 6] = [
    Channel::Color,
    Channel::Alpha,
    Channel::Normal,
    Channel::Distance,
    Channel::PlaneDepth,
    Channel::ExpectedDepth,
];
const ALL_GROUPS: [Group; 5] = [
    Group::Means,
    Group::LogScales,
    Group::Rotations,
    Group::Opacity,
    Group::Sh,
];

#[test]
fn gradcheck_one_gaussian_all_channels_all_groups() {
    let cam = camera(32, 32, 40.0);
    let g = random_scene(1, 3, 1, 0.2);
    gradcheck_scene(&g, &cam, &ALL_CHANNELS, &ALL_GROUPS, 10);
}

#[test]
fn gradcheck_four_gaussians_all_channels_all_groups() {
    let cam = camera(32, 32, 40.0);
    let g = random_scene(4, 2, 2, 0.8);
    gradcheck_scene(&g, &cam, &ALL_CHANNELS, &ALL_GROUPS, 11);
}

#[test]
fn gradcheck_sixteen_gaussians_all_channels_all_groups() {
    let cam = camera(32, 32, 40.0);
    let g = random_scene(16, 1, 3, 1.2);
    gradcheck_scene(&g, &cam, &ALL_CHANNELS, &ALL_GROUPS, 12);
}

#[test]
fn gradcheck_antialiased_and_clamped_jacobian() {
    // Antialiased compensation on (with 3DGS' low-pass filter and Mip-Splatting's), and a
    // Gaussian beyond 1.3·tan(fov/2) whose tail still reaches the image (Jacobian clamp active).
    for low_pass in [crate::LOW_PASS, 0.1] {
        gradcheck_antialiased(low_pass);
    }
}

fn gradcheck_antialiased(low_pass: f32) {
    let cam = camera(32, 32, 40.0);
    let mut g = random_scene(3, 1, 4, 0.6);
    g.means[0] = [3.2, 0.0, 0.0];
    g.log_scales[0] = [0.2, 0.0, -2.0];
    let cfg = RasterConfig {
        antialiased: true,
        low_pass,
        ..test_config()
    };
    let cp = CamParams::new(&cam);
    let t = cp.r * gs_core::glam::Vec3::from(g.means[0]) + cp.t;
    assert!(
        (t.x / t.z).abs() > cp.lim_x,
        "test setup: the Jacobian clamp must be active"
    );
    let req = RenderRequest::all();
    let out = render(&g, &cam, &req, &cfg).unwrap();
    assert!(out.radii[0] > 0);
    let w = weights(&out, Channel::Color, 5);
    let wa = weights(&out, Channel::Alpha, 6);
    let grads = backward(
        &g,
        &cam,
        &cfg,
        &out,
        &OutputGradients {
            color: Some(&w),
            alpha: Some(&wa),
            ..Default::default()
        },
    )
    .unwrap();
    for group in ALL_GROUPS {
        let x = get_group(&g, group);
        let analytic = grad_group(&grads, group);
        let max_a = analytic.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let mut gg = g.clone();
        let f = |x: &[f64]| {
            set_group(&mut gg, group, x);
            let o = render(&gg, &cam, &req, &cfg).unwrap();
            loss(&o, Channel::Color, &w) + loss(&o, Channel::Alpha, &wa)
        };
        let eps = if matches!(group, Group::Sh) {
            1e-2
        } else {
            1e-3
        };
        let opts = GradCheck {
            eps,
            rtol: 3e-2,
            atol: 3e-3 * max_a + 1e-6,
            indices: None,
        };
        let report = check_gradient(f, &x, &analytic, &opts);
        assert!(report.is_ok(), "low-pass {low_pass} px², {group:?}: {report:?}");
    }
}

/// Gradients of the 2D splat quantities (mean2d, conic, opacity, features) from the tile
/// backward against central differences of the tile forward; this checks the densification
/// accumulator `mean2d` directly.
#[test]
fn splat_level_gradients_match_finite_differences() {
    let cam = camera(32, 32, 40.0);
    let g = random_scene(6, 0, 7, 0.7);
    let cfg = test_config();
    let req = RenderRequest::all();
    let out = render(&g, &cam, &req, &cfg).unwrap();
    let wc = weights(&out, Channel::Color, 1);
    let wa = weights(&out, Channel::Alpha, 2);
    let wn = weights(&out, Channel::Normal, 3);
    let wd = weights(&out, Channel::Distance, 4);
    let og = OutputGradients {
        color: Some(&wc),
        alpha: Some(&wa),
        normal: Some(&wn),
        distance: Some(&wd),
        ..Default::default()
    };
    let grads = backward(&g, &cam, &cfg, &out, &og).unwrap();
    // Re-run the tile forward with perturbed splats.
    let st = out.state.cpu().expect("the CPU render returns a CPU state");
    let cp = CamParams::new(&cam);
    let eval = |splats: &[Splat], feats: &[Features]| -> f64 {
        let ctx = raster::Ctx {
            splats,
            features: feats,
            bins: &st.bins,
            width: 32,
            height: 32,
            tiles_x: cp.tiles_x,
            threshold: cfg.alpha_threshold,
            geometry_cut: 0.0,
        };
        let tiles = raster::forward_tiles(&ctx, true, true, false, false);
        let mut l = 0.0f64;
        for (tile, to) in tiles.iter().enumerate() {
            let (x0, y0) = ((tile % 2) * 16, (tile / 2) * 16);
            for (lp, a) in to.acc.iter().enumerate() {
                let (x, y) = (x0 + lp % 16, y0 + lp / 16);
                let t = to.final_t[lp];
                for c in 0..3 {
                    l += (a[c] + t * cfg.background[c]) as f64 * wc.get(x, y, c) as f64;
                    l += a[3 + c] as f64 * wn.get(x, y, c) as f64;
                }
                l += (1.0 - t) as f64 * wa.get(x, y, 0) as f64;
                l += a[6] as f64 * wd.get(x, y, 0) as f64;
            }
        }
        l
    };
    for i in 0..g.len() {
        let (sx, sy) = (16.0f64, 16.0f64);
        let analytic = [
            grads.mean2d[i][0] as f64 / sx,
            grads.mean2d[i][1] as f64 / sy,
        ];
        let k = st.order.iter().position(|&o| o as usize == i).unwrap();
        let x0 = [st.splats[k].x as f64, st.splats[k].y as f64];
        let f = |x: &[f64]| {
            let mut s = st.splats.clone();
            s[k].x = x[0] as f32;
            s[k].y = x[1] as f32;
            eval(&s, &st.features)
        };
        let max_a = analytic[0].abs().max(analytic[1].abs());
        let r = check_gradient(
            f,
            &x0,
            &analytic,
            &GradCheck {
                eps: 1e-2,
                rtol: 3e-2,
                atol: 1e-3 * max_a + 1e-5,
                indices: None,
            },
        );
        assert!(r.is_ok(), "mean2d of {i}: {r:?}");
        // The absolute accumulator bounds the signed one.
        assert!(
            grads.mean2d_abs[i][0] >= grads.mean2d[i][0].abs()
                && grads.mean2d_abs[i][1] >= grads.mean2d[i][1].abs()
        );
        assert!(grads.mean2d_abs_norm(i) >= grads.mean2d_norm(i));
    }
}

/// The projection backward against central differences of the projection forward, with a
/// random linear functional of every projected quantity.
#[test]
fn projection_backward_matches_finite_differences() {
    let cam = camera(32, 32, 40.0);
    let cp = CamParams::new(&cam);
    for (seed, aa) in [(21u64, false), (22, true)] {
        let g = random_scene(5, 3, seed, 0.8);
        let cfg = RasterConfig {
            antialiased: aa,
            ..test_config()
        };
        let mut rng = Rng::new(seed + 100);
        for i in 0..g.len() {
            let sg = SplatGrad {
                xy: [rng.normal(), rng.normal()],
                conic: [
                    rng.normal() * 10.0,
                    rng.normal() * 10.0,
                    rng.normal() * 10.0,
                ],
                opacity: rng.normal(),
                features: std::array::from_fn(|_| rng.normal()),
                abs_xy: [0.0; 2],
            };
            let pg = project::project_backward(&g, i, &cp, &cfg, &sg).unwrap();
            let lin = |g: &Gaussians| -> f64 {
                let p = project::project(g, i, &cp, &cfg).unwrap();
                let s = p.splat;
                let mut l = sg.xy[0] as f64 * s.x as f64 + sg.xy[1] as f64 * s.y as f64;
                l += sg.conic[0] as f64 * s.ca as f64
                    + sg.conic[1] as f64 * s.cb as f64
                    + sg.conic[2] as f64 * s.cc as f64;
                l += sg.opacity as f64 * s.opacity as f64;
                for k in 0..8 {
                    l += sg.features[k] as f64 * p.features[k] as f64;
                }
                l
            };
            let mut x: Vec<f64> = g.means[i]
                .iter()
                .chain(&g.log_scales[i])
                .chain(&g.rotations[i])
                .map(|&v| v as f64)
                .collect();
            x.push(g.opacity_logits[i] as f64);
            let mut analytic: Vec<f64> = pg
                .mean
                .iter()
                .chain(&pg.log_scale)
                .chain(&pg.rotation)
                .map(|&v| v as f64)
                .collect();
            analytic.push(pg.opacity_logit as f64);
            let mut gg = g.clone();
            let f = |x: &[f64]| {
                for k in 0..3 {
                    gg.means[i][k] = x[k] as f32;
                    gg.log_scales[i][k] = x[3 + k] as f32;
                }
                for k in 0..4 {
                    gg.rotations[i][k] = x[6 + k] as f32;
                }
                gg.opacity_logits[i] = x[10] as f32;
                lin(&gg)
            };
            let max_a = analytic.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let r = check_gradient(
                f,
                &x,
                &analytic,
                &GradCheck {
                    eps: 1e-3,
                    rtol: 2e-2,
                    atol: 2e-3 * max_a,
                    indices: None,
                },
            );
            assert!(r.is_ok(), "Gaussian {i}, antialiased {aa}: {r:?}");
        }
    }
}

#[test]
fn tiled_matches_naive_reference() {
    for (seed, n, w, h) in [
        (31u64, 60usize, 50u32, 37u32),
        (32, 150, 64, 48),
        (33, 20, 17, 16),
    ] {
        let cam = camera(w, h, w as f64 * 1.1);
        let mut g = random_scene(n, 2, seed, 1.5);
        // A few opaque ones so that saturation and the 0.99 cap occur.
        for i in 0..n / 5 {
            g.opacity_logits[i] = 6.0;
        }
        for cfg in [
            RasterConfig::default(),
            RasterConfig {
                antialiased: true,
                background: [1.0, 0.0, 0.5],
                ..Default::default()
            },
        ] {
            let req = RenderRequest::all();
            let a = render(&g, &cam, &req, &cfg).unwrap();
            let b = render_naive(&g, &cam, &req, &cfg).unwrap();
            let pairs = [
                (&a.color, &b.color),
                (&a.alpha, &b.alpha),
                (&a.normal, &b.normal),
                (&a.distance, &b.distance),
                (&a.plane_depth, &b.plane_depth),
                (&a.expected_depth, &b.expected_depth),
            ];
            for (k, (x, y)) in pairs.iter().enumerate() {
                let (x, y) = (x.as_ref().unwrap(), y.as_ref().unwrap());
                let scale = y.data().iter().fold(1.0f32, |m, v| m.max(v.abs()));
                let err = x
                    .data()
                    .iter()
                    .zip(y.data())
                    .fold(0.0f32, |m, (p, q)| m.max((p - q).abs()));
                assert!(
                    err <= 1e-5 * scale,
                    "seed {seed} output {k}: max error {err}"
                );
            }
            assert_eq!(a.observed, b.observed);
            assert_eq!(a.radii, b.radii);
            assert!(a.observed.as_ref().unwrap().iter().any(|&c| c > 0));
        }
    }
}

#[test]
fn deterministic_across_runs_and_thread_counts() {
    let cam = camera(70, 50, 60.0);
    let g = random_scene(300, 3, 41, 1.5);
    let cfg = RasterConfig::default();
    let req = RenderRequest::all();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let out = render(&g, &cam, &req, &cfg).unwrap();
            let w3 = Image::filled(70, 50, 3, 0.7).unwrap();
            let w1 = Image::filled(70, 50, 1, -0.3).unwrap();
            let og = OutputGradients {
                color: Some(&w3),
                alpha: Some(&w1),
                normal: Some(&w3),
                distance: Some(&w1),
                plane_depth: Some(&w1),
                expected_depth: Some(&w1),
            ..OutputGradients::default()
            };
            let gr = backward(&g, &cam, &cfg, &out, &og).unwrap();
            (
                out.color.unwrap(),
                out.plane_depth.unwrap(),
                out.observed.unwrap(),
                gr,
            )
        })
    };
    let a = run(1);
    let b = run(2);
    let c = run(2);
    let bits = |im: &Image| im.data().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a.0), bits(&b.0));
    assert_eq!(bits(&a.1), bits(&b.1));
    assert_eq!(a.2, b.2);
    assert_eq!(bits(&b.0), bits(&c.0));
    // Gradients compared bitwise too (tile-ordered merge).
    let gb = |g: &GaussianGradients| {
        g.means
            .as_flattened()
            .iter()
            .chain(g.sh.as_flattened().as_flattened())
            .chain(g.mean2d_abs.as_flattened())
            .map(|v| v.to_bits())
            .collect::<Vec<_>>()
    };
    assert_eq!(gb(&a.3), gb(&b.3));
    assert_eq!(gb(&b.3), gb(&c.3));
}

/// An identity camera: camera frame = world frame.
fn identity_camera(w: u32, h: u32, f: f64, cx: f64, cy: f64) -> Camera {
    Camera::new(
        w,
        h,
        Intrinsics::new(f, f, cx, cy),
        DMat3::IDENTITY,
        DVec3::ZERO,
    )
    .unwrap()
}

#[test]
fn pixel_centre_convention() {
    // A tiny isotropic Gaussian projected at (i + 0.5, j + 0.5) peaks at pixel (i, j).
    let cam = identity_camera(20, 16, 30.0, 9.7, 8.3);
    for (i, j) in [(0u32, 0u32), (5, 7), (19, 15), (10, 3)] {
        let z = 2.0f64;
        let (u, v) = (i as f64 + 0.5, j as f64 + 0.5);
        let mean = [
            ((u - 9.7) / 30.0 * z) as f32,
            ((v - 8.3) / 30.0 * z) as f32,
            z as f32,
        ];
        let mut g = Gaussians::with_len(1).unwrap();
        g.means[0] = mean;
        g.log_scales[0] = [-4.0; 3];
        g.opacity_logits[0] = 0.0;
        let out = render(
            &g,
            &cam,
            &RenderRequest::default(),
            &RasterConfig::default(),
        )
        .unwrap();
        let a = out.alpha.unwrap();
        let mut best = (0, 0, -1.0f32);
        for y in 0..16 {
            for x in 0..20 {
                if a.get(x, y, 0) > best.2 {
                    best = (x, y, a.get(x, y, 0));
                }
            }
        }
        assert_eq!((best.0 as u32, best.1 as u32), (i, j));
        // Peak α = o·exp(0) = 0.5 exactly at the centre.
        assert!((best.2 - 0.5).abs() < 1e-6);
    }
}

#[test]
fn single_gaussian_renders_the_analytic_footprint() {
    // Fronto-parallel anisotropic Gaussian at depth z: Σ' = diag((f sx/z)², (f sy/z)²) + 0.3.
    let (f, z) = (50.0f64, 3.0f64);
    let cam = identity_camera(48, 40, f, 23.2, 20.9);
    let mut g = Gaussians::with_len(1).unwrap();
    g.means[0] = [0.05, -0.03, z as f32];
    g.log_scales[0] = [(-2.5f32), (-2.1f32), -6.0];
    let o = 0.8f64;
    g.opacity_logits[0] = gs_core::gaussians::inverse_sigmoid(o as f32);
    let out = render(
        &g,
        &cam,
        &RenderRequest::default(),
        &RasterConfig::default(),
    )
    .unwrap();
    let a = out.alpha.unwrap();
    let sx = (-2.5f64).exp() * f / z;
    let sy = (-2.1f64).exp() * f / z;
    let (vx, vy) = (sx * sx + 0.3, sy * sy + 0.3);
    let (mx, my) = (f * 0.05 / z + 23.2, f * -0.03 / z + 20.9);
    let mut checked = 0;
    for y in 0..40 {
        for x in 0..48 {
            let (dx, dy) = (x as f64 + 0.5 - mx, y as f64 + 0.5 - my);
            let want = o * (-0.5 * (dx * dx / vx + dy * dy / vy)).exp();
            let got = a.get(x, y, 0) as f64;
            if want >= 1.0 / 255.0 + 1e-5 {
                assert!((got - want).abs() < 2e-6, "({x},{y}) {got} vs {want}");
                checked += 1;
            } else if want < 1.0 / 255.0 - 1e-5 {
                assert_eq!(got, 0.0, "({x},{y}) below the threshold must be skipped");
            }
        }
    }
    assert!(checked > 50);
    // Opacity-aware radius: ceil(sqrt(2 ln(255 o)) · sqrt(λ_max)).
    let want_r = ((2.0 * (255.0 * o).ln()).sqrt() * vx.max(vy).sqrt()).ceil() as u32;
    assert_eq!(out.radii[0], want_r);
}

#[test]
fn opacity_and_depth_ordering() {
    let cam = identity_camera(16, 16, 20.0, 8.0, 8.0);
    let make = |z_red: f32, z_blue: f32| {
        let mut g = Gaussians::with_len(2).unwrap();
        g.means[0] = [0.0, 0.0, z_red];
        g.means[1] = [0.0, 0.0, z_blue];
        for i in 0..2 {
            g.log_scales[i] = [1.0, 1.0, -5.0]; // covers the image, α ≈ o everywhere
        }
        g.opacity_logits[0] = gs_core::gaussians::inverse_sigmoid(0.6);
        g.opacity_logits[1] = gs_core::gaussians::inverse_sigmoid(0.5);
        g.sh[0][0] = [
            gs_core::gaussians::rgb_to_sh_dc(1.0),
            gs_core::gaussians::rgb_to_sh_dc(0.0),
            gs_core::gaussians::rgb_to_sh_dc(0.0),
        ];
        g.sh[1][0] = [
            gs_core::gaussians::rgb_to_sh_dc(0.0),
            gs_core::gaussians::rgb_to_sh_dc(0.0),
            gs_core::gaussians::rgb_to_sh_dc(1.0),
        ];
        g
    };
    let cfg = RasterConfig {
        background: [0.0, 1.0, 0.0],
        ..Default::default()
    };
    let at_centre = |g: &Gaussians| {
        let c = render(g, &cam, &RenderRequest::default(), &cfg)
            .unwrap()
            .color
            .unwrap();
        [c.get(8, 8, 0), c.get(8, 8, 1), c.get(8, 8, 2)]
    };
    let front_red = at_centre(&make(2.0, 3.0));
    let g_red = 0.6 * (-0.5f32 * 0.0).exp();
    assert!((front_red[0] - g_red).abs() < 2e-3, "{front_red:?}");
    assert!((front_red[2] - 0.5 * 0.4).abs() < 2e-3);
    assert!((front_red[1] - 0.4 * 0.5).abs() < 2e-3); // background through both
    let front_blue = at_centre(&make(3.0, 2.0));
    assert!(
        (front_blue[2] - 0.5).abs() < 2e-3 && (front_blue[0] - 0.6 * 0.5).abs() < 2e-3,
        "{front_blue:?}"
    );
}

#[test]
fn fronto_parallel_plane_gives_exact_plane_depth_and_normals() {
    // A textured plane of flat Gaussians (z = 0 in the world), seen straight on and obliquely.
    let mut rng = Rng::new(9);
    let mut g = Gaussians::with_len(0).unwrap();
    for iy in -12..=12 {
        for ix in -12..=12 {
            let mut sh = [[0.0f32; 3]; 16];
            sh[0] = [rng.normal(), rng.normal(), rng.normal()];
            let q = [1.0, 0.0, 0.0, rng.uniform_range(-0.3, 0.3)]; // spin about the normal
            g.push(
                [ix as f32 * 0.1, iy as f32 * 0.1, 0.0],
                [-2.3, -2.3, -9.0],
                q,
                4.0,
                sh,
            );
        }
    }
    let cfg = RasterConfig::default();
    let req = RenderRequest {
        plane_depth: true,
        normal: true,
        distance: true,
        ..Default::default()
    };
    for (eye, target) in [
        (DVec3::new(0.0, 0.0, -3.0), DVec3::ZERO),
        (DVec3::new(0.7, -0.5, -2.5), DVec3::new(0.1, 0.1, 0.0)),
    ] {
        let cam = Camera::look_at(
            48,
            40,
            Intrinsics::new(40.0, 40.0, 24.0, 20.0),
            eye,
            target,
            DVec3::new(0.0, -1.0, 0.0),
        )
        .unwrap();
        let out = render(&g, &cam, &req, &cfg).unwrap();
        let (z, n, a) = (
            out.plane_depth.unwrap(),
            out.normal.unwrap(),
            out.alpha.unwrap(),
        );
        let n_want = cam.rotation * DVec3::new(0.0, 0.0, -1.0);
        let mut checked = 0;
        for y in 0..40 {
            for x in 0..48 {
                if a.get(x, y, 0) < 0.5 {
                    continue;
                }
                // Exact depth: intersect the pixel ray with the plane z = 0 (f64).
                let ray_c = cam.ray(x as f64 + 0.5, y as f64 + 0.5);
                let ray_w = cam.rotation.transpose() * ray_c;
                let c = cam.center();
                let s = -c.z / ray_w.z; // C + s·ray_w on z = 0; camera depth = s (ray z = 1)
                let got = z.get(x, y, 0) as f64;
                assert!(
                    ((got - s) / s).abs() < 1e-4,
                    "({x},{y}) plane depth {got} vs {s}"
                );
                let nv = DVec3::new(
                    n.get(x, y, 0) as f64,
                    n.get(x, y, 1) as f64,
                    n.get(x, y, 2) as f64,
                );
                assert!(
                    (nv.normalize() - n_want).length() < 1e-5,
                    "normal {nv:?} vs {n_want:?}"
                );
                checked += 1;
            }
        }
        assert!(checked > 500, "{checked}");
        if eye.x == 0.0 {
            assert!((n_want - DVec3::new(0.0, 0.0, -1.0)).length() < 1e-12);
        }
    }
}

#[test]
fn observed_counts_follow_the_half_transmittance_rule() {
    let cam = identity_camera(16, 16, 20.0, 8.0, 8.0);
    let mut g = Gaussians::with_len(3).unwrap();
    for i in 0..3 {
        g.means[i] = [0.0, 0.0, 2.0 + i as f32];
        g.log_scales[i] = [2.0, 2.0, -5.0];
    }
    g.opacity_logits = vec![
        gs_core::gaussians::inverse_sigmoid(0.3),
        gs_core::gaussians::inverse_sigmoid(0.3),
        gs_core::gaussians::inverse_sigmoid(0.9),
    ];
    // T before: 1, 0.7, 0.49 → the third is not observed.
    let out = render(
        &g,
        &cam,
        &RenderRequest {
            observed: true,
            ..Default::default()
        },
        &RasterConfig::default(),
    )
    .unwrap();
    assert_eq!(out.observed.unwrap(), vec![256, 256, 0]);
}

fn assert_finite_grads(gr: &GaussianGradients) {
    assert!(gr.means.as_flattened().iter().all(|v| v.is_finite()));
    assert!(gr.log_scales.as_flattened().iter().all(|v| v.is_finite()));
    assert!(gr.rotations.as_flattened().iter().all(|v| v.is_finite()));
    assert!(gr.opacity_logits.iter().all(|v| v.is_finite()));
    assert!(
        gr.sh
            .as_flattened()
            .as_flattened()
            .iter()
            .all(|v| v.is_finite())
    );
    assert!(gr.mean2d.as_flattened().iter().all(|v| v.is_finite()));
    assert!(gr.mean2d_abs.as_flattened().iter().all(|v| v.is_finite()));
}

fn render_and_backward_finite(g: &Gaussians, cam: &Camera, cfg: &RasterConfig) -> RenderOutput {
    let req = RenderRequest::all();
    let out = render(g, cam, &req, cfg).unwrap();
    for im in [
        &out.color,
        &out.alpha,
        &out.normal,
        &out.distance,
        &out.plane_depth,
        &out.expected_depth,
    ] {
        assert!(im.as_ref().unwrap().is_finite());
    }
    let (w, h) = (cam.width as usize, cam.height as usize);
    let w3 = Image::filled(w, h, 3, 1.0).unwrap();
    let w1 = Image::filled(w, h, 1, 1.0).unwrap();
    let og = OutputGradients {
        color: Some(&w3),
        alpha: Some(&w1),
        normal: Some(&w3),
        distance: Some(&w1),
        plane_depth: Some(&w1),
        expected_depth: Some(&w1),
        ..OutputGradients::default()
    };
    let gr = backward(g, cam, cfg, &out, &og).unwrap();
    assert_finite_grads(&gr);
    out
}

#[test]
fn extremes_give_finite_outputs_and_gradients() {
    let cam = camera(40, 30, 40.0);
    let base = random_scene(1, 3, 51, 0.3);
    type Edit = Box<dyn Fn(&mut Gaussians)>;
    let cases: Vec<(&str, Edit)> = vec![
        (
            "needle log-scale -20",
            Box::new(|g| g.log_scales[0] = [-20.0, -20.0, -20.0]),
        ),
        (
            "huge log-scale +10",
            Box::new(|g| g.log_scales[0] = [10.0, 10.0, 10.0]),
        ),
        (
            "mixed -20/+10",
            Box::new(|g| g.log_scales[0] = [10.0, -20.0, 0.0]),
        ),
        (
            "equal scales",
            Box::new(|g| g.log_scales[0] = [-1.0, -1.0, -1.0]),
        ),
        ("zero quaternion", Box::new(|g| g.rotations[0] = [0.0; 4])),
        (
            "tiny quaternion",
            Box::new(|g| g.rotations[0] = [1e-30, 0.0, 1e-30, 0.0]),
        ),
        (
            "non-normalised quaternion",
            Box::new(|g| g.rotations[0] = [30.0, -2.0, 5.0, 1.0]),
        ),
        ("logit +30", Box::new(|g| g.opacity_logits[0] = 30.0)),
        ("logit -30", Box::new(|g| g.opacity_logits[0] = -30.0)),
        ("far away 1e5", Box::new(|g| g.means[0] = [1e5, -1e5, 1e5])),
        ("at the border", Box::new(|g| g.means[0] = [2.2, 1.6, 0.0])),
        (
            "far outside the frustum",
            Box::new(|g| g.means[0] = [50.0, 0.0, -3.0]),
        ),
        ("huge SH", Box::new(|g| g.sh[0] = [[1e6; 3]; 16])),
    ];
    for (name, edit) in &cases {
        for aa in [false, true] {
            let mut g = base.clone();
            g.push(
                [0.0, 0.0, 0.3],
                [-1.5, -1.6, -3.0],
                [1.0, 0.2, 0.0, 0.0],
                1.0,
                [[0.1; 3]; 16],
            );
            edit(&mut g);
            let cfg = RasterConfig {
                antialiased: aa,
                ..Default::default()
            };
            let out = std::panic::catch_unwind(|| render_and_backward_finite(&g, &cam, &cfg));
            assert!(
                out.is_ok(),
                "case {name} (antialiased {aa}) panicked or was not finite"
            );
        }
    }
}

#[test]
fn behind_camera_and_near_plane_are_culled() {
    let cam = identity_camera(16, 16, 20.0, 8.0, 8.0);
    let mut g = Gaussians::with_len(4).unwrap();
    g.means = vec![
        [0.0, 0.0, -1.0],
        [0.0, 0.0, 0.01],
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0100001],
    ];
    for i in 0..4 {
        g.log_scales[i] = [-6.0; 3];
    }
    let cfg = RasterConfig::default();
    let out = render_and_backward_finite(&g, &cam, &cfg);
    assert_eq!(&out.radii[..3], &[0, 0, 0]);
    assert!(out.radii[3] > 0, "just beyond the near plane is kept");
    let cfg2 = RasterConfig {
        near: 0.2,
        ..Default::default()
    };
    let out2 = render(&g, &cam, &RenderRequest::default(), &cfg2).unwrap();
    assert_eq!(out2.radii[3], 0, "the near plane is configurable");
}

#[test]
fn edge_on_plane_and_zero_distance_are_guarded() {
    // A flat Gaussian whose plane contains the camera centre (D = 0) and one seen edge-on.
    let cam = identity_camera(24, 24, 30.0, 12.0, 12.0);
    let mut g = Gaussians::with_len(2).unwrap();
    g.means[0] = [0.0, 0.0, 2.0];
    g.log_scales[0] = [-1.0, -8.0, -1.0]; // normal = y axis, plane y = 0 through the camera
    g.means[1] = [0.2, 0.1, 2.5];
    g.log_scales[1] = [-8.0, -1.0, -1.0]; // normal = x axis: edge-on at the centre column
    g.opacity_logits = vec![3.0, 3.0];
    let out = render_and_backward_finite(&g, &cam, &RasterConfig::default());
    let z = out.plane_depth.unwrap();
    assert!(z.data().iter().all(|v| v.is_finite() && *v >= 0.0));
}

#[test]
fn image_sizes_and_gaussian_counts_at_the_extremes() {
    let cfg = RasterConfig::default();
    // 1×1 image.
    let cam1 = camera(1, 1, 2.0);
    let g = random_scene(5, 1, 61, 0.2);
    render_and_backward_finite(&g, &cam1, &cfg);
    // 0 Gaussians: background only, zero-length gradients.
    let cam = camera(20, 10, 20.0);
    let empty = Gaussians::with_len(0).unwrap();
    let bg = RasterConfig {
        background: [0.25, 0.5, 1.0],
        ..Default::default()
    };
    let out = render_and_backward_finite(&empty, &cam, &bg);
    let c = out.color.unwrap();
    assert!(c.data().chunks(3).all(|p| p == [0.25, 0.5, 1.0]));
    // 1 Gaussian.
    let one = random_scene(1, 0, 62, 0.1);
    render_and_backward_finite(&one, &cam, &cfg);
    // Empty camera and over-cap image: errors, no allocation.
    let mut bad = cam.clone();
    bad.width = 0;
    assert!(matches!(
        render(&one, &bad, &RenderRequest::default(), &cfg),
        Err(RasterError::InvalidCamera(_))
    ));
    let mut huge = cam.clone();
    huge.width = 100_000;
    huge.height = 100_000;
    assert!(matches!(
        render(&one, &huge, &RenderRequest::default(), &cfg),
        Err(RasterError::InvalidCamera(_))
    ));
    let mut nan = cam.clone();
    nan.intrinsics.fx = f64::NAN;
    assert!(render(&one, &nan, &RenderRequest::default(), &cfg).is_err());
}

#[test]
fn huge_gaussians_stay_bounded_and_the_cap_is_an_error() {
    let cam = camera(160, 120, 100.0);
    let mut g = random_scene(200, 0, 71, 1.0);
    for ls in g.log_scales.iter_mut() {
        *ls = [10.0, 10.0, 9.0];
    }
    let out = render(
        &g,
        &cam,
        &RenderRequest::default(),
        &RasterConfig::default(),
    )
    .unwrap();
    // Every Gaussian covers at most all 10 × 8 tiles.
    assert!(out.stats.intersections <= 200 * 80);
    assert!(out.color.unwrap().is_finite());
    let capped = RasterConfig {
        max_intersections: 1000,
        ..Default::default()
    };
    assert!(matches!(
        render(&g, &cam, &RenderRequest::default(), &capped),
        Err(RasterError::TooManyIntersections { .. })
    ));
}

#[test]
fn invalid_inputs_are_errors() {
    let cam = camera(16, 16, 20.0);
    let mut g = random_scene(2, 0, 81, 0.2);
    let cfg = RasterConfig::default();
    let out = render(&g, &cam, &RenderRequest::default(), &cfg).unwrap();
    // Gradient for a channel that was not rendered, wrong size.
    let w1 = Image::filled(16, 16, 1, 1.0).unwrap();
    assert!(matches!(
        backward(
            &g,
            &cam,
            &cfg,
            &out,
            &OutputGradients {
                plane_depth: Some(&w1),
                ..Default::default()
            }
        ),
        Err(RasterError::InvalidGradients(_))
    ));
    let w_small = Image::filled(8, 16, 3, 1.0).unwrap();
    assert!(
        backward(
            &g,
            &cam,
            &cfg,
            &out,
            &OutputGradients {
                color: Some(&w_small),
                ..Default::default()
            }
        )
        .is_err()
    );
    // Mismatched arrays, bad degree, bad config.
    g.opacity_logits.pop();
    assert!(matches!(
        render(&g, &cam, &RenderRequest::default(), &cfg),
        Err(RasterError::InvalidGaussians(_))
    ));
    let mut g2 = random_scene(2, 0, 82, 0.2);
    g2.sh_degree = 4;
    assert!(render(&g2, &cam, &RenderRequest::default(), &cfg).is_err());
    g2.sh_degree = 0;
    assert!(
        render(
            &g2,
            &cam,
            &RenderRequest::default(),
            &RasterConfig {
                near: -1.0,
                ..Default::default()
            }
        )
        .is_err()
    );
    assert!(
        render(
            &g2,
            &cam,
            &RenderRequest::default(),
            &RasterConfig {
                alpha_threshold: 0.0,
                ..Default::default()
            }
        )
        .is_err()
    );
    for low_pass in [-0.1, f32::NAN, 9.5] {
        let e = render(&g2, &cam, &RenderRequest::default(), &RasterConfig { low_pass, ..Default::default() });
        assert!(matches!(&e, Err(RasterError::InvalidConfig(m)) if m.contains("low_pass")), "{e:?}");
    }
    // Backward with a different model size than the forward.
    let g3 = random_scene(3, 0, 83, 0.2);
    let w3 = Image::filled(16, 16, 3, 1.0).unwrap();
    assert!(
        backward(
            &g3,
            &cam,
            &cfg,
            &out,
            &OutputGradients {
                color: Some(&w3),
                ..Default::default()
            }
        )
        .is_err()
    );
    // NaN parameters are culled, not propagated.
    let mut g4 = random_scene(2, 0, 84, 0.2);
    g4.means[0][0] = f32::NAN;
    g4.sh[1][0][0] = f32::INFINITY;
    let o = render(&g4, &cam, &RenderRequest::all(), &cfg).unwrap();
    assert_eq!(o.radii, vec![0, 0]);
    assert!(o.color.unwrap().is_finite());
}

#[test]
fn unrequested_channels_are_absent_and_do_not_change_colour() {
    let cam = camera(40, 30, 40.0);
    let g = random_scene(30, 2, 91, 1.0);
    let cfg = RasterConfig::default();
    let a = render(&g, &cam, &RenderRequest::default(), &cfg).unwrap();
    let b = render(&g, &cam, &RenderRequest::all(), &cfg).unwrap();
    assert!(a.normal.is_none() && a.plane_depth.is_none() && a.observed.is_none());
    assert_eq!(a.color, b.color);
    assert_eq!(a.alpha, b.alpha);
    assert!(b.stats.forward_pairs >= b.stats.backward_pairs && b.stats.backward_pairs > 0);
}

#[test]
fn fast_exp_matches_libm() {
    let mut worst = 0.0f64;
    let mut x = 0.0f32;
    while x < 90.0 {
        let got = raster::exp_neg(x) as f64;
        let want = (-(x as f64)).exp();
        if want > 1e-37 {
            worst = worst.max((got - want).abs() / want);
        }
        x += 0.000731;
    }
    assert!(worst < 3e-7, "relative error {worst}");
    assert_eq!(raster::exp_neg(0.0), 1.0);
    assert_eq!(raster::exp_neg(100.0), 0.0);
    assert_eq!(raster::exp_neg(f32::NAN), 0.0);
    assert_eq!(raster::exp_neg(f32::INFINITY), 0.0);
}

/// A uniform cloud of `n` small Gaussians in front of `camera(…)` (no rejection sampling, so
/// millions are cheap to make).
fn cloud(n: usize, seed: u64) -> Gaussians {
    let mut rng = Rng::new(seed);
    let mut g = Gaussians::with_len(0).unwrap();
    for _ in 0..n {
        let mut sh = [[0.0f32; 3]; 16];
        sh[0] = [rng.uniform_range(-1.0, 1.0), rng.uniform_range(-1.0, 1.0), rng.uniform_range(-1.0, 1.0)];
        g.push(
            [rng.uniform_range(-1.5, 1.5), rng.uniform_range(-1.2, 1.2), rng.uniform_range(-1.0, 1.0)],
            [rng.uniform_range(-4.5, -3.0), rng.uniform_range(-4.5, -3.0), rng.uniform_range(-6.0, -4.0)],
            random_quat(&mut rng),
            rng.uniform_range(-2.0, 3.0),
            sh,
        );
    }
    g
}

#[test]
#[cfg_attr(debug_assertions, ignore = "release only: 4000×3000 and 2 million Gaussians")]
fn extremes_4000x3000_image_and_two_million_gaussians() {
    let cfg = RasterConfig::default();
    // docs/architecture.md §Extremes (5): a 4000×3000 image, every channel, forward and backward.
    let big = camera(4000, 3000, 3500.0);
    let out = render_and_backward_finite(&cloud(20_000, 91), &big, &cfg);
    assert_eq!(out.color.as_ref().unwrap().width(), 4000);
    assert!(out.stats.visible > 10_000, "{:?}", out.stats);
    // docs/architecture.md §Extremes (6): 2 million Gaussians at 640×480, every channel, forward and backward.
    let cam = camera(640, 480, 560.0);
    let many = cloud(2_000_000, 92);
    let out = render_and_backward_finite(&many, &cam, &cfg);
    assert!(out.stats.visible > 1_000_000, "{:?}", out.stats);
    assert_eq!(out.radii.len(), 2_000_000);
}
