//! Executors of a [`StepPlan`] (docs/method.md §Schedule). The [`StepExecutor`] contract takes
//! the run's fixed inputs ([`RunInputs`]) and the training state ([`TrainState`]) explicitly, so
//! an executor holds only what is its own: its rasterizer, per-view caches and loss-term devices.
//!
//! [`ReferenceExecutor`] renders the view on its rasterizer (CPU or wgpu), evaluates the plan's
//! loss terms through the [`crate::LossTerm`] contract (on the CPU, or on the rasterizer's device
//! where [`LossDevices`] has a kernel), back-propagates through exposure and rasterizer and takes
//! the Adam step (on a wgpu rasterizer both on the device, with the densification statistics,
//! on the model kept resident there between [`StepExecutor::release`]s: docs/architecture.md
//! §GPU); density control follows in
//! [`crate::refine`]. With the CPU rasterizer it is the
//! numerical reference that any other executor of the same plan must match.

use crate::budget::Budget;
use crate::caches::{ViewCaches, downscaled_camera, photo};
use crate::config::TrainConfig;
use crate::devices::{LossDevices, TermsUsed};
use crate::error::{Result, TrainError};
use crate::params::{Param, adam_step, set_lr};
use crate::plan::StepPlan;
use crate::profile::{Clock, Part, StepProfile};
use crate::refine::RefineReport;
use crate::source_depths::StoredDepth;
use crate::terms::{Colour, GradientBuffers, LossValues, SourceInputs, TermInputs};
use crate::trainer::TrainState;
use gs_core::Scene;
use gs_raster::{RasterConfig, Rasterizer, RenderRequest};
use serde::Serialize;

mod request;

/// What an executor reads of the run and never changes: the configuration, the scene and its
/// training split, the scene extent, the rasterizer settings and the Gaussian budget.
#[derive(Clone, Copy)]
pub struct RunInputs<'a> {
    /// The run's configuration.
    pub config: &'a TrainConfig,
    /// The scene.
    pub scene: &'a Scene,
    /// The training views (indices into `scene.views`); a plan's slots index this list.
    pub train_views: &'a [usize],
    /// Scene extent r of the training cameras.
    pub extent: f64,
    /// Rasterizer settings used for training.
    pub raster: &'a RasterConfig,
    /// The scene's Gaussian budget.
    pub budget: &'a Budget,
}

/// Where one part of an iteration runs (report.json `parts_on`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PartPlace {
    /// The part, in words ("render and backward", a loss term, "Adam", "the training views' floater votes").
    pub part: String,
    /// Where it runs: `cpu (N threads)` or `wgpu on ADAPTER`.
    pub on: String,
}

