//! Features of one 800×600 image (`GS_FEATURES_BENCH_SIZE=WxH` for another size) at conv2_2 and conv3_3, both conv algorithms, on a 2-thread
//! rayon pool (the development machine's budget), and on the device where there is a wgpu adapter.
//! GFLOP/s = `Vgg16::flops` / time.

use criterion::{Criterion, criterion_group, criterion_main};
use gs_core::{Image, Rng};
use gs_features::{ConvAlgorithm, ExtractOptions, FeatureLevel, Vgg16};
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let threads: usize =
        std::env::var("GS_FEATURES_BENCH_THREADS").ok().and_then(|s| s.parse().ok()).unwrap_or(2);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let net = Vgg16::bundled().unwrap();
    // GS_FEATURES_BENCH_SIZE=WxH (default 800x600): smaller for the device rows on lavapipe.
    let (w, h) = std::env::var("GS_FEATURES_BENCH_SIZE")
        .ok()
        .and_then(|s| s.split_once('x').and_then(|(a, b)| Some((a.parse().ok()?, b.parse().ok()?))))
        .unwrap_or((800, 600));
    let mut rng = Rng::new(1);
    let image = Image::from_vec(w, h, 3, (0..w * h * 3).map(|_| rng.uniform()).collect()).unwrap();
    let mut group = c.benchmark_group(format!("vgg16_{w}x{h}_{threads}threads"));
    group.sample_size(10).warm_up_time(Duration::from_secs(2)).measurement_time(Duration::from_secs(10));
    for level in [FeatureLevel::Conv2_2, FeatureLevel::Conv3_3] {
        for alg in [ConvAlgorithm::Direct, ConvAlgorithm::Im2colGemm] {
            let opts = ExtractOptions { algorithm: alg, ..ExtractOptions::at(level) };
            let gflop = net.flops(w, h, level) as f64 / 1e9;
            eprintln!("{level:?}: {gflop:.2} GFLOP per image");
            group.bench_function(format!("{level:?}_{alg:?}"), |b| {
                b.iter(|| pool.install(|| net.extract_with(&image, &opts).unwrap()))
            });
        }
    }
    group.finish();
    #[cfg(feature = "wgpu")]
    device(c, &net, &image);
}

/// The same image on the device (`Vgg16Gpu`), when there is a wgpu adapter: on lavapipe this
/// measures the kernels' work on the CPU, not GPU speed.
#[cfg(feature = "wgpu")]
fn device(c: &mut Criterion, net: &Vgg16, image: &Image) {
    let ctx = match gs_gpu::GpuContext::new(&gs_gpu::GpuOptions::default()) {
        Ok(ctx) => ctx,
        Err(e) => {
            eprintln!("SKIPPED: the device rows: {e}");
            return;
        }
    };
    let mut gpu = gs_features::Vgg16Gpu::new(&ctx, net).unwrap();
    let mut group = c.benchmark_group(format!("vgg16_{}x{}_device", image.width(), image.height()));
    eprintln!("device: {}", ctx.description());
    group.sample_size(10).warm_up_time(Duration::from_secs(2)).measurement_time(Duration::from_secs(10));
    for level in [FeatureLevel::Conv2_2, FeatureLevel::Conv3_3] {
        group.bench_function(format!("{level:?}"), |b| b.iter(|| gpu.extract(image, level).unwrap()));
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
