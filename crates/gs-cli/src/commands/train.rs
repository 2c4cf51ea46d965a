//! `vagsl train`: the VA-GS training run, with progress, checkpoints and a report.

use gs_run::open_run::peak_memory_bytes;
use gs_run::run_config::{SceneSource, absolute_scene_path, load_scene, view_indices};
use gs_run::{MadeFrom, RunConfig, SceneFingerprint, write_json};
use anyhow::{Context, Result, bail};
use gs_train::{InitMode, Preset, ShPolicy, StepReport, TrainConfig, Trainer, checkpoint};
use gs_train::checkpoint::Elapsed;
use gs_train::config::SettingsFile;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Options of `vagsl train` (see `vagsl train --help`).
#[derive(Debug, Clone, clap::Args)]
pub struct TrainArgs {
    /// Scene folder: `images/` + `sparse/0` (COLMAP), or `transforms.json` (or
    /// `transforms_train.json` + `transforms_test.json`, whose test frames `--eval` holds out).
    /// Omit for the built-in scene.
    pub scene: Option<PathBuf>,
    /// Rasterizer backend: cpu, wgpu, or auto (on a hardware GPU, the faster of the two for
    /// this run, timed on one of its steps; else the CPU).
    #[arg(long, default_value = "auto")]
    pub backend: gs_raster::Backend,
    /// Output folder (created): config.json, point_cloud.ply, report.json, checkpoint.bin.
    /// A folder that already holds a run is refused unless --force or --resume.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Replace the run in the output folder: its config.json, point_cloud.ply, report.json,
    /// checkpoint.bin, exposure.json, mesh.ply, mesh.json, eval_images*.json and renders/ are
    /// removed when training starts (other files are left alone).
    #[arg(long, conflicts_with = "resume")]
    pub force: bool,
    /// Settings preset: standard (the default), fast, or the paper's dtu, tnt and mip360.
    #[arg(long)]
    pub preset: Option<Preset>,
    /// Settings from a file (.toml or .json): a partial configuration (keys as for --set,
    /// tables such as `[weights]` may be partial; `preset` picks the base), or a run's own
    /// OUT/config.json, which reproduces that run (its scene too, unless SCENE, -r, --width or
    /// --eval are given). Precedence: preset, then --iterations, then this file, then the
    /// flags below, then --set.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Any setting by key, e.g. `--set weights.lambda_p=0.2 --set densify.grad_threshold=3e-4`
    /// (keys as in OUT/config.json's "train" table; repeatable; applied last).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Total iterations; every phase boundary of the preset scales with it.
    #[arg(long)]
    pub iterations: Option<u64>,
    /// Downscale images by this factor (1, 2, 4, 8).
    #[arg(short = 'r', long = "resolution")]
    pub resolution: Option<u32>,
    /// Scale images to this width instead.
    #[arg(long)]
    pub width: Option<u32>,
    /// Hold out every 8th image (sorted by name) for evaluation.
    #[arg(long)]
    pub eval: bool,
    /// Seed of every random choice (default 0).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Ablation: no edge term in L_I.
    #[arg(long)]
    pub no_edge: bool,
    /// Ablation: no normal consistency L_nc.
    #[arg(long)]
    pub no_nc: bool,
    /// Ablation: no normal smoothing L_ns.
    #[arg(long)]
    pub no_ns: bool,
    /// Ablation: no multi-view photometric alignment L_p.
    #[arg(long)]
    pub no_photometric: bool,
    /// Ablation: no multi-view feature alignment L_f.
    #[arg(long)]
    pub no_features: bool,
    /// Ablation: edge weight δ ≡ 1 in L_nc and L_ns.
    #[arg(long)]
    pub no_delta: bool,
    /// Per-view exposure compensation: learn an affine colour correction per training photo
    /// (for photos whose exposure or white balance varies); written to OUT/exposure.json.
    #[arg(long)]
    pub exposure: bool,
    /// Source views N per iteration for L_p and L_f.
    #[arg(long)]
    pub source_views: Option<usize>,
    /// NCC patch side (odd, 3–9).
    #[arg(long)]
    pub patch_size: Option<usize>,
    /// Grey images of L_p at this multiple (1–4) of the training resolution (PGSR's
    /// ncc_scale = 1/S): finer NCC texture at the same render cost; needs originals that large.
    #[arg(long)]
    pub ncc_scale: Option<u32>,
    /// τ of L_ns.
    #[arg(long)]
    pub tau: Option<f32>,
    /// L_ns gate: `above` (default, "> τ") or `below` ("< τ").
    #[arg(long)]
    pub ns_gate: Option<gs_losses::NsGate>,
    /// NCC cost: `pgsr` (1 − ρ², masked, default) or `plain` (1 − ρ).
    #[arg(long)]
    pub ncc: Option<gs_mvs::NccMode>,
    /// Keep L_p on during the L_f phase.
    #[arg(long)]
    pub overlap_mv: bool,
    /// Initialisation: `points` (SfM, default), `cube` or `sphere` (random).
    #[arg(long)]
    pub init: Option<InitMode>,
    /// Hard cap on the number of Gaussians.
    #[arg(long)]
    pub max_gaussians: Option<usize>,
    /// Highest SH degree (0–3; default 3).
    #[arg(long)]
    pub sh_degree: Option<u32>,
    /// When the SH degree rises: `schedule` (default, the paper: one band per 1,000 scaled
    /// iterations) or `adaptive` (at each rise the newest band must lower the training views'
    /// L1 by --sh-min-gain, else it is dropped and the degree stays).
    #[arg(long)]
    pub sh_policy: Option<ShPolicy>,
    /// Relative L1 drop a band must give under `--sh-policy adaptive` (default 0.01).
    #[arg(long)]
    pub sh_min_gain: Option<f32>,
    /// Write OUT/checkpoint.bin every this many iterations.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    pub checkpoint_every: Option<u64>,
    /// Refuse, before training, a run whose estimated peak memory exceeds this (e.g. 8GiB,
    /// 500MB; default 60 % of the available memory, or of 4 GiB when /proc/meminfo is
    /// unreadable), as `vagsl mesh --max-memory`.
    #[arg(long, value_parser = gs_run::budget_check::bytes_arg)]
    pub max_memory: Option<u64>,
    /// Continue from a checkpoint: its settings, and the scene of its run's config.json (in
    /// the output folder, else beside the checkpoint), are used; training options are refused
    /// and scene options must match the run's.
    #[arg(long)]
    pub resume: Option<PathBuf>,
    /// The Chamfer-against-time curve (`--track-gt`, …).
    #[command(flatten)]
    pub track: TrackArgs,
    /// No progress bar (log a line every 500 iterations instead; also the default when stderr
    /// is not a terminal, e.g. redirected to a log file).
    #[arg(long)]
    pub quiet: bool,
}

