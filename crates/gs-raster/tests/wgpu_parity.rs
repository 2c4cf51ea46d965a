#![cfg(feature = "wgpu")]
//! Parity of the wgpu backend with the CPU backend (the numerical reference).
//!
//! Set `GS_PARITY_STATS=1` to print per-comparison error statistics.
//!
//! Every test logs the adapter. Without any wgpu adapter the tests print a skip message and
//! return, except in CI (`CI=true`), where `.ci/run` installs Mesa's lavapipe and a missing
//! adapter is a failure.
//!
//! Tolerances (why they are not zero: the kernels evaluate the same f32 formulas, but the
//! driver may fuse multiply-adds, `exp`/`log`/`sqrt` of the projection come from the driver's
//! math library, and the backward sums per-pixel contributions in a different order —
//! workgroup tree reduction plus atomics in arbitrary tile order — than the CPU's serial
//! per-tile merge):
//! - images (every channel): |gpu − cpu| ≤ 1e-4 absolute per value; plane depth (a ratio
//!   D / (−Ñ·r), amplified where the denominator is small) 1e-4 relative + 1e-4 absolute.
//!   A pixel may legitimately differ more when an ulp-level difference flips one of the
//!   discrete decisions (α ≥ 1/255, T·(1−α) < 1e-4, pixel inside the splat's box); at most
//!   [`MAX_FLIP_FRACTION`] of the pixels may exceed the tolerance, and never by more than
//!   [`FLIP_ABS`]. A flipped pixel is one whose last contributor differs or whose final T
//!   differs by a power of (1 − 1/255) (a Gaussian at the α threshold kept by one backend
//!   only: an NVIDIA driver contracts the `exp` polynomial into fused multiply-adds, lavapipe
//!   does not); any other difference in T fails.
//! - integer outputs: visible and intersection counts exact; radii exact except that
//!   ceil(level·√λ) may differ by one for at most 2 + 0.1 % of the Gaussians (never culled on
//!   one side only); last contributor and the
//!   pair counters exact except at such flipped pixels; observed counts (the T > 0.5 rule is
//!   one more such decision) within ±(2 + flipped pixels) per Gaussian for at most
//!   2 + 0.1 % of the Gaussians.
//! - gradients: per value |gpu − cpu| ≤ 1e-3·|cpu| + 1e-5·max|group| (the floor absorbs the
//!   cancellation error of summing many terms of both signs, which is relative to the
//!   terms, not to the sum) for all but 2 + 0.5 % of the values of each group, and the whole
//!   group within 2e-3 in relative L2 norm — over the Gaussians no flipped pixel touches; the
//!   values of those a flipped pixel touches (its screen box holds one) within
//!   [`TOUCHED_L2`] in relative L2. Measured on lavapipe: relative L2 ≤ 1e-4 without
//!   flipped pixels; outliers come from cancellation in the projection backward (e.g. a
//!   log-scale gradient that is a difference of near-equal terms).

use gs_core::glam::DVec3;
use gs_core::{Camera, Gaussians, Image, Intrinsics, Rng};
use gs_raster::{
    Backend, GaussianGradients, OutputGradients, RasterConfig, RasterError, Rasterizer,
    RenderOutput, RenderRequest, WgpuOptions, WgpuRasterizer,
};

const IMG_ABS: f32 = 1e-4;
const MAX_FLIP_FRACTION: f64 = 2e-3;
const FLIP_ABS: f32 = 0.05;
const GRAD_REL: f64 = 1e-3;
const GRAD_FLOOR: f64 = 1e-5;
const GRAD_OUTLIER_FRACTION: f64 = 0.005;
const GRAD_L2: f64 = 2e-3;

/// A wgpu rasterizer on this machine's adapter, or `None` (skip) when there is none locally;
/// panics in CI.
fn gpu(opts: WgpuOptions) -> Option<WgpuRasterizer> {
    match WgpuRasterizer::with_options(opts) {
        Ok(r) => {
            eprintln!(
                "wgpu adapter: {} (native f32 atomics: {})",
                r.adapter_description(),
                r.native_f32_atomics()
            );
            Some(r)
        }
        Err(e) => {
            if std::env::var("CI").is_ok_and(|v| v == "true" || v == "1") {
                panic!("CI=true but no wgpu adapter: {e} (install mesa-vulkan-drivers)");
            }
            eprintln!("SKIPPED: no wgpu adapter ({e}); install mesa-vulkan-drivers for lavapipe");
            None
        }
    }
}

