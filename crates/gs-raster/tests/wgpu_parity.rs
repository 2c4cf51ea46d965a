#![cfg(feature = "wgpu")]
//! Parity of the wgpu backend with the CPU backend (the numerical reference).
//!
//! Set `GS_PARITY_STATS=1` to print per-comparison error statistics.
//!
//! Every test logs the adapter. Without any wgpu adapter the tests print a skip message and
//! return, except in CI (`CI=true`), where `.ci/run` installs Mesa's lavapipe and a missing
//! adapter is a failure.
//!
//! Tolerances and the comparison: `parity/compare.rs`; scenes and cameras: `parity/scenes.rs`.

mod parity;

use gs_core::glam::DVec3;
use gs_core::{Gaussians, Image};
use gs_raster::{
    Backend, OutputGradients, RasterConfig, RasterError, Rasterizer, RenderRequest, WgpuOptions,
    WgpuRasterizer,
};
use parity::compare::*;
use parity::scenes::*;

fn run_scenes(r: &mut WgpuRasterizer, n: usize, w: u32, h: u32, seed: u64) {
    for degree in [0, 3] {
        // 3DGS' low-pass filter with and without the compensation, and Mip-Splatting's 0.1 px².
        for (antialiased, low_pass) in [(false, gs_raster::LOW_PASS), (true, gs_raster::LOW_PASS), (true, 0.1)] {
            let g = random_scene(n, degree, seed + degree as u64, 1.0, (-3.5, -2.0));
            let cfg = RasterConfig {
                antialiased,
                low_pass,
                background: [0.2, 0.5, 0.9],
                ..RasterConfig::default()
            };
            for (c, cam) in cameras(w, h).iter().enumerate() {
                let label = format!("n={n} deg={degree} aa={antialiased} low-pass={low_pass} cam={c}");
                parity(r, &label, &g, cam, &cfg);
            }
        }
    }
}

#[test]
fn parity_16_gaussians() {
    let Some(mut r) = gpu(WgpuOptions::default()) else { return };
    run_scenes(&mut r, 16, 64, 48, 1);
}

#[test]
fn parity_1k_gaussians() {
    let Some(mut r) = gpu(WgpuOptions::default()) else { return };
    run_scenes(&mut r, 1000, 160, 120, 2);
}

#[test]
fn parity_20k_gaussians() {
    let Some(mut r) = gpu(WgpuOptions::default()) else { return };
    let g = random_scene(20_000, 3, 3, 1.5, (-4.5, -3.0));
    let cfg = RasterConfig::default();
    for (c, cam) in cameras(320, 240).iter().enumerate() {
        parity(&mut r, &format!("20k cam={c}"), &g, cam, &cfg);
    }
    let cfg = RasterConfig {
        antialiased: true,
        ..RasterConfig::default()
    };
    let g0 = random_scene(20_000, 0, 4, 1.5, (-4.5, -3.0));
    parity(&mut r, "20k deg0 aa", &g0, &cameras(320, 240)[0], &cfg);
}

/// A hardware GPU runs many workgroups at once where lavapipe runs few: the forward and the
/// backward must repeat bit for bit (the backward sums every gradient in a fixed order; a
/// difference is an order that varies or a race in a kernel).
#[test]
fn repeated_calls_agree_on_the_device() {
    let Some(mut r) = gpu(WgpuOptions::default()) else { return };
    let cfg = RasterConfig::default();
    let cases = [
        (random_scene(20_000, 3, 3, 1.5, (-4.5, -3.0)), cameras(320, 240)[1].clone()),
        (
            random_scene(200, 2, 11, 1.0, (-3.0, -1.5)),
            camera(17, 33, 40.0, DVec3::new(0.4, -0.3, -4.0)),
        ),
    ];
    for (k, (g, cam)) in cases.iter().enumerate() {
        let grads = Grads::new(cam.width, cam.height, 7);
        let mut runs = Vec::new();
        for _ in 0..3 {
            let out = r.render(g, cam, &RenderRequest::all(), &cfg).unwrap();
            let gr = r.backward(g, cam, &cfg, &out, &grads.all()).unwrap();
            runs.push((out, gr));
        }
        let (a, ga) = &runs[0];
        for (b, gb) in &runs[1..] {
            assert_eq!(a.final_t, b.final_t, "case {k}: final_t");
            assert_eq!(a.last_contributor, b.last_contributor, "case {k}: last contributor");
            for (x, y) in [(&a.color, &b.color), (&a.plane_depth, &b.plane_depth), (&a.normal, &b.normal)] {
                assert_eq!(x.as_ref().unwrap().data(), y.as_ref().unwrap().data(), "case {k}: image");
            }
            assert_same_bits(&format!("case {k}"), ga, gb);
        }
    }
}