/// A configuration file's settings as JSON: a run's `config.json` gives its "train" table and
/// scene, anything else is a partial configuration.
fn read_config_file(path: &Path) -> Result<(SettingsFile, Option<RunConfig>)> {
    let bytes = gs_io::read_capped(path, gs_io::SETTINGS_CAP, "a settings file")?;
    let file = gs_train::config::parse_settings_file(&bytes, path)?;
    let run = match &file.run {
        Some(doc) => Some(serde_json::from_value(doc.clone()).with_context(|| format!("{}: not a vagsl run configuration", path.display()))?),
        None => None,
    };
    Ok((file, run))
}

/// The effective configuration of `args` (and the run configuration of a `--config` file that
/// is a run's own `config.json`). Precedence: preset → `--iterations` → file → flags → `--set`.
pub fn build_config(args: &TrainArgs) -> Result<(TrainConfig, Option<RunConfig>)> {
    let (file, run) = match &args.config {
        Some(p) => {
            let (f, run) = read_config_file(p)?;
            (Some((f, p)), run)
        }
        None => (None, None),
    };
    let file_preset = match &file {
        Some((f, p)) => f.preset(p)?,
        None => None,
    };
    let preset = match (args.preset, file_preset) {
        (Some(a), Some(b)) if a != b => bail!(
            "--preset {a} contradicts {}, whose preset is {b}: the run would be labelled with one and use the other's values; give one of them",
            args.config.as_deref().unwrap_or(Path::new("")).display()
        ),
        (Some(p), _) | (None, Some(p)) => p,
        (None, None) => Preset::default(),
    };
    let mut c = TrainConfig::preset(preset);
    if let Some(n) = args.iterations {
        if n == 0 {
            bail!("--iterations must be positive");
        }
        c = c.scaled(n);
    }
    if let Some((f, p)) = &file {
        c = c.with_overlay(&f.settings).with_context(|| format!("{}", p.display()))?;
    }
    for (_, key, value) in setting_flags(args) {
        c = c.with_setting(key, value)?;
    }
    for a in &args.set {
        c = c.with_assignment(a).context("--set")?;
    }
    c.validate()?;
    Ok((c, run))
}

