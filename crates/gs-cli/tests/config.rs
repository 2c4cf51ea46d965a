//! One configuration: `vagsl train --config FILE` and `--set KEY=VALUE` reach every setting, a
//! run's own config.json reproduces it byte for byte, and bad settings are named before any
//! training starts.

use std::path::Path;
use std::process::Command;

fn vagsl(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_vagsl")).args(args).env("RAYON_NUM_THREADS", "2").output().expect("run vagsl");
    (out.status.success(), String::from_utf8_lossy(&out.stderr).into_owned())
}

fn json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

#[test]
fn a_runs_own_config_reproduces_it_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let (ok, err) = vagsl(&["train", "-o", a.to_str().unwrap(), "--iterations", "30", "--seed", "3", "--eval", "--backend", "cpu", "--quiet"]);
    assert!(ok, "{err}");
    let cfg = a.join("config.json");
    let (ok, err) = vagsl(&["train", "--config", cfg.to_str().unwrap(), "-o", b.to_str().unwrap(), "--backend", "cpu", "--quiet"]);
    assert!(ok, "{err}");
    assert_eq!(std::fs::read(a.join("point_cloud.ply")).unwrap(), std::fs::read(b.join("point_cloud.ply")).unwrap());
    // The same configuration, but another run (its own run id).
    let (mut ca, mut cb) = (json(&cfg), json(&b.join("config.json")));
    let (ida, idb) = (ca.as_object_mut().unwrap().remove("run_id"), cb.as_object_mut().unwrap().remove("run_id"));
    assert!(ida.is_some() && ida != idb, "run ids {ida:?} and {idb:?}");
    assert_eq!(ca, cb);
    // The start-up line is words, not a Rust struct.
    assert!(err.contains("config: preset standard, 30 iterations: colour warm-up to") && !err.contains("LossSwitches"), "{err}");
}

#[test]
fn a_partial_toml_file_and_set_change_the_settings_they_name() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("settings.toml");
    std::fs::write(&file, "preset = \"fast\"\nseed = 5\n\n[weights]\nlambda_f = 0.5\n\n[densify]\ngrad_threshold = 3e-4\n").unwrap();
    let out = dir.path().join("run");
    let (ok, err) = vagsl(&[
        "train", "--config", file.to_str().unwrap(), "--iterations", "4", "-o", out.to_str().unwrap(),
        "--set", "weights.lambda_p=0.25", "--set", "ncc=plain", "--no-features", "--backend", "cpu", "--quiet",
    ]);
    assert!(ok, "{err}");
    let t = &json(&out.join("config.json"))["train"];
    assert_eq!((t["preset"].as_str(), t["seed"].as_u64(), t["iterations"].as_u64()), (Some("fast"), Some(5), Some(4)));
    assert_eq!((t["weights"]["lambda_f"].as_f64(), t["weights"]["lambda_p"].as_f64()), (Some(0.5), Some(0.25)));
    assert_eq!((t["ncc"].as_str(), t["losses"]["features"].as_bool()), (Some("plain"), Some(false)));
    assert!((t["densify"]["grad_threshold"].as_f64().unwrap() - 3e-4).abs() < 1e-9);
    // Untouched keys keep the fast preset's values.
    assert_eq!(t["source_views"].as_u64(), Some(2));
    assert!(err.contains("changed from the preset") && err.contains("weights.lambda_p 0.25 (preset 0.15)"), "{err}");
}

#[test]
fn bad_settings_are_named_and_nothing_is_trained() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let o = out.to_str().unwrap();
    for (args, needle) in [
        (vec!["--set", "weights.lambda_q=1"], "unknown setting 'weights.lambda_q'"),
        (vec!["--set", "densify.interval=often"], "densify.interval"),
        (vec!["--set", "weights.beta1=2"], "beta1"),
        (vec!["--set", "patch_size"], "KEY=VALUE"),
        (vec!["--ncc", "fancy"], "unknown NCC reading 'fancy' (one of: pgsr, plain)"),
    ] {
        let mut a = vec!["train", "-o", o, "--backend", "cpu"];
        a.extend(args);
        let (ok, err) = vagsl(&a);
        assert!(!ok && err.contains(needle), "{a:?}: {err}");
        assert!(!out.exists(), "{a:?} left an output folder");
    }
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "[weights\nlambda_p = 1").unwrap();
    let (ok, err) = vagsl(&["train", "-o", o, "--config", bad.to_str().unwrap()]);
    assert!(!ok && err.contains("bad.toml") && err.contains("TOML"), "{err}");
}

#[test]
fn silently_wrong_settings_are_refused_naming_the_problem() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let o = out.to_str().unwrap();
    let file = |name: &str, text: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p.to_str().unwrap().to_string()
    };
    let fast = file("fast.toml", "preset = \"fast\"\n");
    let short = file("short.toml", "iterations = 20\n");
    let nan = file("nan.toml", "[weights]\nlambda_p = nan\n");
    for (args, needles) in [
        // A schedule longer than the run: named, with the way to scale it.
        (vec!["--set", "iterations=20"], vec!["iterations = 20 ends before the schedule's boundaries", "warmup_end = ", "densify.until = ", "give --iterations 20"]),
        (vec!["--config", short.as_str()], vec!["iterations = 20 ends before", "photometric_end = "]),
        // Contradictory presets.
        (vec!["--preset", "dtu", "--config", fast.as_str()], vec!["--preset dtu contradicts", "fast.toml, whose preset is fast"]),
        (vec!["--set", "preset=dtu"], vec!["preset is not a setting", "use --preset dtu"]),
        // Non-finite values name the key; a device is not read whole.
        (vec!["--config", nan.as_str()], vec!["nan.toml: weights.lambda_p = NaN: must be a finite number"]),
        (vec!["--config", "/dev/zero"], vec!["/dev/zero: it gives more than the cap of 4 MiB for a settings file"]),
    ] {
        let mut a = vec!["train", "-o", o, "--backend", "cpu"];
        a.extend(args.iter().copied());
        let t = std::time::Instant::now();
        let (ok, err) = vagsl(&a);
        assert!(!ok, "{a:?} was accepted");
        for n in needles {
            assert!(err.contains(n), "{a:?}: '{n}' not in {err}");
        }
        assert!(t.elapsed().as_secs() < 30 && !out.exists(), "{a:?}: work started");
    }
    // The same preset twice is no contradiction; --iterations scales the whole schedule.
    let (ok, err) = vagsl(&["train", "-o", o, "--preset", "fast", "--config", &fast, "--iterations", "4", "--backend", "cpu", "--quiet"]);
    assert!(ok, "{err}");
    // eval-mesh's crop fraction is checked as an argument.
    let (ok, err) = vagsl(&["eval-mesh", "--pred", "a.ply", "--gt", "b.ply", "--crop-to-gt", "-5"]);
    assert!(!ok && err.contains("'-5'") && err.contains("must be a finite number above -0.5"), "{err}");
}
