//! Generates the built-in scene with default options and prints its statistics and timing.
//! `cargo run --release -p gs-synth --example builtin_stats`

use gs_synth::{BuiltinOptions, generate};
use std::time::Instant;

fn main() {
    let opts = BuiltinOptions::default();
    let t = Instant::now();
    let built = match generate(&opts) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(1);
        }
    };
    let secs = t.elapsed().as_secs_f64();
    println!("{}", built.description);
    println!(
        "generated in {secs:.2} s on {} rayon threads",
        rayon::current_num_threads()
    );
    let (mut hits, mut total, mut obj) = (0usize, 0usize, 0usize);
    for (d, v) in built.gt_depth.iter().zip(&built.scene.views) {
        total += d.data().len();
        hits += d.data().iter().filter(|&&z| z > 0.0).count();
        obj += v
            .mask
            .as_ref()
            .map_or(0, |m| m.data().iter().filter(|&&m| m > 0.5).count());
    }
    println!(
        "pixel-centre hits {hits}/{total}, object pixels {:.1} %",
        100.0 * obj as f64 / total as f64
    );
    let depths: Vec<f32> = built
        .gt_depth
        .iter()
        .flat_map(|d| d.data().iter().copied().filter(|&z| z > 0.0))
        .collect();
    let (lo, hi) = depths
        .iter()
        .fold((f32::MAX, 0.0f32), |(a, b), &z| (a.min(z), b.max(z)));
    println!("depth range {lo:.3} .. {hi:.3}");
}