/// The setting flags given on the command line, as (flag, configuration key, value): one
/// table that `build_config` applies and `--resume` refuses (`resume.rs`), so a new flag
/// cannot be applied on a fresh run and silently dropped on a resumed one.
pub fn setting_flags(args: &TrainArgs) -> Vec<(&'static str, &'static str, serde_json::Value)> {
    let off = |flag: bool| flag.then_some(serde_json::Value::from(false));
    let on = |flag: bool| flag.then_some(serde_json::Value::from(true));
    let flags: [(&str, &str, Option<serde_json::Value>); 20] = [
        ("--no-edge", "losses.edge", off(args.no_edge)),
        ("--no-nc", "losses.normal_consistency", off(args.no_nc)),
        ("--no-ns", "losses.normal_smoothing", off(args.no_ns)),
        ("--no-photometric", "losses.photometric", off(args.no_photometric)),
        ("--no-features", "losses.features", off(args.no_features)),
        ("--no-delta", "losses.delta", off(args.no_delta)),
        ("--exposure", "exposure", on(args.exposure)),
        ("--overlap-mv", "overlap_mv", on(args.overlap_mv)),
        ("--seed", "seed", args.seed.map(Into::into)),
        ("--source-views", "source_views", args.source_views.map(Into::into)),
        ("--ncc-scale", "ncc_scale", args.ncc_scale.map(Into::into)),
        ("--patch-size", "patch_size", args.patch_size.map(Into::into)),
        ("--tau", "weights.tau", args.tau.map(Into::into)),
        ("--ns-gate", "ns_gate", args.ns_gate.map(|g| g.to_string().into())),
        ("--ncc", "ncc", args.ncc.map(|n| n.to_string().into())),
        ("--init", "init", args.init.map(|i| i.to_string().into())),
        ("--max-gaussians", "max_gaussians", args.max_gaussians.map(Into::into)),
        ("--sh-degree", "sh_degree_max", args.sh_degree.map(Into::into)),
        ("--sh-policy", "sh_policy", args.sh_policy.map(|p| p.to_string().into())),
        ("--sh-min-gain", "sh_min_gain", args.sh_min_gain.map(Into::into)),
    ];
    flags.into_iter().filter_map(|(flag, key, value)| value.map(|v| (flag, key, v))).collect()
}

