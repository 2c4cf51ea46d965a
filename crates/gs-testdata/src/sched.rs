//! The schedulers a partition plan is run on, as test prerequisites: a Slurm cluster that
//! takes jobs ([`slurm`], usually the one-node cluster of `scripts/slurm-local.sh`) and the
//! offline schema check of Kubernetes Job manifests ([`k8s_validator`],
//! `scripts/check-k8s-manifest.sh`). Where one is missing the test prints its SKIPPED line, or
//! fails under `CI=true` (see [`crate::skip_or_fail()`]).

use std::ffi::OsString;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// The environment variable naming the local cluster's folder (as in `scripts/slurm-local.sh`).
pub const SLURM_DIR_ENV: &str = "VAGSL_SLURM_DIR";
/// The local cluster's folder when [`SLURM_DIR_ENV`] is not set.
pub const SLURM_DIR_DEFAULT: &str = "/tmp/vagsl-slurm";
/// How to get a cluster, for the SKIPPED line.
const SLURM_HOW: &str = "start the one-node cluster with scripts/slurm-local.sh start (as root; Debian packages slurm-wlm and munge), or point SLURM_CONF at a cluster";
/// A Slurm client that does not answer in this long is taken as no cluster.
const CLIENT_TIMEOUT: Duration = Duration::from_secs(20);

/// A Slurm cluster that answers and has a node that takes jobs.
#[derive(Debug, Clone)]
pub struct Slurm {
    conf: Option<PathBuf>,
}

impl Slurm {
    /// The `slurm.conf` the clients are pointed at (`None`: Slurm's own default).
    pub fn conf(&self) -> Option<&Path> {
        self.conf.as_deref()
    }

    /// A command for a Slurm client (`sbatch`, `squeue`, `scontrol`, …) talking to this
    /// cluster: `SLURM_CONF` is set when the cluster has its own config.
    pub fn command(&self, program: &str) -> Command {
        let mut c = Command::new(program);
        if let Some(conf) = &self.conf {
            c.env("SLURM_CONF", conf);
        }
        c
    }
}

/// The `slurm.conf` the tests use: `$SLURM_CONF` when set and not empty (the developer chose a
/// cluster), else the local cluster's (`<dir>/etc/slurm.conf`) when that file exists, else none
/// (Slurm's default, e.g. `/etc/slurm/slurm.conf`).
pub fn choose_slurm_conf(slurm_conf: Option<OsString>, local_dir: &Path) -> Option<PathBuf> {
    match slurm_conf {
        Some(c) if !c.is_empty() => Some(PathBuf::from(c)),
        _ => {
            let local = local_dir.join("etc/slurm.conf");
            local.is_file().then_some(local)
        }
    }
}

/// The local cluster's folder: `$VAGSL_SLURM_DIR`, else [`SLURM_DIR_DEFAULT`].
pub fn slurm_dir() -> PathBuf {
    match std::env::var_os(SLURM_DIR_ENV) {
        Some(d) if !d.is_empty() => PathBuf::from(d),
        _ => PathBuf::from(SLURM_DIR_DEFAULT),
    }
}

/// Whether `sinfo -h -N -o %T` output (one node state a line) shows a node that takes jobs:
/// idle, mixed, allocated or completing, and responding (no `*`), not drained, down or being
/// rebooted.
pub fn node_takes_jobs(sinfo_states: &str) -> bool {
    sinfo_states.lines().map(str::trim).any(|s| {
        let base = s.trim_end_matches(['~', '#', '!', '%', '$', '@', '^', '-']);
        matches!(base, "idle" | "mixed" | "allocated" | "completing")
    })
}

/// The outcome of a command run with a time limit: exit success, stdout, stderr.
struct Output {
    ok: bool,
    stdout: String,
    stderr: String,
}

