//! How the parity tests compare the two backends' outputs and gradients.
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
//!   only, its α an ulp apart: seen on an NVIDIA H200, never on lavapipe); any other
//!   difference in T fails.
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
use gs_core::{Camera, Gaussians, Image};
use super::scenes::Grads;
use gs_raster::{GaussianGradients, RasterConfig, RenderOutput, RenderRequest, WgpuRasterizer};

pub const IMG_ABS: f32 = 1e-4;
pub const MAX_FLIP_FRACTION: f64 = 2e-3;
pub const FLIP_ABS: f32 = 0.05;
pub const GRAD_REL: f64 = 1e-3;
pub const GRAD_FLOOR: f64 = 1e-5;
pub const GRAD_OUTLIER_FRACTION: f64 = 0.005;
pub const GRAD_L2: f64 = 2e-3;

/// Pixels where a discrete decision flipped between the backends: a different last
/// contributor, or a final transmittance off by a power of (1 − 1/255) — a Gaussian whose α
/// sits at the skip threshold, kept by one backend only (its α an ulp apart: seen on an NVIDIA
/// H200, never on lavapipe). Any other transmittance difference fails here.
pub fn flipped_pixels(label: &str, cpu: &RenderOutput, gpu: &RenderOutput) -> Vec<usize> {
    let step = (1.0f64 - 1.0 / 255.0).ln();
    let mut out = Vec::new();
    assert!(
        gpu.final_t.len() == cpu.final_t.len() && gpu.last_contributor.len() == cpu.last_contributor.len(),
        "{label}: compare renders requested with `traversal` (T_final and last contributors read back)"
    );
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
pub fn touched_by(g: &Gaussians, cam: &Camera, radii: &[u32], pixels: &[usize]) -> Vec<bool> {
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

pub fn compare_image(name: &str, cpu: Option<&Image>, gpu: Option<&Image>, rel: f32) {
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
pub fn compare_outputs(label: &str, cpu: &RenderOutput, gpu: &RenderOutput) -> Vec<usize> {
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
pub const TOUCHED_L2: f64 = 0.05;

/// Per value within the tolerances of the module doc, except the values of Gaussians marked
/// in `touched` (one flag per Gaussian; empty = none), which must stay within [`TOUCHED_L2`].
pub fn compare_group(label: &str, name: &str, cpu: &[f32], gpu: &[f32], touched: &[bool]) {
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

pub fn flat<const K: usize>(v: &[[f32; K]]) -> Vec<f32> {
    v.iter().flatten().copied().collect()
}

/// Every gradient group (see [`compare_group`]; `touched` from [`touched_by`], or empty).
pub fn compare_grads(label: &str, cpu: &GaussianGradients, gpu: &GaussianGradients, touched: &[bool]) {
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
pub fn parity(r: &mut WgpuRasterizer, label: &str, g: &Gaussians, cam: &Camera, cfg: &RasterConfig) {
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

/// Every gradient array of `a` and `b` has the same bits (and is not all zero).
pub fn assert_same_bits(label: &str, a: &GaussianGradients, b: &GaussianGradients) {
    let bits = |v: Vec<f32>| v.into_iter().map(f32::to_bits).collect::<Vec<_>>();
    let sh = |g: &GaussianGradients| g.sh.iter().flatten().flatten().copied().collect();
    for (name, x, y) in [
        ("means", flat(&a.means), flat(&b.means)),
        ("log_scales", flat(&a.log_scales), flat(&b.log_scales)),
        ("rotations", flat(&a.rotations), flat(&b.rotations)),
        ("opacity", a.opacity_logits.clone(), b.opacity_logits.clone()),
        ("mean2d", flat(&a.mean2d), flat(&b.mean2d)),
        ("mean2d_abs", flat(&a.mean2d_abs), flat(&b.mean2d_abs)),
        ("sh", sh(a), sh(b)),
    ] {
        assert!(x.iter().any(|v| *v != 0.0), "{label} {name}: all zero");
        assert!(bits(x) == bits(y), "{label} {name}: runs differ");
    }
}
