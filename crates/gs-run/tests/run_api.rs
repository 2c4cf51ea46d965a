//! gs-run without the command line, on a generated scene (gs-testdata's built-in scene on
//! disk): a run written through the API opens, pairs with its scene, logs its curves, and its
//! derived files are refused once the model changes, naming both fingerprints.

use gs_run::provenance::{self, MadeFrom};
use gs_run::run_config::{SceneSource, load_scene};
use gs_run::run_folder;
use gs_run::{OpenRun, RunConfig, RunError, SceneFingerprint, write_json};
use gs_train::{TrainConfig, Trainer};
use serde::Serialize;
use std::path::{Path, PathBuf};

fn scene_dir() -> PathBuf {
    gs_testdata::builtin::scene_dir(Path::new(env!("CARGO_TARGET_TMPDIR")), &gs_testdata::builtin::small())
}

/// The part of report.json gs-run reads: the record of the model.
#[derive(Serialize)]
struct Report {
    #[serde(flatten)]
    made_from: MadeFrom,
    iterations: u64,
}

/// Trains `iterations` on the built-in scene into `out` through gs-run alone, as a front end
/// would: lock and prepare the folder, write config.json, log the curves, write the report
/// and then the model. Returns the run's configuration.
fn train_run(out: &Path, iterations: u64) -> RunConfig {
    let source = SceneSource { path: Some(scene_dir()), resolution_factor: None, width: None, eval: true };
    let scene = load_scene(&source).unwrap();
    let (train, test) = scene.split(true);
    let config = TrainConfig::preset(gs_train::Preset::default()).scaled(iterations);
    let names = |idx: &[usize]| idx.iter().map(|&i| scene.views[i].name.clone()).collect::<Vec<_>>();
    let run_config = RunConfig {
        scene: source,
        fingerprint: Some(SceneFingerprint::of(&scene)),
        run_id: Some(gs_run::new_run_id(&config)),
        train_views: names(&train),
        test_views: names(&test),
        train: config.clone(),
    };
    run_folder::check(out, false, false).unwrap();
    let mut folder = run_folder::prepare(out, false, false).unwrap();
    write_json(&folder.work.join("config.json"), &run_config).unwrap();
    let mut trainer = Trainer::new(&scene, train, config.clone()).unwrap();
    gs_run::budget_check::check_train(&trainer, None).unwrap();
    let mut log = gs_run::metrics_log::MetricsLog::open(&folder.work, None, config.iterations, true, None).unwrap();
    let mut seconds = 0.0;
    trainer
        .run(|tr, r| {
            seconds += 0.01;
            log.record(tr, r, seconds, &test, r.iteration == config.iterations).unwrap();
            true
        })
        .unwrap();
    drop(log);
    let report = Report { made_from: MadeFrom::of(&run_config, trainer.gaussians().unwrap()), iterations: trainer.iteration() };
    write_json(&folder.work.join("report.json"), &report).unwrap();
    gs_io::write_gaussian_ply(&folder.work.join("point_cloud.ply"), trainer.gaussians().unwrap()).unwrap();
    assert!(folder.commit().unwrap().is_none(), "a new folder is not staged");
    run_config
}

fn message(e: RunError) -> String {
    gs_run::chain_text(&e)
}

#[test]
fn a_run_written_through_the_api_opens_logs_and_pairs_with_its_scene() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let config = train_run(&out, 20);

    // The folder now holds a run: a second training into it is refused without --force.
    let e = message(run_folder::check(&out, false, false).unwrap_err());
    assert!(e.contains("already holds a vagsl run"), "{e}");

    // It opens, with the record of its model.
    let run = OpenRun::open(&out, None).unwrap();
    assert_eq!(run.made_from.run_id, config.run_id);
    assert_eq!(run.made_from.model_fingerprint.len(), 32);
    assert_eq!(run.model().train.len() + run.model().test.len(), 12);

    // The curves: a loss line every 10 iterations and held-out scores at the end.
    let text = std::fs::read_to_string(out.join("metrics.jsonl")).unwrap();
    let lines: Vec<serde_json::Value> = text.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    let losses: Vec<u64> = lines.iter().filter(|l| l.get("loss").is_some()).map(|l| l["iteration"].as_u64().unwrap()).collect();
    assert_eq!(losses, [10, 20]);
    let last = lines.iter().rev().find(|l| l.get("heldout_psnr").is_some()).expect("a held-out line");
    assert_eq!(last["iteration"], 20);
    assert!(last["heldout_psnr"].as_f64().unwrap().is_finite());

    // Pairing: the run's own scene passes; the same cameras with one photo edited are refused.
    config.check_scene(&run.scene, "the run", "give its scene").unwrap();
    let mut edited = run.scene.clone();
    edited.views[3].image.data_mut()[7] += 0.25;
    let e = message(config.check_scene(&edited, "the run", "give its scene").unwrap_err());
    assert!(e.contains("photos' pixels differ"), "{e}");
    // Another scene (fewer views) is refused naming the counts.
    let mut fewer = run.scene.clone();
    fewer.views.pop();
    let e = message(config.check_scene(&fewer, "the run", "give its scene").unwrap_err());
    assert!(e.contains("it has 11 views, the run's scene had 12"), "{e}");
}

