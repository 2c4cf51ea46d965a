//! SIGTERM, SIGHUP and SIGINT stop a training run like Ctrl-C: the current iteration ends, the
//! checkpoint and the model are written, and the exit status is 128 + the signal number.
#![cfg(unix)]

mod common;

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
    let (log, code) = common::signal_while_training(&mut child, number);
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
