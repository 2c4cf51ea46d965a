//! A write killed mid-way leaves `.NAME.PID.tmp`; the next write of the same target removes it
//! when PID is gone, and never touches a live process's file (issue #21, D9). Linux only: the
//! liveness check reads `/proc`.
#![cfg(target_os = "linux")]

use gs_io::{remove_stale_temps, write_atomic};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, SystemTime};

/// A temporary-file name of `target` for `pid`, created with content and modified `age` ago.
fn temp(dir: &Path, target: &str, pid: &str, age: Duration) -> PathBuf {
    let p = dir.join(format!(".{target}.{pid}.tmp"));
    std::fs::write(&p, b"partial").unwrap();
    std::fs::File::options().write(true).open(&p).unwrap().set_modified(SystemTime::now() - age).unwrap();
    p
}

/// The PID of a process that has exited and been reaped.
fn dead_pid() -> u32 {
    let mut child = Command::new("true").spawn().unwrap();
    let pid = child.id();
    child.wait().unwrap();
    assert!(!Path::new(&format!("/proc/{pid}")).exists());
    pid
}

#[test]
fn leftovers_of_dead_writers_are_removed_and_live_ones_kept() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let hour = Duration::from_secs(3600);
    let dead = dead_pid().to_string();
    let mut live = Command::new("sleep").arg("60").spawn().unwrap();
    let live_pid = live.id().to_string();

    let stale = temp(d, "out.ply", &dead, hour);
    let of_live = temp(d, "out.ply", &live_pid, hour);
    // Kept: another target's, a non-PID name, a dead writer's that is too recent.
    let other_target = temp(d, "other.ply", &dead, hour);
    let not_a_pid = temp(d, "out.ply", "12ab", hour);
    let fresh_dead = temp(d, "out.ply", &dead_pid().to_string(), Duration::ZERO);

    write_atomic(&d.join("out.ply"), |w| w.write_all(b"complete")).unwrap();
    assert_eq!(std::fs::read(d.join("out.ply")).unwrap(), b"complete");
    assert!(!stale.exists(), "the dead writer's file is removed");
    for kept in [&of_live, &other_target, &not_a_pid, &fresh_dead] {
        assert!(kept.exists(), "{} must be kept", kept.display());
    }
    live.kill().unwrap();
    live.wait().unwrap();
    // Once the live writer is gone its leftover is stale too.
    assert_eq!(remove_stale_temps(d, "out.ply"), vec![of_live]);
    assert!(remove_stale_temps(d, "out.ply").is_empty());
}

#[test]
fn folders_of_dead_writers_are_removed_too() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let hour = Duration::from_secs(3600);
    let folder = |pid: &str, age: Duration| {
        let p = d.join(format!(".report.{pid}.tmp"));
        std::fs::create_dir_all(p.join("views")).unwrap();
        std::fs::write(p.join("views/0000_photo.jpg"), b"partial").unwrap();
        std::fs::File::open(&p).unwrap().set_modified(SystemTime::now() - age).unwrap();
        p
    };
    let stale = folder(&dead_pid().to_string(), hour);
    let fresh = folder(&dead_pid().to_string(), Duration::ZERO);
    let mine = folder(&std::process::id().to_string(), hour);
    // A link named like a leftover is neither followed nor removed.
    let target = d.join("kept");
    std::fs::create_dir(&target).unwrap();
    let link = d.join(format!(".report.{}.tmp", dead_pid()));
    std::os::unix::fs::symlink(&target, &link).unwrap();
    assert_eq!(remove_stale_temps(d, "report"), vec![stale.clone()]);
    assert!(!stale.exists());
    for kept in [&fresh, &mine, &target, &link] {
        assert!(kept.exists(), "{} must be kept", kept.display());
    }
}
