#![cfg(feature = "wgpu")]
//! The resident model on wgpu against the host: the device's Adam step
//! (`WgpuRasterizer::backward_and_step`) against `gs_raster::adam_step` on the same device
//! gradients, over several steps with moving cameras, the SH groups at degrees 1 and 3, and a
//! loss term's own opacity gradient; the densification statistics accumulated on the device
//! against `DensifyStats::accumulate` (pixel-weighted or not); moments and statistics read
//! back; the residency's guards.
//!
//! Tolerance: parameters and moments within 1e-6 relative (+ 1e-12 absolute). Element-wise
//! f32 arithmetic in the same order as the host; a compiler may still fuse a multiply-add,
//! so bit equality is reported, not required.
//!
//! Without any wgpu adapter the tests print a SKIPPED line and return, except in CI.

#[allow(dead_code)] // the helpers the parity tests use and these do not
mod parity;

use gs_core::{Adam, AdamConfig, DensifyStats, Gaussians, Param};
use gs_raster::{OutputGradients, RasterConfig, RenderRequest, StepExtras, WgpuOptions};
use parity::scenes::*;

/// Adam with a group per parameter for `n` Gaussians, each at its own learning rate.
fn optimiser(n: usize) -> Adam {
    let mut adam = Adam::new(AdamConfig::default());
    for (k, p) in Param::ALL.into_iter().enumerate() {
        adam.add_group(p.name(), 1e-3 * (k + 1) as f32, n, p.row_width()).unwrap();
    }
    adam
}

/// Largest |a − b| / (|a| + |b| + 1e-12) over two arrays, and how many differ in any bit.
fn difference(a: &[f32], b: &[f32]) -> (f64, usize) {
    assert_eq!(a.len(), b.len());
    let rel = |(x, y): (&f32, &f32)| ((x - y).abs() as f64) / ((x.abs() + y.abs()) as f64 + 1e-12);
    let worst = a.iter().zip(b).map(rel).fold(0.0, f64::max);
    (worst, a.iter().zip(b).filter(|(x, y)| x.to_bits() != y.to_bits()).count())
}

