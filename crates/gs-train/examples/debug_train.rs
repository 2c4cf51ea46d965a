use gs_train::*;
fn main() {
    let b = gs_synth::generate(&gs_synth::BuiltinOptions::default()).unwrap();
    let scene = b.scene;
    let (train, _) = scene.split(true);
    let iters: u64 = std::env::args().nth(1).map(|s| s.parse().unwrap()).unwrap_or(300);
    let mut cfg = TrainConfig::default().scaled(iters);
    if std::env::args().nth(2).as_deref() == Some("image") { cfg.losses = LossSwitches::image_only(); }
    let mut t = Trainer::new(&scene, train, cfg).unwrap();
    let t0 = std::time::Instant::now();
    t.run(|tr, r| {
        if r.densify.is_some() || r.iteration % 50 == 0 {
            let st = &tr.state().unwrap().stats;
            let _ = st;
            println!("{} {:.1}s L {:.4} l1 {:.4} G {} {:?} trim {:?}", r.iteration, t0.elapsed().as_secs_f64(), r.losses.total, r.losses.l1, r.gaussians, r.densify, r.trimmed);
        }
        true
    }).unwrap();
}