#[test]
fn parity_for_channel_subsets_and_single_gradients() {
    let Some(mut r) = gpu(WgpuOptions::default()) else { return };
    let g = random_scene(400, 1, 6, 1.0, (-3.5, -2.0));
    let cam = &cameras(80, 64)[0];
    let cfg = RasterConfig::default();
    let grads = Grads::new(80, 64, 9);
    // T_final and the last contributors come back (`traversal`) to tell flips from errors.
    let requests = [
        RenderRequest { traversal: true, ..RenderRequest::default() },
        RenderRequest {
            color: false,
            alpha: false,
            plane_depth: true,
            traversal: true,
            ..RenderRequest::default()
        },
        RenderRequest {
            color: true,
            alpha: false,
            expected_depth: true,
            observed: true,
            traversal: true,
            ..RenderRequest::default()
        },
        RenderRequest {
            color: false,
            alpha: true,
            normal: true,
            distance: true,
            traversal: true,
            ..RenderRequest::default()
        },
    ];
    for (k, req) in requests.iter().enumerate() {
        let cpu = gs_raster::render(&g, cam, req, &cfg).unwrap();
        let gpu = r.render(&g, cam, req, &cfg).unwrap();
        let label = format!("request {k}");
        let touched = touched_by(&g, cam, &cpu.radii, &compare_outputs(&label, &cpu, &gpu));
        let og = OutputGradients {
            color: req.color.then_some(&grads.color),
            alpha: req.alpha.then_some(&grads.alpha),
            normal: req.normal.then_some(&grads.normal),
            distance: req.distance.then_some(&grads.distance),
            plane_depth: req.plane_depth.then_some(&grads.plane_depth),
            expected_depth: req.expected_depth.then_some(&grads.expected_depth),
            ..OutputGradients::default()
        };
        let gc = gs_raster::backward(&g, cam, &cfg, &cpu, &og).unwrap();
        let gg = r.backward(&g, cam, &cfg, &gpu, &og).unwrap();
        compare_grads(&label, &gc, &gg, &touched);
    }
}

