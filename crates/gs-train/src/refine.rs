//! Density control (docs/method.md §Densification) as its own call after a step, as brush separates `step`
//! and `refine`: clone / split / prune on the accumulated statistics, opacity reset and the
//! multi-view trim, each when the [`StepPlan`] says so. Free functions of a rasterizer and the
//! explicit [`TrainState`], so that any executor runs the same control.

use crate::capture_path::CapturePath;
use crate::budget::GrowthLimit;
use crate::densify::{self, DensifyReport};
use crate::floaters::{FloaterReport, FloaterRule, FreeSpaceVotes};
use crate::error::Result;
use crate::executor::RunInputs;
use crate::plan::StepPlan;
use crate::trainer::TrainState;
use gs_core::Gaussians;
use gs_raster::{Rasterizer, RenderRequest, TrimOnDevice};
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

/// What of a step's density control the device that holds the model has already done.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct DoneOnDevice {
    /// The densification ([`densify_on_device`]).
    pub densified: Option<DensifyReport>,
    /// The floater removal ([`floaters_on_device`]).
    pub floaters: Option<FloaterReport>,
    /// The opacity reset ([`reset_on_device`]).
    pub opacity_reset: bool,
    /// The multi-view trim, with how many it removed ([`trim_on_device`]).
    pub trimmed: Option<usize>,
    /// Whether the device changed the model's rows or values (the host's moments and
    /// statistics are then behind).
    pub changed: bool,
    /// Whether the host's parameters are the device's afterwards.
    pub params_current: bool,
}

impl DoneOnDevice {
    /// Whether the host has a part of `r` left to run (it needs the model back for it).
    pub fn host_left(&self, r: &crate::plan::RefinePlan) -> bool {
        (r.densify && self.densified.is_none())
            || (r.remove_floaters && self.floaters.is_none())
            || (r.reset_opacity && !self.opacity_reset)
            || (r.trim && self.trimmed.is_none())
    }
}

/// The parts of `plan`'s density control that the device holding the model takes, in the
/// host's order (densification, floater removal, opacity reset, trim) until a part the
/// device declines: that part and those after it are left to the host. `params_current`
/// says whether the host's parameters are the device's now; the floater rule and the trim's
/// never-empty rule read them back when they need them and are not.
pub(crate) fn on_device(rasterizer: &mut Rasterizer, run: &RunInputs<'_>, state: &mut TrainState, plan: &StepPlan, params_current: bool) -> Result<DoneOnDevice> {
    let r = plan.refine;
    let mut done = DoneOnDevice { params_current, ..Default::default() };
    if !rasterizer.is_resident() {
        return Ok(done);
    }
    // The device holds only the active SH coefficients: it moves rows only where the others are zero.
    let rows_move = inactive_sh_zero(state);
    if r.densify {
        done.densified = if rows_move { densify_on_device(rasterizer, run, state, plan)? } else { None };
        if done.densified.is_none() {
            return Ok(done);
        }
        (done.changed, done.params_current) = (true, false);
    }
    if r.remove_floaters {
        done.floaters = if rows_move { floaters_on_device(rasterizer, run, state, &mut done)? } else { None };
        if done.floaters.is_none() {
            return Ok(done);
        }
    }
    if r.reset_opacity {
        reset_on_device(rasterizer, state, done.params_current)?;
        (done.opacity_reset, done.changed) = (true, true);
    }
    if r.trim && rows_move {
        done.trimmed = trim_on_device(rasterizer, run, state, &mut done)?;
    }
    Ok(done)
}

