//! `vagsl view`: the report page of a run, `RUN/report.html` (gs-report), and with `--serve` a
//! local web server for it.

use gs_run::OpenRun;
use anyhow::{Context, Result};
use gs_raster::RenderRequest;
use gs_report::{PageData, ReportWriter, ViewScores};
use std::path::{Path, PathBuf};

/// Options of `vagsl view`.
#[derive(Debug, Clone, clap::Args)]
pub struct ViewArgs {
    /// A `vagsl train` output folder.
    pub run: PathBuf,
    /// The run's scene folder, if it has moved since training.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Rasterizer backend for the view renders: cpu, wgpu, or auto.
    #[arg(long, default_value = "auto")]
    pub backend: gs_raster::Backend,
    /// Skip LPIPS in the per-view scores (about 1 s per 800×600 view on 2 cores).
    #[arg(long)]
    pub no_lpips: bool,
    /// Serve the page on 127.0.0.1 and print its address (until Ctrl-C).
    #[arg(long)]
    pub serve: bool,
    /// Port of `--serve` (0: any free port).
    #[arg(long, default_value_t = 8765)]
    pub port: u16,
}

/// Runs `vagsl view`.
pub fn run(args: &ViewArgs) -> Result<()> {
    gs_run::run_folder::check_output_file(&args.run.join("report.html"), "the report page", &[args.run.join("report.html")])?;
    let folder = args.run.join("report");
    if std::fs::symlink_metadata(&folder).is_ok_and(|m| !m.is_dir()) {
        anyhow::bail!("{}: is a link or a file, not the report's folder, and the report would replace it; move it away", folder.display());
    }
    let run = OpenRun::open(&args.run, args.scene.as_deref())?;
    // The mesh and its scores shown must come from this model.
    let remake = format!("vagsl mesh {}", run.dir.display());
    gs_run::provenance::check(&run.dir.join("mesh.ply"), &run.dir.join("mesh.json"), &run.made_from, &remake)?;
    gs_run::provenance::check(&run.dir.join("eval_mesh.json"), &run.dir.join("eval_mesh.json"), &run.made_from, "vagsl eval-mesh --pred RUN/mesh.ply --gt GT")?;
    let model = run.model();
    let lpips = if args.no_lpips { None } else { Some(gs_losses::Lpips::bundled()?) };
    let mut rasterizer = super::rasterizer(args.backend)?;
    let req = RenderRequest { color: true, normal: true, plane_depth: true, ..Default::default() };
    let splats = gs_report::SplatData::from_gaussians(model.gaussians, model.raster)?;
    let mut writer = ReportWriter::new(&run.dir)?;
    let mut test_psnr = Vec::new();
    let splits = [("test", model.test), ("train", model.train)];
    for (split, views) in splits {
        for &i in views {
            let view = &run.scene.views[i];
            let out = model.render(&mut rasterizer, i, &req)?;
            let mut color = out.color.expect("requested");
            color.data_mut().iter_mut().for_each(|v| *v = v.clamp(0.0, 1.0));
            let m = gs_train::score_view(view, &color, lpips.as_ref(), None)?;
            let veil = gs_train::find_veil(&model, &mut rasterizer, i, None)?;
            if split == "test" {
                test_psnr.push(m.psnr);
            }
            let normal = super::render::world_normal_png(&view.camera, out.normal.as_ref().expect("requested"))?;
            let scores = ViewScores { psnr: m.psnr, ssim: m.ssim, lpips: m.lpips, note: veil.map(|v| v.describe()) };
            let depth = out.plane_depth.as_ref().expect("requested");
            writer.add_view(&view.name, split, &view.camera, &view.image, &color, &normal, depth, Some(scores))?;
        }
    }
    let mesh_path = run.dir.join("mesh.ply");
    let mesh = match mesh_path.exists() {
        true => Some(gs_report::MeshData::from_mesh(&gs_io::read_mesh_ply(&mesh_path)?)?),
        false => None,
    };
    let has_mesh = mesh.is_some();
    let page = PageData {
        title: String::new(),
        facts: facts(&run, &test_psnr, mesh.as_ref()),
        splats,
        mesh,
        background: model.raster.background,
        curves: read_curves(&run.dir.join("metrics.jsonl"))?,
        mesh_metrics: read_json_if_present(&run.dir.join("eval_mesh.json"))?,
        tradeoff_svg: tradeoff_svg(&run.dir),
    };
    let path = writer.finish(page)?;
    gs_run::provenance::write_report_page_record(&run.dir, &run.made_from)?;
    println!(
        "wrote {} ({} views, {} Gaussians{}); open it in a browser{}",
        path.display(),
        model.train.len() + model.test.len(),
        model.gaussians.len(),
        if has_mesh { ", the mesh" } else { "" },
        if args.serve { "" } else { ", or serve it with `vagsl view RUN --serve`" }
    );
    if args.serve {
        crate::serve::serve(&run.dir, args.port)?;
    }
    Ok(())
}

