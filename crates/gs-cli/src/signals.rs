//! Stop requests from the terminal or the system: SIGINT (Ctrl-C), SIGTERM (`kill`, batch
//! schedulers ending a job) and SIGHUP (the terminal closed) all ask a training run to stop
//! after the current iteration and write its checkpoint; the process then exits with the
//! conventional status 128 + signal number (130, 143, 129).
//!
//! `signal-hook` rather than `ctrlc`: `ctrlc` can catch SIGTERM and SIGHUP too, but does not
//! say which signal arrived, and the exit status needs it.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

/// The signal that asked the run to stop (0 while none has).
#[derive(Debug, Clone)]
pub struct StopRequest(Arc<AtomicUsize>);

/// The signals that stop a run gracefully.
#[cfg(unix)]
const SIGNALS: &[i32] = &[signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM, signal_hook::consts::SIGHUP];
#[cfg(not(unix))]
const SIGNALS: &[i32] = &[signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM];

impl StopRequest {
    /// Installs the handlers. A second signal while the checkpoint is written changes nothing:
    /// the write is atomic and finishes.
    pub fn install() -> std::io::Result<Self> {
        let flag = Arc::new(AtomicUsize::new(0));
        for &s in SIGNALS {
            signal_hook::flag::register_usize(s, flag.clone(), s as usize)?;
        }
        Ok(Self(flag))
    }

    /// The signal number, once one has arrived.
    pub fn signal(&self) -> Option<i32> {
        match self.0.load(Ordering::SeqCst) {
            0 => None,
            s => Some(s as i32),
        }
    }
}

/// The error of a run stopped by a signal; `main` turns it into exit status 128 + signal.
#[derive(Debug)]
pub struct Stopped {
    /// The signal number.
    pub signal: i32,
    /// What was kept, in words.
    pub message: String,
}

impl std::fmt::Display for Stopped {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        use signal_hook::consts;
        let name = match self.signal {
            consts::SIGINT => "SIGINT",
            consts::SIGTERM => "SIGTERM",
            #[cfg(unix)]
            consts::SIGHUP => "SIGHUP",
            _ => "a signal",
        };
        write!(f, "stopped by {name}: {}", self.message)
    }
}

impl std::error::Error for Stopped {}

impl Stopped {
    /// The conventional exit status, 128 + the signal number.
    pub fn exit_status(&self) -> u8 {
        (128 + self.signal).clamp(0, 255) as u8
    }
}
