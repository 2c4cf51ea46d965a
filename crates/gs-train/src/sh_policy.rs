//! The SH degree of each iteration (docs/method.md §Parameters): the paper's schedule, or under
//! [`ShPolicy::Adaptive`] only while the newest band pays on the training views. Free functions
//! over the parts of the training state they change; the trainer calls them once per step.

use crate::config::{ShPolicy, TrainConfig};
use crate::error::Result;
use crate::params::Param;
use gs_core::{Adam, Gaussians, Scene};
use gs_raster::{RasterConfig, RenderRequest, Rasterizer};
use serde::Serialize;

/// Training views rendered to judge an SH band (evenly spread over the training set).
const SH_JUDGE_VIEWS: usize = 8;

/// The adaptive SH policy's judgement of band `band` at a scheduled rise.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ShBandDecision {
    /// The band judged (= the degree before the rise).
    pub band: u32,
    /// Mean L1 of the judged training views at degree `band − 1`.
    pub l1_without: f64,
    /// The same at degree `band`.
    pub l1_with: f64,
    /// Relative drop (l1_without − l1_with) / l1_without.
    pub gain: f64,
    /// Whether the band paid (and the degree rose to band + 1); otherwise it was dropped.
    pub kept: bool,
    /// The degree used from this iteration on.
    pub degree: u32,
}

/// What [`update_sh_degree`] does at one iteration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ShMove {
    /// The degree stays.
    Stay,
    /// The degree becomes this one.
    Set(u32),
    /// A scheduled rise past band `band`: judge whether that band pays.
    Judge(u32),
}

/// The move from degree `current` at iteration `it`.
fn sh_move(cfg: &TrainConfig, current: u32, it: u64) -> ShMove {
    let scheduled = cfg.sh_degree(it);
    let adaptive = cfg.sh_policy == ShPolicy::Adaptive && cfg.sh_degree_interval > 0 && it > 1;
    if !adaptive || scheduled <= current {
        return if scheduled == current { ShMove::Stay } else { ShMove::Set(scheduled) };
    }
    if scheduled > current + 1 || current == 0 {
        // Behind the schedule: an earlier band did not pay, the degree stays. Degree 0 → 1:
        // band 1 is always tried.
        return if current == 0 && scheduled == 1 { ShMove::Set(1) } else { ShMove::Stay };
    }
    ShMove::Judge(current)
}

/// The degree that [`update_sh_degree`] sets at iteration `it` from degree `current` where it
/// only raises it by the schedule (no band judged): the new bands start at zero.
pub(crate) fn plain_rise(cfg: &TrainConfig, current: u32, it: u64) -> Option<u32> {
    match sh_move(cfg, current, it) {
        ShMove::Set(degree) if degree > current => Some(degree),
        _ => None,
    }
}

/// A plain rise ([`plain_rise`]) on the device that holds the model resident
/// ([`Rasterizer::raise_sh_degree_resident`]), before the host sets the degree: exact where
/// the host's coefficients and moments above the current degree are zero (the new bands'
/// values on both). `false`, with nothing changed, where they are not or the device declines.
pub(crate) fn raise_on_device(rasterizer: &mut Rasterizer, state: &crate::trainer::TrainState, degree: u32) -> Result<bool> {
    if !crate::refine::inactive_sh_zero(state) {
        return Ok(false);
    }
    Ok(rasterizer.raise_sh_degree_resident(&state.gaussians, degree)?)
}

/// Whether [`update_sh_degree`] changes anything at iteration `it` from degree `current`
/// (another degree, or a band judged and maybe its moments zeroed).
pub(crate) fn acts(cfg: &TrainConfig, current: u32, it: u64) -> bool {
    sh_move(cfg, current, it) != ShMove::Stay
}

/// Sets the SH degree of iteration `it` from the schedule and, under
/// [`ShPolicy::Adaptive`], judges the newest band at a scheduled rise: `judge_l1(g, degree)`
/// renders `g` at `degree` and returns the mean L1 of the judged views ([`judge_l1`]). The rule
/// only reads the degree of the previous iteration (stored in checkpoints), so a resumed run
/// takes the same decisions.
pub(crate) fn update_sh_degree(
    cfg: &TrainConfig,
    gaussians: &mut Gaussians,
    adam: &mut Adam,
    it: u64,
    mut judge_l1: impl FnMut(&mut Gaussians, u32) -> Result<f64>,
) -> Result<Option<ShBandDecision>> {
    let band = match sh_move(cfg, gaussians.sh_degree, it) {
        ShMove::Stay => return Ok(None),
        ShMove::Set(degree) => {
            gaussians.sh_degree = degree;
            return Ok(None);
        }
        ShMove::Judge(band) => band,
    };
    // A scheduled rise from `band` to `band + 1`: does band `band` pay on the training views?
    let [l1_without, l1_with] = [judge_l1(gaussians, band - 1)?, judge_l1(gaussians, band)?];
    let gain = if l1_without > 0.0 { (l1_without - l1_with) / l1_without } else { 0.0 };
    let kept = gain >= cfg.sh_min_gain as f64;
    let degree = if kept {
        band + 1
    } else {
        // Drop band `band`: zero its coefficients and moments so nothing drifts there.
        let coeffs = (band * band) as usize..((band + 1) * (band + 1)) as usize;
        for sh in &mut gaussians.sh {
            sh[coeffs.clone()].iter_mut().for_each(|c| *c = [0.0; 3]);
        }
        // The SH-rest rows hold coefficients 1..16, three floats each.
        adam.zero_columns(Param::ShRest.name(), (coeffs.start - 1) * 3..(coeffs.end - 1) * 3)?;
        band - 1
    };
    gaussians.sh_degree = degree;
    Ok(Some(ShBandDecision { band, l1_without, l1_with, gain, kept, degree }))
}

/// Mean L1 of the judged training views (up to [`SH_JUDGE_VIEWS`] of `train_views`, evenly
/// spread) with `g` rendered at SH degree `degree` (left set on `g`).
pub(crate) fn judge_l1(
    g: &mut Gaussians,
    degree: u32,
    scene: &Scene,
    train_views: &[usize],
    rasterizer: &mut Rasterizer,
    raster: &RasterConfig,
) -> Result<f64> {
    let n = SH_JUDGE_VIEWS.min(train_views.len());
    let views: Vec<usize> = (0..n).map(|k| train_views[k * train_views.len() / n]).collect();
    let req = RenderRequest { color: true, alpha: false, ..RenderRequest::default() };
    g.sh_degree = degree;
    let mut l1 = 0.0f64;
    for &v in &views {
        let view = &scene.views[v];
        let img = rasterizer.render(g, &view.camera, &req, raster)?.color.expect("requested");
        let sum: f64 = img.data().iter().zip(view.image.data()).map(|(a, b)| (a - b).abs() as f64).sum();
        l1 += sum / img.data().len() as f64 / views.len() as f64;
    }
    Ok(l1)
}