/// Runs `cmd`, killing it after `limit`; `Err` with a sentence when it cannot start or hangs.
/// Its output is read on threads so that a chatty command cannot block on a full pipe.
fn run_with_timeout(mut cmd: Command, limit: Duration) -> Result<Output, String> {
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| format!("cannot run {}: {e}", cmd.get_program().to_string_lossy()))?;
    let read = |pipe: Option<Box<dyn Read + Send>>| {
        std::thread::spawn(move || {
            let mut s = String::new();
            if let Some(mut p) = pipe {
                let _ = p.read_to_string(&mut s);
            }
            s
        })
    };
    let stdout = read(child.stdout.take().map(|p| Box::new(p) as Box<dyn Read + Send>));
    let stderr = read(child.stderr.take().map(|p| Box::new(p) as Box<dyn Read + Send>));
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().map_err(|e| e.to_string())? {
            break s;
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!("{} did not answer in {} s", cmd.get_program().to_string_lossy(), limit.as_secs_f32()));
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let (stdout, stderr) = (stdout.join().unwrap_or_default(), stderr.join().unwrap_or_default());
    Ok(Output { ok: status.success(), stdout, stderr })
}

/// Whether `program` is found on `PATH`.
fn on_path(program: &str) -> bool {
    std::env::var_os("PATH")
        .is_some_and(|p| std::env::split_paths(&p).any(|d| d.join(program).is_file()))
}

/// The Slurm cluster the tests submit to, when one answers and a node takes jobs. Where not,
/// reports the skip for `test` (naming what is missing and `scripts/slurm-local.sh start`) and
/// returns `None`; under `CI=true` that panics. The cluster is probed once per test binary.
/// Use through [`crate::slurm!`].
pub fn slurm(test: &str) -> Option<Slurm> {
    static PROBE: OnceLock<Result<Slurm, String>> = OnceLock::new();
    match PROBE.get_or_init(probe_slurm) {
        Ok(s) => Some(s.clone()),
        Err(why) => {
            crate::skip_or_fail(test, why, SLURM_HOW);
            None
        }
    }
}

/// The cluster, or what is missing.
fn probe_slurm() -> Result<Slurm, String> {
    if !on_path("sinfo") || !on_path("sbatch") {
        return Err("needs Slurm (no sinfo or sbatch on PATH)".into());
    }
    let dir = slurm_dir();
    let cluster = Slurm { conf: choose_slurm_conf(std::env::var_os("SLURM_CONF"), &dir) };
    let conf_name = cluster.conf().map_or("Slurm's default config".to_string(), |c| c.display().to_string());
    // The local cluster's controller not running: said at once (sinfo retries for ~20 s).
    if cluster.conf() == Some(dir.join("etc/slurm.conf").as_path()) && !pid_alive(&dir.join("run/slurmctld.pid")) {
        return Err(format!("needs a running Slurm cluster (the local one in {} is stopped)", dir.display()));
    }
    let mut sinfo = cluster.command("sinfo");
    sinfo.args(["-h", "-N", "-o", "%T"]);
    match run_with_timeout(sinfo, CLIENT_TIMEOUT) {
        Ok(o) if o.ok && node_takes_jobs(&o.stdout) => Ok(cluster),
        Ok(o) if o.ok => {
            let states = o.stdout.split_whitespace().collect::<Vec<_>>().join(", ");
            let states = if states.is_empty() { "no nodes".to_string() } else { states };
            Err(format!("needs a Slurm node that takes jobs (sinfo with {conf_name} reports: {states})"))
        }
        Ok(o) => Err(format!(
            "needs a running Slurm cluster (sinfo with {conf_name} failed: {})",
            o.stderr.lines().next().unwrap_or("no message")
        )),
        Err(e) => Err(format!("needs a running Slurm cluster ({e}, with {conf_name})")),
    }
}

/// Whether the pid file `path` names a running process.
fn pid_alive(path: &Path) -> bool {
    std::fs::read_to_string(path)
        .ok()
        .and_then(|p| p.trim().parse::<u32>().ok())
        .is_some_and(|pid| Path::new(&format!("/proc/{pid}")).exists())
}

/// The offline Kubernetes Job schema check, `scripts/check-k8s-manifest.sh`.
#[derive(Debug, Clone)]
pub struct K8sValidator {
    script: PathBuf,
}

impl K8sValidator {
    /// Checks the manifest `file`: `Err` with the validator's message when it is not a batch/v1
    /// Job that validates against the schema.
    pub fn check(&self, file: &Path) -> Result<(), String> {
        let mut cmd = Command::new("bash");
        cmd.arg(&self.script).arg(file);
        let o = run_with_timeout(cmd, Duration::from_secs(120))?;
        if o.ok {
            Ok(())
        } else {
            Err(format!("{}{}", o.stdout, o.stderr).trim().to_string())
        }
    }
}

