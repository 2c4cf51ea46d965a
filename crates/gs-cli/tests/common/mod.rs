//! Helpers shared by the gs-cli integration tests.
#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::process::Child;

/// Waits until the training `child` (spawned with its stderr piped) prints its budget line —
/// just before the training loop installs its signal handlers — lets it train 1.5 s, sends it
/// `signal`, and returns its whole stderr and exit code.
#[cfg(unix)]
pub fn signal_while_training(child: &mut Child, signal: i32) -> (String, Option<i32>) {
    let mut lines = BufReader::new(child.stderr.take().expect("stderr piped")).lines();
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
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, signal) }, 0);
    log.extend(lines.map(|l| l.unwrap() + "\n"));
    let code = child.wait().unwrap().code();
    (log, code)
}