fn camera(w: u32, h: u32, f: f64, eye: DVec3) -> Camera {
    Camera::look_at(
        w,
        h,
        Intrinsics::new(f, f * 1.05, w as f64 * 0.5 + 0.3, h as f64 * 0.5 - 0.2),
        eye,
        DVec3::new(0.1, 0.05, 0.0),
        DVec3::new(0.1, -1.0, 0.0),
    )
    .unwrap()
}

fn cameras(w: u32, h: u32) -> Vec<Camera> {
    let f = w.max(h) as f64 * 0.9;
    vec![
        camera(w, h, f, DVec3::new(0.4, -0.3, -4.0)),
        camera(w, h, f * 0.6, DVec3::new(-2.5, 0.8, -2.0)),
        camera(w, h, f * 1.4, DVec3::new(1.0, 2.0, 3.0)),
    ]
}

/// `n` random Gaussians in a cube of half-size `spread` around the origin.
fn random_scene(n: usize, degree: u32, seed: u64, spread: f32, scale: (f32, f32)) -> Gaussians {
    let mut rng = Rng::new(seed);
    let mut g = Gaussians::with_len(0).unwrap();
    g.sh_degree = degree;
    for _ in 0..n {
        let mean = [
            rng.uniform_range(-spread, spread),
            rng.uniform_range(-spread, spread),
            rng.uniform_range(-spread, spread),
        ];
        let ls = [
            rng.uniform_range(scale.0, scale.1),
            rng.uniform_range(scale.0, scale.1),
            rng.uniform_range(scale.0 - 1.5, scale.1 - 1.0),
        ];
        let q = [rng.normal(), rng.normal(), rng.normal(), rng.normal()];
        let o: f32 = rng.uniform_range(0.05, 0.995);
        let mut sh = [[0.0f32; 3]; 16];
        for (k, c) in sh.iter_mut().enumerate() {
            for v in c.iter_mut() {
                *v = if k == 0 {
                    rng.uniform_range(-1.5, 1.5)
                } else {
                    0.3 * rng.normal()
                };
            }
        }
        g.push(mean, ls, q, gs_core::gaussians::inverse_sigmoid(o), sh);
    }
    g
}

fn random_image(w: u32, h: u32, c: usize, rng: &mut Rng) -> Image {
    let data = (0..w as usize * h as usize * c)
        .map(|_| rng.uniform_range(-1.0, 1.0))
        .collect();
    Image::from_vec(w as usize, h as usize, c, data).unwrap()
}

struct Grads {
    color: Image,
    alpha: Image,
    normal: Image,
    distance: Image,
    plane_depth: Image,
    expected_depth: Image,
}

impl Grads {
    fn new(w: u32, h: u32, seed: u64) -> Self {
        let mut rng = Rng::new(seed);
        Self {
            color: random_image(w, h, 3, &mut rng),
            alpha: random_image(w, h, 1, &mut rng),
            normal: random_image(w, h, 3, &mut rng),
            distance: random_image(w, h, 1, &mut rng),
            plane_depth: random_image(w, h, 1, &mut rng),
            expected_depth: random_image(w, h, 1, &mut rng),
        }
    }
    fn all(&self) -> OutputGradients<'_> {
        OutputGradients {
            color: Some(&self.color),
            alpha: Some(&self.alpha),
            normal: Some(&self.normal),
            distance: Some(&self.distance),
            plane_depth: Some(&self.plane_depth),
            expected_depth: Some(&self.expected_depth),
        }
    }
}

