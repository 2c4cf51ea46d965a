//! The training loop of `vagsl train`: progress, notices, periodic checkpoints and the stop
//! signals, around [`Trainer::run`].

use super::train::{TrainArgs, describe};
use anyhow::{Context, Result};
use gs_train::checkpoint::Elapsed;
use gs_train::{StepReport, TrainConfig, Trainer};
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::Path;
use std::time::Instant;

/// What the training loop hands back for the report.
pub struct Looped {
    pub last: Option<StepReport>,
    pub sh_bands: Vec<gs_train::ShBandDecision>,
    /// The iteration and the limit of the last densification step.
    pub growth: Option<(u64, gs_train::GrowthLimit)>,
    /// Floaters removed.
    pub floaters_removed: usize,
    /// The signal that stopped the loop early.
    pub signal: Option<i32>,
}

/// The training loop with progress (a bar on a terminal, else a line every 500 iterations),
/// notices, periodic checkpoints and Ctrl-C / SIGTERM / SIGHUP (stop after the current
/// iteration, [`crate::signals`]). `elapsed`
/// gains this segment's time per phase.
pub fn train_loop(
    (args, work): (&TrainArgs, &Path),
    config: &TrainConfig,
    trainer: &mut Trainer,
    elapsed: &mut Elapsed,
    (curves, test): (&mut gs_run::metrics_log::MetricsLog, &[usize]),
) -> Result<Looped> {
    let stop = crate::signals::StopRequest::install().context("installing the Ctrl-C / SIGTERM / SIGHUP handlers")?;
    // Without a terminal indicatif draws nothing, so a redirected run logs lines instead.
    let log_lines = args.quiet || !std::io::stderr().is_terminal();
    let bar = if log_lines {
        ProgressBar::hidden()
    } else {
        let b = ProgressBar::new(config.iterations);
        b.set_style(
            ProgressStyle::with_template("{bar:30} {pos}/{len} {per_sec} ETA {eta} {msg}")
                .expect("valid template"),
        );
        b.set_position(trainer.iteration());
        b
    };
    let ckpt_path = work.join("checkpoint.bin");
    let mut last: Option<StepReport> = None;
    let mut checkpoint_error: Option<anyhow::Error> = None;
    let mut curve_error: Option<anyhow::Error> = None;
    let mut warned_cap = false;
    let mut sh_bands = Vec::new();
    let mut growth = None;
    let mut floaters_removed = 0;
    let t0 = Instant::now();
    let mut t_prev = Instant::now();
    trainer.run(|tr, r| {
        let now = Instant::now();
        elapsed.add(config, r.iteration, (now - t_prev).as_secs_f64());
        t_prev = now;
        // The held-out scoring of the curves is not training time.
        match curves.record(tr, r, elapsed.total(), test, r.iteration == config.iterations) {
            Ok(scoring) => t_prev += scoring,
            Err(e) => {
                curve_error = Some(anyhow::Error::new(e));
                return false;
            }
        }
        if r.iteration % 10 == 0 || r.iteration == config.iterations {
            bar.set_position(r.iteration);
            bar.set_message(describe(r));
        }
        if log_lines && (r.iteration % 500 == 0 || r.iteration == config.iterations) {
            eprintln!("[{:>6}/{}] {} ({:.1}s)", r.iteration, config.iterations, describe(r), t0.elapsed().as_secs_f64());
        }
        // A hidden bar (log-line mode) prints nothing, so notices go to stderr directly there.
        let notice = |m: String| if log_lines { eprintln!("{m}") } else { bar.println(m) };
        if let Some(b) = r.sh_band {
            sh_bands.push(b);
            notice(format!(
                "[{:>6}] SH band {}: L1 {:.5} → {:.5} ({:+.2} %), {}; degree {}",
                r.iteration,
                b.band,
                b.l1_without,
                b.l1_with,
                -100.0 * b.gain,
                if b.kept { "pays" } else { "does not pay, dropped" },
                b.degree
            ));
        }
        if let Some(d) = r.densify {
            growth = Some((r.iteration, d.limit));
        }
        if let Some(f) = r.floaters
            && f.removed() > 0
        {
            floaters_removed += f.removed();
            notice(format!("[{:>6}] {}", r.iteration, f.describe()));
        }
        if r.densify.is_some_and(|d| d.capped) && !warned_cap {
            warned_cap = true;
            notice(format!("warning: reached --max-gaussians {}; densification stops", config.max_gaussians));
        }
        if let Some(every) = args.checkpoint_every
            && every > 0
            && r.iteration % every == 0
            && r.iteration < config.iterations
            && let Err(e) = tr.save_checkpoint(&ckpt_path, elapsed)
        {
            checkpoint_error = Some(e.into());
            return false;
        }
        last = Some(r.clone());
        stop.signal().is_none()
    })?;
    bar.finish_and_clear();
    if let Some(e) = curve_error {
        return Err(e);
    }
    if let Some(e) = checkpoint_error {
        return Err(e.context(format!("writing {}", ckpt_path.display())));
    }
    Ok(Looped { last, sh_bands, growth, floaters_removed, signal: stop.signal() })
}