/// The run's facts for the top of the page, in words and units.
fn facts(run: &OpenRun, test_psnr: &[f64], mesh: Option<&gs_report::MeshData>) -> Vec<(String, String)> {
    let model = run.model();
    let report = read_json_if_present(&run.dir.join("report.json")).ok().flatten().unwrap_or_default();
    let cam = &run.scene.views[model.train[0]].camera;
    let mut f = vec![(
        "Views".to_string(),
        format!("{} training, {} held-out, {} × {} px", model.train.len(), model.test.len(), cam.width, cam.height),
    )];
    let num = |k: &str| report.get(k).and_then(|v| v.as_f64());
    if let (Some(it), Some(s)) = (num("iterations"), num("train_seconds")) {
        f.push(("Training".into(), format!("{it} iterations in {s:.1} s")));
    }
    let budget = report.pointer("/budget/gaussians").and_then(|v| v.as_u64());
    f.push((
        "Gaussians".into(),
        format!("{}{}", model.gaussians.len(), budget.map_or(String::new(), |b| format!(" (budget {b})"))),
    ));
    if let Some(b) = num("peak_memory_bytes") {
        f.push(("Peak memory in training".into(), format!("{:.0} MiB", b / (1u64 << 20) as f64)));
    }
    if !test_psnr.is_empty() {
        f.push(("Held-out PSNR".into(), format!("{:.2} dB (mean of {} views)", test_psnr.iter().sum::<f64>() / test_psnr.len() as f64, test_psnr.len())));
    }
    if let Some(m) = mesh {
        f.push(("Mesh".into(), format!("{} triangles (mesh.ply)", m.source_triangles)));
    }
    f.push(("Model".into(), run.made_from.describe()));
    f
}

/// `metrics.jsonl`, one JSON object per line; a line cut short by a kill is skipped with a
/// warning naming it.
fn read_curves(path: &Path) -> Result<Vec<serde_json::Value>> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(e).with_context(|| format!("{}: cannot read the training curves", path.display())),
    };
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        match serde_json::from_str(line) {
            Ok(v) => out.push(v),
            Err(e) => eprintln!("warning: {}:{}: skipped a line that is not JSON ({e})", path.display(), n + 1),
        }
    }
    Ok(out)
}

fn read_json_if_present(path: &Path) -> Result<Option<serde_json::Value>> {
    match std::fs::read_to_string(path) {
        Ok(t) => Ok(Some(serde_json::from_str(&t).with_context(|| format!("{}: not valid JSON", path.display()))?)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(e).with_context(|| format!("{}: cannot read", path.display())),
    }
}

/// The tradeoff plot of the run's folder, or of the `vagsl tradeoff` output it is a rung of.
fn tradeoff_svg(run: &Path) -> Option<String> {
    [run.join("tradeoff.svg"), run.join("..").join("tradeoff.svg")].iter().find_map(|p| std::fs::read_to_string(p).ok())
}