/// A render reads back only what its request needs: without `traversal`, a plane-depth render
/// leaves T_final and the last contributors on the device (8 bytes a pixel fewer) and a colour
/// render brings T_final alone; without `radii`, 4 bytes a Gaussian fewer; plane depth without
/// the normal or distance comes back as one plane made on the device (12 bytes a pixel
/// fewer). The images and the backward (which reads the device's copies, and takes its window
/// count from the device's longest list) are the same bits.
#[test]
fn a_render_reads_back_what_its_request_needs() {
    let Some(mut r) = gpu(WgpuOptions::default()) else { return };
    // One tile's list longer than a backward window (256), so the window count matters.
    let mut g = random_scene(600, 1, 8, 0.25, (-4.5, -4.0));
    for o in g.opacity_logits.iter_mut() {
        *o = gs_core::gaussians::inverse_sigmoid(0.02);
    }
    let cam = camera(32, 32, 40.0, DVec3::new(0.0, 0.0, -4.0));
    let cfg = RasterConfig::default();
    let npix = 32 * 32;
    let grads = Grads::new(32, 32, 5);
    let depth_only = RenderRequest { color: false, alpha: false, plane_depth: true, ..RenderRequest::default() };
    let n = g.len() as u64;
    // Every render below guesses its buffers from this one (one readback each, the counters
    // in it; a first render of a size reads them back once more before it blends).
    r.render(&g, &cam, &RenderRequest::default(), &cfg).unwrap();
    // (a request, the same without what it saves, the bytes saved)
    for (full, lean, saved) in [
        (RenderRequest { traversal: true, ..depth_only }, depth_only, 8 * npix),
        (RenderRequest { traversal: true, ..RenderRequest::default() }, RenderRequest::default(), 4 * npix),
        (RenderRequest::default(), RenderRequest { radii: false, ..RenderRequest::default() }, 4 * n),
        // Plane depth alone: one plane made on the device instead of Ñ and D (4 planes); the
        // backward reads them from the device.
        (RenderRequest { normal: true, ..depth_only }, depth_only, 12 * npix),
    ] {
        let mut read = |req: &RenderRequest| {
            let before = r.context().transfers();
            let out = r.render(&g, &cam, req, &cfg).unwrap();
            let down = (r.context().transfers() - before).bytes_down;
            let og = OutputGradients {
                color: req.color.then_some(&grads.color),
                alpha: req.alpha.then_some(&grads.alpha),
                plane_depth: req.plane_depth.then_some(&grads.plane_depth),
                ..OutputGradients::default()
            };
            let back = r.backward(&g, &cam, &cfg, &out, &og).unwrap();
            (out, down, back)
        };
        let (a, a_down, a_back) = read(&full);
        let (b, b_down, b_back) = read(&lean);
        assert_eq!(a_down - b_down, saved, "{lean:?}: bytes read back");
        if full.traversal {
            assert!(a.last_contributor.iter().max().copied().unwrap_or(0) > 256, "the list must outgrow one backward window");
            assert!(b.last_contributor.is_empty());
            assert_eq!(b.final_t.is_empty(), !lean.color);
        } else if !lean.radii {
            assert!(b.radii.is_empty() && a.radii.len() == g.len());
        }
        for (x, y) in [(&a.color, &b.color), (&a.alpha, &b.alpha)] {
            assert_eq!(x.as_ref().map(|i| i.data()), y.as_ref().map(|i| i.data()));
        }
        // The device's plane depth against the host's from the same Ñ and D: equal but for the
        // device's rounding of a·b + c and of the division (within 1e-6 relative).
        let (x, y) = (a.plane_depth.as_ref().map(|i| i.data()), b.plane_depth.as_ref().map(|i| i.data()));
        assert_eq!(x.map(<[f32]>::len), y.map(<[f32]>::len));
        for (u, v) in x.unwrap_or_default().iter().zip(y.unwrap_or_default()) {
            assert!((u - v).abs() <= 1e-6 * u.abs(), "{lean:?}: plane depth {u} against {v}");
        }
        assert_eq!(a_back, b_back, "{lean:?}: the backward");
    }
}

#[test]
fn parity_of_the_geometry_cut() {
    // The front-surface geometry `vagsl mesh` fuses: the same cut on both backends, and the
    // backward of its geometry refused on both.
    let Some(mut r) = gpu(WgpuOptions::default()) else { return };
    let g = random_scene(400, 1, 7, 1.0, (-3.5, -2.0));
    let cam = &cameras(80, 64)[1];
    let cfg = RasterConfig::default();
    for cut in [0.15, 0.5] {
        let req = RenderRequest { geometry_cut: cut, ..RenderRequest::all() };
        let cpu = gs_raster::render(&g, cam, &req, &cfg).unwrap();
        let gpu = r.render(&g, cam, &req, &cfg).unwrap();
        compare_outputs(&format!("geometry cut {cut}"), &cpu, &gpu);
        let grads = Grads::new(80, 64, 3);
        let og = OutputGradients { plane_depth: Some(&grads.plane_depth), ..OutputGradients::default() };
        assert!(matches!(r.backward(&g, cam, &cfg, &gpu, &og), Err(RasterError::InvalidGradients(_))));
    }
}

