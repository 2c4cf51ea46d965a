//! # gs-testdata
//!
//! Test support for the vagsl workspace, used only as a dev-dependency. Two jobs:
//!
//! - **The shared test data** (real photos such as dtu-scan24 and fox, synth-bunny's reference
//!   values, LPIPS/VGG reference weights): [`root`] is `$VAGSL_TEST_DATA`, or the `shared`
//!   folder beside the clone. A test asks for what it reads with [`needs!`]; where something is
//!   missing it prints one `SKIPPED: …` line to stderr and the test returns early, except under
//!   `CI=true`, where a missing data set fails the test ([`skip_or_fail()`], the rule the
//!   Chromium and wgpu-adapter checks follow too).
//! - **Schedulers** ([`sched`]): a Slurm cluster that takes jobs ([`slurm!`]) and the
//!   Kubernetes Job schema check ([`k8s_validator!`]), with the same SKIPPED / CI rule.
//! - **Generated scenes** ([`builtin`]): the built-in procedural scene of gs-synth written as a
//!   COLMAP scene folder with exact ground truth, cached under `target/`, for tests that need a
//!   scene on disk but no particular one.
//! - **Mesh comparison** ([`MeshShape`]): one surface made in different orders compares equal.
//!
//! In a test, `if !gs_testdata::needs!("data/fox") { return; }` fills in the test's name;
//! the function form:
//!
//! ```no_run
//! if gs_testdata::needs("scene_load::loads_fox", &["data/fox"]) {
//!     let fox = gs_testdata::root().join("data/fox");
//!     assert!(fox.join("sparse/0").is_dir());
//! }
//! ```

pub mod builtin;
pub mod mesh_shape;
pub mod sched;

pub use mesh_shape::MeshShape;
pub use sched::{K8sValidator, Slurm};

use std::io::Write;
use std::path::PathBuf;

/// The environment variable naming the shared test-data folder (the one holding `data/` and
/// `weights/`).
pub const ENV: &str = "VAGSL_TEST_DATA";

/// The repository root (this crate lives in `crates/gs-testdata`).
pub fn repo_root() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

/// The shared test-data folder: `$VAGSL_TEST_DATA` when set and not empty (a relative path is
/// taken from the repository root), else `shared` beside the clone (`<repo>/../shared`).
pub fn root() -> PathBuf {
    match std::env::var_os(ENV) {
        Some(v) if !v.is_empty() => repo_root().join(v),
        _ => repo_root().join("../shared"),
    }
}

/// Whether this is a CI run (`CI=true` or `CI=1`), where nothing may be skipped.
pub fn in_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true" || v == "1")
}

/// The name of the running test: the test target (`crate_name`) and libtest's thread name.
pub fn test_name(crate_name: &str) -> String {
    match std::thread::current().name() {
        Some(t) if t != "main" => format!("{crate_name}::{t}"),
        _ => crate_name.to_string(),
    }
}

/// Reports a check that cannot run here: under `CI=true` it panics with `why`; elsewhere it
/// prints `SKIPPED: <test>: <why> (<how>)` as one line on stderr. The line goes straight to
/// the process's stderr because libtest captures `eprintln!` of a passing test.
pub fn skip_or_fail(test: &str, why: &str, how: &str) {
    if in_ci() {
        panic!("{test}: CI=true, and nothing may be skipped there: {why} ({how})");
    }
    let _ = writeln!(std::io::stderr(), "SKIPPED: {test}: {why} ({how})");
}

/// Whether every path in `needs` (relative to [`root`], e.g. `data/fox` or
/// `weights/vgg16_imagenet_conv1_1-conv3_3.npz`) exists. Where one is missing this reports the
/// skip once for the test (see [`skip_or_fail()`]) and returns `false`. Use through [`needs!`],
/// which fills in the test's name.
pub fn needs(test: &str, needs: &[&str]) -> bool {
    let root = root();
    let mut missing: Vec<&str> = Vec::new();
    for &n in needs {
        if !root.join(n).exists() && !missing.contains(&n) {
            missing.push(n);
        }
    }
    if missing.is_empty() {
        return true;
    }
    let why = format!("needs {} (not in {})", missing.join(", "), root.display());
    skip_or_fail(test, &why, "set VAGSL_TEST_DATA=DIR holding data/ and weights/, or put the shared folder beside the clone");
    false
}

/// `needs!("data/fox", "data/synth-bunny")`: whether the shared test data holds each path,
/// printing the test's one SKIPPED line (or failing under `CI=true`) where not. See [`needs()`].
#[macro_export]
macro_rules! needs {
    ($($path:expr),+ $(,)?) => {
        $crate::needs(&$crate::test_name(env!("CARGO_CRATE_NAME")), &[$($path),+])
    };
}

/// `skip_or_fail!(why, how)`: [`skip_or_fail()`] with the running test's name.
#[macro_export]
macro_rules! skip_or_fail {
    ($why:expr, $how:expr $(,)?) => {
        $crate::skip_or_fail(&$crate::test_name(env!("CARGO_CRATE_NAME")), $why, $how)
    };
}

/// `wgpu_context!(&options)`: a `gs_gpu::GpuContext` on this machine's adapter (its name
/// printed), or `None` after the SKIPPED line (a failure under `CI=true`, where `.ci/run`
/// installs lavapipe). The calling test's crate depends on gs-gpu.
#[macro_export]
macro_rules! wgpu_context {
    ($options:expr) => {
        match gs_gpu::GpuContext::new($options) {
            Ok(c) => {
                eprintln!("wgpu adapter: {}", c.description());
                Some(c)
            }
            Err(e) => {
                $crate::skip_or_fail!(&format!("no wgpu adapter: {e}"), "install mesa-vulkan-drivers for lavapipe");
                None
            }
        }
    };
}

/// `slurm!()`: the Slurm cluster to submit to ([`sched::slurm`]) with the running test's name,
/// `None` after the SKIPPED line (a failure under `CI=true`).
#[macro_export]
macro_rules! slurm {
    () => {
        $crate::sched::slurm(&$crate::test_name(env!("CARGO_CRATE_NAME")))
    };
}

/// `k8s_validator!()`: the Kubernetes Job schema check ([`sched::k8s_validator`]) with the
/// running test's name, `None` after the SKIPPED line (a failure under `CI=true`).
#[macro_export]
macro_rules! k8s_validator {
    () => {
        $crate::sched::k8s_validator(&$crate::test_name(env!("CARGO_CRATE_NAME")))
    };
}

/// `n` Gaussians with every parameter drawn from N(0, 1) (scales around e⁻⁴, SH degree 3),
/// seeded: the input of the I/O and fingerprint benchmarks.
pub fn random_gaussians(n: usize) -> gs_core::Gaussians {
    let mut rng = gs_core::Rng::new(1);
    let mut g = gs_core::Gaussians::default();
    for _ in 0..n {
        let mut sh = [[0f32; 3]; gs_core::sh::SH_COEFFS];
        for c in sh.iter_mut() {
            *c = [rng.normal(), rng.normal(), rng.normal()];
        }
        g.push([rng.normal(); 3], [rng.normal() - 4.0; 3], [1.0, rng.normal(), 0.0, 0.0], rng.normal(), sh);
    }
    g.sh_degree = 3;
    g
}