/// `OUT/report.json`.
#[derive(Debug, Serialize)]
pub struct TrainReport {
    /// The run this model belongs to (the `run_id` of config.json) and the fingerprint of
    /// the model this report describes (`gs_run::model_fingerprint`), as the one provenance
    /// record of every derived file: the report is written before point_cloud.ply, so a model
    /// that is not this one is noticed (see `gs_run::OpenRun::open`).
    #[serde(flatten)]
    pub made_from: MadeFrom,
    /// Iterations completed.
    pub iterations: u64,
    /// Whether the run was stopped (Ctrl-C, SIGTERM, SIGHUP) before the last iteration.
    pub interrupted: bool,
    /// Final number of Gaussians.
    pub gaussians: usize,
    /// Whether the Gaussian cap stopped densification.
    pub capped: bool,
    /// Wall seconds of the training loop over the whole run, earlier segments of a resumed run
    /// included (when the checkpoint carries them, format version 3 on).
    pub train_seconds: f64,
    /// Seconds per phase over the whole run: warm-up, photometric (L_p), features (L_f), refinement.
    pub phase_seconds: [f64; 4],
    /// Wall seconds of this process's training loop (equals `train_seconds` without a resume).
    pub segment_seconds: f64,
    /// The iteration this process resumed from, if it did.
    pub resumed_from: Option<u64>,
    /// False when resumed from a checkpoint older than format version 3, which does not carry
    /// the earlier segments' time: `train_seconds` then counts from the resume only.
    pub earlier_time_known: bool,
    /// Peak resident memory, bytes.
    pub peak_memory_bytes: Option<u64>,
    /// Bytes of the per-view caches (guides, grey images, features, reused source depths).
    pub cache_bytes: usize,
    /// SH degree the model ended with.
    pub sh_degree: u32,
    /// The adaptive SH policy's band judgements of this run (empty on the schedule).
    pub sh_bands: Vec<gs_train::ShBandDecision>,
    /// The scene's Gaussian budget (training pixels, views per surface point, B).
    pub budget: gs_train::Budget,
    /// Final Gaussians per training pixel.
    pub gaussians_per_training_pixel: f64,
    /// Why the model stopped growing, in words.
    pub growth_stopped: String,
    /// Free-space floaters removed over this process's run (see gs_train::floaters).
    pub floaters_removed: usize,
    /// Where this process's training time went: milliseconds per iteration by part, per phase
    /// (gs_train::profile).
    pub time_by_part: gs_train::StepProfile,
    /// Where the loss terms ran, in words (gs_train::devices).
    pub loss_terms_on: String,
    /// Where each part of an iteration ran (render and backward, each loss term, Adam,
    /// density control).
    pub parts_on: Vec<gs_train::PartPlace>,
    /// How `--backend auto` chose (the step it timed on each backend), absent for a named
    /// backend.
    pub backend_choice: Option<gs_train::BackendChoice>,
    /// Loss values of the last iteration.
    pub last: Option<StepReport>,
}

pub(super) fn describe(r: &StepReport) -> String {
    let l = &r.losses;
    let mut s = format!("L {:.4} L1 {:.4}", l.total, l.l1);
    for (name, v) in [("nc", l.normal_consistency), ("ns", l.normal_smoothing), ("Lp", l.photometric), ("Lf", l.features), ("Lo", l.opacity_entropy), ("Ls", l.flatness)] {
        if let Some(v) = v {
            s.push_str(&format!(" {name} {v:.4}"));
        }
    }
    s.push_str(&format!(" | {} Gaussians", r.gaussians));
    s
}

/// Where a run starts: its configuration, a checkpointed state (with `--resume`), the time
/// spent before, the run it continues or reproduces, the scene source and the run id.
struct Start {
    config: TrainConfig,
    resumed: Option<gs_train::TrainState>,
    earlier: Option<Elapsed>,
    base: Option<BaseRun>,
    source: SceneSource,
    run_id: String,
}

/// The run whose `config.json` a start builds on: the run a `--resume` continues, or the run a
/// `--config OUT/config.json` reproduces.
struct BaseRun {
    run: RunConfig,
    file: PathBuf,
    resuming: bool,
}

/// Reads `--resume` or builds the configuration, and picks the scene source (a run's own
/// config.json brings its scene unless the command line names one; a resumed run keeps its
/// scene and its run id).
fn start(args: &TrainArgs) -> Result<Start> {
    let (config, resumed, earlier, base) = match &args.resume {
        Some(p) => {
            let ck = checkpoint::load(p)?;
            let options = gs_run::resume::SceneOptions {
                output: &args.output,
                scene: args.scene.as_deref(),
                resolution: args.resolution,
                width: args.width,
                eval: args.eval,
            };
            let base = Some(gs_run::resume::run_of_checkpoint(&options, &given_training_options(args), p, &ck.config)?);
            eprintln!("resuming {} at iteration {} (its configuration is used)", p.display(), ck.state.iteration);
            if ck.elapsed.is_none() {
                eprintln!("note: this checkpoint predates format 3 and does not carry the earlier training time; report.json counts from the resume");
            }
            (ck.config, Some(ck.state), ck.elapsed, base.map(|(run, file)| BaseRun { run, file, resuming: true }))
        }
        None => {
            let (config, run) = build_config(args)?;
            let base = run.map(|run| BaseRun { run, file: args.config.clone().expect("a run configuration comes from --config"), resuming: false });
            (config, None, Some(Elapsed::default()), base)
        }
    };
    let cli_scene = args.scene.is_some() || args.resolution.is_some() || args.width.is_some() || args.eval;
    let source = match &base {
        Some(b) if b.resuming || !cli_scene => b.run.scene.clone(),
        _ => SceneSource { path: args.scene.as_deref().map(absolute_scene_path), resolution_factor: args.resolution, width: args.width, eval: args.eval },
    };
    let run_id = match &base {
        Some(BaseRun { run: RunConfig { run_id: Some(id), .. }, resuming: true, .. }) => id.clone(),
        _ => gs_run::new_run_id(&config),
    };
    Ok(Start { config, resumed, earlier, base, source, run_id })
}

