//! Median-of-5 wall time of one 800×600 extraction per level and conv algorithm, the same
//! protocol as `shared/tools/anchors/torch_vgg_features.py` (run them back to back):
//! `cargo run --release -p gs-features --example extract_timing [threads]`.

use gs_core::{Image, Rng};
use gs_features::{ConvAlgorithm, ExtractOptions, FeatureLevel, Vgg16};
use std::time::Instant;

fn main() {
    let threads: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(2);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let net = Vgg16::bundled().unwrap();
    let (w, h) = (800, 600);
    let mut rng = Rng::new(1);
    let image = Image::from_vec(w, h, 3, (0..w * h * 3).map(|_| rng.uniform()).collect()).unwrap();
    for level in [FeatureLevel::Conv2_2, FeatureLevel::Conv3_3] {
        for alg in [ConvAlgorithm::Direct, ConvAlgorithm::Im2colGemm] {
            let opts = ExtractOptions { algorithm: alg, ..ExtractOptions::at(level) };
            pool.install(|| net.extract_with(&image, &opts).unwrap());
            let mut ts: Vec<f64> = (0..5)
                .map(|_| {
                    let t = Instant::now();
                    std::hint::black_box(pool.install(|| net.extract_with(&image, &opts).unwrap()));
                    t.elapsed().as_secs_f64()
                })
                .collect();
            ts.sort_by(f64::total_cmp);
            let gflop = net.flops(w, h, level) as f64 / 1e9;
            println!(
                "{level:?} {alg:?}: median {:.1} ms (min {:.1}), {gflop:.2} GFLOP, {:.1} GFLOP/s, {threads} threads",
                ts[2] * 1e3,
                ts[0] * 1e3,
                gflop / ts[2]
            );
        }
    }
}
