#![cfg(feature = "wgpu")]
//! Parity of D-SSIM on the device ([`SsimGpu`]) with the CPU reference
//! ([`gs_losses::ssim::ssim_backward`] and [`image_loss`]), both in f32: random and smooth
//! images, 1 and 3 channels, sizes below, at and above the 11-tap window. Without a wgpu
//! adapter the tests print one SKIPPED line (a failure under `CI=true`).
//!
//! Tolerances (f32 on both sides; the device may fuse a·b + c, the host does not): the mean
//! SSIM within 1e-6 absolute, the gradient within 3e-4 relative L2 error (lavapipe: at most
//! 4.7e-5 at 200×150×3).

use gs_core::{Image, Rng};
use gs_gpu::{GpuContext, GpuOptions};
use gs_losses::ssim::ssim_backward;
use gs_losses::{Dims, EdgeGuide, ImageLossConfig, SsimGpu, SsimRegion, image_loss};

fn gpu() -> Option<SsimGpu> {
    match GpuContext::new(&GpuOptions::default()) {
        Ok(c) => {
            eprintln!("wgpu adapter: {}", c.description());
            Some(SsimGpu::new(&c).expect("the SSIM kernels on an adapter that exists"))
        }
        Err(e) => {
            gs_testdata::skip_or_fail!(&format!("no wgpu adapter: {e}"), "install mesa-vulkan-drivers for lavapipe");
            None
        }
    }
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
fn device_image_loss_matches_with_the_edge_term() {
    let Some(mut g) = gpu() else { return };
    let (w, h) = (80, 60);
    let (a, b) = pair(w, h, 3, 5);
    let (rendered, gt) = (Image::from_vec(w, h, 3, a).unwrap(), Image::from_vec(w, h, 3, b).unwrap());
    let guide = EdgeGuide::from_gt(&gt).unwrap();
    let cfg = ImageLossConfig::default();
    let cpu = image_loss(&rendered, &gt, Some(&guide), &cfg).unwrap();
    let dev = g.image_loss(&rendered, &gt, Some(&guide), &cfg).unwrap();
    assert_eq!((cpu.l1, cpu.edge), (dev.l1, dev.edge), "L1 and the edge term run on the host in both");
    assert!((cpu.ssim - dev.ssim).abs() < 1e-6 && (cpu.total - dev.total).abs() < 1e-6);
    let e = relative_l2(cpu.grad_rendered.data(), dev.grad_rendered.data());
    assert!(e < 3e-4, "∂L_I/∂Ĩ relative L2 error {e:e}");
    // Mismatched sizes are refused as on the CPU.
    let small = Image::from_vec(4, 4, 3, vec![0.5; 48]).unwrap();
    assert!(g.image_loss(&small, &gt, None, &ImageLossConfig { edge: false, ..cfg }).is_err());
}
