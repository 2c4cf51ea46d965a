//! A run folder is never silently wrong (issue #21): an existing run is not overwritten without
//! `--force`, a run reopens only with its own scene and its own model, and `--resume` refuses
//! options it would ignore or that would change the run.

use std::path::Path;
use std::process::Command;

fn vagsl(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_vagsl")).args(args).env("RAYON_NUM_THREADS", "2").output().expect("run vagsl");
    (out.status.success(), String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned())
}

/// A 4-iteration CPU run of the built-in scene into `out`, with `extra` arguments.
fn train(out: &Path, extra: &[&str]) -> (bool, String) {
    let mut a = vec!["train", "-o", out.to_str().unwrap(), "--iterations", "4", "--backend", "cpu", "--quiet"];
    a.extend_from_slice(extra);
    let (ok, _, err) = vagsl(&a);
    (ok, err)
}

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn an_existing_run_is_replaced_only_with_force() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let (ok, err) = train(&out, &[]);
    assert!(ok, "{err}");
    // Outputs of later commands, and a file of the user's.
    std::fs::write(out.join("mesh.ply"), b"old mesh").unwrap();
    std::fs::write(out.join("eval_images.json"), b"{}").unwrap();
    std::fs::create_dir_all(out.join("renders/test")).unwrap();
    std::fs::write(out.join("renders/test/0000.png"), b"old").unwrap();
    std::fs::write(out.join("notes.txt"), b"mine").unwrap();
    let (config, model) = (read(&out.join("config.json")), read(&out.join("point_cloud.ply")));

    // Refused before any work, naming the folder and the ways out; nothing changed.
    let (ok, err) = train(&out, &["--seed", "5"]);
    assert!(!ok, "re-training into a used folder was accepted");
    assert!(err.contains(out.to_str().unwrap()) && err.contains("already holds a vagsl run"), "{err}");
    assert!(err.contains("-o") && err.contains("--force"), "{err}");
    assert!(!err.contains("scene:"), "work started before the refusal: {err}");
    assert_eq!(read(&out.join("config.json")), config);
    assert_eq!(read(&out.join("point_cloud.ply")), model);

    // --force with a start that fails keeps the old run.
    let (ok, _) = train(&out, &["--force", "--patch-size", "4"]);
    assert!(!ok);
    assert_eq!(read(&out.join("point_cloud.ply")), model);
    assert!(out.join("mesh.ply").is_file());

    // --force replaces the run: its known outputs go, the user's file stays.
    let (ok, err) = train(&out, &["--force", "--seed", "5"]);
    assert!(ok, "{err}");
    assert!(err.contains("removed the previous run's"), "{err}");
    for gone in ["mesh.ply", "eval_images.json", "renders"] {
        assert!(!out.join(gone).exists(), "{gone} of the old run is still there");
    }
    assert_eq!(read(&out.join("notes.txt")), b"mine");
    let cfg: serde_json::Value = serde_json::from_slice(&read(&out.join("config.json"))).unwrap();
    assert_eq!(cfg["train"]["seed"], 5);

    // --force and --resume contradict each other.
    let ck = out.join("checkpoint.bin");
    let (ok, err) = train(&out, &["--force", "--resume", ck.to_str().unwrap()]);
    assert!(!ok && err.contains("--force") && err.contains("--resume"), "{err}");
}

#[test]
fn a_failed_start_leaves_no_folder() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("new");
    let (ok, err) = train(&out, &["--patch-size", "4"]);
    assert!(!ok, "an even patch size was accepted");
    assert!(!out.exists(), "a refused configuration left {}: {err}", out.display());
    let (ok, _, err) = vagsl(&["train", "/nonexistent/scene", "-o", out.to_str().unwrap(), "--backend", "cpu"]);
    assert!(!ok && err.contains("/nonexistent/scene"), "{err}");
    assert!(!out.exists(), "a missing scene left {}", out.display());
    // An output path that is a file is refused.
    let file = dir.path().join("file");
    std::fs::write(&file, b"x").unwrap();
    let (ok, err) = train(&file, &[]);
    assert!(!ok && err.contains("not a folder"), "{err}");
}

/// The built-in scene with `views` views of 120 × 90 written as a scene folder, cached under
/// target/.
fn builtin_dir(views: usize) -> std::path::PathBuf {
    let opts = gs_synth::BuiltinOptions { views, ..gs_testdata::builtin::small() };
    gs_testdata::builtin::scene_dir(Path::new(env!("CARGO_TARGET_TMPDIR")), &opts)
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &to.join(e.file_name()));
        } else {
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
    }
}