/// Carries out a [`StepPlan`] on a [`TrainState`] that the caller owns and passes in.
pub trait StepExecutor {
    /// Render, loss terms, backward and Adam (no density control); returns the loss values and
    /// accumulates the densification statistics when the plan says so. Time goes to `profile`.
    fn execute(&mut self, run: &RunInputs<'_>, state: &mut TrainState, plan: &StepPlan, profile: &mut StepProfile) -> Result<LossValues>;

    /// The density control that `plan` schedules after its step ([`crate::refine`]).
    fn refine(&mut self, run: &RunInputs<'_>, state: &mut TrainState, plan: &StepPlan) -> Result<RefineReport>;

    /// Brings into `state` what the executor keeps on its device (the parameters and Adam
    /// moments of a resident model), so that the host may read it; the residency goes on.
    fn pull(&mut self, state: &mut TrainState) -> Result<()>;

    /// Brings into `state` the resident model's parameters alone (what renders, exports and
    /// held-out scoring read), not its moments, statistics or the memo's depths.
    fn pull_parameters(&mut self, state: &mut TrainState) -> Result<()>;

    /// [`StepExecutor::pull`], then ends the residency, so that the host may change the
    /// state; the next [`StepExecutor::execute`] takes it up again.
    fn release(&mut self, state: &mut TrainState) -> Result<()>;

    /// Before the host raises the SH degree to `degree` by the schedule: a resident model's SH
    /// rows widen where it lives ([`crate::sh_policy::raise_on_device`]), or the residency ends.
    fn raise_sh_degree(&mut self, state: &mut TrainState, degree: u32) -> Result<()>;

    /// Whether `state` holds everything the executor's device holds (always on the CPU; on a
    /// resident model, until the next step).
    fn host_current(&self) -> bool;
}

/// The reference executor: a rasterizer, the per-view caches and the loss terms' device kernels
/// (none on the CPU rasterizer).
pub struct ReferenceExecutor {
    /// Renders and back-propagates (CPU or wgpu).
    pub(crate) rasterizer: Rasterizer,
    /// Edge guides, grey images, feature maps and downscaled photos per training view.
    pub(crate) caches: ViewCaches,
    /// The loss terms' device executors, when the rasterizer runs on wgpu.
    devices: LossDevices,
    /// Why the terms run on the CPU although the rasterizer runs on wgpu, if they do.
    devices_error: Option<String>,
    /// Whether Adam runs on the rasterizer's device with the model resident there (a wgpu
    /// rasterizer and no 3D smoothing filter, which works on the host's parameters).
    adam_on_device: bool,
    /// What the state's host copy misses of the resident model since its last step.
    behind: Behind,
    /// The last device step, its divergence flag not read yet (with its iteration): read
    /// after the next render, whose wait for the device brings it, or before the host reads
    /// the model.
    step: Option<(gs_raster::StartedStep, u64)>,
    /// Whether the depth memo keeps depths on the device alone
    /// ([`crate::source_depths::memo_fits_on_device`]), decided at the first step.
    memo_on_device: Option<bool>,
}

/// What of a resident model the host's [`TrainState`] lacks: a device step moves the
/// parameters, the moments and the densification statistics on the device only.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Behind {
    /// The parameters (L_o reads them back alone: 236 bytes a Gaussian at SH degree 3).
    parameters: bool,
    /// The Adam moments and the densification statistics.
    optimiser: bool,
}

impl ReferenceExecutor {
    /// An executor on `rasterizer` for `views` training views; the loss terms go to its device
    /// when it has one (L_p's and L_f's kernels only when the run `uses` them), and Adam too
    /// unless `smoothing` (the 3D filter) is on.
    pub fn new(rasterizer: Rasterizer, views: usize, uses: TermsUsed, smoothing: bool) -> Self {
        let (devices, devices_error) = devices_of(&rasterizer, uses);
        let adam_on_device = rasterizer.backend() == gs_raster::Backend::Wgpu && !smoothing;
        Self { rasterizer, caches: ViewCaches::new(views), devices, devices_error, adam_on_device, behind: Behind::default(), step: None, memo_on_device: None }
    }

    /// Moves to `rasterizer` (and its device's loss kernels), keeping the caches; `state`
    /// first receives what the old rasterizer's device kept ([`StepExecutor::release`]).
    pub fn set_rasterizer(&mut self, rasterizer: Rasterizer, uses: TermsUsed, smoothing: bool, state: &mut TrainState) -> Result<()> {
        // The old device's depths too.
        self.pull(state)?;
        self.release(state)?;
        let caches = std::mem::replace(&mut self.caches, ViewCaches::new(0));
        *self = Self { caches, ..Self::new(rasterizer, 0, uses, smoothing) };
        Ok(())
    }

    /// Where the loss terms run, in words (with the reason when the wgpu rasterizer's device
    /// could not take them).
    pub fn describe(&self) -> String {
        let on = self.devices.describe();
        match &self.devices_error {
            Some(e) => format!("{on}: the device kernels failed to build ({e})"),
            None => on,
        }
    }

    /// Where each part of the step runs: render and backward on the rasterizer, each loss
    /// term on its device kernel or the CPU, Adam and the densification statistics on the
    /// rasterizer's device when the model is resident there, and so does density control
    /// (where [`crate::refine::on_device`] applies), the trim's view counts and the capture
    /// path's test (the default floater rule) with it; the training views' floater votes (the
    /// full floater rule, off by default) are summed on the CPU.
    pub fn parts_on(&self) -> Vec<PartPlace> {
        let cpu = gs_raster::cpu_description();
        let device = self.rasterizer.description();
        let place = |part: &str, on_device: bool| PartPlace { part: part.into(), on: if on_device { device.clone() } else { cpu.clone() } };
        let mut parts = vec![place("render and backward", true)];
        parts.extend(self.devices.term_parts().into_iter().map(|(part, on_device)| place(part, on_device)));
        parts.push(place("Adam", self.adam_on_device));
        parts.push(place("densification statistics", self.adam_on_device));
        parts.push(place("density control (clone, split, prune, opacity reset, trim, floater removal)", self.adam_on_device));
        parts.push(place("the trim's view counts", self.adam_on_device));
        parts.push(place("the capture path's floater test", self.adam_on_device));
        parts.push(place("the training views' floater votes", false));
        parts
    }

