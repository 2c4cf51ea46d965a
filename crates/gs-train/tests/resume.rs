//! Checkpoint / resume: N + resume N iterations gives bit-identical parameters to 2N
//! iterations (same seed and thread count), across densification, opacity reset, trim and
//! every loss phase; and corrupt checkpoints are clear errors.

use gs_train::checkpoint::Elapsed;
use gs_train::{TrainConfig, Trainer, checkpoint};

mod common;
use common::{busy_config as config, small_scene};

/// A trainer 3 iterations into the run: enough state for the checkpoint format tests.
fn three_iterations(scene: &gs_core::Scene) -> Trainer<'_> {
    let (train, _) = scene.split(false);
    let mut t = Trainer::new(scene, train, config()).unwrap();
    t.run(|_, r| r.iteration < 3).unwrap();
    t
}

#[test]
fn resume_continues_bit_identically() {
    let scene = small_scene();
    let (train, _) = scene.split(false);
    let cfg = config();
    let (warm, lp, lf) = (cfg.warmup_end, cfg.photometric_end, cfg.iterations);
    assert!(warm < 60 && lp < lf, "the run covers every phase: {warm} {lp} {lf}");

    let mut straight = Trainer::new(&scene, train.clone(), cfg.clone()).unwrap();
    straight.run(|_, _| true).unwrap();

    let mut first = Trainer::new(&scene, train.clone(), cfg.clone()).unwrap();
    first.run(|_, r| r.iteration < 60).unwrap();
    assert_eq!(first.iteration(), 60);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ckpt.bin");
    let spent = Elapsed { phase_seconds: [12.5, 3.25, 0.0, 0.0] };
    first.save_checkpoint(&path, &spent).unwrap();
    drop(first);
    let ck = checkpoint::load(&path).unwrap();
    assert_eq!(ck.config, cfg);
    // The time spent so far travels with the checkpoint, so a resumed run reports the total.
    assert_eq!(ck.elapsed, Some(spent));
    let mut resumed = Trainer::with_state(&scene, train, ck.config, ck.state).unwrap();
    resumed.run(|_, _| true).unwrap();

    assert_eq!(resumed.iteration(), straight.iteration());
    assert_eq!(resumed.state().unwrap(), straight.state().unwrap(), "parameters, optimiser and statistics must match bit for bit");
    assert!(straight.gaussians().unwrap().len() != 400, "densification ran");
    assert!(straight.state().unwrap().exposure.as_ref().unwrap().params.iter().any(|p| p[0] != 0.0), "exposure was learned");
    let memo = &straight.state().unwrap().source_depths;
    assert!(memo.entries().iter().flatten().count() > 1, "the geometry phases stored plane depths");
}

#[test]
fn corrupt_checkpoints_are_named_errors() {
    let scene = small_scene();
    let mut t = three_iterations(&scene);
    let bytes = t.checkpoint(&Elapsed::default()).unwrap();
    let p = std::path::Path::new("run/checkpoint.bin");
    let err = |b: &[u8]| checkpoint::decode(b, p).unwrap_err().to_string();
    assert!(err(&bytes[..bytes.len() / 2]).contains("checksum"));
    assert!(err(b"hello world, not a checkpoint").contains("magic"));
    assert!(err(&[]).contains("magic"));
    let mut flipped = bytes.clone();
    flipped[100] ^= 1;
    let e = err(&flipped);
    assert!(e.contains("run/checkpoint.bin") && e.contains("checksum"), "{e}");
    let missing = checkpoint::load(std::path::Path::new("/nonexistent/ckpt.bin")).unwrap_err().to_string();
    assert!(missing.contains("/nonexistent/ckpt.bin"), "{missing}");
    assert!(checkpoint::decode(&bytes, p).is_ok());
    // A NaN elapsed time (with a valid checksum) is refused, not summed into the report.
    let bad = t.checkpoint(&Elapsed { phase_seconds: [f64::NAN, 0.0, 0.0, 0.0] }).unwrap();
    assert!(err(&bad).contains("elapsed time"), "{}", err(&bad));
}

#[test]
fn version_2_to_4_checkpoints_still_load() {
    let scene = small_scene();
    let (train, _) = scene.split(false);
    let mut t = Trainer::new(&scene, train, TrainConfig { source_depth_max_age: 0, ..config() }).unwrap();
    t.run(|_, r| r.iteration < 3).unwrap();
    let v5 = t.checkpoint(&Elapsed::default()).unwrap();
    // A version-4 file is the version-5 body without the trailing 3D-filter flag (4 bytes, 0);
    // a version-3 file also lacks the (empty) source-depth memo before it (a 4-byte slot
    // count); a version-2 file also lacks the elapsed record (8-byte count + 4 × 8 bytes).
    // Each has its own version number and checksum.
    let old = |version: u32, cut: usize| {
        let mut b = v5[..v5.len() - 4 - cut].to_vec();
        b[8..12].copy_from_slice(&version.to_le_bytes());
        let crc = gs_features::weights::crc32(&b);
        b.extend_from_slice(&crc.to_le_bytes());
        checkpoint::decode(&b, std::path::Path::new("old.bin")).unwrap()
    };
    let v4 = old(4, 4);
    assert_eq!((v4.elapsed, &v4.state), (Some(Elapsed::default()), t.state().unwrap()));
    let v3 = old(3, 8);
    assert_eq!((v3.elapsed, &v3.state), (Some(Elapsed::default()), t.state().unwrap()));
    let v2 = old(2, 8 + 40);
    assert_eq!((v2.elapsed, &v2.state), (None, t.state().unwrap()));
}