/// Pixels where a discrete decision flipped between the backends: a different last
/// contributor, or a final transmittance off by a power of (1 − 1/255) — a Gaussian whose α
/// sits at the skip threshold, kept by one backend only. (A hardware driver contracts the
/// `exp` polynomial into fused multiply-adds, so α differs by an ulp: seen on an NVIDIA H200,
/// never on lavapipe.) Any other transmittance difference fails here.
fn flipped_pixels(label: &str, cpu: &RenderOutput, gpu: &RenderOutput) -> Vec<usize> {
    let step = (1.0f64 - 1.0 / 255.0).ln();
    let mut out = Vec::new();
    for (i, (&a, &b)) in cpu.final_t.iter().zip(&gpu.final_t).enumerate() {
        if cpu.last_contributor[i] != gpu.last_contributor[i] {
            out.push(i);
        } else if (a - b).abs() > IMG_ABS {
            let k = ((b as f64) / (a as f64)).ln() / step;
            assert!(
                k.round() != 0.0 && (k - k.round()).abs() < 0.05,
                "{label}: final_t at pixel {i} differs (cpu {a}, gpu {b}) with the same last \
                 contributor, not by a threshold flip"
            );
            out.push(i);
        }
    }
    out
}

/// Gaussians whose screen box (projected mean ± radius, one pixel of slack) holds a flipped
/// pixel: their gradients include that pixel's changed terms and are compared loosely.
fn touched_by(g: &Gaussians, cam: &Camera, radii: &[u32], pixels: &[usize]) -> Vec<bool> {
    let w = cam.width as usize;
    (0..g.len())
        .map(|i| {
            let m = g.means[i];
            let Some((c, _)) = cam.project(DVec3::new(m[0] as f64, m[1] as f64, m[2] as f64)) else {
                return radii[i] > 0;
            };
            let r = radii[i] as f64 + 1.0;
            radii[i] > 0
                && pixels.iter().any(|&p| {
                    let (x, y) = ((p % w) as f64 + 0.5, (p / w) as f64 + 0.5);
                    (x - c.x).abs() <= r && (y - c.y).abs() <= r
                })
        })
        .collect()
}

fn compare_image(name: &str, cpu: Option<&Image>, gpu: Option<&Image>, rel: f32) {
    let (a, b) = match (cpu, gpu) {
        (None, None) => return,
        (Some(a), Some(b)) => (a, b),
        _ => panic!("{name}: rendered by one backend only"),
    };
    assert_eq!(
        (a.width(), a.height(), a.channels()),
        (b.width(), b.height(), b.channels()),
        "{name}: shape"
    );
    let (mut bad, mut worst) = (0usize, 0.0f32);
    for (x, y) in a.data().iter().zip(b.data()) {
        let d = (x - y).abs();
        assert!(y.is_finite(), "{name}: non-finite GPU value");
        if d > IMG_ABS + rel * x.abs() {
            bad += 1;
            worst = worst.max(d);
        }
    }
    let frac = bad as f64 / a.data().len() as f64;
    if std::env::var("GS_PARITY_STATS").is_ok() {
        eprintln!("ISTAT {name} bad {bad} of {} worst {worst}", a.data().len());
    }
    assert!(
        frac <= MAX_FLIP_FRACTION && worst <= FLIP_ABS.max(rel * 100.0),
        "{name}: {bad} of {} values beyond tolerance (worst {worst})",
        a.data().len()
    );
}

