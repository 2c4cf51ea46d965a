//! `vagsl partition` and `vagsl merge`: training a scene too large for one machine as blocks
//! (gs-partition does the work; this parses and prints). docs/architecture.md §Partitioned training.

use anyhow::{Context, Result, bail};
use clap::Parser;
use gs_partition::runners::{self, RunnerOptions};
use gs_partition::{BlockCount, PartitionOptions};
use gs_run::run_config::{SceneSource, absolute_scene_path};
use std::path::{Path, PathBuf};

/// Options of `vagsl partition`.
#[derive(Debug, Clone, clap::Args)]
pub struct PartitionArgs {
    /// Scene folder (COLMAP or transforms.json).
    pub scene: PathBuf,
    /// The plan folder to create: plan.json, blocks/NN (scene folders linking the photos),
    /// runs/NN (where the blocks train), run-block.sh, slurm.sbatch, k8s-job.yaml.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Number of blocks.
    #[arg(long, required_unless_present = "max_memory_per_job", conflicts_with = "max_memory_per_job")]
    pub blocks: Option<usize>,
    /// Make as few blocks as keep each block's training memory estimate within this (e.g. 16GiB).
    #[arg(long, value_parser = gs_run::budget_check::bytes_arg)]
    pub max_memory_per_job: Option<u64>,
    /// Each block's region grows by this fraction of its size on every side it shares with
    /// another block: the overlap its views and points come from.
    #[arg(long, default_value_t = 0.2)]
    pub margin: f64,
    /// A view joins a block when this fraction of the sparse points it sees lie in the block's
    /// grown region (or when it was taken from inside that region).
    #[arg(long, default_value_t = 0.25)]
    pub visibility: f64,
    /// Downscale images by this factor (1, 2, 4, 8) in every block.
    #[arg(short = 'r', long = "resolution")]
    pub resolution: Option<u32>,
    /// Scale images to this width in every block.
    #[arg(long)]
    pub width: Option<u32>,
    /// Hold out every 8th view of the whole scene (sorted by name) from every block, to score
    /// the merged run on.
    #[arg(long)]
    pub eval: bool,
    /// CPU cores per block job (Slurm --cpus-per-task, Kubernetes cpu request).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub cpus_per_job: u32,
    /// Time limit per block job in minutes (default: an upper bound from the iterations and
    /// image size, at least 30).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=100_000))]
    pub minutes_per_job: Option<u64>,
    /// Every block trains the whole run's iterations, instead of its share (its views over the
    /// scene's training views, which visits every view as often as one run of the whole scene).
    #[arg(long)]
    pub full_iterations: bool,
    /// Every block grows Gaussians wherever its views look, to a budget of all they see,
    /// instead of only in its grown region to that region's share (Gaussians outside a block's
    /// core are dropped at the merge).
    #[arg(long)]
    pub grow_everywhere: bool,
    /// Container image of the Kubernetes job (it must provide bash and vagsl).
    #[arg(long, default_value = "vagsl")]
    pub image: String,
    /// `vagsl train` options every block trains with, after `--` (e.g. `-- --preset fast
    /// --iterations 7000`). The scene, -o, -r, --width, --eval, --resume, --force,
    /// --checkpoint-every, --config and --exposure are the plan's own.
    #[arg(last = true)]
    pub train_args: Vec<String>,
}

/// Options of `vagsl merge`.
#[derive(Debug, Clone, clap::Args)]
pub struct MergeArgs {
    /// The plan folder of `vagsl partition`, its blocks trained.
    pub plan: PathBuf,
    /// Output folder of the merged run (created; a folder holding a run needs --force).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Replace the run in the output folder (once the merged run is written).
    #[arg(long)]
    pub force: bool,
}

/// `vagsl train`'s own parser, to read the blocks' training options exactly as `train` will.
#[derive(Debug, Parser)]
#[command(name = "vagsl train")]
struct TrainOptions {
    #[command(flatten)]
    args: super::train::TrainArgs,
}

/// Options that belong to the plan, not to each block's training.
const PLAN_OWNED: &[&str] =
    &["-o", "--output", "-r", "--resolution", "--width", "--eval", "--resume", "--force", "--checkpoint-every", "--config", "--exposure"];

/// The training configuration of the blocks' `train` options.
fn block_config(train_args: &[String]) -> Result<gs_train::TrainConfig> {
    if let Some(a) = train_args.iter().find(|a| PLAN_OWNED.iter().any(|o| a.as_str() == *o || a.starts_with(&format!("{o}=")))) {
        bail!("`{a}` after `--`: the plan sets it for every block (give -r, --width and --eval to partition itself; --exposure and --config are not supported for blocks)");
    }
    let argv = ["vagsl train", "-o", "unused"].into_iter().map(String::from).chain(train_args.iter().cloned());
    let parsed = TrainOptions::try_parse_from(argv).map_err(|e| anyhow::anyhow!("the training options after `--`: {}", e.to_string().trim()))?;
    if let Some(s) = &parsed.args.scene {
        bail!("`{}` after `--`: the blocks' scenes are the plan's; give the scene before `--`", s.display());
    }
    Ok(super::train::build_config(&parsed.args)?.0)
}