#[test]
fn parity_at_the_extremes() {
    let Some(mut r) = gpu(WgpuOptions::default()) else { return };
    let cfg = RasterConfig::default();
    // Image sizes: 1x1, non-multiples of 16, one row / one column.
    let g = random_scene(200, 2, 11, 1.0, (-3.0, -1.5));
    for (w, h) in [(1, 1), (17, 33), (31, 1), (1, 45), (50, 23)] {
        let cam = camera(w, h, 40.0, DVec3::new(0.4, -0.3, -4.0));
        parity(&mut r, &format!("{w}x{h}"), &g, &cam, &cfg);
    }
    let cam = camera(96, 72, 80.0, DVec3::new(0.4, -0.3, -4.0));
    // Empty scene.
    parity(&mut r, "empty", &Gaussians::with_len(0).unwrap(), &cam, &cfg);
    // Tiny (sub-pixel) and huge (screen-covering) Gaussians mixed.
    let mut g = random_scene(300, 3, 12, 1.0, (-9.0, -7.0));
    g.extend_from(&random_scene(6, 3, 13, 0.5, (0.5, 1.5)));
    parity(&mut r, "tiny+huge", &g, &cam, &cfg);
    // Near plane: Gaussians straddling and behind the camera, clamped Jacobians off-screen.
    let mut g = random_scene(300, 1, 14, 4.5, (-3.0, -2.0));
    for i in 0..g.len() {
        if i % 3 == 0 {
            g.means[i][2] = -4.0 + 0.02 * (i % 7) as f32; // near the camera plane z ≈ 0..0.1
        }
    }
    parity(&mut r, "near plane", &g, &cam, &cfg);
    // Grazing planes: flat Gaussians almost edge-on to the view direction.
    let mut g = random_scene(200, 0, 15, 1.0, (-2.5, -2.0));
    for i in 0..g.len() {
        g.log_scales[i][2] = -9.0;
        // Rotate the flat axis (local z) to be nearly perpendicular to the view (world z).
        g.rotations[i] = [1.0, 1.0 + 0.0015 * (i % 5) as f32, 0.0, 0.0];
    }
    parity(&mut r, "grazing", &g, &cam, &cfg);
    // Saturated (opacity close to 1) stacks hit the 0.99 cap and the transmittance stop.
    let mut g = random_scene(500, 0, 16, 0.3, (-2.0, -1.5));
    for o in g.opacity_logits.iter_mut() {
        *o = 8.0;
    }
    parity(&mut r, "saturated", &g, &cam, &cfg);
}

#[test]
fn parity_across_projection_chunks_and_long_tile_lists() {
    let Some(mut r) = gpu(WgpuOptions::default()) else { return };
    let cfg = RasterConfig::default();
    // 270k Gaussians: the per-Gaussian kernels run in chunks of 2^18; all but those around
    // the chunk boundary (and a few at both ends) are behind the camera.
    let mut g = random_scene(270_000, 1, 60, 1.0, (-3.5, -2.5));
    for i in 0..g.len() {
        let keep = !(50..269_950).contains(&i) || (262_000..262_300).contains(&i);
        if !keep {
            g.means[i][2] = -10.0;
        }
    }
    let cam = camera(96, 64, 90.0, DVec3::new(0.4, -0.3, -4.0));
    parity(&mut r, "chunks", &g, &cam, &cfg);
    // One 16x16 tile with a 40k-entry list of faint, tiny Gaussians: pixels stay unsaturated
    // past a forward window (2,048 to 16,384 entries by tile split) and the backward runs ~160
    // windows.
    let mut g = random_scene(40_000, 0, 61, 0.25, (-5.5, -5.0));
    for o in g.opacity_logits.iter_mut() {
        *o = gs_core::gaussians::inverse_sigmoid(0.006);
    }
    let cam = camera(16, 16, 40.0, DVec3::new(0.0, 0.0, -4.0));
    let out = r.render(&g, &cam, &RenderRequest::all(), &cfg).unwrap();
    let longest = out.last_contributor.iter().max().copied().unwrap_or(0);
    assert!(longest > 33_000, "the list should reach past one forward window ({longest})");
    parity(&mut r, "long list", &g, &cam, &cfg);
}