/// Refuses a scene that is not the one of the run a start builds on: another scene at its
/// path (by fingerprint), or other training views.
fn check_base_scene(base: &BaseRun, source: &SceneSource, scene: &gs_core::Scene, train_views: &[String]) -> Result<()> {
    let remedy = if base.resuming {
        "a resumed run needs its own scene; restore it, or start a new run without --resume"
    } else {
        "give that scene as SCENE"
    };
    if base.run.scene == *source {
        base.run.check_scene(scene, &format!("the run of {}", base.file.display()), remedy)?;
    }
    if base.run.train_views != train_views {
        bail!(
            "{}: the run trained on {} views, this scene gives {} other training views; {}",
            base.file.display(),
            base.run.train_views.len(),
            train_views.len(),
            if base.resuming { remedy } else { "pass the run's SCENE, -r/--width and --eval (or none of them)" }
        );
    }
    Ok(())
}

/// Runs `vagsl train`.
pub fn run(args: &TrainArgs) -> Result<()> {
    let out = &args.output;
    gs_run::run_folder::check(out, args.force, args.resume.is_some())?;
    let Start { config, resumed, earlier, base, source, run_id } = start(args)?;
    let resumed_from = resumed.as_ref().map(|s| s.iteration);
    let t_load = Instant::now();
    let scene = load_scene(&source)?;
    let (train_idx, test_idx) = scene.split(source.eval);
    let names = |idx: &[usize]| idx.iter().map(|&i| scene.views[i].name.clone()).collect::<Vec<_>>();
    let run_config = RunConfig {
        scene: source.clone(),
        fingerprint: Some(SceneFingerprint::of(&scene)),
        run_id: Some(run_id.clone()),
        train_views: names(&train_idx),
        test_views: names(&test_idx),
        train: config.clone(),
    };
    if let Some(b) = &base {
        check_base_scene(b, &source, &scene, &run_config.train_views)?;
    }
    view_indices(&scene, &run_config.train_views)?;
    eprintln!(
        "scene: {} views ({} train, {} test), {} points, loaded in {:.1}s",
        scene.views.len(),
        train_idx.len(),
        test_idx.len(),
        scene.points.len(),
        t_load.elapsed().as_secs_f64()
    );
    eprintln!("config: {}", config.summary());
    let mut trainer = match resumed {
        Some(state) => Trainer::with_state(&scene, train_idx.clone(), config.clone(), state)?,
        None => Trainer::new(&scene, train_idx.clone(), config.clone())?,
    };
    if config.ncc_scale > 1 {
        trainer.set_grey_images(gs_run::run_config::high_resolution_greys(&source, &scene, &train_idx, config.ncc_scale)?)?;
        eprintln!("L_p grey images at {}x the training resolution", config.ncc_scale);
    }
    let backend_choice = match args.backend {
        gs_raster::Backend::Auto => {
            let choice = trainer.choose_backend(false)?;
            eprintln!("rasterizer: {} (--backend auto)", choice.in_words());
            Some(choice)
        }
        named => {
            trainer.set_rasterizer(super::rasterizer(named)?)?;
            None
        }
    };
    eprintln!("loss terms: {}", trainer.loss_executors());
    eprintln!("{}", gs_run::budget_check::check_train(&trainer, args.max_memory)?);
    let mesh_track = load_mesh_track(&args.track, gs_run::budget_check::limit(args.max_memory))?;
    // Everything that can refuse the run has run: only now is the folder touched.
    let mut folder = gs_run::run_folder::prepare(out, args.force, args.resume.is_some())?;
    if let Some(note) = &folder.resume_note {
        eprintln!("{note}");
    }
    let work = folder.work.clone();
    write_json(&work.join("config.json"), &run_config)?;
    eprintln!("initial Gaussians: {}, scene extent r = {:.4}", trainer.gaussian_count(), trainer.extent());
    let b = *trainer.budget();
    if b.active {
        eprintln!("Gaussian budget: {}", b.describe(config.densify.gaussians_per_surface_pixel));
    }

    let mut elapsed = earlier.unwrap_or_default();
    let mut curves = gs_run::metrics_log::MetricsLog::open(&work, resumed_from, config.iterations, !test_idx.is_empty(), mesh_track)?;
    let t0 = Instant::now();
    let super::train_loop::Looped { last, sh_bands, growth, floaters_removed, signal } =
        super::train_loop::train_loop((args, &work), &config, &mut trainer, &mut elapsed, (&mut curves, &test_idx))?;
    let ckpt_path = out.join("checkpoint.bin");
    let segment_seconds = t0.elapsed().as_secs_f64();
    let train_seconds = elapsed.total();
    let interrupted = !trainer.finished();
    if interrupted || args.checkpoint_every.is_some() {
        trainer.save_checkpoint(&work.join("checkpoint.bin"), &elapsed)?;
        eprintln!("checkpoint written to {} (resume with --resume)", ckpt_path.display());
    }
    let made_from = MadeFrom::new(Some(run_id), trainer.gaussians()?);
    let report = TrainReport {
        made_from,
        iterations: trainer.iteration(),
        interrupted,
        gaussians: trainer.gaussian_count(),
        capped: trainer.capped(),
        train_seconds,
        phase_seconds: elapsed.phase_seconds,
        segment_seconds,
        resumed_from,
        earlier_time_known: earlier.is_some(),
        peak_memory_bytes: peak_memory_bytes(),
        cache_bytes: trainer.cache_bytes(),
        sh_degree: trainer.sh_degree(),
        sh_bands,
        budget: b,
        gaussians_per_training_pixel: trainer.gaussian_count() as f64 / b.training_pixels.max(1) as f64,
        growth_stopped: growth_stopped(growth, &b, trainer.gaussian_count()),
        floaters_removed,
        time_by_part: trainer.profile().clone(),
        loss_terms_on: trainer.loss_executors(),
        parts_on: trainer.parts_on(),
        backend_choice,
        last,
    };
    // The report first, then the model it describes: a run stopped between the two leaves a
    // folder whose model is missing or older than its report, which `OpenRun::open` names.
    write_json(&work.join("report.json"), &report)?;
    gs_io::write_gaussian_ply(&work.join("point_cloud.ply"), trainer.gaussians()?)?;
    write_exposure(&work, &run_config, &mut trainer)?;
    drop(curves);
    if let Some(note) = folder.commit()? {
        eprintln!("{note}");
    }
    warn_degenerate(&report, &config);
    let done_here = report.iterations - resumed_from.unwrap_or(0);
    println!(
        "trained {} iterations in {:.1}s ({:.1} it/s{}): {} Gaussians, peak memory {}; wrote point_cloud.ply, report.json and metrics.jsonl to {}",
        report.iterations,
        train_seconds,
        done_here as f64 / segment_seconds.max(1e-9),
        match resumed_from {
            Some(from) => format!(" over the {done_here} since the resume at {from}, which took {segment_seconds:.1}s"),
            None => String::new(),
        },
        report.gaussians,
        report.peak_memory_bytes.map_or("n/a".into(), |b| format!("{:.0} MiB", b as f64 / (1 << 20) as f64)),
        out.display()
    );
    for line in report.time_by_part.describe() {
        eprintln!("time: {line}");
    }
    if interrupted {
        let message = format!("interrupted at iteration {}; checkpoint in {}", report.iterations, ckpt_path.display());
        return Err(crate::signals::Stopped { signal: signal.unwrap_or(signal_hook::consts::SIGINT), message }.into());
    }
    println!("next: `vagsl mesh {o}` for the mesh, then `vagsl view {o}` for the report page", o = out.display());
    Ok(())
}