/// `vagsl` started in `cwd`.
fn vagsl_in(cwd: &Path, args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_vagsl")).args(args).current_dir(cwd).env("RAYON_NUM_THREADS", "2").output().expect("run vagsl");
    (out.status.success(), String::from_utf8_lossy(&out.stderr).into_owned())
}

fn config_of(run: &Path) -> serde_json::Value {
    serde_json::from_slice(&read(&run.join("config.json"))).unwrap()
}

#[test]
fn a_run_keeps_its_scene_wherever_it_is_opened_from() {
    let dir = tempfile::tempdir().unwrap();
    let here = dir.path().join("here");
    copy_dir(&builtin_dir(12), &here.join("scene"));
    let run = dir.path().join("run");
    let r = run.to_str().unwrap();
    // The scene is typed relative to the working folder; config.json keeps it absolute.
    let (ok, err) =
        vagsl_in(&here, &["train", "scene", "-o", r, "--width", "40", "--eval", "--iterations", "4", "--backend", "cpu", "--quiet"]);
    assert!(ok, "{err}");
    let cfg = config_of(&run);
    let stored = std::path::PathBuf::from(cfg["scene"]["path"].as_str().unwrap());
    assert_eq!(stored, here.join("scene").canonicalize().unwrap());
    assert_eq!(cfg["fingerprint"]["views"], 12);
    // Reopened from another folder.
    let renders = dir.path().join("renders");
    let render = |extra: &[&str]| {
        let mut a = vec!["render", r, "--backend", "cpu", "-o", renders.to_str().unwrap()];
        a.extend_from_slice(extra);
        vagsl_in(dir.path(), &a)
    };
    let (ok, err) = render(&[]);
    assert!(ok, "{err}");

    // The scene moved: the error says so and how to point at it; --scene does.
    let moved = dir.path().join("elsewhere");
    std::fs::rename(here.join("scene"), &moved).unwrap();
    let (ok, err) = render(&[]);
    assert!(!ok && err.contains(stored.to_str().unwrap()) && err.contains("--scene PATH"), "{err}");
    let (ok, err) = render(&["--scene", moved.to_str().unwrap()]);
    assert!(ok, "{err}");

    // Two photos swapped between names, cameras unchanged: refused by the pixels' hash.
    let (p1, p2) = (moved.join("images/0001.png"), moved.join("images/0002.png"));
    let (b1, b2) = (read(&p1), read(&p2));
    std::fs::write(&p1, &b2).unwrap();
    std::fs::write(&p2, &b1).unwrap();
    let (ok, err) = render(&["--scene", moved.to_str().unwrap()]);
    assert!(!ok && err.contains("photos' pixels differ") && err.contains("swapped or edited"), "{err}");
    std::fs::write(&p1, &b1).unwrap();
    std::fs::write(&p2, &b2).unwrap();
    // A split that no longer matches the run's (a training view now listed as held out).
    let saved = read(&run.join("config.json"));
    let mut cfg = config_of(&run);
    let moved_view = cfg["train_views"].as_array_mut().unwrap().remove(0);
    cfg["test_views"].as_array_mut().unwrap().push(moved_view);
    std::fs::write(run.join("config.json"), serde_json::to_string_pretty(&cfg).unwrap()).unwrap();
    let (ok, err) = render(&["--scene", moved.to_str().unwrap()]);
    assert!(!ok && err.contains("its split changed"), "{err}");
    std::fs::write(run.join("config.json"), saved).unwrap();

    // Another scene is refused, by its fingerprint.
    let mut images = std::fs::read_to_string(moved.join("sparse/0/images.txt")).unwrap();
    let pose = images.lines().find(|l| l.contains(".png")).unwrap().to_string();
    let mut fields: Vec<String> = pose.split_whitespace().map(String::from).collect();
    fields[5] = format!("{}", fields[5].parse::<f64>().unwrap() + 0.01);
    images = images.replacen(&pose, &fields.join(" "), 1);
    std::fs::write(moved.join("sparse/0/images.txt"), images).unwrap();
    let (ok, err) = render(&["--scene", moved.to_str().unwrap()]);
    assert!(!ok && err.contains("is not the scene the run in") && err.contains("differ in image names, sizes or cameras"), "{err}");
    let (ok, err) = render(&["--scene", builtin_dir(8).to_str().unwrap()]);
    assert!(!ok && err.contains("it has 8 views, the run's scene had 12"), "{err}");

    // A configuration from before fingerprints opens unchecked.
    let mut cfg = config_of(&run);
    cfg.as_object_mut().unwrap().remove("fingerprint");
    std::fs::write(run.join("config.json"), serde_json::to_string_pretty(&cfg).unwrap()).unwrap();
    let (ok, err) = render(&["--scene", moved.to_str().unwrap()]);
    assert!(ok, "{err}");
}

