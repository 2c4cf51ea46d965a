//! Partitioning a real scene folder (the built-in scene written to disk): every training view
//! in a block, no held-out view in any, block folders that load like any scene with the
//! fingerprint the plan records, and plans that are refused when absurd or damaged.

use gs_partition::{BlockCount, PartitionOptions, Plan, partition};
use gs_run::SceneSource;
use std::path::{Path, PathBuf};

fn scene() -> PathBuf {
    gs_testdata::builtin::scene_dir(Path::new(env!("CARGO_TARGET_TMPDIR")), &gs_testdata::builtin::small())
}

/// The settings of block arguments: `--iterations N` and `--set KEY=VALUE` over the default
/// preset (what the CLI's parser makes of them).
fn config_of(args: &[String]) -> Result<gs_train::TrainConfig, String> {
    let mut c = gs_train::TrainConfig::preset(gs_train::Preset::default());
    for w in args.windows(2) {
        match w[0].as_str() {
            "--iterations" => c = c.scaled(w[1].parse().map_err(|_| format!("--iterations {}", w[1]))?),
            "--set" => c = c.with_assignment(&w[1]).map_err(|e| e.to_string())?,
            _ => {}
        }
    }
    Ok(c)
}

fn options(count: BlockCount) -> PartitionOptions<'static> {
    PartitionOptions { count, margin: 0.2, visibility: 0.25, train_args: vec!["--iterations".into(), "100".into()], share_iterations: true, grow_in_region: true, config_of: &config_of }
}

fn source(eval: bool) -> SceneSource {
    SceneSource { path: Some(scene()), resolution_factor: None, width: None, eval }
}

#[test]
fn blocks_cover_the_training_views_and_load_as_scenes() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("plan");
    let plan = partition(&source(true), &out, &options(BlockCount::Exactly(2)), &mut |_| {}).unwrap();
    assert_eq!(plan.blocks.len(), 2);
    let back = Plan::read(&out).unwrap();
    assert_eq!((&back.held_out, back.blocks.len()), (&plan.held_out, 2), "plan.json reads back as written");
    for (a, b) in back.blocks.iter().zip(&plan.blocks) {
        assert_eq!((&a.views, &a.fingerprint, a.memory_bytes), (&b.views, &b.fingerprint, b.memory_bytes));
    }
    // 12 views, every 8th held out (sorted by name): 0000 and 0008.
    assert_eq!(plan.held_out, vec!["0000.png".to_string(), "0008.png".to_string()]);
    let full = gs_io::load_scene(&scene(), &Default::default()).unwrap();
    let (train, _) = full.split(true);
    for &i in &train {
        let name = &full.views[i].name;
        assert!(plan.blocks.iter().any(|b| b.views.contains(name)), "training view {name} is in no block");
    }
    for b in &plan.blocks {
        assert!(b.views.len() >= gs_partition::MIN_BLOCK_VIEWS);
        assert!(b.views.iter().all(|v| !plan.held_out.contains(v)));
        let dir = out.join(&b.scene);
        assert!(std::fs::symlink_metadata(dir.join("images").join(&b.views[0])).unwrap().file_type().is_symlink(), "photos are linked, not copied");
        let loaded = gs_io::load_scene(&dir, &Default::default()).unwrap();
        assert_eq!(loaded.views.len(), b.views.len());
        assert_eq!(gs_run::SceneFingerprint::of(&loaded), b.fingerprint);
        assert!(loaded.views.iter().all(|v| v.mask.is_some()), "masks are linked too");
        // The block's pixels are the scene's own.
        let v = &loaded.views[0];
        let orig = full.views.iter().find(|w| w.name == v.name).unwrap();
        assert_eq!(v.image.data(), orig.image.data());
        assert!(b.memory_bytes > 0 && b.memory.contains("Gaussians"));
        // Its share of the 100 iterations: its views over the scene's 10 training views.
        assert_eq!(b.train.iterations, (100.0 * b.views.len() as f64 / 10.0).round() as u64);
        // It grows in its grown region (open sides pushed further out), in the plan's frame.
        let r = b.train.densify.region.expect("a block grows in its region");
        // (Through `--set`'s JSON: serde_json parses to within an ulp.)
        let near = |a: [f64; 3], b: [f64; 3]| a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= 1e-12);
        assert!(near(r.origin, plan.frame.origin) && near(r.u, plan.frame.u) && near(r.v, plan.frame.v), "{r:?}");
        for a in 0..2 {
            assert!(r.min[a] <= b.grown.min[a] && r.max[a] >= b.grown.max[a]);
            let bounded = |side: [Option<f64>; 2]| (side[0].is_some(), side[1].is_some());
            let (lo, hi) = bounded(if a == 0 { b.core.u } else { b.core.v });
            assert_eq!((r.min[a] == b.grown.min[a], r.max[a] == b.grown.max[a]), (lo, hi));
        }
        // Its budget counts that region's surface only: below the whole scene's.
        let trainer = gs_train::Trainer::new(&loaded, (0..loaded.views.len()).collect(), b.train.clone()).unwrap();
        let whole = gs_train::Trainer::new(&full, train.clone(), plan.train.clone()).unwrap();
        assert!(trainer.budget().gaussians < whole.budget().gaussians, "{} against {}", trainer.budget().gaussians, whole.budget().gaussians);
    }
    // The run script passes the region as the block's own setting; a user's region is refused.
    let o = gs_partition::runners::RunnerOptions {
        vagsl: "vagsl".into(),
        plan_dir: out.display().to_string(),
        cpus: 2,
        memory_bytes: 1 << 30,
        time_seconds: 3600,
        image: "vagsl".into(),
        data_root: tmp.path().display().to_string(),
    };
    let script = gs_partition::runners::block_script(&plan, &o);
    assert_eq!(script.matches("--set 'densify.region={").count(), 2, "{script}");
    let mut o = options(BlockCount::Exactly(2));
    o.train_args.extend(["--set".into(), "densify.region=null".into()]);
    let e = partition(&source(true), &tmp.path().join("p2"), &o, &mut |_| {}).unwrap_err().to_string();
    assert!(e.contains("the plan sets each block's growth region"), "{e}");
    // The cores tile the plane: each block centre lies in exactly one core.
    for b in &plan.blocks {
        let c = [(b.grown.min[0] + b.grown.max[0]) / 2.0, (b.grown.min[1] + b.grown.max[1]) / 2.0];
        assert_eq!(plan.blocks.iter().filter(|o| o.core.contains(c)).count(), 1);
    }
}

