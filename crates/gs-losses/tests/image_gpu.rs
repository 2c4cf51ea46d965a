#![cfg(feature = "wgpu")]
//! Parity of L_I on the device ([`ImageLossGpu`]) with the CPU reference
//! ([`gs_losses::ssim::ssim_backward`] and [`image_loss`]), both in f32: random and smooth
//! images, 1 and 3 channels, sizes below, at and above the 11-tap window, with and without the
//! edge term. Without a wgpu adapter the tests print one SKIPPED line (a failure under
//! `CI=true`).
//!
//! Tolerances (f32 on both sides; the device may fuse a·b + c, the host does not): the mean
//! SSIM within 1e-6 absolute, L1 within 1e-6 relative (|a − b| rounds the same everywhere, but
//! the device sums each row in compensated f32 where the reference sums in f64), the edge term
//! within 1e-6 relative (a device may round 1/x differently), the gradient within 3e-4
//! relative L2 error (lavapipe: at most 4.7e-5 at 200×150×3).

use gs_core::{Image, Rng};
use gs_gpu::{GpuContext, GpuOptions};
use gs_losses::ssim::ssim_backward;
use gs_losses::{Dims, EdgeGuide, ImageLossConfig, ImageLossGpu, SsimRegion, image_loss};

fn gpu() -> Option<ImageLossGpu> {
    gpu_and_context().map(|(g, _)| g)
}

/// The executor and its context (for its traffic ledger).
fn gpu_and_context() -> Option<(ImageLossGpu, GpuContext)> {
    let c = gs_testdata::wgpu_context!(&GpuOptions::default())?;
    Some((ImageLossGpu::new(&c).expect("the L_I kernels on an adapter that exists"), c))
}

/// A rendered-like image and a ground truth near it: smooth structure plus noise.
fn pair(w: usize, h: usize, c: usize, seed: u64) -> (Vec<f32>, Vec<f32>) {
    let mut rng = Rng::new(seed);
    let n = w * h * c;
    let gt: Vec<f32> = (0..n).map(|i| (0.5 + 0.4 * ((i % (w * c)) as f32 * 0.13).sin() * ((i / (w * c)) as f32 * 0.21).cos()).clamp(0.0, 1.0)).collect();
    let a = gt.iter().map(|&v| (v + 0.15 * (rng.uniform() - 0.5)).clamp(0.0, 1.0)).collect();
    (a, gt)
}

fn relative_l2(x: &[f32], y: &[f32]) -> f64 {
    let num: f64 = x.iter().zip(y).map(|(a, b)| ((a - b) as f64).powi(2)).sum();
    let den: f64 = x.iter().map(|a| (*a as f64).powi(2)).sum();
    (num / den.max(1e-30)).sqrt()
}

#[test]
fn device_ssim_and_gradient_match_the_cpu_reference() {
    let Some(mut g) = gpu() else { return };
    for (w, h, c) in [(7, 5, 1), (11, 11, 3), (64, 48, 3), (200, 150, 3), (33, 70, 1)] {
        let (a, b) = pair(w, h, c, (w * h * c) as u64);
        let dims = Dims { width: w, height: h, channels: c };
        let mut gc = vec![0.25f32; a.len()];
        let mut gd = gc.clone();
        let sc = ssim_backward(&a, &b, dims, SsimRegion::Full, -0.2, &mut gc).unwrap();
        let sd = g.ssim_backward(&a, &b, dims, -0.2, &mut gd).unwrap();
        let e = relative_l2(&gc.iter().map(|v| v - 0.25).collect::<Vec<_>>(), &gd.iter().map(|v| v - 0.25).collect::<Vec<_>>());
        eprintln!("{w}x{h}x{c}: SSIM {sc:.7} (CPU) vs {sd:.7} (device), gradient relative L2 {e:.2e}");
        assert!((sc - sd).abs() < 1e-6, "{w}x{h}x{c}: SSIM {sc} vs {sd}");
        assert!(e < 3e-4, "{w}x{h}x{c}: gradient relative L2 error {e:e}");
        // One input, one result.
        let mut again = vec![0.25f32; a.len()];
        assert_eq!(g.ssim_backward(&a, &b, dims, -0.2, &mut again).unwrap(), sd);
        assert_eq!(again, gd);
    }
}

