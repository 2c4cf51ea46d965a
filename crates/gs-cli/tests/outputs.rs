//! Every output path goes through one check (issue #35): never a run's own file unless it is
//! the command's own output, never through a link or onto a device, a file standing in for a
//! folder is named, and a bad path is refused before the work. `--force` keeps the previous
//! run until the new one is written, and two `train -o SAME` cannot run at once.
#![cfg(unix)]

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn vagsl(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_vagsl")).args(args).env("RAYON_NUM_THREADS", "2").output().expect("run vagsl");
    (out.status.success(), String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned())
}

fn train_args<'a>(out: &'a str, iterations: &'a str) -> Vec<&'a str> {
    vec!["train", "-o", out, "--iterations", iterations, "--backend", "cpu", "--quiet"]
}

/// A 4-iteration CPU run of the built-in scene in `dir/run`.
fn trained_run(dir: &Path) -> PathBuf {
    let run = dir.join("run");
    let (ok, _, err) = vagsl(&train_args(run.to_str().unwrap(), "4"));
    assert!(ok, "{err}");
    run
}

fn refused(args: &[&str], words: &[&str]) -> String {
    let (ok, out, err) = vagsl(args);
    assert!(!ok, "{args:?} succeeded: {out}");
    for w in words {
        assert!(err.contains(w), "{args:?}: '{w}' not in {err}");
    }
    assert!(!err.contains("rasterizer:"), "{args:?}: work started before the refusal: {err}");
    err
}

/// SHA-256 of every file of `dir` (not recursive) by name, but for the lock file of `train`.
fn snapshot(dir: &Path) -> Vec<(String, String)> {
    use sha2::{Digest, Sha256};
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap())
        .filter(|e| e.file_type().unwrap().is_file() && e.file_name() != ".vagsl-train.lock")
        .map(|e| {
            let digest = Sha256::digest(std::fs::read(e.path()).unwrap()).iter().map(|b| format!("{b:02x}")).collect();
            (e.file_name().to_string_lossy().into_owned(), digest)
        })
        .collect();
    v.sort();
    v
}