fn parameters(g: &Gaussians) -> [(&'static str, Vec<f32>); 5] {
    [
        ("means", g.means.as_flattened().to_vec()),
        ("log-scales", g.log_scales.as_flattened().to_vec()),
        ("rotations", g.rotations.as_flattened().to_vec()),
        ("opacity", g.opacity_logits.clone()),
        ("sh", g.sh.as_flattened().as_flattened().to_vec()),
    ]
}

fn assert_close(label: &str, what: &str, a: &[f32], b: &[f32]) {
    let (worst, differ) = difference(a, b);
    eprintln!("{label} {what}: {differ} of {} values differ in a bit, largest relative difference {worst:.2e}", a.len());
    assert!(worst <= 1e-6, "{label} {what}: relative difference {worst:.3e} > 1e-6");
}

/// `steps` training steps of one model on the host (backward read back, host Adam and
/// statistics) and on the device (resident, device Adam and statistics), with the same
/// per-pixel gradients; both on wgpu. `pixels`: the renders count pixels (Pixel-GS weights).
fn host_and_device(degree: u32, steps: usize, extra: bool, pixels: bool) {
    let (Some(mut host), Some(mut dev)) = (gpu(WgpuOptions::default()), gpu(WgpuOptions::default())) else { return };
    let label = format!(
        "degree {degree}, {steps} steps{}{}",
        if extra { ", extra opacity and log-scale gradients" } else { "" },
        if pixels { ", pixel-weighted statistics" } else { "" }
    );
    let cfg = RasterConfig { antialiased: true, low_pass: 0.1, ..RasterConfig::default() };
    let (w, h) = (64, 48);
    let cams = cameras(w, h);
    let mut gh = random_scene(400, degree, 11 + degree as u64, 1.0, (-3.5, -2.0));
    let mut gd = gh.clone();
    let start = gh.clone();
    let n = gh.len();
    let (mut ah, mut ad) = (optimiser(n), optimiser(n));
    // Statistics that do not start at zero, as after a readback mid-gathering.
    let mut sh = DensifyStats::new(n);
    sh.grad_sum.iter_mut().enumerate().for_each(|(i, v)| *v = (i % 5) as f32 * 1e-4);
    sh.visible_count.iter_mut().enumerate().for_each(|(i, v)| *v = (i % 3) as u32);
    sh.visible_count[7] = u32::MAX - 1;
    let mut sd = sh.clone();
    let start_sums = sh.grad_sum.clone();
    let req = RenderRequest { observed: pixels, ..RenderRequest::all() };
    // The device's renders read back neither radii nor per-pixel state: its statistics read
    // the device's copies.
    let dreq = RenderRequest { radii: false, traversal: false, ..req };
    dev.make_resident(&gd, &ad, &sd).unwrap();
    for s in 0..steps {
        let cam = &cams[s % cams.len()];
        let grads = Grads::new(w, h, 3 + s as u64);
        let extra_opacity: Option<Vec<f32>> = extra.then(|| (0..n).map(|i| ((i % 7) as f32 - 3.0) * 1e-3).collect());
        // L_s's shape: on one axis of each Gaussian.
        let extra_scales: Option<Vec<[f32; 3]>> =
            extra.then(|| (0..n).map(|i| std::array::from_fn(|k| if k == i % 3 { 2e-3 + (i % 5) as f32 * 1e-4 } else { 0.0 })).collect());
        // Host: the wgpu backward, read back, then the host's Adam.
        let out = host.render(&gh, cam, &req, &cfg).unwrap();
        let mut g = host.backward(&gh, cam, &cfg, &out, &grads.all()).unwrap();
        if let Some(x) = &extra_opacity {
            g.opacity_logits.iter_mut().zip(x).for_each(|(a, b)| *a += b);
        }
        if let Some(x) = &extra_scales {
            g.log_scales.iter_mut().zip(x).for_each(|(a, b)| (0..3).for_each(|k| a[k] += b[k]));
        }
        let scale = 1.0 + s as f32;
        sh.accumulate(&out.radii, out.observed.as_deref(), &g.mean2d, &g.mean2d_abs, scale);
        gs_raster::adam_step(&mut ah, &mut gh, &g).unwrap();
        // Device: the same render of the resident model, backward and Adam there.
        let out = dev.render(&gd, cam, &dreq, &cfg).unwrap();
        assert!(out.radii.is_empty());
        if s % 2 == 1 {
            // A render of another view in between (a source view's, as in training): the step
            // rebuilds its own render's state, radii and pixel counts included.
            dev.render(&gd, &cams[(s + 1) % cams.len()], &dreq, &cfg).unwrap();
        }
        let extras = StepExtras { extra_opacity: extra_opacity.as_deref(), extra_log_scales: extra_scales.as_deref(), accumulate: Some(scale) };
        let before = dev.context().transfers();
        let step = dev.backward_and_step(&gd, cam, &cfg, &out, &grads.all(), &mut ad, extras).unwrap();
        assert!(step.means_finite);
        let t = dev.context().transfers() - before;
        if s % 2 == 0 {
            assert_eq!((t.syncs, t.bytes_down), (1, 4), "{label}: the step reads back its 4-byte flag alone");
        }
    }
    assert_eq!(gd, start, "{label}: the steps read nothing back into the host's copy");
    dev.read_resident(&mut gd, Some((&mut ad, &mut sd))).unwrap();
    for ((what, a), (_, b)) in parameters(&gh).iter().zip(parameters(&gd).iter()) {
        assert_close(&label, what, a, b);
    }
    for (x, y) in ah.groups.iter().zip(&ad.groups) {
        assert_eq!((x.step, x.lr), (y.step, y.lr), "{label} {}", x.name);
        assert_close(&label, &format!("{} m", x.name), &x.m, &y.m);
        assert_close(&label, &format!("{} v", x.name), &x.v, &y.v);
    }
    assert_close(&label, "gradient sums", &sh.grad_sum, &sd.grad_sum);
    assert_close(&label, "absolute gradient sums", &sh.abs_grad_sum, &sd.abs_grad_sum);
    assert_eq!(sh.max_radius, sd.max_radius, "{label}: largest radii");
    assert_eq!(sh.visible_count, sd.visible_count, "{label}: view or pixel counts");
    assert_eq!(sd.visible_count[7], u32::MAX, "{label}: the count saturates");
    assert!(sh.grad_sum.iter().zip(&start_sums).filter(|(a, b)| a != b).count() > n / 4, "{label}: most Gaussians gathered");
}

#[test]
fn the_device_step_matches_the_host_at_sh_degree_3() {
    host_and_device(3, 4, false, false);
}

#[test]
fn the_device_step_matches_the_host_at_sh_degree_1_with_parameter_terms_and_pixel_weights() {
    host_and_device(1, 3, true, true);
}

/// A step without any gradient (the camera sees nothing) still moves the model by its
/// momentum, as the host's Adam does.
#[test]
fn a_step_without_gradients_keeps_the_momentum() {
    let (Some(mut host), Some(mut dev)) = (gpu(WgpuOptions::default()), gpu(WgpuOptions::default())) else { return };
    let cfg = RasterConfig::default();
    let cams = cameras(32, 24);
    let mut gh = random_scene(50, 0, 5, 1.0, (-3.0, -2.0));
    let mut gd = gh.clone();
    let (mut ah, mut ad) = (optimiser(gh.len()), optimiser(gh.len()));
    let (mut sh, mut sd) = (DensifyStats::new(gh.len()), DensifyStats::new(gh.len()));
    dev.make_resident(&gd, &ad, &sd).unwrap();
    let req = RenderRequest::default();
    let grads = Grads::new(32, 24, 1);
    let color = OutputGradients { color: Some(&grads.color), ..Default::default() };
    // One step with gradients, then one with every Gaussian beyond the far plane.
    for (s, far) in [(0, cfg.far), (1, 0.02)] {
        let cfg = RasterConfig { far, ..cfg };
        let out = host.render(&gh, &cams[s], &req, &cfg).unwrap();
        let g = host.backward(&gh, &cams[s], &cfg, &out, &color).unwrap();
        sh.accumulate(&out.radii, None, &g.mean2d, &g.mean2d_abs, 1.0);
        gs_raster::adam_step(&mut ah, &mut gh, &g).unwrap();
        let out = dev.render(&gd, &cams[s], &req, &cfg).unwrap();
        let extras = StepExtras { accumulate: Some(1.0), ..Default::default() };
        dev.backward_and_step(&gd, &cams[s], &cfg, &out, &color, &mut ad, extras).unwrap();
    }
    dev.read_resident(&mut gd, Some((&mut ad, &mut sd))).unwrap();
    assert_eq!(sh, sd, "the statistics of a step without gradients");
    for ((what, a), (_, b)) in parameters(&gh).iter().zip(parameters(&gd).iter()) {
        assert_close("no gradients", what, a, b);
    }
}

/// While resident, a render of another model size or SH degree is refused instead of
/// drawing the device's parameters; released, the rasterizer uploads again.
#[test]
fn the_residency_refuses_other_models_until_released() {
    let Some(mut r) = gpu(WgpuOptions::default()) else { return };
    let cfg = RasterConfig::default();
    let cam = &cameras(32, 24)[0];
    let g = random_scene(30, 2, 9, 1.0, (-3.0, -2.0));
    let adam = optimiser(g.len());
    let stats = DensifyStats::new(g.len());
    assert!(!r.is_resident());
    r.make_resident(&g, &adam, &stats).unwrap();
    assert!(r.is_resident());
    let req = RenderRequest::default();
    let first = r.render(&g, cam, &req, &cfg).unwrap();
    let mut other = g.clone();
    other.sh_degree = 1;
    let err = r.render(&other, cam, &req, &cfg).unwrap_err().to_string();
    assert!(err.contains("resident model holds 30 Gaussians of SH degree 2"), "{err}");
    let fewer = random_scene(20, 2, 9, 1.0, (-3.0, -2.0));
    assert!(r.render(&fewer, cam, &req, &cfg).is_err());
    // Moments of the wrong size are refused before anything is uploaded.
    let err = r.make_resident(&fewer, &adam, &stats).unwrap_err().to_string();
    assert!(err.contains("holds 90 moments, not 20 rows of 3"), "{err}");
    let err = r.make_resident(&g, &adam, &DensifyStats::new(3)).unwrap_err().to_string();
    assert!(err.contains("densification statistics hold [3, 3, 3, 3] rows, not 30"), "{err}");
    r.make_resident(&g, &adam, &stats).unwrap();
    let err = r.read_resident(&mut fewer.clone(), None).unwrap_err().to_string();
    assert!(err.contains("not the 20 of degree 2 given to read it into"), "{err}");
    r.release_resident();
    let again = r.render(&g, cam, &req, &cfg).unwrap();
    assert_eq!(first.color, again.color, "the resident render is the uploaded one");
    assert!(r.render(&other, cam, &req, &cfg).is_ok());
    let (mut moments, mut counts) = (adam.clone(), stats.clone());
    assert!(r.read_resident(&mut g.clone(), Some((&mut moments, &mut counts))).is_err(), "nothing is resident");
}

/// A step started and finished after the next render costs no wait of its own: the render's
/// wait brings its flag. The model moves as with the step that waits.
#[test]
fn a_started_step_is_read_after_the_next_render_without_a_wait() {
    let (Some(mut waits), Some(mut defers)) = (gpu(WgpuOptions::default()), gpu(WgpuOptions::default())) else { return };
    let cfg = RasterConfig::default();
    let cams = cameras(32, 24);
    let (mut ga, mut gb) = (random_scene(60, 1, 12, 1.0, (-3.0, -2.0)), random_scene(60, 1, 12, 1.0, (-3.0, -2.0)));
    let (mut aa, mut ab) = (optimiser(ga.len()), optimiser(gb.len()));
    let stats = DensifyStats::new(ga.len());
    waits.make_resident(&ga, &aa, &stats).unwrap();
    defers.make_resident(&gb, &ab, &stats).unwrap();
    let req = RenderRequest::default();
    let grads = Grads::new(32, 24, 2);
    let color = OutputGradients { color: Some(&grads.color), ..Default::default() };
    let mut started = None;
    for s in 0..3 {
        let out = waits.render(&ga, &cams[s], &req, &cfg).unwrap();
        assert!(waits.backward_and_step(&ga, &cams[s], &cfg, &out, &color, &mut aa, StepExtras::default()).unwrap().means_finite);
        let out = defers.render(&gb, &cams[s], &req, &cfg).unwrap();
        if let Some(step) = started.take() {
            let before = defers.context().transfers();
            assert!(defers.finish_step(step).unwrap().means_finite);
            assert_eq!((defers.context().transfers() - before).syncs, 0, "the render's wait brought the flag");
        }
        started = Some(defers.start_step(&gb, &cams[s], &cfg, &out, &color, &mut ab, StepExtras::default()).unwrap());
    }
    assert!(defers.finish_step(started.take().unwrap()).unwrap().means_finite);
    waits.read_resident(&mut ga, None).unwrap();
    defers.read_resident(&mut gb, None).unwrap();
    for ((what, a), (_, b)) in parameters(&ga).iter().zip(parameters(&gb).iter()) {
        assert_eq!(a, b, "{what}: the same step, read later");
    }
}