/// The extremes of docs/architecture.md §Extremes (scales, quaternions, opacities, positions, edge-on planes, one
/// Gaussian) mixed into an ordinary scene: same outputs and gradients, all finite.
#[test]
fn parity_design_md_extremes() {
    let Some(mut r) = gpu(WgpuOptions::default()) else { return };
    let cfg = RasterConfig::default();
    let cam = camera(80, 60, 70.0, DVec3::new(0.4, -0.3, -4.0));
    let mut g = random_scene(200, 3, 70, 1.0, (-3.5, -2.0));
    let base = random_scene(1, 3, 71, 0.1, (-2.5, -2.0));
    let mut add = |mean: [f32; 3], ls: [f32; 3], q: [f32; 4], logit: f32| {
        g.push(mean, ls, q, logit, base.sh[0]);
    };
    let q0 = [0.9, 0.2, -0.3, 0.1];
    add([0.1, 0.0, 0.0], [-20.0, -20.0, -20.0], q0, 2.0); // needle / degenerate
    add([0.2, 0.1, 0.0], [-20.0, -1.0, -2.0], q0, 2.0);
    add([0.0, 0.0, 0.0], [10.0, 10.0, 10.0], q0, -3.0); // bigger than the scene
    add([0.3, -0.2, 0.0], [-2.0, -2.0, -2.0], q0, 1.0); // equal scales
    add([0.0, 0.3, 0.2], [-2.0, -2.5, -4.0], [1e-12, 1e-12, 0.0, 0.0], 1.0); // ~zero quaternion
    add([-0.3, 0.3, 0.2], [-2.0, -2.5, -4.0], [0.0, 0.0, 0.0, 0.0], 1.0); // zero quaternion
    add([-0.2, -0.3, 0.1], [-2.0, -2.5, -4.0], [30.0, -4.0, 7.0, 2.0], 1.0); // not normalised
    add([0.25, 0.25, -0.1], [-2.0, -2.5, -4.0], q0, 30.0); // opacity logit +30
    add([-0.25, 0.25, -0.1], [-2.0, -2.5, -4.0], q0, -30.0); // opacity logit −30
    add([0.0, 0.0, 1e5], [-2.0, -2.5, -4.0], q0, 2.0); // far away
    add([1e5, 0.0, 0.0], [-2.0, -2.5, -4.0], q0, 2.0); // far outside the frustum
    add([0.0, 0.0, -9.0], [-2.0, -2.5, -4.0], q0, 2.0); // behind the camera
    // Exactly on and just beyond the near plane (camera-space z = 0.01).
    let c = cam.center();
    let fwd = (DVec3::new(0.1, 0.05, 0.0) - c).normalize();
    for dz in [0.01, 0.0100001, 0.02] {
        let p = c + fwd * dz;
        add([p.x as f32, p.y as f32, p.z as f32], [-3.0, -3.0, -4.0], q0, 2.0);
    }
    // At the image border (projected near the corners and edges).
    for (u, v) in [(-0.9, -0.9), (0.9, -0.9), (0.0, 0.95), (-1.0, 0.0)] {
        add([u * 2.3, v * 1.7, 0.0], [-2.5, -2.5, -4.0], q0, 2.0);
    }
    // Edge-on plane: the flat axis (local z) perpendicular to the viewing direction.
    add([0.0, -0.2, 0.0], [-1.5, -1.5, -12.0], [1.0, 1.0, 0.0, 0.0], 2.0);
    parity(&mut r, "extremes", &g, &cam, &cfg);
    let aa = RasterConfig {
        antialiased: true,
        ..cfg.clone()
    };
    parity(&mut r, "extremes aa", &g, &cam, &aa);
    // One Gaussian.
    let one = random_scene(1, 0, 72, 0.1, (-1.5, -1.0));
    parity(&mut r, "one", &one, &cam, &cfg);
}

