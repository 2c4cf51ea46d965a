//! Per-layer timing of the VGG16 trunk at 800×600 (both conv algorithms) on a rayon pool of
//! `threads` (default 2): `cargo run --release -p gs-features --example layer_timing [threads]`.

use gs_features::conv::{ConvAlgorithm, Padded, PreparedConv, max_pool2};
use gs_features::VggWeights;
use std::time::Instant;

fn main() {
    let threads: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(2);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let w = VggWeights::bundled().unwrap();
    let layers: Vec<PreparedConv> =
        w.layers.iter().map(|l| PreparedConv::new(l.cout, l.cin, &l.kernel, &l.bias)).collect();
    for alg in [ConvAlgorithm::Direct, ConvAlgorithm::Im2colGemm] {
        pool.install(|| {
            let mut x = Padded::zeros(600, 800, 3);
            for v in x.data.iter_mut() {
                *v = 0.5;
            }
            let mut total = 0.0;
            for (i, l) in layers.iter().enumerate() {
                if i == 2 || i == 4 {
                    let t = Instant::now();
                    x = max_pool2(&x);
                    let dt = t.elapsed().as_secs_f64();
                    total += dt;
                    println!("{alg:?} pool: {:.1} ms", dt * 1e3);
                }
                let t = Instant::now();
                let y = l.forward(&x, alg);
                let dt = t.elapsed().as_secs_f64();
                total += dt;
                let gf = 2.0 * l.macs(x.h, x.w) as f64 / 1e9;
                println!("{alg:?} {}: {:.1} ms, {:.2} GFLOP, {:.1} GFLOP/s", w.layers[i].name, dt * 1e3, gf, gf / dt);
                x = y;
            }
            println!("{alg:?} total {:.1} ms", total * 1e3);
        });
    }
}
