//! `vagsl tradeoff`: the ablation ladder on a preset's schedule (only L_I ≈ 3DGS, then with
//! the edge term, L_nc and L_ns, L_p, and L_f where the schedule has an L_f phase; the last
//! rung is the preset itself) and the fast preset, each trained, meshed and scored, written as
//! a Markdown / JSON table and an SVG plot of mesh error against wall time.

use crate::commands::eval_mesh::read_mesh;
use gs_run::open_run::peak_memory_bytes;
use gs_run::run_config::{SceneSource, absolute_scene_path, load_scene};
use gs_run::{RunConfig, SceneFingerprint, write_json};
use anyhow::{Context, Result, bail};
use gs_core::TriangleMesh;
use gs_train::{LossSwitches, MeshOptions, Preset, TrainConfig, Trainer};
use gs_tsdf::{Aabb, EvalOptions, evaluate_meshes};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

/// Options of `vagsl tradeoff`.
#[derive(Debug, Clone, clap::Args)]
pub struct TradeoffArgs {
    /// Scene folder. Omit for the built-in scene (its exact object mesh is the default GT).
    pub scene: Option<PathBuf>,
    /// Rasterizer backend: cpu, wgpu, or auto (wgpu on a hardware GPU, else the CPU; unlike
    /// `train`'s, not chosen by timing a step, so that every rung runs on one backend).
    #[arg(long, default_value = "auto")]
    pub backend: gs_raster::Backend,
    /// Ground-truth mesh (PLY/OBJ) the meshes are scored against.
    #[arg(long)]
    pub gt: Option<PathBuf>,
    /// Output folder: one sub-folder per rung, tradeoff.{md,json,svg}.
    #[arg(short, long)]
    pub output: PathBuf,
    /// The schedule the ladder ablates: standard (the default, as `vagsl train`), fast, or the
    /// paper's dtu, tnt and mip360.
    #[arg(long, default_value = "standard")]
    pub preset: Preset,
    /// Iterations of the ladder's runs (default: the preset's own length; every phase
    /// boundary scales with it). The fast rung keeps the fast preset's own length.
    #[arg(long)]
    pub iterations: Option<u64>,
    /// Downscale images by this factor.
    #[arg(short = 'r', long = "resolution")]
    pub resolution: Option<u32>,
    /// Hold out every 8th view and report PSNR on them.
    #[arg(long)]
    pub eval: bool,
    /// Crop the prediction to the GT's bounding box grown by this fraction per side (object
    /// protocol: 0.05); `--min-z` also drops everything below that height (a floor).
    #[arg(long, default_value_t = 0.05)]
    pub crop_to_gt: f64,
    /// With the crop: drop everything below this z (synth-bunny and the built-in scene: 0.005).
    #[arg(long)]
    pub min_z: Option<f64>,
    /// Points sampled per mesh for the metrics.
    #[arg(long, default_value_t = 200_000)]
    pub samples: usize,
    /// Seed of every run.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Voxel size of the rungs' meshes (default: as `vagsl mesh`).
    #[arg(long)]
    pub voxel_size: Option<f64>,
    /// Refuse, before fusing, a rung's mesh whose estimated memory exceeds this (as `vagsl mesh
    /// --max-memory`: e.g. 8GiB, 500MB; default 60 % of the available memory, or of 4 GiB
    /// when /proc/meminfo is unreadable).
    #[arg(long, value_parser = gs_run::budget_check::bytes_arg)]
    pub max_memory: Option<u64>,
}

/// One rung of the ladder.
#[derive(Debug, Clone, Serialize)]
pub struct Rung {
    /// Name.
    pub name: String,
    /// Iterations.
    pub iterations: u64,
    /// Training wall time, seconds.
    pub train_seconds: f64,
    /// Mesh extraction wall time, seconds.
    pub mesh_seconds: f64,
    /// Final Gaussians.
    pub gaussians: usize,
    /// Mesh accuracy (pred → GT).
    pub accuracy: f64,
    /// Mesh completeness (GT → pred).
    pub completeness: f64,
    /// Chamfer.
    pub chamfer: f64,
    /// F1 at τ.
    pub f1: f64,
    /// Held-out PSNR (with --eval).
    pub psnr: Option<f64>,
}