#[test]
fn an_existing_folder_and_absurd_options_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let e = partition(&source(false), tmp.path(), &options(BlockCount::Exactly(2)), &mut |_| {}).unwrap_err().to_string();
    assert!(e.contains("already exists"), "{e}");
    let out = tmp.path().join("p");
    for (count, words) in [(BlockCount::Exactly(0), "give 1 to"), (BlockCount::MemoryPerJob(0), "above 0 bytes")] {
        let e = partition(&source(false), &out, &options(count), &mut |_| {}).unwrap_err().to_string();
        assert!(e.contains(words), "{e}");
    }
    let mut o = options(BlockCount::Exactly(2));
    o.margin = f64::NAN;
    assert_eq!(
        gs_partition::block_train_args(&["--preset".into(), "fast".into(), "--iterations".into(), "9".into(), "--iterations=8".into()], 3, None),
        vec!["--preset", "fast", "--iterations", "3"]
    );
    assert!(partition(&source(false), &out, &o, &mut |_| {}).unwrap_err().to_string().contains("--margin NaN"));
    // More blocks than the ring of 12 cameras can give views to: refused, nothing left behind.
    let e = partition(&source(false), &out, &options(BlockCount::Exactly(12)), &mut |_| {}).unwrap_err().to_string();
    assert!(e.contains("ask for fewer blocks"), "{e}");
    assert!(!out.exists());
    let leftovers: Vec<_> = std::fs::read_dir(tmp.path()).unwrap().filter_map(|e| e.ok()).filter(|e| e.file_name().to_string_lossy().contains("partial")).collect();
    assert!(leftovers.is_empty(), "staging folders left: {leftovers:?}");
    let no_folder = SceneSource { path: None, resolution_factor: None, width: None, eval: false };
    assert!(partition(&no_folder, &out, &options(BlockCount::Exactly(2)), &mut |_| {}).unwrap_err().to_string().contains("built-in scene has no folder"));
}

#[test]
fn a_memory_limit_per_job_sets_the_block_count() {
    let tmp = tempfile::tempdir().unwrap();
    let one = partition(&source(false), &tmp.path().join("one"), &options(BlockCount::Exactly(1)), &mut |_| {}).unwrap();
    let whole = one.blocks[0].memory_bytes;
    let limit = whole - 1;
    let mut notes = Vec::new();
    match partition(&source(false), &tmp.path().join("fit"), &options(BlockCount::MemoryPerJob(limit)), &mut |l| notes.push(l)) {
        Ok(plan) => {
            assert!(plan.blocks.len() >= 2, "{notes:?}");
            assert!(plan.blocks.iter().all(|b| b.memory_bytes <= limit));
        }
        // The fixed parts (program, weights) may keep every block above the limit: then the
        // refusal says so, with the numbers.
        Err(e) => assert!(e.to_string().contains("fewer blocks") || e.to_string().contains("--max-memory-per-job"), "{e}"),
    }
    let plan = partition(&source(false), &tmp.path().join("roomy"), &options(BlockCount::MemoryPerJob(whole)), &mut |_| {}).unwrap();
    assert_eq!(plan.blocks.len(), 1, "a limit the whole scene fits needs one block");
}

#[test]
fn damaged_plans_are_refused_naming_the_problem() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("plan");
    partition(&source(true), &out, &options(BlockCount::Exactly(2)), &mut |_| {}).unwrap();
    let text = std::fs::read_to_string(out.join("plan.json")).unwrap();
    let cases: [(&str, Box<dyn Fn(&mut serde_json::Value)>, &str); 5] = [
        ("index", Box::new(|v| v["blocks"][1]["index"] = 5.into()), "block 1: its index is 5"),
        ("escape", Box::new(|v| v["blocks"][0]["run"] = "../../elsewhere".into()), "not a relative path inside the plan folder"),
        ("held-out", Box::new(|v| v["blocks"][0]["views"][0] = "0008.png".into()), "a held-out view"),
        ("version", Box::new(|v| v["version"] = 99.into()), "plan format version 99"),
        ("margin", Box::new(|v| v["margin"] = 7.into()), "margin 7"),
    ];
    for (what, edit, words) in cases {
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        edit(&mut v);
        std::fs::write(out.join("plan.json"), serde_json::to_string(&v).unwrap()).unwrap();
        let e = Plan::read(&out).unwrap_err().to_string();
        assert!(e.contains(words) && e.contains("plan.json"), "{what}: {e}");
    }
    std::fs::write(out.join("plan.json"), "{\"version\": 1, \"margin\": NaN}").unwrap();
    let e = Plan::read(&out).unwrap_err().to_string();
    assert!(e.contains("not a vagsl partition plan"), "{e}");
    let e = Plan::read(tmp.path()).unwrap_err().to_string();
    assert!(e.contains("cannot read the plan"), "{e}");
}