#[test]
fn derived_files_of_an_older_model_are_refused_naming_both_fingerprints() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    train_run(&out, 10);
    let run = OpenRun::open(&out, None).unwrap();
    let now = run.made_from.clone();

    // The older model: the same run's model with one SH coefficient changed (a colour edit
    // the fingerprint must notice).
    let (config, mut older) = gs_run::read_run_model(&out).unwrap();
    older.sh[0][1][2] += 0.5;
    let then = MadeFrom::of(&config, &older);
    assert_ne!(then.model_fingerprint, now.model_fingerprint, "the fingerprint misses the SH coefficients");

    let expect_refused = |r: gs_run::Result<()>, what: &str| {
        let e = r.expect_err(what);
        assert!(matches!(e, RunError::Stale(_)), "{what}: {e}");
        let m = e.to_string();
        assert!(m.contains(&then.model_fingerprint) && m.contains(&now.model_fingerprint), "{what}: {m}");
    };

    // mesh.json / eval_*.json style: a JSON file with `made_from`.
    let mesh_json = out.join("mesh.json");
    write_json(&mesh_json, &provenance::with_made_from(&serde_json::json!({ "triangles": 1 }), &then).unwrap()).unwrap();
    expect_refused(provenance::check(&out.join("mesh.ply"), &mesh_json, &now, "vagsl mesh RUN"), "mesh.json");
    write_json(&mesh_json, &provenance::with_made_from(&serde_json::json!({ "triangles": 1 }), &now).unwrap()).unwrap();
    provenance::check(&out.join("mesh.ply"), &mesh_json, &now, "vagsl mesh RUN").unwrap();

    // Renders.
    let renders = out.join("renders").join("test");
    std::fs::create_dir_all(&renders).unwrap();
    provenance::write_renders_record(&renders, "test", &["0000.png".into()], &then).unwrap();
    expect_refused(provenance::check_renders(&renders, &now, "vagsl render RUN"), "renders");
    provenance::write_renders_record(&renders, "test", &["0000.png".into()], &now).unwrap();
    provenance::check_renders(&renders, &now, "vagsl render RUN").unwrap();

    // The report page.
    std::fs::create_dir_all(out.join("report")).unwrap();
    provenance::write_report_page_record(&out, &then).unwrap();
    expect_refused(provenance::check_report_page(&out, &now), "report page");
    provenance::write_report_page_record(&out, &now).unwrap();
    provenance::check_report_page(&out, &now).unwrap();

    // Exports, through the run's index.
    let export = dir.path().join("model.splat");
    provenance::record_export(&out, &export, "splat", &then).unwrap();
    expect_refused(provenance::check_export(&out, &export, &now), "export");
    provenance::record_export(&out, &export, "splat", &now).unwrap();
    provenance::check_export(&out, &export, &now).unwrap();
    assert_eq!(provenance::read_exports(&out).len(), 1, "an export made again replaces its entry");

    // report.json itself: a model that is not the one the report describes is refused at open.
    let mut g = older.clone();
    g.sh_degree = 0;
    gs_io::write_gaussian_ply(&out.join("point_cloud.ply"), &g).unwrap();
    let e = message(OpenRun::open(&out, None).err().expect("a model the report does not describe"));
    assert!(e.contains("point_cloud.ply is not the model report.json describes"), "{e}");
}

#[test]
fn a_train_lock_keeps_a_second_writer_out_and_force_stages_the_new_run() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("config.json"), "{}").unwrap();
    std::fs::write(out.join("mesh.ply"), "old").unwrap();
    std::fs::write(out.join("notes.txt"), "the user's").unwrap();
    let mut first = run_folder::prepare(&out, true, false).unwrap();
    assert_ne!(first.work, out, "--force over a run stages the new one");
    let e = message(run_folder::prepare(&out, true, false).err().expect("a second writer"));
    assert!(e.contains("another `vagsl train` is writing this run folder"), "{e}");
    std::fs::write(first.work.join("config.json"), "{\"new\":1}").unwrap();
    let note = first.commit().unwrap().expect("a staged run says what it replaced");
    assert!(note.contains("config.json") && note.contains("mesh.ply"), "{note}");
    assert_eq!(std::fs::read_to_string(out.join("config.json")).unwrap(), "{\"new\":1}");
    assert!(!out.join("mesh.ply").exists());
    assert_eq!(std::fs::read_to_string(out.join("notes.txt")).unwrap(), "the user's");
}