#[test]
fn the_builtin_scene_is_fingerprinted_and_needs_no_folder() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let (ok, err) = train(&run, &["--eval"]);
    assert!(ok, "{err}");
    let cfg = config_of(&run);
    assert_eq!(cfg["scene"]["path"], serde_json::Value::Null);
    assert_eq!(cfg["fingerprint"]["views"], 32);
    let (ok, _, err) = vagsl(&["render", run.to_str().unwrap(), "--backend", "cpu", "--scene", builtin_dir(12).to_str().unwrap()]);
    assert!(!ok && err.contains("built-in scene, which has no folder"), "{err}");
}

/// Renders the held-out views of `run`.
fn render_test(run: &Path) -> (bool, String) {
    let out = run.with_extension("renders");
    let (ok, _, err) = vagsl(&["render", run.to_str().unwrap(), "--backend", "cpu", "-o", out.to_str().unwrap()]);
    (ok, err)
}

#[test]
fn a_folder_mixing_two_runs_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    for (run, seed) in [(&a, "1"), (&b, "2")] {
        let (ok, err) = train(run, &["--eval", "--seed", seed]);
        assert!(ok, "{err}");
    }
    let id = config_of(&a)["run_id"].as_str().unwrap().to_string();
    let report: serde_json::Value = serde_json::from_slice(&read(&a.join("report.json"))).unwrap();
    assert_eq!(report["run_id"], id.as_str());
    assert_ne!(config_of(&b)["run_id"], id.as_str());
    let (ok, err) = render_test(&a);
    assert!(ok, "{err}");

    // B's configuration beside A's model.
    let own = read(&a.join("config.json"));
    std::fs::copy(b.join("config.json"), a.join("config.json")).unwrap();
    let (ok, err) = render_test(&a);
    assert!(!ok && err.contains("the folder mixes two training runs") && err.contains(&id), "{err}");
    std::fs::write(a.join("config.json"), &own).unwrap();
    // A model without the report that names its run.
    let report = read(&a.join("report.json"));
    std::fs::remove_file(a.join("report.json")).unwrap();
    let (ok, err) = render_test(&a);
    assert!(!ok && err.contains("report.json is missing or names no run"), "{err}");
    std::fs::write(a.join("report.json"), &report).unwrap();

    // The model is written after the report that describes it (D2): a run stopped between the
    // two leaves no model, or an older one that the report's fingerprint does not match.
    let fields: serde_json::Value = serde_json::from_slice(&report).unwrap();
    // 32 hex digits: SHA-256 over every parameter, SH included (older runs' 16 still open).
    assert_eq!(fields["model_fingerprint"].as_str().map(str::len), Some(32), "{fields}");
    let model = read(&a.join("point_cloud.ply"));
    std::fs::copy(b.join("point_cloud.ply"), a.join("point_cloud.ply")).unwrap();
    let (ok, err) = render_test(&a);
    assert!(!ok && err.contains("point_cloud.ply is not the model report.json describes") && err.contains("--resume"), "{err}");
    std::fs::remove_file(a.join("point_cloud.ply")).unwrap();
    let (ok, err) = render_test(&a);
    assert!(!ok && err.contains("no point_cloud.ply") && err.contains("stopped after its report, while writing its model"), "{err}");
    std::fs::write(a.join("point_cloud.ply"), &model).unwrap();
    let (ok, err) = render_test(&a);
    assert!(ok, "{err}");

    // A training killed after it wrote its configuration: the folder does not reopen as a run.
    // (A `--force` re-train killed so leaves the previous run whole: tests/outputs.rs.)
    let c = dir.path().join("c");
    let mut child = Command::new(env!("CARGO_BIN_EXE_vagsl"))
        .args(["train", "-o", c.to_str().unwrap(), "--eval", "--iterations", "100000", "--backend", "cpu", "--quiet"])
        .env("RAYON_NUM_THREADS", "2")
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let t0 = std::time::Instant::now();
    while std::fs::read(c.join("config.json")).ok().and_then(|t| serde_json::from_slice::<serde_json::Value>(&t).ok()).is_none() {
        assert!(t0.elapsed().as_secs() < 120, "the training never wrote its config.json");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let (ok, err) = render_test(&c);
    assert!(!ok && err.contains("no point_cloud.ply") && err.contains("has not written its model"), "{err}");
}

