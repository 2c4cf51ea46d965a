//! Density control (docs/method.md §Densification) as its own call after a step, as brush separates `step`
//! and `refine`: clone / split / prune on the accumulated statistics, opacity reset and the
//! multi-view trim, each when the [`StepPlan`] says so.

use crate::capture_path::CapturePath;
use crate::densify::{self, DensifyReport};
use crate::floaters::{FloaterReport, FloaterRule, FreeSpaceVotes};
use crate::error::Result;
use crate::plan::StepPlan;
use crate::trainer::Trainer;
use gs_core::Camera;
use gs_raster::RenderRequest;
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

impl Trainer<'_> {
    /// Runs the density control that `plan` schedules after its step, continuing the
    /// iteration's random stream.
    pub fn refine(&mut self, plan: &StepPlan) -> Result<RefineReport> {
        let r = plan.refine;
        let mut report = RefineReport::default();
        let s = &mut self.state;
        if r.densify {
            let mut rng = plan.refine_rng.clone();
            let d = densify::densify_and_prune(
                &mut s.gaussians,
                &mut s.adam,
                &mut s.stats,
                &self.config.densify,
                self.extent as f32,
                r.prune_big,
                densify::Growth { target: self.budget.target(plan.iteration, &self.config.densify), cap: self.config.max_gaussians },
                &mut rng,
            )?;
            s.capped |= d.capped;
            report.densify = Some(d);
        }
        if r.remove_floaters {
            let rule = self.config.densify.floaters;
            report.floaters = Some(self.remove_floaters(&rule)?);
        }
        let s = &mut self.state;
        if r.reset_opacity {
            densify::reset_opacity(&mut s.gaussians, &mut s.adam)?;
            report.opacity_reset = true;
        }
        if r.trim {
            let counts = self.views_observed()?;
            let s = &mut self.state;
            report.trimmed =
                Some(densify::trim_unobserved(&mut s.gaussians, &mut s.adam, &mut s.stats, &counts, self.config.densify.trim_min_views)?);
        }
        Ok(report)
    }

    /// For every Gaussian, the number of training views in which it was observed (contributed
    /// while T > 0.5), for the multi-view trim.
    pub fn views_observed(&mut self) -> Result<Vec<u32>> {
        let mut counts = vec![0u32; self.state.gaussians.len()];
        let req = RenderRequest { color: false, alpha: false, observed: true, ..RenderRequest::default() };
        for &i in &self.train_views {
            let out = self.rasterizer.render(&self.state.gaussians, &self.scene.views[i].camera, &req, &self.raster)?;
            for (c, &o) in counts.iter_mut().zip(out.observed.as_ref().expect("requested")) {
                *c += (o > 0) as u32;
            }
        }
        Ok(counts)
    }
}

/// The floater rule run on the trainer's own model and training views (docs/method.md §Floaters).
impl Trainer<'_> {
    /// Renders every training view's plane depth and alpha and collects the free-space votes
    /// of the current model (no renders when only the capture path is asked for).
    pub fn free_space_votes(&mut self, rule: &FloaterRule) -> Result<FreeSpaceVotes> {
        let mut votes = FreeSpaceVotes::new(self.state.gaussians.len());
        let req = RenderRequest { color: false, alpha: true, plane_depth: true, ..RenderRequest::default() };
        let views = if rule.enabled { self.train_views.as_slice() } else { &[] };
        for &v in views {
            let camera = &self.scene.views[v].camera;
            let out = self.rasterizer.render(&self.state.gaussians, camera, &req, &self.raster)?;
            let (depth, alpha) = (out.plane_depth.expect("requested"), out.alpha.expect("requested"));
            votes.add_view(&self.state.gaussians, camera, &depth, &alpha, self.raster.near, rule)?;
        }
        let cameras: Vec<&Camera> = self.train_views.iter().map(|&v| &self.scene.views[v].camera).collect();
        let surface: Vec<gs_core::glam::DVec3> = self.scene.points.iter().map(|p| p.position).collect();
        votes.mark_capture_path(&self.state.gaussians, &CapturePath::new(&cameras, rule.path_clearance as f64, &surface));
        Ok(votes)
    }

    /// Removes the floaters of `rule` (Gaussians, optimiser rows and statistics together).
    pub fn remove_floaters(&mut self, rule: &FloaterRule) -> Result<FloaterReport> {
        let votes = self.free_space_votes(rule)?;
        let (mut keep, report) = votes.verdict(rule);
        let s = &mut self.state;
        crate::densify::retain_rows(&mut s.gaussians, &mut s.adam, &mut keep)?;
        s.stats.retain(&keep);
        Ok(report)
    }
}