/// Runs the density control that `plan` schedules after its step, continuing the iteration's
/// random stream; renders (floaters, trim) go through `rasterizer`. What `done` says the
/// device did is not done again.
pub(crate) fn refine(rasterizer: &mut Rasterizer, run: &RunInputs<'_>, state: &mut TrainState, plan: &StepPlan, done: DoneOnDevice) -> Result<RefineReport> {
    let (r, config) = (plan.refine, run.config);
    let mut report = RefineReport::default();
    if let Some(d) = done.densified {
        state.capped |= d.capped;
        report.densify = Some(d);
    } else if r.densify {
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
    if done.floaters.is_some() {
        report.floaters = done.floaters;
    } else if r.remove_floaters {
        report.floaters = Some(remove_floaters(rasterizer, run, state, &config.densify.floaters)?);
    }
    if r.reset_opacity && !done.opacity_reset {
        densify::reset_opacity(&mut state.gaussians, &mut state.adam)?;
    }
    report.opacity_reset = r.reset_opacity;
    if done.trimmed.is_some() {
        report.trimmed = done.trimmed;
    } else if r.trim {
        let counts = views_observed(rasterizer, run, &state.gaussians)?;
        let s = &mut *state;
        report.trimmed = Some(densify::trim_unobserved(&mut s.gaussians, &mut s.adam, &mut s.stats, &counts, config.densify.trim_min_views)?);
    }
    Ok(report)
}

/// Clone, split and prune on the device that holds the model resident
/// ([`Rasterizer::densify_resident`]), with the host's rule and its sampled positions
/// ([`densify::sample_near`], the same random stream): the model the host would make. `None`, with
/// nothing changed, where it does not apply (a growth region, or a step the device declines).
/// After it the host's Gaussians and moments are placeholders of the new size, behind the
/// device's until read back; the statistics start again at zero on both.
pub(crate) fn densify_on_device(rasterizer: &mut Rasterizer, run: &RunInputs<'_>, state: &mut TrainState, plan: &StepPlan) -> Result<Option<DensifyReport>> {
    let cfg = &run.config.densify;
    if cfg.region.is_some() {
        return Ok(None);
    }
    let n = state.gaussians.len();
    let growth = densify::Growth { target: run.budget.target(plan.iteration, cfg), cap: run.config.max_gaussians };
    let rule = densify::device_rule(cfg, run.extent as f32, plan.refine.prune_big, growth.room(n));
    let mut rng = plan.refine_rng.clone();
    let Some(c) = rasterizer.densify_resident(&state.gaussians, &rule, &mut |parent| densify::sample_near(parent, &mut rng))? else {
        return Ok(None);
    };
    behind_on_host(state, c.len, None)?;
    let limit = growth.limit(c.candidates, rule.room);
    Ok(Some(DensifyReport { cloned: c.cloned, split: c.split, pruned: c.removed - c.split, capped: limit == GrowthLimit::Cap, limit, on_device: true }))
}

/// The opacity reset ([`densify::reset_opacity`]) on the device that holds the model resident
/// ([`Rasterizer::reset_opacity_resident`]); the host's parameters too where they are
/// `current`, so that they stay so.
fn reset_on_device(rasterizer: &mut Rasterizer, state: &mut TrainState, current: bool) -> Result<()> {
    let level = densify::RESET_OPACITY;
    rasterizer.reset_opacity_resident(&state.gaussians, level, gs_core::gaussians::inverse_sigmoid(level))?;
    if current {
        densify::cap_opacities(&mut state.gaussians);
    }
    Ok(())
}

/// The floater rule ([`remove_floaters`]) on the device that holds the model resident. The
/// capture path alone (the default rule) is tested there ([`path_on_device`]). The view
/// votes read the Gaussians' geometry (the host's parameters where current, else the device's
/// records without the SH, [`Rasterizer::read_resident_records`]), and the device keeps the
/// rows the verdict keeps ([`Rasterizer::retain_resident`]). `None`, with nothing changed,
/// where the device declines the removal.
fn floaters_on_device(rasterizer: &mut Rasterizer, run: &RunInputs<'_>, state: &mut TrainState, done: &mut DoneOnDevice) -> Result<Option<FloaterReport>> {
    let rule = &run.config.densify.floaters;
    if !rule.enabled
        && let Some(removed) = path_on_device(rasterizer, run, state, done)?
    {
        return Ok(Some(FloaterReport { on_capture_path: removed, ..FloaterReport::default() }));
    }
    let records;
    let geometry = match done.params_current {
        true => &state.gaussians,
        false => {
            let mut g = Gaussians::with_len(state.gaussians.len())?;
            g.sh_degree = state.gaussians.sh_degree;
            rasterizer.read_resident_records(&mut g)?;
            records = g;
            &records
        }
    };
    let (mut keep, report) = free_space_votes(rasterizer, run, geometry, rule)?.verdict(rule);
    densify::keep_one(&mut keep, &geometry.opacity_logits);
    Ok(retain_on_device(rasterizer, state, &keep, done)?.then_some(report))
}

/// The capture-path rule alone on the device: each mean is tested against the path's capsules
/// there, the host tests the few f32 cannot settle with its own rule, and the rows in front of
/// the path go on the device; no parameter crosses. Returns how many went, or `None`, with
/// nothing changed, where the device declines or would keep none (the host's rule then keeps
/// the most opaque one).
fn path_on_device(rasterizer: &mut Rasterizer, run: &RunInputs<'_>, state: &mut TrainState, done: &mut DoneOnDevice) -> Result<Option<usize>> {
    let path = capture_path(run, &run.config.densify.floaters);
    let Some(unsure) = rasterizer.mark_capsules_resident(&state.gaussians, path.capsules())? else {
        return Ok(None);
    };
    let inside: Vec<usize> = unsure.into_iter().filter(|(_, m)| path.contains(gs_core::glam::DVec3::from(m.map(f64::from)))).map(|(i, _)| i).collect();
    let n = state.gaussians.len();
    match rasterizer.retain_outside_resident(&state.gaussians, &inside)? {
        Some(TrimOnDevice::Kept(kept)) => {
            kept_on_device(state, n, kept, done)?;
            Ok(Some(n - kept))
        }
        Some(TrimOnDevice::NoneKept) | None => Ok(None),
    }
}

/// The multi-view trim ([`densify::trim_unobserved`]) on the device that holds the model
/// resident: its renders bind the resident model and keep their pixel counts there, the
/// device counts each Gaussian's observing views, makes the keep mask and keeps those rows;
/// the survivors' number alone comes back. Where the trim would leave no Gaussian, the counts
/// and the host's parameters come back and the host's rule keeps the most opaque one. `None`,
/// with nothing changed, where the device declines.
fn trim_on_device(rasterizer: &mut Rasterizer, run: &RunInputs<'_>, state: &mut TrainState, done: &mut DoneOnDevice) -> Result<Option<usize>> {
    let cameras: Vec<&gs_core::Camera> = run.train_views.iter().map(|&v| &run.scene.views[v].camera).collect();
    rasterizer.count_views_resident(&state.gaussians, &cameras, run.raster)?;
    let n = state.gaussians.len();
    match rasterizer.retain_observed_resident(&state.gaussians, run.config.densify.trim_min_views)? {
        None => Ok(None),
        Some(TrimOnDevice::Kept(kept)) => {
            kept_on_device(state, n, kept, done)?;
            Ok(Some(n - kept))
        }
        Some(TrimOnDevice::NoneKept) => {
            let counts = rasterizer.read_view_counts()?;
            let mut keep = densify::observed_enough(&counts, run.config.densify.trim_min_views);
            bring_parameters(rasterizer, state, done)?;
            densify::keep_one(&mut keep, &state.gaussians.opacity_logits);
            let removed = keep.iter().filter(|k| !**k).count();
            Ok(retain_on_device(rasterizer, state, &keep, done)?.then_some(removed))
        }
    }
}

/// After the device kept `kept` of `n` rows by a mask the host does not know: the host's copy
/// becomes placeholders of the new size.
fn kept_on_device(state: &mut TrainState, n: usize, kept: usize, done: &mut DoneOnDevice) -> Result<()> {
    if kept < n {
        done.params_current = false;
        behind_on_host(state, kept, None)?;
        done.changed = true;
    }
    Ok(())
}

/// Reads the resident parameters into the host's Gaussians unless they are current there.
fn bring_parameters(rasterizer: &mut Rasterizer, state: &mut TrainState, done: &mut DoneOnDevice) -> Result<()> {
    if !done.params_current {
        rasterizer.read_resident(&mut state.gaussians, None)?;
        done.params_current = true;
    }
    Ok(())
}

/// Keeps the resident rows where `keep` is true; the host's parameters follow where they are
/// current, its moments and statistics become placeholders of the new size. `false`, with
/// nothing changed, where the device declines.
fn retain_on_device(rasterizer: &mut Rasterizer, state: &mut TrainState, keep: &[bool], done: &mut DoneOnDevice) -> Result<bool> {
    let Some(kept) = rasterizer.retain_resident(&state.gaussians, keep)? else {
        return Ok(false);
    };
    if kept < keep.len() {
        behind_on_host(state, kept, done.params_current.then_some(keep))?;
        done.changed = true;
    }
    Ok(true)
}

/// After the device changed the model's rows: the host's moments and statistics become
/// placeholders of `len` rows (the statistics at zero), and its Gaussians too unless `kept`
/// gives the rows to keep of current ones.
fn behind_on_host(state: &mut TrainState, len: usize, kept: Option<&[bool]>) -> Result<()> {
    match kept {
        Some(keep) => state.gaussians.retain(keep)?,
        None => {
            let degree = state.gaussians.sh_degree;
            state.gaussians = Gaussians::with_len(len)?;
            state.gaussians.sh_degree = degree;
        }
    }
    for group in &mut state.adam.groups {
        group.m = vec![0.0; len * group.row_width];
        group.v = vec![0.0; len * group.row_width];
    }
    state.stats = gs_core::DensifyStats::new(len);
    Ok(())
}

/// Whether every SH coefficient above the active degree is zero, in the Gaussians and in the
/// moments: the device holds only the active ones, so it may move rows only then.
pub(crate) fn inactive_sh_zero(state: &TrainState) -> bool {
    let active = gs_core::sh::coeffs_for_degree(state.gaussians.sh_degree);
    let values = state.gaussians.sh.iter().all(|c| c[active..].iter().all(|v| *v == [0.0; 3]));
    let Some(rest) = state.adam.groups.iter().find(|g| g.name == crate::params::Param::ShRest.name()) else {
        return false;
    };
    let (w, from) = (rest.row_width, 3 * active.saturating_sub(1));
    let zero = |m: &[f32]| m.chunks(w).all(|row| row[from.min(w)..].iter().all(|v| *v == 0.0));
    values && zero(&rest.m) && zero(&rest.v)
}

/// For every Gaussian, the number of training views in which it was observed (contributed
/// while T > 0.5), for the multi-view trim.
pub fn views_observed(rasterizer: &mut Rasterizer, run: &RunInputs<'_>, gaussians: &Gaussians) -> Result<Vec<u32>> {
    let mut counts = vec![0u32; gaussians.len()];
    let req = RenderRequest { color: false, alpha: false, observed: true, ..RenderRequest::default() };
    for views in run.train_views.chunks(VIEWS_TOGETHER) {
        let cameras: Vec<_> = views.iter().map(|&i| (&run.scene.views[i].camera, req)).collect();
        for out in rasterizer.render_views(gaussians, &cameras, run.raster)? {
            for (c, &o) in counts.iter_mut().zip(out.observed.as_ref().expect("requested")) {
                *c += (o > 0) as u32;
            }
        }
    }
    Ok(counts)
}

/// Training views rendered in one call by the trim and the floater votes: a device uploads
/// the model once a call (the model is not resident during host density control), and the
/// host holds this many views' outputs at once.
const VIEWS_TOGETHER: usize = 8;

/// Renders every training view's plane depth and alpha and collects the free-space votes of
/// `gaussians` (docs/method.md §Floaters; no renders when only the capture path is asked for).
pub fn free_space_votes(rasterizer: &mut Rasterizer, run: &RunInputs<'_>, gaussians: &Gaussians, rule: &FloaterRule) -> Result<FreeSpaceVotes> {
    let mut votes = FreeSpaceVotes::new(gaussians.len());
    let req = RenderRequest { color: false, alpha: true, plane_depth: true, ..RenderRequest::default() };
    let views = if rule.enabled { run.train_views } else { &[] };
    for group in views.chunks(VIEWS_TOGETHER) {
        let cameras: Vec<_> = group.iter().map(|&v| (&run.scene.views[v].camera, req)).collect();
        for ((camera, _), out) in cameras.iter().zip(rasterizer.render_views(gaussians, &cameras, run.raster)?) {
            let (depth, alpha) = (out.plane_depth.expect("requested"), out.alpha.expect("requested"));
            votes.add_view(gaussians, camera, &depth, &alpha, run.raster.near, rule)?;
        }
    }
    votes.mark_capture_path(gaussians, &capture_path(run, rule));
    Ok(votes)
}

/// The free space in front of the training cameras' path, bounded by the scene's sparse
/// points ([`CapturePath::new`] with `rule`'s clearance).
fn capture_path(run: &RunInputs<'_>, rule: &FloaterRule) -> CapturePath {
    let cameras = run.scene.cameras_of(run.train_views);
    let surface: Vec<gs_core::glam::DVec3> = run.scene.points.iter().map(|p| p.position).collect();
    CapturePath::new(&cameras, rule.path_clearance as f64, &surface)
}

/// Removes the floaters of `rule` from `state` (Gaussians, optimiser rows and statistics together).
pub fn remove_floaters(rasterizer: &mut Rasterizer, run: &RunInputs<'_>, state: &mut TrainState, rule: &FloaterRule) -> Result<FloaterReport> {
    let votes = free_space_votes(rasterizer, run, &state.gaussians, rule)?;
    let (mut keep, report) = votes.verdict(rule);
    crate::densify::retain_rows(&mut state.gaussians, &mut state.adam, &mut keep)?;
    state.stats.retain(&keep);
    Ok(report)
}