/// Compares every output; returns the flipped pixels (see [`flipped_pixels`]).
fn compare_outputs(label: &str, cpu: &RenderOutput, gpu: &RenderOutput) -> Vec<usize> {
    let npix = cpu.final_t.len();
    let flipped = flipped_pixels(label, cpu, gpu);
    let flips = flipped.len();
    if std::env::var("GS_PARITY_STATS").is_ok() {
        eprintln!("FSTAT {label} flips {flips}");
    }
    assert!(
        flips as f64 <= MAX_FLIP_FRACTION * npix as f64 + 1.0,
        "{label}: {flips} of {npix} pixels flipped a discrete decision"
    );
    compare_image(&format!("{label} color"), cpu.color.as_ref(), gpu.color.as_ref(), 0.0);
    compare_image(&format!("{label} alpha"), cpu.alpha.as_ref(), gpu.alpha.as_ref(), 0.0);
    compare_image(&format!("{label} normal"), cpu.normal.as_ref(), gpu.normal.as_ref(), 0.0);
    compare_image(
        &format!("{label} distance"),
        cpu.distance.as_ref(),
        gpu.distance.as_ref(),
        0.0,
    );
    compare_image(
        &format!("{label} plane_depth"),
        cpu.plane_depth.as_ref(),
        gpu.plane_depth.as_ref(),
        1e-4,
    );
    compare_image(
        &format!("{label} expected_depth"),
        cpu.expected_depth.as_ref(),
        gpu.expected_depth.as_ref(),
        1e-4,
    );
    if std::env::var("GS_PARITY_STATS").is_ok() {
        let radius_diffs = cpu.radii.iter().zip(&gpu.radii).filter(|(a, b)| a != b).count();
        eprintln!("TSTAT {label} flipped pixels {flipped:?}, radii differ {radius_diffs}");
    }
    // Radii: ceil(level·√λ) may flip by one where the driver's exp/log/sqrt differ by an ulp.
    assert_eq!(cpu.radii.len(), gpu.radii.len(), "{label}: radii length");
    let radius_diffs: Vec<usize> = (0..cpu.radii.len())
        .filter(|&i| cpu.radii[i] != gpu.radii[i])
        .collect();
    assert!(
        radius_diffs.len() as f64 <= 2.0 + 1e-3 * cpu.radii.len() as f64,
        "{label}: {} radii differ",
        radius_diffs.len()
    );
    if radius_diffs.is_empty() {
        assert_eq!(cpu.stats.intersections, gpu.stats.intersections, "{label}: intersections");
    }
    for &i in &radius_diffs {
        let (a, b) = (cpu.radii[i], gpu.radii[i]);
        assert!(
            a != 0 && b != 0 && a.abs_diff(b) <= 1,
            "{label}: radius[{i}] cpu {a} gpu {b}"
        );
    }
    assert_eq!(cpu.stats.visible, gpu.stats.visible, "{label}: visible");
    if cpu.last_contributor == gpu.last_contributor {
        assert_eq!(cpu.stats.forward_pairs, gpu.stats.forward_pairs, "{label}: forward pairs");
        assert_eq!(cpu.stats.backward_pairs, gpu.stats.backward_pairs, "{label}: backward pairs");
    }
    if let (Some(a), Some(b)) = (&cpu.observed, &gpu.observed) {
        let differing: Vec<usize> = (0..a.len()).filter(|&i| a[i] != b[i]).collect();
        assert!(
            differing.len() as f64 <= 2.0 + 1e-3 * a.len() as f64,
            "{label}: observed differs for {} Gaussians",
            differing.len()
        );
        for &i in &differing {
            assert!(
                a[i].abs_diff(b[i]) as usize <= 2 + flips,
                "{label}: observed[{i}] cpu {} gpu {} ({flips} flipped pixels)",
                a[i],
                b[i]
            );
        }
    } else {
        assert_eq!(cpu.observed.is_some(), gpu.observed.is_some(), "{label}: observed presence");
    }
    flipped
}

/// Relative L2 bound on the gradients of the Gaussians a flipped pixel touches: their terms
/// at that pixel change by one α ≈ 1/255 contribution, and the transmittance behind it by
/// 1/255 (measured on an NVIDIA H200: see BENCHMARKS.md).
const TOUCHED_L2: f64 = 0.05;

