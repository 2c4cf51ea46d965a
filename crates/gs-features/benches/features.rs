//! Features of one 800×600 image at conv2_2 and conv3_3, both conv algorithms, on a 2-thread
//! rayon pool (the development machine's budget). GFLOP/s = `Vgg16::flops` / time.

use criterion::{Criterion, criterion_group, criterion_main};
use gs_core::{Image, Rng};
use gs_features::{ConvAlgorithm, ExtractOptions, FeatureLevel, Vgg16};
use std::time::Duration;

fn bench(c: &mut Criterion) {
    let threads: usize =
        std::env::var("GS_FEATURES_BENCH_THREADS").ok().and_then(|s| s.parse().ok()).unwrap_or(2);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let net = Vgg16::bundled().unwrap();
    let (w, h) = (800, 600);
    let mut rng = Rng::new(1);
    let image = Image::from_vec(w, h, 3, (0..w * h * 3).map(|_| rng.uniform()).collect()).unwrap();
    let mut group = c.benchmark_group(format!("vgg16_800x600_{threads}threads"));
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
}

criterion_group!(benches, bench);
criterion_main!(benches);