/// The rungs: each loss term added in turn to `preset`'s schedule (an L_f rung only where the
/// schedule has an L_f phase, so no two rungs train the same thing), the last being the preset
/// itself; then the fast preset when the ladder is not already it.
fn ladder(preset: Preset, iterations: Option<u64>, seed: u64) -> Vec<(String, TrainConfig)> {
    let own = TrainConfig::preset(preset);
    let base = TrainConfig { seed, ..iterations.map_or_else(|| own.clone(), |n| own.scaled(n)) };
    let with = |losses: LossSwitches| TrainConfig { losses, ..base.clone() };
    let image_only = LossSwitches::image_only();
    let mut rungs = vec![
        ("only L_I (≈ 3DGS)".to_string(), with(image_only)),
        ("+ edge".to_string(), with(LossSwitches { edge: true, ..image_only })),
        ("+ L_nc, L_ns".to_string(), with(LossSwitches { normal_consistency: true, normal_smoothing: true, edge: true, ..image_only })),
    ];
    if base.has_feature_phase() {
        rungs.push(("+ L_p".to_string(), with(LossSwitches { features: false, ..base.losses })));
        rungs.push(("+ L_f (full VA-GS)".to_string(), base.clone()));
    } else {
        // Without an L_f phase the preset's own switches train exactly "+ L_p".
        rungs.push(("+ L_p".to_string(), base.clone()));
    }
    // The last ablation rung is the preset itself.
    if let Some((name, _)) = rungs.last_mut() {
        name.push_str(&format!(" = {preset}"));
    }
    if preset != Preset::Fast {
        rungs.push(("fast".to_string(), TrainConfig { seed, ..TrainConfig::preset(Preset::Fast) }));
    }
    rungs
}

fn slug(name: &str) -> String {
    name.chars().filter(|c| c.is_ascii_alphanumeric() || *c == ' ' || *c == '_').collect::<String>().split_whitespace().collect::<Vec<_>>().join("_").to_lowercase()
}

/// The SVG plot: Chamfer against training time, one labelled point per rung.
pub fn svg_plot(rungs: &[Rung]) -> String {
    let (w, h, m) = (640.0, 400.0, 60.0);
    let tmax = rungs.iter().map(|r| r.train_seconds).fold(1e-9, f64::max) * 1.1;
    let cmax = rungs.iter().map(|r| r.chamfer).fold(1e-12, f64::max) * 1.1;
    let x = |t: f64| m + t / tmax * (w - 2.0 * m);
    let y = |c: f64| h - m - c / cmax * (h - 2.0 * m);
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\" font-size=\"12\">\n\
         <rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n\
         <line x1=\"{m}\" y1=\"{b}\" x2=\"{r}\" y2=\"{b}\" stroke=\"black\"/>\n\
         <line x1=\"{m}\" y1=\"{m}\" x2=\"{m}\" y2=\"{b}\" stroke=\"black\"/>\n\
         <text x=\"{cx}\" y=\"{ty}\" text-anchor=\"middle\">training time (s), max {tmax:.0}</text>\n\
         <text x=\"14\" y=\"{cy}\" transform=\"rotate(-90 14 {cy})\" text-anchor=\"middle\">Chamfer (lower is better), max {cmax:.5}</text>\n",
        b = h - m,
        r = w - m,
        cx = w / 2.0,
        ty = h - 20.0,
        cy = h / 2.0
    );
    for r in rungs {
        let _ = writeln!(
            s,
            "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"4\" fill=\"#1f77b4\"/><text x=\"{:.1}\" y=\"{:.1}\">{}</text>",
            x(r.train_seconds),
            y(r.chamfer),
            x(r.train_seconds) + 6.0,
            y(r.chamfer) - 6.0,
            gs_report::escape_html(&r.name)
        );
    }
    s.push_str("</svg>\n");
    s
}