#[test]
fn parity_in_bands_of_tile_rows() {
    // A 1 MiB binding limit splits a 200x300 image into 3 bands of 8 tile rows (a 4000x3000
    // image on lavapipe's 128 MiB limit takes the same path).
    let Some(mut r) = gpu(WgpuOptions {
        max_storage_binding: Some(1 << 20),
        ..Default::default()
    }) else {
        return;
    };
    let cfg = RasterConfig::default();
    // 1200 Gaussians: their ~11k intersections' 64-byte gradient partials fit the 1 MiB too.
    let g = random_scene(1200, 1, 80, 1.2, (-3.5, -2.0));
    for (w, h) in [(200, 300), (200, 257)] {
        let cam = camera(w, h, 250.0, DVec3::new(0.4, -0.3, -4.0));
        parity(&mut r, &format!("bands {w}x{h}"), &g, &cam, &cfg);
    }
    // 3000 Gaussians (~29k intersections) render, but their partials do not fit one binding:
    // the backward says so.
    let g = random_scene(3000, 1, 80, 1.2, (-3.5, -2.0));
    let cam = camera(200, 300, 250.0, DVec3::new(0.4, -0.3, -4.0));
    let out = r.render(&g, &cam, &RenderRequest::default(), &cfg).unwrap();
    let ones = Image::filled(200, 300, 3, 1.0).unwrap();
    let og = OutputGradients {
        color: Some(&ones),
        ..Default::default()
    };
    match r.backward(&g, &cam, &cfg, &out, &og) {
        Err(RasterError::Gpu(m)) => assert!(m.contains("per-intersection gradients"), "{m}"),
        other => panic!("expected a binding-limit error, got {other:?}"),
    }
    // Too wide for 4 tile rows in one binding: a clear error.
    let cam = camera(2000, 64, 900.0, DVec3::new(0.4, -0.3, -4.0));
    assert!(matches!(
        r.render(&g, &cam, &RenderRequest::default(), &cfg),
        Err(RasterError::Gpu(_))
    ));
}

#[test]
fn a_gaussian_covering_more_tiles_than_one_emit_window() {
    let Some(mut r) = gpu(WgpuOptions::default()) else { return };
    // 144 x 228 = 32832 tiles (> 32768, the per-dispatch window of `isect_emit`), one
    // screen-filling Gaussian plus a few small ones; alpha only (8.4 M pixels).
    let mut g = random_scene(20, 0, 90, 1.0, (-3.0, -2.5));
    g.push([0.0, 0.0, 0.5], [1.5, 1.5, -3.0], [1.0, 0.0, 0.0, 0.0], -2.0, g.sh[0]);
    let cam = camera(2304, 3648, 1500.0, DVec3::new(0.4, -0.3, -4.0));
    let cfg = RasterConfig::default();
    let req = RenderRequest {
        color: false,
        traversal: true,
        ..RenderRequest::default()
    };
    let cpu = gs_raster::render(&g, &cam, &req, &cfg).unwrap();
    let gpu = r.render(&g, &cam, &req, &cfg).unwrap();
    assert!(cpu.radii[20] > 2000, "the last Gaussian must cover the image");
    let _ = compare_outputs("32k tiles", &cpu, &gpu);
}

