//! Density control (docs/method.md §Densification) as its own call after a step, as brush separates `step`
//! and `refine`: clone / split / prune on the accumulated statistics, opacity reset and the
//! multi-view trim, each when the [`StepPlan`] says so.

use crate::densify::{self, DensifyReport};
use crate::error::Result;
use crate::plan::StepPlan;
use crate::trainer::Trainer;
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