/// A loud warning for a model that ended nearly empty (e.g. `densify.min_opacity = 0.999`
/// pruning thousands of Gaussians to one): it renders little or nothing and meshes to nothing.
fn warn_degenerate(report: &TrainReport, config: &TrainConfig) {
    let floor = (report.budget.gaussians / 100).clamp(1, 100);
    if report.gaussians < floor && report.gaussians * 10 < report.budget.initial {
        eprintln!(
            "warning: the model ended with only {} Gaussian{} of the {} it started with (the scene's budget is {}): almost everything was pruned, so renders and the mesh will be nearly empty; check densify.min_opacity ({}), the learning rates and the schedule",
            report.gaussians,
            if report.gaussians == 1 { "" } else { "s" },
            report.budget.initial,
            report.budget.gaussians,
            config.densify.min_opacity
        );
    }
}

/// `OUT/exposure.json`: each training photo's learned gain and bias (with `--exposure`).
fn write_exposure(out: &Path, run_config: &RunConfig, trainer: &mut Trainer) -> Result<()> {
    if let Some(e) = trainer.exposure() {
        let per_view: serde_json::Map<String, serde_json::Value> = run_config
            .train_views
            .iter()
            .zip(&e.params)
            .map(|(name, p)| {
                let gain: Vec<f32> = p[..3].iter().map(|a| a.exp()).collect();
                (name.clone(), serde_json::json!({ "gain_rgb": gain, "bias_rgb": &p[3..] }))
            })
            .collect();
        write_json(&out.join("exposure.json"), &per_view)?;
    }
    Ok(())
}

