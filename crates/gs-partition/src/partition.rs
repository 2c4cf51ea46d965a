//! `vagsl partition` as a library call (docs/architecture.md §Partitioned training): the
//! capture's ground frame, a grid of blocks balanced by training pixels, each block's views and
//! points, its scene folder, and its training memory estimate — exactly the estimate `train`
//! checks, from the block's scene as `train` will load it. With a memory limit per job the
//! number of blocks grows until every block fits.

use crate::assign::{Members, assign};
use crate::block_folder::write_block;
use crate::capture::Capture;
use crate::error::{Context, Result, refuse};
use crate::ground::GroundFrame;
use crate::plan::{Block, PLAN_VERSION, Plan};
use crate::regions::{Rect, Region, core_regions, grid_shape};
use gs_run::{SceneFingerprint, SceneSource};
use gs_train::{GrowthRegion, TrainConfig};
use std::path::{Path, PathBuf};

/// How many blocks to make.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BlockCount {
    /// Exactly this many.
    Exactly(usize),
    /// As few as keep every block's training memory estimate at or under this many bytes.
    MemoryPerJob(u64),
}

/// The most blocks a partition makes.
pub const MAX_BLOCKS: usize = 1024;

/// A block needs at least this many views to train (and for L_p to find neighbours).
pub const MIN_BLOCK_VIEWS: usize = 3;

/// The training configuration of `vagsl train` arguments (the plan's, or a block's from
/// [`block_train_args`]), as `vagsl train` builds it; an error in words.
pub type ConfigOf<'a> = &'a dyn Fn(&[String]) -> std::result::Result<TrainConfig, String>;

/// Options of a partition.
pub struct PartitionOptions<'a> {
    /// How many blocks.
    pub count: BlockCount,
    /// Fraction of a core's size it grows by on each bounded side (VastGaussian: 0.2).
    pub margin: f64,
    /// Fraction of a view's sparse points that must lie in a block's grown region for the view
    /// to join the block.
    pub visibility: f64,
    /// The arguments of every block's `vagsl train` (recorded in the plan; `--iterations` and
    /// the growth region are set per block, see [`block_train_args`]).
    pub train_args: Vec<String>,
    /// Each block grows Gaussians only in its grown region and budgets only that region's
    /// surface (`densify.region`, docs/architecture.md §Partitioned training); `false`: a block
    /// grows wherever its views look, to a budget of all they see.
    pub grow_in_region: bool,
    /// Each block trains for its share of the whole run's iterations (its views over the
    /// scene's training views, so every view is visited as often as in one run of the whole
    /// scene); `false`: every block trains the whole run's iterations.
    pub share_iterations: bool,
    /// The training configuration of the arguments (for the memory estimates and the checks
    /// of the merge).
    pub config_of: ConfigOf<'a>,
}

/// `train_args` with `--iterations` set to `iterations` (any `--iterations N` or
/// `--iterations=N` given is replaced) and, with a `region`, `--set densify.region=JSON`:
/// what block runs are started with.
pub fn block_train_args(train_args: &[String], iterations: u64, region: Option<&GrowthRegion>) -> Vec<String> {
    let mut out = Vec::with_capacity(train_args.len() + 2);
    let mut skip = false;
    for a in train_args {
        if skip {
            skip = false;
        } else if a == "--iterations" {
            skip = true;
        } else if !a.starts_with("--iterations=") {
            out.push(a.clone());
        }
    }
    out.extend(["--iterations".to_string(), iterations.to_string()]);
    if let Some(r) = region {
        let json = serde_json::to_string(r).expect("a region of finite numbers serialises");
        out.extend(["--set".to_string(), format!("{REGION_KEY}={json}")]);
    }
    out
}

/// The setting that carries a block's growth region; the plan's, never the user's.
pub const REGION_KEY: &str = "densify.region";

impl PartitionOptions<'_> {
    /// Refuses absurd values, in words.
    pub fn validate(&self) -> Result<()> {
        match self.count {
            BlockCount::Exactly(n) if n == 0 || n > MAX_BLOCKS => refuse!("--blocks {n}: give 1 to {MAX_BLOCKS} blocks"),
            BlockCount::MemoryPerJob(0) => refuse!("--max-memory-per-job must be above 0 bytes"),
            _ => {}
        }
        if !(self.margin.is_finite() && (0.0..=1.0).contains(&self.margin)) {
            refuse!("--margin {}: give a fraction of a block's size from 0 to 1 (0.2 grows each side by a fifth)", self.margin);
        }
        if self.train_args.iter().any(|a| a.contains(REGION_KEY)) {
            refuse!("`{REGION_KEY}` in the training options: the plan sets each block's growth region");
        }
        if !(self.visibility.is_finite() && self.visibility > 0.0 && self.visibility <= 1.0) {
            refuse!("--visibility {}: give a fraction above 0 and at most 1 of the points a view sees", self.visibility);
        }
        Ok(())
    }
}