    /// Waits for the last step the device was given, if any (its divergence flag read): what
    /// a caller timing a step waits for.
    pub fn finish_device_work(&mut self) -> Result<()> {
        self.check_step()
    }

    /// The rasterizer.
    pub fn rasterizer(&self) -> &Rasterizer {
        &self.rasterizer
    }

    /// Bytes held by the per-view caches.
    pub fn cache_bytes(&self) -> usize {
        self.caches.bytes()
    }
}

impl ReferenceExecutor {
    /// Fills the per-view caches that `plan` needs (edge guide, grey images, feature maps).
    fn prepare_caches(&mut self, run: &RunInputs<'_>, plan: &StepPlan) -> Result<()> {
        let (scene, views, cfg) = (run.scene, run.train_views, run.config);
        if plan.needs_guide() {
            self.caches.guide(plan.slot, photo(scene, views, plan.slot), cfg.losses.delta)?;
        }
        let with_reference = |s: &[usize]| std::iter::once(plan.slot).chain(s.to_vec()).collect::<Vec<usize>>();
        // L_f on the device names its views by their grey images, as L_p does (its υ/ω are
        // L_p's kernels').
        let lf_on_device = plan.phase.features && self.devices.features_on_device();
        if plan.photometric.is_some() || lf_on_device {
            for k in with_reference(&plan.sources) {
                self.caches.ensure_grey(k, photo(scene, views, k), cfg.ncc_scale)?;
            }
        }
        if plan.phase.features && !plan.sources.is_empty() {
            let level = cfg.feature_layer;
            for k in with_reference(&plan.sources) {
                self.caches.ensure_features(k, photo(scene, views, k), level, &self.devices)?;
            }
        }
        Ok(())
    }

    /// The plan's source depths that the memo cannot serve ([`crate::source_depths`]), then
    /// the reference view's render `request`. On a rasterizer that renders views together (a
    /// device) they are one call and one wait, timed as the render; on the CPU the sources
    /// first, timed apart. Renders are pure, so the grouping changes no value. The source
    /// depths are kept on the device where `on_device` (they never come back); with reuse on
    /// they go into the memo, else they are returned in source order.
    fn render_views_of_step(
        &mut self,
        run: &RunInputs<'_>,
        state: &mut TrainState,
        plan: &StepPlan,
        (camera, request, on_device): (&gs_core::Camera, &RenderRequest, bool),
        (profile, phase, clock): (&mut StepProfile, usize, &mut Clock),
    ) -> Result<(Vec<StoredDepth>, gs_raster::RenderOutput)> {
        let (it, max_age) = (plan.iteration, run.config.source_depth_max_age);
        let mut missing: Vec<usize> = Vec::new();
        for &s in &plan.sources {
            // With the memo a source drawn twice is rendered once (the second is served).
            if state.source_depths.fresh(s, it, max_age).is_none() && !(max_age > 0 && missing.contains(&s)) {
                missing.push(s);
            }
        }
        let downscale = run.config.source_depth_downscale;
        let cameras = missing
            .iter()
            .map(|&s| downscaled_camera(&run.scene.views[run.train_views[s]].camera, downscale))
            .collect::<Result<Vec<_>>>()?;
        let on_device = on_device && downscale == 1;
        let depth_only = RenderRequest {
            color: false,
            alpha: false,
            plane_depth: true,
            radii: false,
            surface_on_device: on_device,
            plane_depth_on_device: on_device,
            ..RenderRequest::default()
        };
        let mut views: Vec<(&gs_core::Camera, RenderRequest)> = cameras.iter().map(|c| (c, depth_only)).collect();
        let g = &state.gaussians;
        let mut outs = if self.rasterizer.renders_together() {
            views.push((camera, *request));
            self.rasterizer.render_views(g, &views, run.raster)?
        } else {
            let mut outs = self.rasterizer.render_views(g, &views, run.raster)?;
            profile.add(phase, Part::SourceDepths, clock.lap());
            outs.push(self.rasterizer.render(g, camera, request, run.raster)?);
            outs
        };
        let out = outs.pop().expect("the reference view rendered last");
        profile.add(phase, Part::Render, clock.lap());
        let mut rendered = Vec::new();
        for (&s, source) in missing.iter().zip(outs) {
            if on_device {
                let kept = crate::source_depths::keep_source_depth((&self.devices, &self.caches, &self.rasterizer), s, &source, it)?;
                match max_age {
                    0 => rendered.push(kept),
                    _ => state.source_depths.store(s, it, kept),
                }
                continue;
            }
            let mut depth = source.plane_depth.expect("requested");
            if downscale > 1 {
                let full = &run.scene.views[run.train_views[s]].camera;
                depth = crate::source_depths::upsample_depth(&depth, full.width as usize, full.height as usize)?;
            }
            if max_age > 0 {
                state.source_depths.store(s, it, StoredDepth::Host(depth));
            } else {
                rendered.push(StoredDepth::Host(depth));
            }
        }
        profile.add(phase, Part::SourceDepths, clock.lap());
        Ok((rendered, out))
    }
}

impl ReferenceExecutor {
    /// Makes the model resident on the rasterizer's device when Adam runs there and it is
    /// not resident yet (the first step, or the first after a [`StepExecutor::release`]).
    fn take_up(&mut self, state: &TrainState) -> Result<()> {
        if self.adam_on_device && !self.rasterizer.is_resident() {
            self.rasterizer.make_resident(&state.gaussians, &state.adam, &state.stats)?;
        }
        Ok(())
    }