#[test]
fn device_image_loss_matches_with_and_without_the_edge_term() {
    let Some(mut g) = gpu() else { return };
    for (w, h, c) in [(80, 60, 3), (200, 150, 3), (37, 23, 1), (3, 3, 3), (2, 7, 3), (1, 1, 1)] {
        let (a, b) = pair(w, h, c, (w + h) as u64);
        let (rendered, gt) = (Image::from_vec(w, h, c, a).unwrap(), Image::from_vec(w, h, c, b).unwrap());
        let guide = EdgeGuide::from_gt(&gt).unwrap();
        for edge in [true, false] {
            let cfg = ImageLossConfig { edge, ..Default::default() };
            let what = format!("{w}x{h}x{c} edge {edge}");
            let cpu = image_loss(&rendered, &gt, Some(&guide), &cfg).unwrap();
            let dev = g.image_loss(&rendered, &gt, Some(&guide), &cfg).unwrap();
            let e = relative_l2(cpu.grad_rendered.data(), dev.grad_rendered.data());
            eprintln!(
                "{what}: L1 {:.7e} / {:.7e}, SSIM {:.7} / {:.7}, edge {:?} / {:?}, gradient relative L2 {e:.2e}",
                cpu.l1, dev.l1, cpu.ssim, dev.ssim, cpu.edge, dev.edge
            );
            assert!((cpu.l1 - dev.l1).abs() <= 1e-6 * cpu.l1.abs().max(1e-12), "{what}: L1 {} vs {}", cpu.l1, dev.l1);
            assert_eq!(cpu.edge.is_some(), dev.edge.is_some(), "{what}: edge term on");
            if let (Some(x), Some(y)) = (cpu.edge, dev.edge) {
                assert!((x - y).abs() <= 1e-6 * x.abs().max(1e-12), "{what}: edge {x} vs {y}");
            }
            assert!((cpu.ssim - dev.ssim).abs() < 1e-6 && (cpu.total - dev.total).abs() < 1e-6, "{what}: SSIM or total");
            assert!(e < 3e-4, "{what}: ∂L_I/∂Ĩ relative L2 error {e:e}");
            // One input, one result.
            let again = g.image_loss(&rendered, &gt, Some(&guide), &cfg).unwrap();
            assert_eq!((again.total, again.grad_rendered.data()), (dev.total, dev.grad_rendered.data()), "{what}: repeat");
        }
    }
    // The edge term's own gradient: L_I at β1 = 0 is L1 plus the edge term, with no SSIM noise
    // in the comparison.
    let (w, h) = (64, 48);
    let (a, b) = pair(w, h, 3, 9);
    let (rendered, gt) = (Image::from_vec(w, h, 3, a).unwrap(), Image::from_vec(w, h, 3, b).unwrap());
    let guide = EdgeGuide::from_gt(&gt).unwrap();
    let cfg = ImageLossConfig { beta1: 0.0, beta2: 1.0, edge: true };
    let cpu = image_loss(&rendered, &gt, Some(&guide), &cfg).unwrap();
    let dev = g.image_loss(&rendered, &gt, Some(&guide), &cfg).unwrap();
    let e = relative_l2(cpu.grad_rendered.data(), dev.grad_rendered.data());
    assert!(e < 1e-6, "L1 + edge gradient relative L2 error {e:e}");
    // Mismatched sizes and a missing guide are refused as on the CPU.
    let small = Image::from_vec(4, 4, 3, vec![0.5; 48]).unwrap();
    assert!(g.image_loss(&small, &gt, None, &ImageLossConfig { edge: false, ..cfg }).is_err());
    let msg = g.image_loss(&rendered, &gt, None, &cfg).unwrap_err().to_string();
    assert!(msg.contains("EdgeGuide"), "{msg}");
}

/// An evaluation reads back the gradient and three totals (SSIM, L1, edge; each a double-f32
/// pair of 8 bytes), in one round trip: not every value's terms, nor a sum a row.
#[test]
fn an_evaluation_reads_back_the_gradient_and_three_totals() {
    let Some((mut g, ctx)) = gpu_and_context() else { return };
    let (w, h, c) = (200, 150, 3);
    let (a, b) = pair(w, h, c, 4);
    let (rendered, gt) = (Image::from_vec(w, h, c, a).unwrap(), Image::from_vec(w, h, c, b).unwrap());
    let guide = EdgeGuide::from_gt(&gt).unwrap();
    let before = ctx.transfers();
    g.image_loss(&rendered, &gt, Some(&guide), &ImageLossConfig::default()).unwrap();
    let t = ctx.transfers() - before;
    assert_eq!((t.syncs, t.bytes_down), (1, 4 * (w * h * c) as u64 + 24));
}