/// Per value within the tolerances of the module doc, except the values of Gaussians marked
/// in `touched` (one flag per Gaussian; empty = none), which must stay within [`TOUCHED_L2`].
fn compare_group(label: &str, name: &str, cpu: &[f32], gpu: &[f32], touched: &[bool]) {
    assert_eq!(cpu.len(), gpu.len());
    if cpu.is_empty() {
        return;
    }
    let per = if touched.is_empty() { cpu.len() } else { cpu.len() / touched.len() };
    let is_touched = |i: usize| !touched.is_empty() && touched[i / per];
    let max = cpu.iter().fold(0.0f64, |m, v| m.max(v.abs() as f64));
    let floor = GRAD_FLOOR * max;
    let (mut ok, mut num, mut den) = (0usize, 0.0f64, 0.0f64);
    let (mut n_touched, mut tnum, mut tden) = (0usize, 0.0f64, 0.0f64);
    let mut worst = (0usize, 0.0f32, 0.0f32);
    let mut worst_excess = 0.0f64;
    let mut listed = Vec::new();
    for (i, (&a, &b)) in cpu.iter().zip(gpu).enumerate() {
        assert!(b.is_finite(), "{label} {name}[{i}]: non-finite GPU gradient {b}");
        let d = (a as f64 - b as f64).abs();
        if is_touched(i) {
            n_touched += 1;
            tnum += d * d;
            tden += (a as f64) * (a as f64);
            continue;
        }
        let tol = GRAD_REL * (a as f64).abs() + floor;
        if d <= tol {
            ok += 1;
        } else {
            if listed.len() < 12 {
                listed.push(format!("[{i}] {a} / {b}"));
            }
            if d / tol > worst_excess {
                worst_excess = d / tol;
                worst = (i, a, b);
            }
        }
        num += d * d;
        den += (a as f64) * (a as f64);
    }
    let strict = cpu.len() - n_touched;
    let outliers = strict - ok;
    let rel = |num: f64, den: f64| if den > 0.0 { (num / den).sqrt() } else { num.sqrt() };
    let (l2, tl2) = (rel(num, den), rel(tnum, tden));
    if std::env::var("GS_PARITY_STATS").is_ok() {
        eprintln!(
            "STAT {label} {name} bad {outliers} of {strict} l2 {l2:e}; touched {n_touched} l2 {tl2:e}"
        );
        if outliers > 0 {
            eprintln!("  outliers (cpu / gpu; max |cpu| {max:e}): {}", listed.join(", "));
        }
    }
    assert!(
        outliers as f64 <= 2.0 + GRAD_OUTLIER_FRACTION * strict as f64 && l2 <= GRAD_L2,
        "{label} {name}: {outliers} of {strict} values beyond tolerance, relative L2 {l2:.2e}; worst [{}] cpu {} gpu {}",
        worst.0,
        worst.1,
        worst.2
    );
    assert!(
        tl2 <= TOUCHED_L2,
        "{label} {name}: the {n_touched} values of Gaussians at flipped pixels differ by relative L2 {tl2:.2e}"
    );
}

fn flat<const K: usize>(v: &[[f32; K]]) -> Vec<f32> {
    v.iter().flatten().copied().collect()
}

/// Every gradient group (see [`compare_group`]; `touched` from [`touched_by`], or empty).
fn compare_grads(label: &str, cpu: &GaussianGradients, gpu: &GaussianGradients, touched: &[bool]) {
    let t = touched;
    compare_group(label, "means", &flat(&cpu.means), &flat(&gpu.means), t);
    compare_group(label, "log_scales", &flat(&cpu.log_scales), &flat(&gpu.log_scales), t);
    compare_group(label, "rotations", &flat(&cpu.rotations), &flat(&gpu.rotations), t);
    compare_group(label, "opacity", &cpu.opacity_logits, &gpu.opacity_logits, t);
    let sh = |g: &GaussianGradients| -> Vec<f32> {
        g.sh.iter().flat_map(|c| c.iter().flatten().copied()).collect()
    };
    compare_group(label, "sh", &sh(cpu), &sh(gpu), t);
    compare_group(label, "mean2d", &flat(&cpu.mean2d), &flat(&gpu.mean2d), t);
    compare_group(label, "mean2d_abs", &flat(&cpu.mean2d_abs), &flat(&gpu.mean2d_abs), t);
}

/// Forward (all channels) and backward (all gradients) parity of one scene and camera.
fn parity(r: &mut WgpuRasterizer, label: &str, g: &Gaussians, cam: &Camera, cfg: &RasterConfig) {
    let req = RenderRequest::all();
    let cpu = gs_raster::render(g, cam, &req, cfg).unwrap();
    let gpu = r.render(g, cam, &req, cfg).unwrap();
    let flipped = compare_outputs(label, &cpu, &gpu);
    let touched = touched_by(g, cam, &cpu.radii, &flipped);
    let grads = Grads::new(cam.width, cam.height, 7);
    let gc = gs_raster::backward(g, cam, cfg, &cpu, &grads.all()).unwrap();
    let gg = r.backward(g, cam, cfg, &gpu, &grads.all()).unwrap();
    compare_grads(label, &gc, &gg, &touched);
}