    /// The backward and the Adam step on the device ([`Rasterizer::backward_and_step`]), with
    /// the parameter-space terms' own gradients (L_o, L_s) from `parameter_grads`; the
    /// densification statistics accumulate there too when the plan says so.
    #[allow(clippy::too_many_arguments)]
    fn device_step(
        &mut self,
        run: &RunInputs<'_>,
        state: &mut TrainState,
        plan: &StepPlan,
        camera: &gs_core::Camera,
        out: &gs_raster::RenderOutput,
        grads: &gs_raster::OutputGradients,
        parameter_grads: &GradientBuffers,
    ) -> Result<()> {
        let accumulate = plan.refine.accumulate.then_some(plan.scale as f32);
        let extras = gs_raster::StepExtras {
            extra_opacity: parameter_grads.opacity_logits.as_deref(),
            extra_log_scales: parameter_grads.log_scales.as_deref(),
            accumulate,
        };
        let step = self.rasterizer.start_step(&state.gaussians, camera, run.raster, out, grads, &mut state.adam, extras)?;
        self.behind = Behind { parameters: true, optimiser: true };
        self.step = Some((step, plan.iteration));
        Ok(())
    }

    /// Reads the divergence flag of the last device step, if it has not been read (no wait
    /// after a render: the render's wait brought it).
    fn check_step(&mut self) -> Result<()> {
        if let Some((started, iteration)) = self.step.take()
            && !self.rasterizer.finish_step(started)?.means_finite
        {
            return Err(TrainError::Diverged { iteration, problem: "gradient of the means is not finite".into() });
        }
        Ok(())
    }

    /// Brings the resident model (parameters, moments, statistics) into `state`.
    fn pull_model(&mut self, state: &mut TrainState) -> Result<()> {
        self.check_step()?;
        if self.behind != Behind::default() {
            self.rasterizer.read_resident(&mut state.gaussians, Some((&mut state.adam, &mut state.stats)))?;
            self.behind = Behind::default();
        }
        Ok(())
    }