/// The Kubernetes Job schema check, when its validator (`kubernetes-validate`, from PyPI) is
/// installed. Where not, reports the skip for `test` and returns `None`; under `CI=true` that
/// panics. Use through [`crate::k8s_validator!`].
pub fn k8s_validator(test: &str) -> Option<K8sValidator> {
    let how = "pip install kubernetes-validate==1.37.0 (.ci/run installs it)";
    let mut version = Command::new("kubernetes-validate");
    version.arg("--version");
    match run_with_timeout(version, CLIENT_TIMEOUT) {
        Ok(o) if o.ok => Some(K8sValidator { script: crate::repo_root().join("scripts/check-k8s-manifest.sh") }),
        Ok(o) => {
            let why = format!("needs kubernetes-validate (it failed: {})", o.stderr.lines().next().unwrap_or("no message"));
            crate::skip_or_fail(test, &why, how);
            None
        }
        Err(_) => {
            crate::skip_or_fail(test, "needs kubernetes-validate (not installed)", how);
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn takes_jobs_only_when_a_node_responds_in_a_usable_state() {
        assert!(node_takes_jobs("idle\n"));
        assert!(node_takes_jobs("mixed"));
        assert!(node_takes_jobs("down*\nallocated\n"));
        assert!(node_takes_jobs("idle~\n"), "a powered-down cloud node starts on demand");
        assert!(!node_takes_jobs("idle*\n"), "not responding");
        assert!(!node_takes_jobs("down*\n"));
        assert!(!node_takes_jobs("drained\ndraining\n"));
        assert!(!node_takes_jobs("unknown\n"));
        assert!(!node_takes_jobs(""));
    }

    #[test]
    fn slurm_conf_from_the_environment_first_then_the_local_cluster() {
        let tmp = std::env::temp_dir().join(format!("gs-testdata-sched-conf-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&tmp);
        std::fs::create_dir_all(tmp.join("etc")).unwrap();
        // No local config written yet: Slurm's default.
        assert_eq!(choose_slurm_conf(None, &tmp), None);
        assert_eq!(choose_slurm_conf(Some(OsString::new()), &tmp), None);
        std::fs::write(tmp.join("etc/slurm.conf"), "ClusterName=t\n").unwrap();
        assert_eq!(choose_slurm_conf(None, &tmp), Some(tmp.join("etc/slurm.conf")));
        assert_eq!(choose_slurm_conf(Some("/x/slurm.conf".into()), &tmp), Some(PathBuf::from("/x/slurm.conf")));
        std::fs::remove_dir_all(&tmp).unwrap();
    }

    #[test]
    fn a_hanging_command_is_cut_off() {
        let mut c = Command::new("sleep");
        c.arg("30");
        let t = Instant::now();
        let e = run_with_timeout(c, Duration::from_millis(300)).err().unwrap();
        assert!(t.elapsed() < Duration::from_secs(10));
        assert!(e.contains("did not answer"), "{e}");
        let mut c = Command::new("sh");
        c.args(["-c", "echo out; echo err >&2; exit 3"]);
        let o = run_with_timeout(c, CLIENT_TIMEOUT).unwrap();
        assert!(!o.ok);
        assert_eq!((o.stdout.as_str(), o.stderr.as_str()), ("out\n", "err\n"));
    }

    #[test]
    fn pid_files_name_running_processes_or_not() {
        let tmp = std::env::temp_dir().join(format!("gs-testdata-sched-pid-{}", std::process::id()));
        std::fs::write(&tmp, format!("{}\n", std::process::id())).unwrap();
        assert!(pid_alive(&tmp));
        std::fs::write(&tmp, "not a pid").unwrap();
        assert!(!pid_alive(&tmp));
        std::fs::remove_file(&tmp).unwrap();
        assert!(!pid_alive(&tmp));
    }

    #[test]
    fn slurm_commands_carry_the_chosen_config() {
        let s = Slurm { conf: Some(PathBuf::from("/x/slurm.conf")) };
        let c = s.command("sbatch");
        let envs: Vec<_> = c.get_envs().collect();
        assert_eq!(envs, vec![(std::ffi::OsStr::new("SLURM_CONF"), Some(std::ffi::OsStr::new("/x/slurm.conf")))]);
        assert_eq!(Slurm { conf: None }.command("sbatch").get_envs().count(), 0);
    }
}