#[test]
fn buffers_are_reused_across_calls_of_different_sizes() {
    let Some(mut r) = gpu(WgpuOptions::default()) else { return };
    let cfg = RasterConfig::default();
    let sizes = [(2000, 160, 120), (30, 20, 20), (5000, 64, 300), (0, 8, 8), (800, 200, 100)];
    for (k, &(n, w, h)) in sizes.iter().enumerate() {
        let g = random_scene(n, (k % 4) as u32, 20 + k as u64, 1.0, (-3.5, -2.0));
        let cam = camera(w, h, w as f64, DVec3::new(0.4, -0.3, -4.0));
        parity(&mut r, &format!("reuse {k}"), &g, &cam, &cfg);
    }
    // The same render twice gives identical forward outputs.
    let g = random_scene(1000, 3, 30, 1.0, (-3.5, -2.0));
    let cam = camera(100, 80, 90.0, DVec3::new(0.4, -0.3, -4.0));
    let a = r.render(&g, &cam, &RenderRequest::all(), &cfg).unwrap();
    let b = r.render(&g, &cam, &RenderRequest::all(), &cfg).unwrap();
    assert_eq!(a.color.as_ref().unwrap().data(), b.color.as_ref().unwrap().data());
    assert_eq!(a.last_contributor, b.last_contributor);
}

#[test]
fn errors_match_the_cpu_backend_and_states_do_not_mix() {
    let Some(mut r) = gpu(WgpuOptions::default()) else { return };
    let g = random_scene(50, 0, 40, 1.0, (-3.5, -2.0));
    let cam = camera(32, 32, 30.0, DVec3::new(0.4, -0.3, -4.0));
    let cfg = RasterConfig::default();
    let req = RenderRequest::default();
    // Invalid inputs: the same errors as the CPU backend.
    let mut bad = g.clone();
    bad.sh_degree = 4;
    assert_eq!(
        r.render(&bad, &cam, &req, &cfg).unwrap_err(),
        gs_raster::render(&bad, &cam, &req, &cfg).unwrap_err()
    );
    let mut bad = g.clone();
    bad.opacity_logits.pop();
    assert_eq!(
        r.render(&bad, &cam, &req, &cfg).unwrap_err(),
        gs_raster::render(&bad, &cam, &req, &cfg).unwrap_err()
    );
    let bad_cfg = RasterConfig {
        near: -1.0,
        ..cfg.clone()
    };
    assert_eq!(
        r.render(&g, &cam, &req, &bad_cfg).unwrap_err(),
        gs_raster::render(&g, &cam, &req, &bad_cfg).unwrap_err()
    );
    let capped = RasterConfig {
        max_intersections: 3,
        ..cfg.clone()
    };
    assert_eq!(
        r.render(&g, &cam, &req, &capped).unwrap_err(),
        gs_raster::render(&g, &cam, &req, &capped).unwrap_err()
    );
    // Backward of another backend's output, or of a stale render: errors, not panics.
    let cpu = gs_raster::render(&g, &cam, &req, &cfg).unwrap();
    let gpu_out = r.render(&g, &cam, &req, &cfg).unwrap();
    let ones = Image::filled(32, 32, 3, 1.0).unwrap();
    let og = OutputGradients {
        color: Some(&ones),
        ..Default::default()
    };
    assert!(matches!(
        r.backward(&g, &cam, &cfg, &cpu, &og),
        Err(RasterError::InvalidGradients(_))
    ));
    assert!(matches!(
        gs_raster::backward(&g, &cam, &cfg, &gpu_out, &og),
        Err(RasterError::InvalidGradients(_))
    ));
    // An older render of the same rasterizer: its device state is rebuilt, same gradients.
    let g2 = random_scene(80, 1, 41, 1.0, (-3.5, -2.0));
    let _newer = r.render(&g2, &cam, &RenderRequest::all(), &cfg).unwrap();
    let stale = r.backward(&g, &cam, &cfg, &gpu_out, &og).unwrap();
    let fresh_out = r.render(&g, &cam, &req, &cfg).unwrap();
    let fresh = r.backward(&g, &cam, &cfg, &fresh_out, &og).unwrap();
    assert_same_bits("rebuilt state", &fresh, &stale);
    // ... but not with different Gaussians than the render's.
    let _newer = r.render(&g2, &cam, &req, &cfg).unwrap();
    let mut moved = g.clone();
    for m in moved.means.iter_mut() {
        m[0] += 0.5;
    }
    assert!(matches!(
        r.backward(&moved, &cam, &cfg, &gpu_out, &og),
        Err(RasterError::InvalidGradients(_))
    ));
    // Gradient-shape errors as on the CPU.
    let latest = r.render(&g, &cam, &req, &cfg).unwrap();
    let wrong = Image::filled(31, 32, 3, 1.0).unwrap();
    let og = OutputGradients {
        color: Some(&wrong),
        ..Default::default()
    };
    assert_eq!(
        r.backward(&g, &cam, &cfg, &latest, &og).unwrap_err(),
        gs_raster::backward(&g, &cam, &cfg, &cpu, &og).unwrap_err()
    );
    let dl = Image::filled(32, 32, 1, 1.0).unwrap();
    let og = OutputGradients {
        plane_depth: Some(&dl),
        ..Default::default()
    };
    assert_eq!(
        r.backward(&g, &cam, &cfg, &latest, &og).unwrap_err(),
        gs_raster::backward(&g, &cam, &cfg, &cpu, &og).unwrap_err()
    );
    // Another rasterizer's output.
    let mut r2 = gpu(WgpuOptions::default()).unwrap();
    let other = r2.render(&g, &cam, &req, &cfg).unwrap();
    let og = OutputGradients {
        color: Some(&ones),
        ..Default::default()
    };
    assert!(matches!(
        r.backward(&g, &cam, &cfg, &other, &og),
        Err(RasterError::InvalidGradients(_))
    ));
}