/// The 3D smoothing filter (`smoothing_3d`): a run checkpointed between two computations of
/// the variances resumes bit-identically (they travel in the checkpoint), the checkpoint holds
/// the raw parameters, and the model at rest is the filtered one (no axis thinner than √s²).
#[test]
fn the_3d_filter_resumes_bit_identically_and_rests_filtered() {
    let scene = small_scene();
    let (train, _) = scene.split(false);
    let cfg = TrainConfig { smoothing_3d: 0.2, ..config() };
    assert!(cfg.iterations > 100, "the run recomputes the variances at least once");
    let mut straight = Trainer::new(&scene, train.clone(), cfg.clone()).unwrap();
    straight.run(|_, _| true).unwrap();
    let mut first = Trainer::new(&scene, train.clone(), cfg.clone()).unwrap();
    first.run(|_, r| r.iteration < 73).unwrap();
    let bytes = first.checkpoint(&Elapsed::default()).unwrap();
    let ck = checkpoint::decode(&bytes, std::path::Path::new("ck.bin")).unwrap();
    let at_rest = first.state().unwrap();
    let s = at_rest.smoothing.as_ref().expect("the filter is on");
    assert_eq!((&ck.state.gaussians.log_scales[..], &ck.state.gaussians.opacity_logits[..]), s.raw(&at_rest.gaussians));
    assert_ne!(ck.state.gaussians.log_scales, at_rest.gaussians.log_scales, "at rest the model is filtered");
    let mut resumed = Trainer::with_state(&scene, train, ck.config, ck.state).unwrap();
    resumed.run(|_, _| true).unwrap();
    assert_eq!(resumed.state().unwrap(), straight.state().unwrap(), "parameters, optimiser, statistics and filter must match bit for bit");
    let end = straight.state().unwrap();
    let (g, s) = (&end.gaussians, end.smoothing.as_ref().unwrap());
    assert!(s.applied() && s.variances().iter().all(|v| *v > 0.0));
    for (ls, v) in g.log_scales.iter().zip(s.variances()) {
        assert!(ls.iter().all(|l| 2.0 * l >= v.ln() - 1e-4), "{ls:?} thinner than the filter's {v}");
    }
}

#[test]
fn a_source_depth_that_does_not_fill_its_rows_is_refused() {
    let scene = small_scene();
    let mut t = three_iterations(&scene);
    let mut state = t.state().unwrap().clone();
    let depth = gs_core::Image::filled(5, 3, 1, 1.0).unwrap();
    state.source_depths = gs_train::SourceDepths::from_entries(vec![Some((2, depth))]);
    let mut bytes = checkpoint::encode(t.config(), &state, &Elapsed::default());
    // The stored width (the u64 before the 15 depth values and their 8-byte count, which the
    // 3D filter's 4-byte flag follows) becomes 4.
    let at = bytes.len() - 4 - 4 - 15 * 4 - 8 - 8;
    bytes[at..at + 8].copy_from_slice(&4u64.to_le_bytes());
    let body = bytes.len() - 4;
    let crc = gs_features::weights::crc32(&bytes[..body]);
    bytes[body..].copy_from_slice(&crc.to_le_bytes());
    let e = checkpoint::decode(&bytes, std::path::Path::new("ck.bin")).unwrap_err().to_string();
    assert!(e.contains("ck.bin") && e.contains("source depth of training view 0"), "{e}");
}

/// A crafted checkpoint (valid checksum) whose 3D-filter variance is NaN is refused when read,
/// naming the file, not later when training resumes.
#[test]
fn a_smoothing_variance_that_is_not_finite_is_refused_naming_the_file() {
    let scene = small_scene();
    let mut t = three_iterations(&scene);
    let mut state = t.state().unwrap().clone();
    state.smoothing = Some(gs_train::smoothing::Smoothing::new(vec![1e-4; state.gaussians.len()]).unwrap());
    let mut bytes = checkpoint::encode(t.config(), &state, &Elapsed::default());
    assert!(checkpoint::decode(&bytes, std::path::Path::new("ck.bin")).is_ok(), "the valid file loads");
    // The last variance is the f32 before the 4-byte checksum.
    let body = bytes.len() - 4;
    bytes[body - 4..body].copy_from_slice(&f32::NAN.to_le_bytes());
    let crc = gs_features::weights::crc32(&bytes[..body]);
    bytes[body..].copy_from_slice(&crc.to_le_bytes());
    let e = checkpoint::decode(&bytes, std::path::Path::new("ck.bin")).unwrap_err().to_string();
    assert!(e.contains("ck.bin") && e.contains("3D smoothing: variance NaN"), "{e}");
}

/// Found by the `checkpoint` fuzz target: an optimiser group's row width (a u64 of the file)
/// times the Gaussian count overflowed; with 2 Gaussians, a row width of 2^63 wrapped to 0 and
/// matched empty moments, so the group was accepted. The checkpoint is a real one cut to 2
/// Gaussians with its first group's row width set to 2^63 and its moments emptied.
#[test]
fn an_optimiser_row_width_that_overflows_is_refused() {
    let body = include_bytes!("fixtures/checkpoint_row_width_overflow.body");
    let mut bytes = body.to_vec();
    bytes.extend_from_slice(&gs_features::weights::crc32(body).to_le_bytes());
    let e = checkpoint::decode(&bytes, std::path::Path::new("ck.bin")).err().expect("the row width is refused").to_string();
    assert!(e.contains("ck.bin") && e.contains("optimiser group") && e.contains("does not match 2 Gaussians"), "{e}");
}
