//! Density control (docs/method.md §Densification) as its own call after a step, as brush separates `step`
//! and `refine`: clone / split / prune on the accumulated statistics, opacity reset and the
//! multi-view trim, each when the [`StepPlan`] says so. Free functions of a rasterizer and the
//! explicit [`TrainState`], so that any executor runs the same control.

use crate::capture_path::CapturePath;
use crate::densify::{self, DensifyReport};
use crate::floaters::{FloaterReport, FloaterRule, FreeSpaceVotes};
use crate::error::Result;
use crate::executor::RunInputs;
use crate::plan::StepPlan;
use crate::trainer::TrainState;
use gs_core::Gaussians;
use gs_raster::{Rasterizer, RenderRequest};
use serde::Serialize;

/// What one refinement did.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct RefineReport {
    /// Densification, when it ran.
    pub densify: Option<DensifyReport>,
    /// Gaussians removed by the multi-view trim, when it ran.
    pub trimmed: Option<usize>,
    /// Whether the opacity was reset.
    pub opacity_reset: bool,
    /// Free-space floaters removed, when the removal ran.
    pub floaters: Option<crate::floaters::FloaterReport>,
}

/// Runs the density control that `plan` schedules after its step, continuing the iteration's
/// random stream; renders (floaters, trim) go through `rasterizer`.
pub(crate) fn refine(rasterizer: &mut Rasterizer, run: &RunInputs<'_>, state: &mut TrainState, plan: &StepPlan) -> Result<RefineReport> {
    let (r, config) = (plan.refine, run.config);
    let mut report = RefineReport::default();
    if r.densify {
        let mut rng = plan.refine_rng.clone();
        let s = &mut *state;
        let d = densify::densify_and_prune(
            &mut s.gaussians,
            &mut s.adam,
            &mut s.stats,
            &config.densify,
            run.extent as f32,
            r.prune_big,
            densify::Growth { target: run.budget.target(plan.iteration, &config.densify), cap: config.max_gaussians },
            &mut rng,
        )?;
        s.capped |= d.capped;
        report.densify = Some(d);
    }
    if r.remove_floaters {
        report.floaters = Some(remove_floaters(rasterizer, run, state, &config.densify.floaters)?);
    }
    if r.reset_opacity {
        densify::reset_opacity(&mut state.gaussians, &mut state.adam)?;
        report.opacity_reset = true;
    }
    if r.trim {
        let counts = views_observed(rasterizer, run, &state.gaussians)?;
        let s = &mut *state;
        report.trimmed = Some(densify::trim_unobserved(&mut s.gaussians, &mut s.adam, &mut s.stats, &counts, config.densify.trim_min_views)?);
    }
    Ok(report)
}

/// For every Gaussian, the number of training views in which it was observed (contributed
/// while T > 0.5), for the multi-view trim.
pub fn views_observed(rasterizer: &mut Rasterizer, run: &RunInputs<'_>, gaussians: &Gaussians) -> Result<Vec<u32>> {
    let mut counts = vec![0u32; gaussians.len()];
    let req = RenderRequest { color: false, alpha: false, observed: true, ..RenderRequest::default() };
    for &i in run.train_views {
        let out = rasterizer.render(gaussians, &run.scene.views[i].camera, &req, run.raster)?;
        for (c, &o) in counts.iter_mut().zip(out.observed.as_ref().expect("requested")) {
            *c += (o > 0) as u32;
        }
    }
    Ok(counts)
}

/// Renders every training view's plane depth and alpha and collects the free-space votes of
/// `gaussians` (docs/method.md §Floaters; no renders when only the capture path is asked for).
pub fn free_space_votes(rasterizer: &mut Rasterizer, run: &RunInputs<'_>, gaussians: &Gaussians, rule: &FloaterRule) -> Result<FreeSpaceVotes> {
    let mut votes = FreeSpaceVotes::new(gaussians.len());
    let req = RenderRequest { color: false, alpha: true, plane_depth: true, ..RenderRequest::default() };
    let views = if rule.enabled { run.train_views } else { &[] };
    for &v in views {
        let camera = &run.scene.views[v].camera;
        let out = rasterizer.render(gaussians, camera, &req, run.raster)?;
        let (depth, alpha) = (out.plane_depth.expect("requested"), out.alpha.expect("requested"));
        votes.add_view(gaussians, camera, &depth, &alpha, run.raster.near, rule)?;
    }
    let cameras = run.scene.cameras_of(run.train_views);
    let surface: Vec<gs_core::glam::DVec3> = run.scene.points.iter().map(|p| p.position).collect();
    votes.mark_capture_path(gaussians, &CapturePath::new(&cameras, rule.path_clearance as f64, &surface));
    Ok(votes)
}

/// Removes the floaters of `rule` from `state` (Gaussians, optimiser rows and statistics together).
pub fn remove_floaters(rasterizer: &mut Rasterizer, run: &RunInputs<'_>, state: &mut TrainState, rule: &FloaterRule) -> Result<FloaterReport> {
    let votes = free_space_votes(rasterizer, run, &state.gaussians, rule)?;
    let (mut keep, report) = votes.verdict(rule);
    crate::densify::retain_rows(&mut state.gaussians, &mut state.adam, &mut keep)?;
    state.stats.retain(&keep);
    Ok(report)
}