#[test]
fn no_command_writes_over_a_run_file_a_link_or_a_device() {
    let dir = tempfile::tempdir().unwrap();
    let run = trained_run(dir.path());
    let r = run.to_str().unwrap();
    let before = snapshot(&run);
    let own = |f: &str| run.join(f).to_str().unwrap().to_string();
    for f in ["config.json", "report.json", "metrics.jsonl", "point_cloud.ply"] {
        refused(&["export", r, "--format", "ply", "-o", &own(f)], &[&own(f), &format!("the run's own {f}")]);
    }
    // mesh -o RUN/config.ply would write its report as RUN/config.json.
    refused(&["mesh", r, "--backend", "cpu", "-o", &own("config.ply")], &["config.json", "the run's own config.json"]);
    refused(&["mesh", r, "--backend", "cpu", "-o", &own("report.json")], &["the run's own report.json"]);
    assert_eq!(snapshot(&run), before, "a run file changed");

    // A symbolic link stays a link; its target is untouched.
    let target = dir.path().join("target.splat");
    std::fs::write(&target, b"mine").unwrap();
    let link = dir.path().join("link.splat");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    refused(&["export", r, "-o", link.to_str().unwrap()], &["link.splat", "symbolic link"]);
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
    assert_eq!(std::fs::read(&target).unwrap(), b"mine");
    // A device is never replaced by a regular file (as root the rename would do it).
    refused(&["export", r, "-o", "/dev/null", "--format", "splat"], &["/dev/null", "not a regular file"]);
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::metadata("/dev/null").unwrap().file_type().is_char_device());
    refused(&["mesh", r, "--backend", "cpu", "-o", "/dev/null"], &["/dev/null", "not a regular file"]);

    // A file where a folder is expected is named as such; a folder or DIR/ is not a file name;
    // a folder that refuses new files (sysfs refuses even root) is refused before fusing.
    let file = dir.path().join("FILE");
    std::fs::write(&file, b"x").unwrap();
    let under = file.join("m.ply");
    refused(&["mesh", r, "--backend", "cpu", "-o", under.to_str().unwrap()], &[&format!("{} is a file, not a folder", file.display())]);
    let slash = format!("{}/", dir.path().join("newdir").display());
    refused(&["mesh", r, "--backend", "cpu", "-o", &slash], &["newdir/", "folder, not a file"]);
    refused(&["mesh", r, "--backend", "cpu", "-o", dir.path().to_str().unwrap()], &["folder, not a file"]);
    refused(&["mesh", r, "--backend", "cpu", "-o", "/sys/m.ply"], &["/sys/m.ply", "cannot write in the folder /sys"]);

    // view: the report folder replaced by a link is refused before rendering.
    let elsewhere = dir.path().join("elsewhere");
    std::fs::create_dir(&elsewhere).unwrap();
    std::os::unix::fs::symlink(&elsewhere, run.join("report")).unwrap();
    refused(&["view", r, "--backend", "cpu", "--no-lpips"], &["report", "link or a file"]);
    std::fs::remove_file(run.join("report")).unwrap();
    // eval-images: a folder in the scores' place is refused before scoring.
    std::fs::create_dir(run.join("eval_images.json")).unwrap();
    refused(&["eval-images", r, "--backend", "cpu", "--no-lpips"], &["eval_images.json", "folder, not a file"]);
    std::fs::remove_dir(run.join("eval_images.json")).unwrap();

    // An empty mesh is an error, its voxel in scientific notation; nothing is written.
    let (ok, _, err) = vagsl(&["mesh", r, "--backend", "cpu", "--voxel-size", "1e300", "-o", &own("mesh.ply")]);
    assert!(!ok && err.contains("the fused mesh is empty (0 triangles") && err.contains("voxel size 1.000e300"), "{err}");
    assert!(!run.join("mesh.ply").exists());

    // The command's own output in its own run is fine.
    let (ok, _, err) = vagsl(&["mesh", r, "--backend", "cpu", "--voxel-size", "0.06", "-o", &own("mesh.ply")]);
    assert!(ok, "{err}");
}