#[test]
fn backend_selector() {
    assert_eq!("cpu".parse::<Backend>().unwrap(), Backend::Cpu);
    assert_eq!("WGPU".parse::<Backend>().unwrap(), Backend::Wgpu);
    assert_eq!("auto".parse::<Backend>().unwrap(), Backend::Auto);
    assert!("cuda".parse::<Backend>().is_err());
    let cpu = Rasterizer::new(Backend::Cpu).unwrap();
    assert_eq!(cpu.backend_name(), "cpu");
    // Auto never picks a software adapter.
    let auto = Rasterizer::new(Backend::Auto).unwrap();
    eprintln!("auto backend: {}", auto.description());
    assert_eq!(
        auto.backend() == Backend::Wgpu,
        gs_raster::hardware_adapter_available()
    );
    let Some(_) = gpu(WgpuOptions::default()) else { return };
    let mut w = Rasterizer::new(Backend::Wgpu).unwrap();
    assert_eq!(w.backend_name(), "wgpu");
    let g = random_scene(100, 0, 50, 1.0, (-3.5, -2.0));
    let cam = camera(40, 30, 40.0, DVec3::new(0.4, -0.3, -4.0));
    let cfg = RasterConfig::default();
    let req = RenderRequest { traversal: true, ..RenderRequest::default() };
    let out = w.render(&g, &cam, &req, &cfg).unwrap();
    let ones = Image::filled(40, 30, 3, 1.0).unwrap();
    let og = OutputGradients {
        color: Some(&ones),
        ..Default::default()
    };
    let gg = w.backward(&g, &cam, &cfg, &out, &og).unwrap();
    let cpu_out = gs_raster::render(&g, &cam, &req, &cfg).unwrap();
    let gc = gs_raster::backward(&g, &cam, &cfg, &cpu_out, &og).unwrap();
    let touched = touched_by(&g, &cam, &cpu_out.radii, &flipped_pixels("selector", &cpu_out, &out));
    compare_grads("selector", &gc, &gg, &touched);
}