/// Runs `vagsl partition`.
pub fn run_partition(args: &PartitionArgs) -> Result<()> {
    // The training options are refused before the scene is read.
    block_config(&args.train_args)?;
    let config_of = |given: &[String]| block_config(given).map_err(|e| format!("{e:#}"));
    let source = SceneSource { path: Some(absolute_scene_path(&args.scene)), resolution_factor: args.resolution, width: args.width, eval: args.eval };
    let count = match (args.blocks, args.max_memory_per_job) {
        (Some(n), _) => BlockCount::Exactly(n),
        (None, Some(m)) => BlockCount::MemoryPerJob(m),
        (None, None) => bail!("give --blocks N or --max-memory-per-job SIZE"),
    };
    let opts = PartitionOptions {
        count,
        margin: args.margin,
        visibility: args.visibility,
        train_args: args.train_args.clone(),
        share_iterations: !args.full_iterations,
        grow_in_region: !args.grow_everywhere,
        config_of: &config_of,
    };
    let t0 = std::time::Instant::now();
    let plan = gs_partition::partition(&source, &args.output, &opts, &mut |line| eprintln!("{line}"))?;
    let dir = absolute_scene_path(&args.output);
    let runner = RunnerOptions {
        vagsl: std::env::current_exe().context("cannot find the vagsl binary's path for the job scripts")?.display().to_string(),
        plan_dir: dir.display().to_string(),
        cpus: args.cpus_per_job,
        memory_bytes: runners::job_memory(&plan),
        time_seconds: args.minutes_per_job.map_or_else(|| runners::time_limit(&plan, args.cpus_per_job), |m| m * 60),
        image: args.image.clone(),
        data_root: common_root(&dir, source.path.as_deref().unwrap_or(&dir)).display().to_string(),
    };
    runners::write_runners(&dir, &plan, &runner)?;
    let held = if plan.held_out.is_empty() { String::new() } else { format!(", {} views held out for the merged run", plan.held_out.len()) };
    println!("{}: {} blocks in {:.1}s{held}", dir.display(), plan.blocks.len(), t0.elapsed().as_secs_f64());
    println!(
        "each job: {} core(s), {} of memory (the largest block's estimate plus a quarter), {} min",
        runner.cpus,
        gs_tsdf::format_bytes(runner.memory_bytes),
        runner.time_seconds.div_ceil(60)
    );
    println!("train the blocks with any runner, then merge:");
    println!("  sbatch --wait {}/{}", dir.display(), runners::SLURM_SCRIPT);
    println!("  kubectl apply -f {}/{}", dir.display(), runners::K8S_MANIFEST);
    println!("  for i in $(seq 0 {}); do bash {}/{} $i; done", plan.blocks.len() - 1, dir.display(), runners::BLOCK_SCRIPT);
    println!("  vagsl merge {} -o MERGED && vagsl mesh MERGED", dir.display());
    Ok(())
}

/// The deepest folder holding both `a` and `b`.
fn common_root(a: &Path, b: &Path) -> PathBuf {
    let mut root = PathBuf::new();
    for (x, y) in a.components().zip(b.components()) {
        if x != y {
            break;
        }
        root.push(x);
    }
    if root.as_os_str().is_empty() { PathBuf::from("/") } else { root }
}

/// Runs `vagsl merge`.
pub fn run_merge(args: &MergeArgs) -> Result<()> {
    let merged = gs_partition::merge(&args.plan, &mut |line| eprintln!("{line}"))?;
    let replaced = gs_partition::write_merged(&args.output, &merged, args.force)?;
    if let Some(r) = replaced {
        eprintln!("{r}");
    }
    let r = &merged.report;
    println!(
        "{}: {} Gaussians from {} blocks ({:.0} s of training in all, {:.0} s for the longest block; merged in {:.1} s)",
        args.output.display(),
        r.gaussians,
        r.blocks.len(),
        r.train_seconds,
        r.longest_block_seconds,
        r.merge_seconds
    );
    if let Some(m) = r.peak_memory_bytes {
        println!("largest peak memory of a block: {}", gs_tsdf::format_bytes(m));
    }
    println!("next: vagsl mesh {0}; vagsl eval-images {0}; vagsl view {0}", args.output.display());
    Ok(())
}
