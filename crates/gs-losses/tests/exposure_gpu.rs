#![cfg(feature = "wgpu")]
//! Exposure compensation on the device (`ExposureGpu`) against its CPU reference
//! (`apply_exposure`, `exposure_backward`), on an RGB image of odd size with varied colours,
//! gains and biases, and what comes back (the six totals). Tolerances (f32 on both sides; the
//! device may fuse a multiply-add, and sums each row in compensated f32 and the rows as
//! double-f32 pairs where the host sums in f64): the corrected colour and
//! ∂L/∂c within 2 ulp-scale of each value (1e-6 relative to its magnitude), ∂L/∂(a, b) within
//! 1e-5 relative. Without a wgpu adapter the tests print one SKIPPED line (a failure under
//! `CI=true`).

use gs_core::{Image, Rng};
use gs_gpu::{DeviceImage, GpuOptions};
use gs_losses::{ExposureGpu, apply_exposure, exposure_backward};

fn image(w: usize, h: usize, seed: u64, lo: f32, hi: f32) -> Image {
    let mut rng = Rng::new(seed);
    let data = (0..w * h * 3).map(|_| lo + (hi - lo) * rng.uniform()).collect();
    Image::from_vec(w, h, 3, data).unwrap()
}

fn close(a: &[f32], b: &[f32], what: &str) {
    assert_eq!(a.len(), b.len());
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        assert!((x - y).abs() <= 1e-6 * (x.abs() + y.abs()).max(1e-3), "{what} value {k}: {x} against {y}");
    }
}

#[test]
fn the_device_corrects_and_back_propagates_as_the_host() {
    let Some(ctx) = gs_testdata::wgpu_context!(&GpuOptions::default()) else { return };
    let mut gpu = ExposureGpu::new(&ctx).unwrap();
    let (w, h) = (37, 23);
    let color = image(w, h, 1, 0.0, 1.0);
    let grad = image(w, h, 2, -1e-3, 1e-3);
    let e = [0.12, -0.3, 0.05, 0.02, -0.04, 0.01];
    let up = |i: &Image| DeviceImage::upload(&ctx, "test", (w, h, 3), i.data()).unwrap();
    let (dc, dg) = (up(&color), up(&grad));
    let corrected = gpu.apply(&dc, &e).unwrap();
    close(&corrected.read(&ctx).unwrap(), apply_exposure(&color, &e).unwrap().data(), "corrected colour");
    let (gc, ge) = gpu.backward(&dc, &e, &dg).unwrap();
    let (host_gc, host_ge) = exposure_backward(&color, &e, &grad).unwrap();
    close(&gc.read(&ctx).unwrap(), host_gc.data(), "∂L/∂c");
    for k in 0..6 {
        let (x, y) = (ge[k], host_ge[k]);
        assert!(host_ge[k] != 0.0 && (x - y).abs() <= 1e-5 * y.abs(), "∂L/∂(a, b)[{k}]: {x} against {y}");
    }
    // The same inputs give the same bits.
    let before = ctx.transfers();
    let (gc2, ge2) = gpu.backward(&dc, &e, &dg).unwrap();
    let t = ctx.transfers() - before;
    assert_eq!((t.syncs, t.bytes_down), (1, 64), "the six totals alone come back, as double-f32 pairs");
    assert_eq!((gc2.read(&ctx).unwrap(), ge2), (gc.read(&ctx).unwrap(), ge));
    // Refused with the problem named: a grey image, a gradient of another size.
    let grey = DeviceImage::new(&ctx, "grey", w, h, 1).unwrap();
    assert!(gpu.apply(&grey, &e).unwrap_err().to_string().contains("1 channels"));
    let small = DeviceImage::new(&ctx, "small", w - 1, h, 3).unwrap();
    assert!(gpu.backward(&dc, &e, &small).unwrap_err().to_string().contains("36x23"));
}
