//! Forward + backward of every loss at 800×600 (and the metrics), CPU, rayon default threads;
//! with the `wgpu` feature and an adapter, also the device twins of L_I and L_nc / L_ns.

use criterion::{Criterion, criterion_group, criterion_main};
use gs_core::{Image, Intrinsics, Rng};
use gs_losses::gradient::{edge_l1, image_gradient, image_gradient_backward};
use gs_losses::l1::{l1, l1_backward};
use gs_losses::ssim::ssim_backward;
use gs_losses::{
    Dims, EdgeGuide, ImageLossConfig, Lpips, NormalLossConfig, SsimRegion, image_loss,
    normal_losses, psnr, ssim_metric,
};
use std::hint::black_box;

const W: usize = 800;
const H: usize = 600;

fn smooth_image(rng: &mut Rng, c: usize) -> Image {
    let (a, b) = (rng.uniform() * 10.0, rng.uniform() * 10.0);
    let data = (0..W * H * c)
        .map(|i| {
            let (p, k) = (i / c, i % c);
            let (x, y) = ((p % W) as f32 / W as f32, (p / W) as f32 / H as f32);
            (0.5 + 0.3 * (a * x + k as f32).sin() * (b * y).cos() + 0.1 * rng.uniform())
                .clamp(0.0, 1.0)
        })
        .collect();
    Image::from_vec(W, H, c, data).unwrap()
}

fn bench(c: &mut Criterion) {
    let mut rng = Rng::new(7);
    let gt = smooth_image(&mut rng, 3);
    let rendered = smooth_image(&mut rng, 3);
    let dims = Dims::of(&gt);
    let guide = EdgeGuide::from_gt(&gt).unwrap();
    let mut g = c.benchmark_group("losses_800x600");
    g.sample_size(10);
    g.bench_function("l1_fwd_bwd", |b| {
        b.iter(|| {
            let mut grad = vec![0.0f32; dims.len()];
            let v = l1(rendered.data(), gt.data());
            l1_backward(rendered.data(), gt.data(), 0.8, &mut grad);
            black_box((v, grad))
        })
    });
    g.bench_function("ssim_fwd_bwd", |b| {
        b.iter(|| {
            let mut grad = vec![0.0f32; dims.len()];
            let v = ssim_backward(
                rendered.data(),
                gt.data(),
                dims,
                SsimRegion::Full,
                -0.2,
                &mut grad,
            )
            .unwrap();
            black_box((v, grad))
        })
    });
    g.bench_function("edge_fwd_bwd", |b| {
        b.iter(|| {
            let gr = image_gradient(rendered.data(), dims);
            let mut up = vec![0.0f32; dims.pixels()];
            let e = edge_l1(&gr.map, guide.gradient.data(), 0.03, Some(&mut up));
            let mut grad = vec![0.0f32; dims.len()];
            image_gradient_backward(rendered.data(), dims, &gr, &up, &mut grad);
            black_box((e, grad))
        })
    });
    g.bench_function("edge_guide_from_gt", |b| {
        b.iter(|| black_box(EdgeGuide::from_gt(&gt).unwrap()))
    });
    g.bench_function("image_loss_L_I_fwd_bwd", |b| {
        b.iter(|| {
            black_box(
                image_loss(&rendered, &gt, Some(&guide), &ImageLossConfig::default()).unwrap(),
            )
        })
    });
    // Normal terms on a smooth depth map and noisy normals.
    let k = Intrinsics::new(800.0, 800.0, 400.0, 300.0);
    let z = Image::from_vec(
        W,
        H,
        1,
        (0..W * H)
            .map(|p| {
                2.0 + 0.2 * ((p % W) as f32 / 90.0).sin() + 0.1 * ((p / W) as f32 / 70.0).cos()
            })
            .collect(),
    )
    .unwrap();
    let n = Image::from_vec(
        W,
        H,
        3,
        (0..W * H * 3)
            .map(|i| {
                if i % 3 == 2 {
                    -0.95
                } else {
                    0.2 * (rng.uniform() - 0.5)
                }
            })
            .collect(),
    )
    .unwrap();
    g.bench_function("normal_losses_L_nc_L_ns_fwd_bwd", |b| {
        b.iter(|| {
            black_box(
                normal_losses(&z, &n, None, &guide, &k, &NormalLossConfig::default()).unwrap(),
            )
        })
    });
    // The device twins (behind the `wgpu` feature, on the default adapter when there is one;
    // each call uploads its inputs and reads its outputs back, as training calls them today).
    #[cfg(feature = "wgpu")]
    if let Ok(ctx) = gs_gpu::GpuContext::new(&gs_gpu::GpuOptions::default()) {
        let mut normal = gs_losses::NormalGpu::new(&ctx).unwrap();
        g.bench_function("normal_losses_L_nc_L_ns_fwd_bwd_wgpu", |b| {
            b.iter(|| black_box(normal.normal_losses(&z, &n, None, &guide, &k, &NormalLossConfig::default()).unwrap()))
        });
        let mut image = gs_losses::ImageLossGpu::new(&ctx).unwrap();
        g.bench_function("image_loss_L_I_fwd_bwd_wgpu", |b| {
            b.iter(|| black_box(image.image_loss(&rendered, &gt, Some(&guide), &ImageLossConfig::default()).unwrap()))
        });
    }
    g.bench_function("psnr", |b| {
        b.iter(|| black_box(psnr(&rendered, &gt).unwrap()))
    });
    g.bench_function("ssim_metric", |b| {
        b.iter(|| black_box(ssim_metric(&rendered, &gt).unwrap()))
    });
    let lp = Lpips::bundled().unwrap();
    g.bench_function("lpips_alex", |b| {
        b.iter(|| black_box(lp.distance(&rendered, &gt).unwrap()))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
