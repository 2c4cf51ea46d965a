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
    /// Score only the object inside each view's mask (`SCENE/masks/<stem>.png`, required for
    /// every scored view): PSNR over the mask's pixels, SSIM and LPIPS with render and photo
    /// on black outside it — the masked protocol of DTU novel-view benchmarks. Written to
    /// eval_images_masked.json.
    #[arg(long)]
    pub masked: bool,
    /// Score only the pixels whose surface some training view sees, judged from exact depth
    /// maps in DIR (one per view, named as for `vagsl mesh --depth-dir`, e.g. a synthetic
    /// scene's `gt/`): where no training view saw the surface, no reconstruction can know its
    /// colour. PSNR over those pixels, SSIM and LPIPS on black outside them; the share scored
    /// is printed. Written to eval_images_seen.json.
    #[arg(long, value_name = "DIR", conflicts_with = "masked")]
    pub seen_from: Option<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Rasterizer backend: cpu, wgpu, or auto (wgpu on a hardware GPU, else the CPU).
    #[arg(long, default_value = "auto")]
    pub backend: gs_raster::Backend,
}

/// Runs `vagsl eval-images`; writes RUN/eval_images.json.
pub fn run(args: &EvalImagesArgs) -> Result<()> {
    let pixels = if args.masked { "_masked" } else if args.seen_from.is_some() { "_seen" } else { "" };
    let file = format!("eval_images{}{pixels}.json", if args.train { "_train" } else { "" });
    // A link, device or folder in the scores' place is refused before the work; a read-only
    // run folder is not (the scores are printed first).
    gs_io::check_output_path(&args.run.join(&file))?;
    let run = OpenRun::open(&args.run, args.scene.as_deref())?;
    let lpips = if args.no_lpips { None } else { Some(gs_losses::Lpips::bundled()?) };
    let model = run.model();
    let views = if args.train { model.train } else { model.test };
    let mut rasterizer = super::rasterizer(args.backend)?;
    let seen = match &args.seen_from {
        Some(dir) => {
            let mut read = |v: &gs_core::View| Ok(gs_io::read_view_depth(dir, &v.name)?);
            Some(gs_train::seen_masks(&model, views, &mut read)?)
        }
        None => None,
    };
    let masks = match (&seen, args.masked) {
        (Some(m), _) => gs_train::PixelMasks::Seen(m),
        (None, true) => gs_train::PixelMasks::Object,
        (None, false) => gs_train::PixelMasks::None,
    };
    let metrics = gs_train::evaluate_images(&model, &mut rasterizer, views, lpips.as_ref(), masks)?;
    // Scores first: a read-only run folder must not cost the numbers just computed.
    if args.json {
        println!("{}", serde_json::to_string_pretty(&metrics)?);
    } else {
        for v in &metrics.views {
            println!(
                "{:<24} PSNR {:6.2}  SSIM {:.4}{}{}",
                v.name,
                v.psnr,
                v.ssim,
                v.lpips.map_or(String::new(), |l| format!("  LPIPS {l:.4}")),
                v.mask_fraction.map_or(String::new(), |f| format!("  ({:.1} % of the image)", 100.0 * f))
            );
            if let Some(veil) = &v.veil {
                println!("{:<24} {}", "", veil.describe());
            }
        }
        println!(
            "mean over {} views{}: PSNR {:.2} dB, SSIM {:.4}{}",
            metrics.views.len(),
            masks.describe(),
            metrics.psnr,
            metrics.ssim,
            metrics.lpips.map_or(String::new(), |l| format!(", LPIPS {l:.4}"))
        );
    }
    write_json(&run.dir.join(file), &gs_run::provenance::with_made_from(&metrics, &run.made_from)?)
        .map_err(|e| anyhow::Error::new(e).context("the scores above were computed but could not be saved"))
}