fn markdown(rungs: &[Rung]) -> String {
    let mut s = String::from(
        "| run | iterations | train s | mesh s | Gaussians | accuracy | completeness | Chamfer | F1 | PSNR |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rungs {
        let _ = writeln!(
            s,
            "| {} | {} | {:.0} | {:.1} | {} | {:.5} | {:.5} | {:.5} | {:.4} | {} |",
            r.name,
            r.iterations,
            r.train_seconds,
            r.mesh_seconds,
            r.gaussians,
            r.accuracy,
            r.completeness,
            r.chamfer,
            r.f1,
            r.psnr.map_or("–".into(), |p| format!("{p:.2}"))
        );
    }
    s
}

/// Runs `vagsl tradeoff`.
pub fn run(args: &TradeoffArgs) -> Result<()> {
    let source = SceneSource { path: args.scene.as_deref().map(absolute_scene_path), resolution_factor: args.resolution, width: None, eval: args.eval };
    let (gt, min_z): (TriangleMesh, Option<f64>) = match (&args.gt, &args.scene) {
        (Some(p), _) => (read_mesh(p)?, args.min_z),
        (None, None) => (gs_synth::generate(&gs_synth::BuiltinOptions::default())?.object_mesh, Some(args.min_z.unwrap_or(0.005))),
        (None, Some(_)) => bail!("--gt is required for a scene folder (the mesh the runs are scored against)"),
    };
    let scene = load_scene(&source)?;
    let (train, test) = scene.split(args.eval);
    std::fs::create_dir_all(&args.output).with_context(|| format!("{}: cannot create folder", args.output.display()))?;
    let b = Aabb::of_mesh(&gt).context("the ground-truth mesh has no vertices")?;
    let eval = EvalOptions { samples: args.samples, ..EvalOptions::for_gt(&b, Some(b.grown(args.crop_to_gt, min_z))) };
    let names = |idx: &[usize]| idx.iter().map(|&i| scene.views[i].name.clone()).collect::<Vec<_>>();
    let mut rungs = Vec::new();
    for (name, config) in ladder(args.preset, args.iterations, args.seed) {
        let name = name.as_str();
        let dir = args.output.join(slug(name));
        std::fs::create_dir_all(&dir).with_context(|| format!("{}: cannot create folder", dir.display()))?;
        eprintln!("[tradeoff] {name}: {} iterations", config.iterations);
        let t0 = Instant::now();
        let mut trainer = Trainer::new(&scene, train.clone(), config.clone())?;
        trainer.set_backend(args.backend)?;
        trainer.run(|_, _| true)?;
        let train_seconds = t0.elapsed().as_secs_f64();
        let t1 = Instant::now();
        // The same memory check as `vagsl mesh`: refused before any volume is allocated.
        let mesh_options =
            MeshOptions { voxel_size: args.voxel_size, max_memory: Some(gs_run::budget_check::limit(args.max_memory)), ..MeshOptions::default() };
        let (mesh, _) = trainer.extract_mesh(&mesh_options).with_context(|| format!("meshing the '{name}' run"))?;
        let mesh_seconds = t1.elapsed().as_secs_f64();
        let run_config = RunConfig {
            scene: source.clone(),
            fingerprint: Some(SceneFingerprint::of(&scene)),
            run_id: None,
            train_views: names(&train), test_views: names(&test), train: config.clone(),
        };
        write_json(&dir.join("config.json"), &run_config)?;
        gs_io::write_gaussian_ply(&dir.join("point_cloud.ply"), trainer.gaussians()?)?;
        gs_io::write_mesh_ply(&dir.join("mesh.ply"), &mesh)?;
        let m = evaluate_meshes(&mesh, &gt, &eval)?.metrics;
        let psnr = if test.is_empty() {
            None
        } else {
            Some(trainer.evaluate_images(&test, None)?.psnr)
        };
        let rung = Rung {
            name: name.to_string(),
            iterations: config.iterations,
            train_seconds,
            mesh_seconds,
            gaussians: trainer.gaussian_count(),
            accuracy: m.accuracy,
            completeness: m.completeness,
            chamfer: m.chamfer,
            f1: m.f1,
            psnr,
        };
        eprintln!("[tradeoff] {}", markdown(std::slice::from_ref(&rung)).lines().last().unwrap_or_default());
        rungs.push(rung);
        // Write after every rung so an interrupted ladder keeps what it measured.
        write_json(&args.output.join("tradeoff.json"), &serde_json::json!({
            "rungs": rungs, "tau": eval.tau, "samples": eval.samples, "peak_memory_bytes": peak_memory_bytes(),
        }))?;
        let md = markdown(&rungs);
        gs_io::write_atomic(&args.output.join("tradeoff.md"), |w| w.write_all(md.as_bytes()))?;
        let svg = svg_plot(&rungs);
        gs_io::write_atomic(&args.output.join("tradeoff.svg"), |w| w.write_all(svg.as_bytes()))?;
    }
    print!("{}", markdown(&rungs));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ladder_adds_one_term_per_rung() {
        // standard has no L_f phase: four ablation rungs, the last being standard itself, then fast.
        let l = ladder(Preset::Standard, None, 3);
        let names: Vec<&str> = l.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["only L_I (≈ 3DGS)", "+ edge", "+ L_nc, L_ns", "+ L_p = standard", "fast"]);
        assert_eq!(l[0].1.losses, LossSwitches::image_only());
        assert!(l[1].1.losses.edge && !l[1].1.losses.normal_consistency);
        assert!(l[2].1.losses.normal_smoothing && !l[2].1.losses.photometric);
        let standard = TrainConfig { seed: 3, ..TrainConfig::preset(Preset::Standard) };
        assert_eq!(l[3].1, standard);
        assert_eq!(l[4].1, TrainConfig { seed: 3, ..TrainConfig::preset(Preset::Fast) });
        assert!(l.iter().all(|(_, c)| c.seed == 3 && c.validate().is_ok()));
        assert!(l[..4].iter().all(|(_, c)| c.iterations == gs_train::config::STANDARD_ITERATIONS));
        // dtu's schedule has an L_f phase: a fifth rung, the preset itself, scaled to --iterations.
        let d = ladder(Preset::Dtu, Some(2000), 0);
        assert_eq!(d.len(), 6);
        assert_eq!(d[4].0, "+ L_f (full VA-GS) = dtu");
        assert_eq!(d[4].1, TrainConfig::preset(Preset::Dtu).scaled(2000));
        assert!(d[3].1.losses.photometric && !d[3].1.losses.features);
        // The fast ladder has no second fast rung.
        assert_eq!(ladder(Preset::Fast, None, 0).len(), 4);
        assert_eq!(slug("+ L_nc, L_ns"), "l_nc_l_ns");
        assert_eq!(slug("+ L_p = standard"), "l_p_standard");
        let rung = Rung {
            name: "a<b".into(),
            iterations: 1,
            train_seconds: 2.0,
            mesh_seconds: 0.1,
            gaussians: 5,
            accuracy: 0.1,
            completeness: 0.2,
            chamfer: 0.15,
            f1: 0.5,
            psnr: None,
        };
        let svg = svg_plot(std::slice::from_ref(&rung));
        assert!(svg.starts_with("<svg") && svg.contains("a&lt;b") && svg.trim_end().ends_with("</svg>"));
        assert!(markdown(&[rung]).contains("| a<b | 1 | 2 |"));
    }
}