/// A view's photo and edge guide stay on the device under its key: the second evaluation of a
/// view uploads the rendered image alone, and views taken in turn (other sizes too) give the
/// results of evaluations that upload everything.
#[test]
fn a_views_photo_and_guide_are_uploaded_once() {
    let Some((mut g, ctx)) = gpu_and_context() else { return };
    let cfg = ImageLossConfig::default();
    let views: Vec<(Image, Image, EdgeGuide)> = [(200, 150, 3, 1), (200, 150, 3, 2), (100, 75, 3, 3)]
        .into_iter()
        .map(|(w, h, c, seed)| {
            let (a, b) = pair(w, h, c, seed);
            let gt = Image::from_vec(w, h, c, b).unwrap();
            let guide = EdgeGuide::from_gt(&gt).unwrap();
            (Image::from_vec(w, h, c, a).unwrap(), gt, guide)
        })
        .collect();
    let mut reference = ImageLossGpu::new(&ctx).unwrap();
    for round in 0..3 {
        for (key, (rendered, gt, guide)) in views.iter().enumerate() {
            let before = ctx.transfers();
            let kept = g.image_loss_of_view(rendered, gt, Some(guide), key as u64, &cfg).unwrap();
            let up = (ctx.transfers() - before).bytes_up;
            let whole = reference.image_loss(rendered, gt, Some(guide), &cfg).unwrap();
            assert_eq!((kept.total, kept.grad_rendered.data()), (whole.total, whole.grad_rendered.data()), "view {key} round {round}");
            let (n, pixels) = (rendered.data().len() as u64, (rendered.width() * rendered.height()) as u64);
            // The rendered image, plus the photo and the guide on first use; uniforms besides.
            let images = 4 * if round == 0 { 2 * n + pixels } else { n };
            assert!(up >= images && up < images + 4096, "view {key} round {round}: {up} bytes written, {images} of images");
        }
    }
}

/// A rendered image kept on the device (a render's colour that never came to the host): the
/// same values and gradient bits as the evaluation of its host copy, and only the row sums come
/// back; nothing per value goes up after the view's photo and guide are held.
#[test]
fn a_rendered_image_on_the_device_gives_the_same_result_and_its_gradient_stays_there() {
    let Some((mut g, ctx)) = gpu_and_context() else { return };
    let cfg = ImageLossConfig::default();
    for (w, h, c) in [(200, 150, 3), (37, 23, 3), (1, 1, 3)] {
        let (a, b) = pair(w, h, c, (3 * w + h) as u64);
        let (rendered, gt) = (Image::from_vec(w, h, c, a).unwrap(), Image::from_vec(w, h, c, b).unwrap());
        let guide = EdgeGuide::from_gt(&gt).unwrap();
        let on_device = gs_gpu::DeviceImage::upload(&ctx, "rendered", (w, h, c), rendered.data()).unwrap();
        let host = g.image_loss_of_view(&rendered, &gt, Some(&guide), 7, &cfg).unwrap();
        let before = ctx.transfers();
        let started = g.start_on_device(&on_device, &gt, Some(&guide), Some(7), &cfg).unwrap();
        let dev = g.finish_on_device(started).unwrap();
        let t = ctx.transfers() - before;
        let what = format!("{w}x{h}x{c}");
        assert_eq!((t.syncs, t.bytes_down), (1, 24), "{what}: the three totals alone come back");
        assert!(t.bytes_up < 4096, "{what}: {} bytes written (uniforms alone)", t.bytes_up);
        assert_eq!((dev.l1, dev.ssim, dev.edge, dev.total), (host.l1, host.ssim, host.edge, host.total), "{what}: values");
        assert_eq!(dev.grad_rendered.read(&ctx).unwrap(), host.grad_rendered.data(), "{what}: gradient bits");
    }
    // A size mismatch is refused as on the host.
    let small = gs_gpu::DeviceImage::new(&ctx, "small", 4, 4, 3).unwrap();
    let gt = Image::from_vec(8, 4, 3, vec![0.5; 96]).unwrap();
    let err = g.start_on_device(&small, &gt, None, None, &ImageLossConfig { edge: false, ..cfg }).err().expect("refused");
    assert!(err.to_string().contains("4×4×3"), "{err}");
}