#[test]
fn resume_refuses_options_it_would_ignore_or_that_change_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let (ok, err) = train(&run, &["--eval", "--checkpoint-every", "2"]);
    assert!(ok, "{err}");
    let ck = run.join("checkpoint.bin");
    let c = ck.to_str().unwrap();
    let config = read(&run.join("config.json"));
    // Outputs made from the model the resume will replace, and a file of the user's.
    std::fs::write(run.join("mesh.ply"), b"old mesh").unwrap();
    std::fs::write(run.join("eval_images.json"), b"{}").unwrap();
    std::fs::create_dir_all(run.join("renders/test")).unwrap();
    std::fs::write(run.join("renders/test/0000.png"), b"old").unwrap();
    std::fs::write(run.join("notes.txt"), b"mine").unwrap();
    let resume = |out: &Path, extra: &[&str]| {
        let mut a = vec!["train", "-o", out.to_str().unwrap(), "--resume", c, "--backend", "cpu", "--quiet"];
        a.extend_from_slice(extra);
        let (ok, _, err) = vagsl(&a);
        (ok, err)
    };
    let (ok, err) = resume(&run, &["--iterations", "8", "--seed", "3"]);
    assert!(!ok && err.contains("--iterations, --seed would be ignored"), "{err}");
    let (ok, err) = resume(&run, &["--width", "50"]);
    assert!(!ok && err.contains("these options would change it: --width 50 (the run's: none)"), "{err}");
    let scene = builtin_dir(12);
    let (ok, err) = resume(&run, &[scene.to_str().unwrap()]);
    assert!(!ok && err.contains("(the run's: the built-in scene)") && err.contains("SCENE"), "{err}");
    assert_eq!(read(&run.join("config.json")), config, "a refused resume rewrote config.json");

    assert!(run.join("mesh.ply").is_file() && run.join("renders").is_dir(), "a refused resume removed outputs");

    // The run's own options are accepted; the run keeps its id. The outputs made from the
    // previous model go (they would describe an older model); the user's file stays.
    let (ok, err) = resume(&run, &["--eval"]);
    assert!(ok, "{err}");
    assert!(err.contains("--resume: removed the previous model's mesh.ply, eval_images.json, renders/"), "{err}");
    for gone in ["mesh.ply", "eval_images.json", "renders"] {
        assert!(!run.join(gone).exists(), "{gone} of the previous model is still there");
    }
    assert_eq!(read(&run.join("notes.txt")), b"mine");
    let id = config_of(&run)["run_id"].clone();
    let report: serde_json::Value = serde_json::from_slice(&read(&run.join("report.json"))).unwrap();
    assert_eq!(report["run_id"], id);
    assert_eq!(read(&run.join("config.json")), config);
    let (ok, err) = render_test(&run);
    assert!(ok, "{err}");

    // Into a new folder the run (scene, held-out views, id) comes from beside the checkpoint.
    let moved = dir.path().join("moved");
    let (ok, err) = resume(&moved, &[]);
    assert!(ok, "{err}");
    assert_eq!(config_of(&moved)["run_id"], id);
    assert_eq!(config_of(&moved)["test_views"].as_array().unwrap().len(), 4);
    // Into a folder holding another run: refused.
    let other = dir.path().join("other");
    let (ok, err) = train(&other, &["--seed", "9"]);
    assert!(ok, "{err}");
    let (ok, err) = resume(&other, &[]);
    assert!(!ok && err.contains("so the folder holds another run"), "{err}");
    // A checkpoint copied on its own names no scene: refused, not resumed on whatever SCENE,
    // -r or --width say (issue #35).
    let alone = dir.path().join("alone");
    std::fs::create_dir(&alone).unwrap();
    std::fs::copy(&ck, alone.join("checkpoint.bin")).unwrap();
    let a = alone.join("checkpoint.bin");
    let fresh = dir.path().join("fresh");
    let (ok, _, err) = vagsl(&["train", "-o", fresh.to_str().unwrap(), "--resume", a.to_str().unwrap(), builtin_dir(8).to_str().unwrap(), "-r", "2", "--backend", "cpu"]);
    assert!(!ok && err.contains("no config.json of the checkpoint's run") && err.contains("alone/checkpoint.bin"), "{err}");
    assert!(!fresh.exists());
}