    /// The error of work after the last device step, unless that step diverged: then the
    /// divergence, which explains the failure better.
    fn instead_of(&mut self, error: TrainError) -> TrainError {
        match self.check_step() {
            Err(diverged) => diverged,
            Ok(()) => error,
        }
    }
}

impl StepExecutor for ReferenceExecutor {
    fn execute(&mut self, run: &RunInputs<'_>, state: &mut TrainState, plan: &StepPlan, profile: &mut StepProfile) -> Result<LossValues> {
        let it = plan.iteration;
        let phase = crate::checkpoint::Elapsed::phase_of(run.config, it);
        let mut clock = Clock::start();
        set_lr(&mut state.adam, Param::Means, plan.lr_means)?;
        self.take_up(state)?;
        self.prepare_caches(run, plan)?;
        let small = downscaled_camera(&run.scene.views[plan.view].camera, plan.scale)?;
        let camera = if plan.scale > 1 { &small } else { &run.scene.views[plan.view].camera };
        if plan.scale > 1 {
            self.caches.ensure_scaled(plan.slot, &run.scene.views[plan.view].image, plan.scale, camera)?;
        }
        profile.add(phase, Part::Caches, clock.lap());
        // The sources' depths before the reference's render: a device rasterizer keeps only its
        // last render's state, which the backward below reuses (rendering them after it would
        // cost the backward one more render to rebuild that state). Renders are pure, so the
        // order changes no value. A step on the device gathers its statistics from the radii
        // there.
        let max_age = run.config.source_depth_max_age;
        let (request, placed) = self.step_request(run, state, plan)?;
        let keep_depth = placed.keep_depth;
        let (rendered_depths, out) = self
            .render_views_of_step(run, state, plan, (camera, &request, placed.sources_stay), (profile, phase, &mut clock))
            .map_err(|e| self.instead_of(e))?;
        // The render's wait brought the last step's divergence flag.
        self.check_step()?;
        let rendered = out.color.as_ref();
        // Exposure compensation: the loss sees exp(a)·c + b of this view.
        let corrected = match (&state.exposure, rendered) {
            (Some(e), Some(c)) => Some(gs_losses::apply_exposure(c, &e.params[plan.slot])?),
            _ => None,
        };
        #[cfg(feature = "wgpu")]
        let corrected_on_device = crate::exposure::correct_on_device(&self.devices, state.exposure.as_ref(), plan.slot, out.device_color.as_ref())?;
        let color = match (&corrected, rendered) {
            (Some(c), _) | (None, Some(c)) => Colour::Host(c),
            #[cfg(feature = "wgpu")]
            (None, None) if out.device_color.is_some() => Colour::Device(corrected_on_device.as_ref().or(out.device_color.as_ref()).expect("checked")),
            _ => return Err(TrainError::InvalidConfig("the render has no colour for L_I".into())),
        };
        profile.add(phase, Part::Render, clock.lap());
        if plan.weights.lambda_o > 0.0 || plan.weights.lambda_s > 0.0 {
            // L_o and L_s read the opacity logits and log-scales, which moved on the device only.
            self.pull_parameters(state)?;
        }
        // Each depth with the iteration that rendered it (its version on a device).
        let memo = &state.source_depths;
        let depths: Vec<(&StoredDepth, u64)> = match max_age {
            0 => rendered_depths.iter().map(|d| (d, it)).collect(),
            _ => plan.sources.iter().map(|&s| memo.fresh(s, it, max_age).expect("stored above")).collect(),
        };
        let sources: Vec<SourceInputs> = plan
            .sources
            .iter()
            .zip(depths)
            .map(|(&s, (d, version))| SourceInputs {
                slot: s,
                camera: &run.scene.views[run.train_views[s]].camera,
                plane_depth: d,
                depth_version: version,
                grey: self.caches.grey(s),
                features: self.caches.features(s),
            })
            .collect();
        let inputs = TermInputs {
            slot: plan.slot,
            gaussians: &state.gaussians,
            camera,
            photo: self.caches.scaled(plan.slot, plan.scale).unwrap_or(&run.scene.views[plan.view].image),
            render: &out,
            color,
            guide: self.caches.guide_of(plan.slot),
            grey: self.caches.grey(plan.slot),
            features: self.caches.features(plan.slot),
            sources: &sources,
            devices: &self.devices,
            keep_depth,
        };
        let mut values = LossValues::default();
        let mut grads = GradientBuffers::default();
        // Every term started before the first is read: the device executors' readbacks then
        // cost the host one wait. Each term's time is its start and its fold (the wait counts
        // to the first term read).
        let terms = plan.terms(run.config);
        let mut folds = Vec::with_capacity(terms.len());
        for term in &terms {
            folds.push(term.start(&inputs, &plan.weights)?);
            profile.add(phase, term.part(), clock.lap());
        }
        for (term, fold) in terms.iter().zip(folds) {
            fold.apply(&mut grads, &mut values)?;
            profile.add(phase, term.part(), clock.lap());
        }
        values.total = plan.weights.total(&values);
        if !values.total.is_finite() {
            return Err(TrainError::Diverged { iteration: it, problem: format!("the loss is not finite ({})", values.in_words()) });
        }
        drop(sources);
        // L_I's colour gradient: on the host (through the exposure backward when that is on),
        // or on the device beside the rendered colour.
        let grad_color = match (grads.color.take(), &mut state.exposure, rendered) {
            (Some(gc), Some(e), Some(c)) => {
                let (gc, ge) = gs_losses::exposure_backward(c, &e.params[plan.slot], &gc)?;
                e.step(plan.slot, &ge, it, run.config.iterations)?;
                Some(gc)
            }
            (gc, ..) => gc,
        };
        #[cfg(feature = "wgpu")]
        crate::exposure::backward_on_device(&self.devices, state.exposure.as_mut(), (plan.slot, it, run.config.iterations), out.device_color.as_ref(), &mut grads)?;
        let output_grads = grads.as_output(grad_color.as_ref());
        if self.adam_on_device {
            // Backward and Adam in one device submission: their time is the backward's.
            self.device_step(run, state, plan, camera, &out, &output_grads, &grads)?;
            profile.add(phase, Part::Backward, clock.lap());
        } else {
            let mut g = self.rasterizer.backward(&state.gaussians, camera, run.raster, &out, &output_grads)?;
            if let Some(go) = &grads.opacity_logits {
                g.opacity_logits.iter_mut().zip(go).for_each(|(a, b)| *a += b);
            }
            if let Some(gs) = &grads.log_scales {
                g.log_scales.iter_mut().zip(gs).for_each(|(a, b)| (0..3).for_each(|k| a[k] += b[k]));
            }
            // Rendered through the 3D smoothing filter: back to the raw parameters for Adam
            // and density control (the trainer applies the filter again after them).
            if let Some(s) = &mut state.smoothing {
                s.chain(&mut g)?;
                s.revert(&mut state.gaussians);
            }
            profile.add(phase, Part::Backward, clock.lap());
            if plan.refine.accumulate {
                state.stats.accumulate(&out.radii, out.observed.as_deref(), &g.mean2d, &g.mean2d_abs, plan.scale as f32);
            }
            adam_step(&mut state.adam, &mut state.gaussians, &g, it)?;
            profile.add(phase, Part::Optimizer, clock.lap());
        }
        if max_age > 0 && plan.scale == 1 {
            self.store_reference_depth(state, plan, camera, out.plane_depth, keep_depth);
        }
        Ok(values)
    }