/// A child process killed when the test ends, passing or not.
struct Killed(std::process::Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Waits until `cond` holds, at most `secs` seconds.
fn wait_for(secs: u64, cond: impl Fn() -> bool) -> bool {
    let t = Instant::now();
    while t.elapsed() < Duration::from_secs(secs) {
        if cond() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    false
}

/// The staging folder of a `--force` run in `run`, if one exists.
fn staging(run: &Path) -> Option<PathBuf> {
    std::fs::read_dir(run).ok()?.map(|e| e.unwrap().path()).find(|p| p.file_name().unwrap().to_string_lossy().starts_with(".train."))
}

#[test]
fn force_keeps_the_old_run_until_the_new_one_is_written_and_one_train_per_folder() {
    let dir = tempfile::tempdir().unwrap();
    let run = trained_run(dir.path());
    let r = run.to_str().unwrap();
    std::fs::write(run.join("mesh.ply"), b"old mesh").unwrap();
    let before = snapshot(&run);

    // A long --force run: the old run stays whole while it trains.
    let mut a = train_args(r, "100000");
    a.extend(["--force", "--seed", "3"]);
    let mut child = Killed(Command::new(env!("CARGO_BIN_EXE_vagsl")).args(&a).env("RAYON_NUM_THREADS", "1").stderr(Stdio::null()).spawn().unwrap());
    assert!(wait_for(120, || staging(&run).is_some_and(|s| s.join("config.json").is_file())), "no staging folder appeared");
    assert_eq!(snapshot(&run), before, "the old run changed while the new one trains");

    // A second train into the same folder meanwhile is refused, by the lock.
    let mut b = train_args(r, "4");
    b.push("--force");
    let (ok, _, err) = vagsl(&b);
    assert!(!ok && err.contains("another `vagsl train` is writing this run folder"), "{err}");

    // Killed (power loss, out of disk): the old run is intact and still opens.
    child.0.kill().unwrap();
    child.0.wait().unwrap();
    assert_eq!(snapshot(&run), before, "the old run changed");
    let (ok, _, err) = vagsl(&["export", r, "-o", dir.path().join("m.splat").to_str().unwrap()]);
    assert!(ok, "{err}");

    // A --force run that ends replaces the run and removes the old mesh.
    let mut c = train_args(r, "4");
    c.extend(["--force", "--seed", "5"]);
    let (ok, _, err) = vagsl(&c);
    assert!(ok, "{err}");
    assert!(err.contains("removed the previous run's mesh.ply"), "{err}");
    assert!(!run.join("mesh.ply").exists());
    let cfg: serde_json::Value = serde_json::from_slice(&std::fs::read(run.join("config.json")).unwrap()).unwrap();
    assert_eq!(cfg["train"]["seed"], 5);
    let (ok, _, err) = vagsl(&["export", r, "-o", dir.path().join("n.splat").to_str().unwrap()]);
    assert!(ok, "{err}");
}

#[test]
fn a_mesh_of_another_model_is_refused_by_its_readers() {
    let dir = tempfile::tempdir().unwrap();
    let a = trained_run(dir.path());
    let b = dir.path().join("b");
    let (ok, _, err) = vagsl(&train_args(b.to_str().unwrap(), "4").into_iter().chain(["--seed", "7"]).collect::<Vec<_>>());
    assert!(ok, "{err}");
    let (ok, _, err) = vagsl(&["mesh", a.to_str().unwrap(), "--backend", "cpu", "--voxel-size", "0.06"]);
    assert!(ok, "{err}");
    let record: serde_json::Value = serde_json::from_slice(&std::fs::read(a.join("mesh.json")).unwrap()).unwrap();
    let fa = record["made_from"]["model_fingerprint"].as_str().unwrap().to_string();
    let obj = dir.path().join("m.obj");
    let (ok, _, err) = vagsl(&["export", a.to_str().unwrap(), "-o", obj.to_str().unwrap()]);
    assert!(ok, "{err}");
    // The export and the renders record the model they came from, as the mesh does.
    assert_eq!(fa.len(), 32, "the model fingerprint covers every parameter, SH included");
    let index: serde_json::Value = serde_json::from_slice(&std::fs::read(a.join("exports.json")).unwrap()).unwrap();
    assert_eq!(index["exports"][0]["made_from"]["model_fingerprint"], fa.as_str(), "{index}");
    assert_eq!(index["exports"][0]["format"], "obj", "{index}");
    let renders = dir.path().join("a_renders");
    let (ok, _, err) = vagsl(&["render", a.to_str().unwrap(), "--backend", "cpu", "--split", "train", "-o", renders.to_str().unwrap()]);
    assert!(ok, "{err}");
    let record: serde_json::Value = serde_json::from_slice(&std::fs::read(renders.join("renders.json")).unwrap()).unwrap();
    assert_eq!(record["made_from"]["model_fingerprint"], fa.as_str(), "{record}");
    // A's mesh beside B's model (as a mesh made while B was re-trained): refused, naming both.
    for f in ["mesh.ply", "mesh.json"] {
        std::fs::copy(a.join(f), b.join(f)).unwrap();
    }
    let err = refused(&["export", b.to_str().unwrap(), "-o", dir.path().join("n.obj").to_str().unwrap()], &["mesh.ply: made from model", &fa, "but the run's model is now", "vagsl mesh"]);
    let cfg: serde_json::Value = serde_json::from_slice(&std::fs::read(b.join("config.json")).unwrap()).unwrap();
    assert!(err.contains(cfg["run_id"].as_str().unwrap()), "{err}");
    refused(&["view", b.to_str().unwrap(), "--backend", "cpu", "--no-lpips"], &["mesh.ply: made from model", &fa]);
}
