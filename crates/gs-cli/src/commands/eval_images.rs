//! `vagsl eval-images`: PSNR / SSIM / LPIPS of a run's held-out views (docs/method.md §Metrics).

use gs_run::{OpenRun, write_json};
use anyhow::Result;
use std::path::PathBuf;

/// Options of `vagsl eval-images`.
#[derive(Debug, Clone, clap::Args)]
pub struct EvalImagesArgs {
    /// A `vagsl train --eval` output folder.
    pub run: PathBuf,
    /// The run's scene folder, if it has moved since training (it must still be the scene the
    /// run was trained on).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Also score the training views (to see over-fitting).
    #[arg(long)]
    pub train: bool,
    /// Skip LPIPS (it costs about 1 s per 800×600 image on 2 cores).
    #[arg(long)]
    pub no_lpips: bool,
    /// Score only the object inside each view's mask (SCENE/masks/<stem>.png, required for
    /// every scored view): PSNR over the mask's pixels, SSIM and LPIPS with render and photo
    /// on black outside it — the masked protocol of DTU novel-view benchmarks. Written to
    /// eval_images_masked.json.
    #[arg(long)]
    pub masked: bool,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Rasterizer backend: cpu, wgpu, or auto (wgpu on a hardware GPU, else the CPU).
    #[arg(long, default_value = "auto")]
    pub backend: gs_raster::Backend,
}

/// Runs `vagsl eval-images`; writes RUN/eval_images.json.
pub fn run(args: &EvalImagesArgs) -> Result<()> {
    let file = format!("eval_images{}{}.json", if args.train { "_train" } else { "" }, if args.masked { "_masked" } else { "" });
    // A link, device or folder in the scores' place is refused before the work; a read-only
    // run folder is not (the scores are printed first).
    gs_io::check_output_path(&args.run.join(&file))?;
    let run = OpenRun::open(&args.run, args.scene.as_deref())?;
    let lpips = if args.no_lpips { None } else { Some(gs_losses::Lpips::bundled()?) };
    let model = run.model();
    let views = if args.train { model.train } else { model.test };
    let mut rasterizer = super::rasterizer(args.backend)?;
    let metrics = gs_train::evaluate_images(&model, &mut rasterizer, views, lpips.as_ref(), args.masked)?;
    // Scores first: a read-only run folder must not cost the numbers just computed.
    if args.json {
        println!("{}", serde_json::to_string_pretty(&metrics)?);
    } else {
        for v in &metrics.views {
            println!(
                "{:<24} PSNR {:6.2}  SSIM {:.4}{}",
                v.name,
                v.psnr,
                v.ssim,
                v.lpips.map_or(String::new(), |l| format!("  LPIPS {l:.4}"))
            );
            if let Some(veil) = &v.veil {
                println!("{:<24} {}", "", veil.describe());
            }
        }
        println!(
            "mean over {} views{}: PSNR {:.2} dB, SSIM {:.4}{}",
            metrics.views.len(),
            if args.masked { " (inside the masks)" } else { "" },
            metrics.psnr,
            metrics.ssim,
            metrics.lpips.map_or(String::new(), |l| format!(", LPIPS {l:.4}"))
        );
    }
    write_json(&run.dir.join(file), &gs_run::provenance::with_made_from(&metrics, &run.made_from)?)
        .map_err(|e| anyhow::Error::new(e).context("the scores above were computed but could not be saved"))
}