/// Partitions the scene of `source` into the new plan folder `out` (written under a temporary
/// name beside it and renamed at the end: an error leaves nothing). `note` receives progress
/// lines for people.
pub fn partition(source: &SceneSource, out: &Path, opts: &PartitionOptions, note: &mut dyn FnMut(String)) -> Result<Plan> {
    opts.validate()?;
    if out.exists() {
        refuse!("{}: already exists; give a new folder for the plan", out.display());
    }
    let capture = Capture::read(source)?;
    if capture.train.len() < MIN_BLOCK_VIEWS {
        refuse!("{}: {} training views; a partition needs at least {MIN_BLOCK_VIEWS}", capture.dir.display(), capture.train.len());
    }
    let train_cams: Vec<gs_core::Camera> = capture.train.iter().map(|&i| capture.cameras[i].clone()).collect();
    let frame = GroundFrame::of(&train_cams, &capture.points)?;
    let whole = (opts.config_of)(&opts.train_args).map_err(crate::PartitionError::Refused)?;
    let mut blocks = match opts.count {
        BlockCount::Exactly(n) => n,
        BlockCount::MemoryPerJob(_) => 1,
    };
    let staging = staging_path(out)?;
    let result = (|| loop {
        if staging.exists() {
            std::fs::remove_dir_all(&staging).with_context(|| format!("{}: cannot remove the earlier attempt", staging.display()))?;
        }
        let plan = build(&capture, (&frame, &train_cams), source, (blocks, &whole), opts, &staging, note)?;
        let worst = plan.blocks.iter().map(|b| b.memory_bytes).max().unwrap_or(0);
        match opts.count {
            BlockCount::MemoryPerJob(limit) if worst > limit => {
                if blocks >= MAX_BLOCKS {
                    refuse!(
                        "{MAX_BLOCKS} blocks still need up to {} of memory each, more than --max-memory-per-job {}; allow more memory per job, or train at a lower resolution (-r)",
                        gs_tsdf::format_bytes(worst),
                        gs_tsdf::format_bytes(limit)
                    );
                }
                let next = (blocks + 1).max((blocks as f64 * worst as f64 / limit as f64).ceil() as usize).min(MAX_BLOCKS);
                note(format!(
                    "{blocks} blocks need up to {} each, over the {} per job: trying {next}",
                    gs_tsdf::format_bytes(worst),
                    gs_tsdf::format_bytes(limit)
                ));
                blocks = next;
            }
            _ => return Ok(plan),
        }
    })();
    let plan = match result {
        Ok(plan) => plan,
        Err(e) => {
            let _ = std::fs::remove_dir_all(&staging);
            return Err(e);
        }
    };
    std::fs::rename(&staging, out).with_context(|| format!("{}: cannot move the plan in place from {}", out.display(), staging.display()))?;
    Ok(plan)
}

/// `.NAME.partial-PID` beside `out`.
fn staging_path(out: &Path) -> Result<PathBuf> {
    let Some(name) = out.file_name() else { refuse!("{}: not a folder name", out.display()) };
    Ok(out.with_file_name(format!(".{}.partial-{}", name.to_string_lossy(), std::process::id())))
}

/// The cores, grown regions, growth regions and members of `n` blocks (`train_cams`: the
/// cameras of `capture.train`).
fn layout(
    capture: &Capture,
    (frame, train_cams): (&GroundFrame, &[gs_core::Camera]),
    n: usize,
    opts: &PartitionOptions,
) -> Result<(Vec<Region>, Vec<Rect>, Vec<GrowthRegion>, Vec<Members>)> {
    let cams: Vec<([f64; 2], f64)> =
        capture.train.iter().map(|&i| (frame.coords(capture.cameras[i].center()), capture.pixels(i))).collect();
    let cam_box = Rect::around(cams.iter().map(|c| c.0)).expect("a partition has training views");
    let extent = Rect::around(cams.iter().map(|c| c.0).chain(capture.points.iter().map(|p| frame.coords(*p)))).unwrap_or(cam_box);
    let (nu, nv) = grid_shape(n, cam_box.size());
    let cores = core_regions(&cams, nu, nv);
    if cores.len() < n {
        refuse!(
            "{}: the camera centres allow only {} distinct blocks, not {n} (too many cameras at the same places); ask for fewer blocks",
            capture.dir.display(),
            cores.len()
        );
    }
    let grown: Vec<Rect> = cores.iter().map(|c| c.grown(opts.margin, &extent)).collect();
    let growth = cores.iter().zip(&grown).map(|(c, g)| growth_region(frame, c, g, &extent)).collect();
    let members = assign(frame, &grown, train_cams, &capture.points, opts.visibility)
        .into_iter()
        .map(|m| Members { views: m.views.iter().map(|&k| capture.train[k]).collect(), points: m.points })
        .collect();
    Ok((cores, grown, growth, members))
}