/// Why the model stopped growing, from the last densification step of this process.
fn growth_stopped(last: Option<(u64, gs_train::GrowthLimit)>, b: &gs_train::Budget, n: usize) -> String {
    match last {
        None => "no densification step ran in this process".into(),
        Some((it, limit)) => format!(
            "the last densification step (iteration {it}) was bounded by {}; {n} Gaussians for a budget of {}{}",
            limit.describe(),
            b.gaussians,
            if b.active { "" } else { " (no budget: ρ = 0)" }
        ),
    }
}

/// The training options of `args` that were given: on a resume the checkpoint's settings are
/// used, so any of these would be ignored (gs_run::resume refuses them).
fn given_training_options(a: &TrainArgs) -> Vec<&'static str> {
    let schedule = [
        (a.preset.is_some(), "--preset"),
        (a.config.is_some(), "--config"),
        (!a.set.is_empty(), "--set"),
        (a.iterations.is_some(), "--iterations"),
    ];
    let schedule = schedule.into_iter().filter(|(g, _)| *g).map(|(_, name)| name);
    schedule.chain(setting_flags(a).into_iter().map(|(flag, _, _)| flag)).collect()
}

/// `vagsl train`'s options of the mesh curve (gs_run::metrics_log).
#[derive(Debug, Clone, clap::Args)]
pub struct TrackArgs {
    /// Ground-truth mesh (PLY or OBJ): at each held-out scoring point (10 per run and the
    /// last iteration) mesh the model and log its Chamfer / F1 against this mesh in
    /// OUT/metrics.jsonl (not counted as training time).
    #[arg(long)]
    pub track_gt: Option<PathBuf>,
    /// With --track-gt: crop the mesh to the GT's bounding box grown by this fraction per side
    /// (as `eval-mesh --crop-to-gt`; the object protocol uses 0.05).
    #[arg(long, requires = "track_gt")]
    pub track_crop_to_gt: Option<f64>,
    /// With --track-crop-to-gt: also drop everything below this z (as `eval-mesh --min-z`).
    #[arg(long, requires = "track_crop_to_gt")]
    pub track_min_z: Option<f64>,
}

/// The mesh curve of `--track-gt` (None without it), fused under `max_memory` bytes.
fn load_mesh_track(args: &TrackArgs, max_memory: u64) -> Result<Option<gs_run::metrics_log::MeshTrack>> {
    let Some(path) = &args.track_gt else { return Ok(None) };
    let gt = super::eval_mesh::read_mesh(path)?;
    Ok(Some(gs_run::metrics_log::MeshTrack::new(path, gt, args.track_crop_to_gt, args.track_min_z, max_memory)?))
}