fn run_scenes(r: &mut WgpuRasterizer, n: usize, w: u32, h: u32, seed: u64) {
    for degree in [0, 3] {
        for antialiased in [false, true] {
            let g = random_scene(n, degree, seed + degree as u64, 1.0, (-3.5, -2.0));
            let cfg = RasterConfig {
                antialiased,
                background: [0.2, 0.5, 0.9],
                ..RasterConfig::default()
            };
            for (c, cam) in cameras(w, h).iter().enumerate() {
                let label = format!("n={n} deg={degree} aa={antialiased} cam={c}");
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

/// A hardware GPU runs many workgroups at once where lavapipe runs few: the forward must
/// repeat bit for bit, and the backward up to the order of its atomic adds; anything more is
/// a race in a kernel.
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
            for (name, x, y) in [
                ("means", flat(&ga.means), flat(&gb.means)),
                ("log_scales", flat(&ga.log_scales), flat(&gb.log_scales)),
                ("opacity", ga.opacity_logits.clone(), gb.opacity_logits.clone()),
            ] {
                let num: f64 = x.iter().zip(&y).map(|(p, q)| ((p - q) as f64).powi(2)).sum();
                let den: f64 = x.iter().map(|p| (*p as f64).powi(2)).sum();
                let rel = (num / den.max(1e-30)).sqrt();
                if std::env::var("GS_PARITY_STATS").is_ok() {
                    eprintln!("RSTAT case {k} {name}: relative L2 between runs {rel:e}");
                }
                assert!(rel <= 1e-5, "case {k} {name}: runs differ, relative L2 {rel:e}");
            }
        }
    }
}

#[test]
fn parity_with_compare_exchange_atomics() {
    let Some(mut r) = gpu(WgpuOptions {
        force_cas_atomics: true,
        ..Default::default()
    }) else {
        return;
    };
    assert!(!r.native_f32_atomics());
    run_scenes(&mut r, 300, 96, 80, 5);
}

#[test]
fn parity_for_channel_subsets_and_single_gradients() {
    let Some(mut r) = gpu(WgpuOptions::default()) else { return };
    let g = random_scene(400, 1, 6, 1.0, (-3.5, -2.0));
    let cam = &cameras(80, 64)[0];
    let cfg = RasterConfig::default();
    let grads = Grads::new(80, 64, 9);
    let requests = [
        RenderRequest::default(),
        RenderRequest {
            color: false,
            alpha: false,
            plane_depth: true,
            ..RenderRequest::default()
        },
        RenderRequest {
            color: true,
            alpha: false,
            expected_depth: true,
            observed: true,
            ..RenderRequest::default()
        },
        RenderRequest {
            color: false,
            alpha: true,
            normal: true,
            distance: true,
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
        };
        let gc = gs_raster::backward(&g, cam, &cfg, &cpu, &og).unwrap();
        let gg = r.backward(&g, cam, &cfg, &gpu, &og).unwrap();
        compare_grads(&label, &gc, &gg, &touched);
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
    // past the forward window (32768 entries) and the backward runs ~160 windows.
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

/// design.md §4 extremes (scales, quaternions, opacities, positions, edge-on planes, one
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
    let g = random_scene(3000, 1, 80, 1.2, (-3.5, -2.0));
    for (w, h) in [(200, 300), (200, 257)] {
        let cam = camera(w, h, 250.0, DVec3::new(0.4, -0.3, -4.0));
        parity(&mut r, &format!("bands {w}x{h}"), &g, &cam, &cfg);
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
    // (Equal up to the order of the float atomics, which varies between runs.)
    compare_grads("rebuilt state", &fresh, &stale, &[]);
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
    let out = w.render(&g, &cam, &RenderRequest::default(), &cfg).unwrap();
    let ones = Image::filled(40, 30, 3, 1.0).unwrap();
    let og = OutputGradients {
        color: Some(&ones),
        ..Default::default()
    };
    let gg = w.backward(&g, &cam, &cfg, &out, &og).unwrap();
    let cpu_out = gs_raster::render(&g, &cam, &RenderRequest::default(), &cfg).unwrap();
    let gc = gs_raster::backward(&g, &cam, &cfg, &cpu_out, &og).unwrap();
    let touched = touched_by(&g, &cam, &cpu_out.radii, &flipped_pixels("selector", &cpu_out, &out));
    compare_grads("selector", &gc, &gg, &touched);
}