/// Where a block grows: its grown region, with the sides its core leaves open pushed one
/// capture extent further out (a Gaussian that drifts past the outermost point still grows).
fn growth_region(frame: &GroundFrame, core: &Region, grown: &Rect, extent: &Rect) -> GrowthRegion {
    let size = extent.size();
    let (mut min, mut max) = (grown.min, grown.max);
    for (a, [lo, hi]) in [core.u, core.v].into_iter().enumerate() {
        if lo.is_none() {
            min[a] -= size[a].max(1.0);
        }
        if hi.is_none() {
            max[a] += size[a].max(1.0);
        }
    }
    GrowthRegion { origin: frame.origin, u: frame.u, v: frame.v, min, max }
}

/// Writes `n` blocks into `dir` and returns their plan (`whole`: the settings of the plan's
/// arguments for the whole scene).
fn build(
    capture: &Capture,
    (frame, train_cams): (&GroundFrame, &[gs_core::Camera]),
    source: &SceneSource,
    (n, whole): (usize, &TrainConfig),
    opts: &PartitionOptions,
    dir: &Path,
    note: &mut dyn FnMut(String),
) -> Result<Plan> {
    let (cores, grown, growth, members) = layout(capture, (frame, train_cams), n, opts)?;
    let mut blocks = Vec::with_capacity(n);
    for (index, (((core, grown), growth), m)) in cores.into_iter().zip(grown).zip(growth).zip(&members).enumerate() {
        let name = format!("{index:02}");
        if m.views.len() < MIN_BLOCK_VIEWS {
            refuse!(
                "block {name} ({}) gets {} views; a block needs at least {MIN_BLOCK_VIEWS}: ask for fewer blocks, or a larger --margin",
                core.describe(),
                m.views.len()
            );
        }
        let (scene, run) = (PathBuf::from("blocks").join(&name), PathBuf::from("runs").join(&name));
        write_block(capture, m, &dir.join(&scene))?;
        let iterations = if opts.share_iterations {
            ((whole.iterations as f64 * m.views.len() as f64 / capture.train.len() as f64).round() as u64).clamp(1, whole.iterations)
        } else {
            whole.iterations
        };
        let region = opts.grow_in_region.then_some(growth);
        let args = block_train_args(&opts.train_args, iterations, region.as_ref());
        let train = (opts.config_of)(&args).map_err(|e| crate::PartitionError::Refused(format!("block {name}: {e}")))?;
        let (fingerprint, largest_view_pixels, (memory_bytes, memory)) =
            estimate(&dir.join(&scene), source, &train).with_context(|| format!("block {name}: estimating its training memory"))?;
        note(format!(
            "block {name}: {} views, {} points, {iterations} iterations, {} ({})",
            m.views.len(),
            m.points.len(),
            gs_tsdf::format_bytes(memory_bytes),
            core.describe()
        ));
        let views = m.views.iter().map(|&v| capture.name(v).to_string()).collect();
        let points = m.points.len();
        blocks.push(Block { index, scene, run, core, grown, views, points, fingerprint, largest_view_pixels, memory_bytes, memory, train });
    }
    std::fs::create_dir_all(dir.join("runs")).with_context(|| format!("{}: cannot create the runs folder", dir.display()))?;
    let plan = Plan {
        version: PLAN_VERSION,
        scene: source.clone(),
        held_out: capture.held_out.clone(),
        frame: *frame,
        margin: opts.margin,
        visibility: opts.visibility,
        train_args: opts.train_args.clone(),
        train: whole.clone(),
        blocks,
    };
    plan.write(dir)?;
    Ok(plan)
}

/// The fingerprint, the largest view's pixels and the training memory estimate (bytes and in
/// words) of the block scene in `dir`, loaded as its `train` will load it (the plan's
/// `-r`/`--width`, every view training).
fn estimate(dir: &Path, source: &SceneSource, config: &TrainConfig) -> Result<(SceneFingerprint, u64, (u64, String))> {
    let src = SceneSource { path: Some(dir.to_path_buf()), resolution_factor: source.resolution_factor, width: source.width, eval: false };
    let scene = gs_run::run_config::load_scene(&src)?;
    let all: Vec<usize> = (0..scene.views.len()).collect();
    let trainer = gs_train::Trainer::new(&scene, all, config.clone())?;
    let e = trainer.memory_estimate();
    let largest = scene.views.iter().map(|v| v.camera.width as u64 * v.camera.height as u64).max().unwrap_or(0);
    Ok((SceneFingerprint::of(&scene), largest, (e.peak_bytes(), e.describe())))
}
