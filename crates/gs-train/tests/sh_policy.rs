//! The adaptive SH policy ("raise the SH degree only while it pays"): its judgement renders
//! change nothing else, a band that does not pay is dropped and stays at zero, and a resumed
//! run takes the same decisions.

use gs_train::{ShPolicy, TrainConfig, Trainer, checkpoint};

fn small_scene() -> gs_core::Scene {
    let opts = gs_synth::BuiltinOptions { width: 64, height: 48, views: 8, supersample: 1, points: 400, ..Default::default() };
    gs_synth::generate(&opts).unwrap().scene
}

fn config(policy: ShPolicy, min_gain: f32) -> TrainConfig {
    let mut c = TrainConfig::default().scaled(80);
    // Rises at iterations 11, 21 and 31: bands 1 and 2 are judged (band 3 is the last one).
    c.sh_degree_interval = 10;
    c.densify.from = 10;
    c.densify.interval = 25;
    c.seed = 3;
    c.sh_policy = policy;
    c.sh_min_gain = min_gain;
    c
}

fn run(scene: &gs_core::Scene, cfg: TrainConfig) -> (Trainer<'_>, Vec<gs_train::ShBandDecision>) {
    let (train, _) = scene.split(false);
    let mut t = Trainer::new(scene, train, cfg).unwrap();
    let mut bands = Vec::new();
    t.run(|_, r| {
        bands.extend(r.sh_band);
        true
    })
    .unwrap();
    (t, bands)
}

#[test]
fn bands_that_pay_follow_the_schedule_bit_for_bit() {
    let scene = small_scene();
    let (mut schedule, none) = run(&scene, config(ShPolicy::Schedule, 0.01));
    assert!(none.is_empty());
    // min_gain −1: every band "pays", so the degree follows the schedule; the judgement renders
    // must not disturb anything.
    let (mut adaptive, bands) = run(&scene, config(ShPolicy::Adaptive, -1.0));
    assert_eq!(bands.iter().map(|b| (b.band, b.kept, b.degree)).collect::<Vec<_>>(), vec![(1, true, 2), (2, true, 3)]);
    for b in &bands {
        assert!(b.l1_with > 0.0 && b.l1_without > 0.0 && b.gain.is_finite(), "{b:?}");
    }
    assert_eq!(adaptive.state().unwrap(), schedule.state().unwrap());
    assert_eq!(adaptive.gaussians().unwrap().sh_degree, 3);
}

#[test]
fn a_band_that_does_not_pay_is_dropped_for_good() {
    let scene = small_scene();
    // min_gain 0.99: no band can lower L1 by 99 %, so band 1 is dropped at its judgement.
    let (mut t, bands) = run(&scene, config(ShPolicy::Adaptive, 0.99));
    assert_eq!(bands.len(), 1, "{bands:?}");
    assert_eq!((bands[0].band, bands[0].kept, bands[0].degree), (1, false, 0));
    let g = t.gaussians().unwrap();
    assert_eq!(g.sh_degree, 0);
    // Band 1 was zeroed with its moments and never moved again; bands 2, 3 never became active.
    assert!(g.sh.iter().all(|c| c[1..].iter().all(|v| *v == [0.0; 3])), "higher bands stay zero");
    assert!(g.sh.iter().any(|c| c[0] != [0.0; 3]));
}

#[test]
fn resumed_runs_take_the_same_sh_decisions() {
    let scene = small_scene();
    let (train, _) = scene.split(false);
    let cfg = config(ShPolicy::Adaptive, 0.99);
    let (mut straight, _) = run(&scene, cfg.clone());
    // Stop right after the drop (iteration 21), checkpoint, resume: the degree stays 0.
    let mut first = Trainer::new(&scene, train.clone(), cfg.clone()).unwrap();
    first.run(|_, r| r.iteration < 25).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ckpt.bin");
    first.save_checkpoint(&path, &Default::default()).unwrap();
    let ck = checkpoint::load(&path).unwrap();
    assert_eq!(ck.config.sh_policy, ShPolicy::Adaptive);
    let mut resumed = Trainer::with_state(&scene, train, ck.config, ck.state).unwrap();
    resumed.run(|_, _| true).unwrap();
    assert_eq!(resumed.state().unwrap(), straight.state().unwrap());
}
