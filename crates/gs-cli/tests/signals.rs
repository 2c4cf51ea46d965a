//! SIGTERM, SIGHUP and SIGINT stop a training run like Ctrl-C: the current iteration ends, the
//! checkpoint and the model are written, and the exit status is 128 + the signal number.
#![cfg(unix)]

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};

fn stop_with(signal: &str, number: i32, status: i32) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let mut child = Command::new(env!("CARGO_BIN_EXE_vagsl"))
        .args(["train", "-o", out.to_str().unwrap(), "--iterations", "100000", "--backend", "cpu", "--quiet"])
        .env("RAYON_NUM_THREADS", "2")
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The budget line is printed just before the training loop installs its handlers.
    let mut lines = BufReader::new(child.stderr.take().unwrap()).lines();
    let mut log = String::new();
    for line in lines.by_ref() {
        let line = line.unwrap();
        log += &line;
        log.push('\n');
        if line.starts_with("Gaussian budget") {
            break;
        }
    }
    assert!(log.contains("Gaussian budget"), "training did not start:\n{log}");
    std::thread::sleep(std::time::Duration::from_millis(1500));
    // SAFETY: kill(2) on our own child's pid, which has not been waited for yet.
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, number) }, 0);
    log.extend(lines.map(|l| l.unwrap() + "\n"));
    let code = child.wait().unwrap().code();
    assert_eq!(code, Some(status), "{signal}:\n{log}");
    assert!(log.contains(&format!("stopped by SIG{signal}: interrupted at iteration")), "{log}");
    assert!(out.join("checkpoint.bin").is_file() && out.join("point_cloud.ply").is_file(), "{log}");
}

#[test]
fn sigterm_checkpoints_and_exits_143() {
    stop_with("TERM", libc::SIGTERM, 143);
}

#[test]
fn sighup_checkpoints_and_exits_129() {
    stop_with("HUP", libc::SIGHUP, 129);
}

#[test]
fn sigint_checkpoints_and_exits_130() {
    stop_with("INT", libc::SIGINT, 130);
}