    fn refine(&mut self, run: &RunInputs<'_>, state: &mut TrainState, plan: &StepPlan) -> Result<RefineReport> {
        let r = plan.refine;
        let mut done = crate::refine::DoneOnDevice::default();
        if self.adam_on_device && (r.densify || r.reset_opacity || r.remove_floaters || r.trim) {
            // The last step's divergence first; then the model is changed where it is.
            self.check_step()?;
            done = crate::refine::on_device(&mut self.rasterizer, run, state, plan, !self.behind.parameters)?;
            self.behind.parameters = !done.params_current;
            self.behind.optimiser |= done.changed;
        }
        if done.host_left(&r) {
            self.release(state)?;
        }
        crate::refine::refine(&mut self.rasterizer, run, state, plan, done)
    }

    fn pull_parameters(&mut self, state: &mut TrainState) -> Result<()> {
        self.check_step()?;
        if self.behind.parameters {
            self.rasterizer.read_resident(&mut state.gaussians, None)?;
            self.behind.parameters = false;
        }
        Ok(())
    }

    fn pull(&mut self, state: &mut TrainState) -> Result<()> {
        self.pull_model(state)?;
        crate::source_depths::bring_back(&mut state.source_depths, &self.devices, &self.caches, None)
    }

    fn release(&mut self, state: &mut TrainState) -> Result<()> {
        // The memo's depths stay on the device: density control does not read them.
        self.pull_model(state)?;
        self.rasterizer.release_resident();
        Ok(())
    }

    fn raise_sh_degree(&mut self, state: &mut TrainState, degree: u32) -> Result<()> {
        self.check_step()?;
        if self.rasterizer.is_resident() && !crate::sh_policy::raise_on_device(&mut self.rasterizer, state, degree)? {
            self.release(state)?;
        }
        Ok(())
    }

    fn host_current(&self) -> bool {
        self.behind == Behind::default()
    }
}

/// The loss terms' kernels on `rasterizer`'s device, or none with the reason they failed to build.
fn devices_of(rasterizer: &Rasterizer, uses: TermsUsed) -> (LossDevices, Option<String>) {
    match LossDevices::for_rasterizer(rasterizer, uses) {
        Ok(d) => (d, None),
        Err(e) => (LossDevices::default(), Some(e)),
    }
}
