//! The VA-GS training driver (docs/method.md §Parameters to §Schedule): [`Trainer::step`] plans an iteration
//! ([`crate::plan`]), sets the SH degree ([`crate::sh_policy`]), executes the plan
//! on its executor ([`crate::executor::StepExecutor::execute`]: render, loss terms, backward,
//! Adam) and then runs the density control ([`crate::executor::StepExecutor::refine`]). The
//! trainer owns the [`TrainState`] and lends it to the executor for each call.
//!
//! Determinism: every random choice of an iteration is drawn from a stream keyed by the seed and
//! the iteration (see [`crate::plan`]), so the state to checkpoint is only the parameters, the
//! optimiser and the statistics — and a resumed run continues bit-identically.

use crate::budget::Budget;
use crate::config::{Phase, TrainConfig};
use crate::densify::{DensifyReport, DensifyStats};
use crate::error::{Result, TrainError};
use crate::exposure::Exposure;
use crate::init::initial_gaussians;
use crate::model::TrainedModel;
use crate::plan::{StepPlan, plan_step};
use crate::profile::{Clock, Part, StepProfile};
use crate::devices::TermsUsed;
use crate::executor::{ReferenceExecutor, RunInputs, StepExecutor};
use crate::sh_policy::{self, ShBandDecision};
use crate::smoothing::Smoothing;
use crate::source_depths::SourceDepths;
use crate::terms::LossValues;
use gs_core::{Adam, Gaussians, Image, NeighbourRule, Scene};
use gs_mvs::{SourceSelection, SourceViewSelector};
use gs_raster::{Backend, RasterConfig, Rasterizer};
use serde::Serialize;

mod backend_choice;
pub use backend_choice::{BackendChoice, BackendProbe};

/// What one iteration did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StepReport {
    /// 1-based iteration just completed.
    pub iteration: u64,
    /// Index (into the scene's views) of the rendered view.
    pub view: usize,
    /// Active terms.
    pub phase: Phase,
    /// Loss values.
    pub losses: LossValues,
    /// Gaussians after the step.
    pub gaussians: usize,
    /// Densification, when it ran.
    pub densify: Option<DensifyReport>,
    /// Gaussians removed by the multi-view trim, when it ran.
    pub trimmed: Option<usize>,
    /// Whether the opacity was reset.
    pub opacity_reset: bool,
    /// Free-space floaters removed, when the removal ran.
    pub floaters: Option<crate::floaters::FloaterReport>,
    /// The judgement of an SH band ([`crate::ShPolicy::Adaptive`]), when one was made.
    pub sh_band: Option<ShBandDecision>,
}

/// The training state that a checkpoint stores (everything else is derived from the scene
/// and the configuration).
#[derive(Debug, Clone, PartialEq)]
pub struct TrainState {
    /// Iterations completed.
    pub iteration: u64,
    /// The model.
    pub gaussians: Gaussians,
    /// Adam moments and steps (one group per [`crate::Param`]).
    pub adam: Adam,
    /// Densification statistics since the last densification.
    pub stats: DensifyStats,
    /// Whether the Gaussian cap has been reached (warned once).
    pub capped: bool,
    /// Per-view exposure corrections (when `config.exposure`).
    pub exposure: Option<Exposure>,
    /// The last rendered plane depth of each training view, reused by L_p / L_f as source
    /// depth (`config.source_depth_max_age`; empty when 0).
    pub source_depths: SourceDepths,
    /// The 3D smoothing filter (when `config.smoothing_3d` > 0): between iterations the
    /// Gaussians hold the filtered values, the model as rendered ([`crate::smoothing`]).
    pub smoothing: Option<Smoothing>,
}

/// The trainer: a scene, its split, the configuration, the [`TrainState`] it owns, and the
/// executor it lends that state to (which holds the rasterizer and the per-view caches).
pub struct Trainer<'s> {
    config: TrainConfig,
    scene: &'s Scene,
    train_views: Vec<usize>,
    /// The training views' cameras, in `train_views` order (the 3D filter's sampling rates).
    train_cameras: Vec<&'s gs_core::Camera>,
    test_views: Vec<usize>,
    extent: f64,
    raster: RasterConfig,
    selector: SourceViewSelector,
    state: TrainState,
    budget: Budget,
    /// Where this process's training time went ([`crate::profile`]).
    profile: StepProfile,
    /// Carries out each plan on `state` ([`crate::executor`]).
    executor: ReferenceExecutor,
}

fn check_scene(scene: &Scene, train_views: &[usize]) -> Result<()> {
    if train_views.is_empty() {
        return Err(TrainError::InvalidScene("the scene has no training views".into()));
    }
    for &i in train_views {
        let v = scene.views.get(i).ok_or_else(|| TrainError::InvalidScene(format!("training view index {i} out of range")))?;
        let (w, h) = (v.camera.width as usize, v.camera.height as usize);
        if v.image.width() != w || v.image.height() != h || v.image.channels() != 3 {
            return Err(TrainError::InvalidScene(format!(
                "view '{}': image is {}x{}x{} but its camera is {w}x{h} (RGB expected)",
                v.name,
                v.image.width(),
                v.image.height(),
                v.image.channels()
            )));
        }
        if !v.image.is_finite() {
            return Err(TrainError::InvalidScene(format!("view '{}': image has NaN/Inf values", v.name)));
        }
    }
    Ok(())
}

/// The budget of a run over `train_views` starting from `init`.
fn budget_of(scene: &Scene, train_views: &[usize], config: &TrainConfig, init: &Gaussians) -> Budget {
    let cams = scene.cameras_of(train_views);
    Budget::of_scene(&cams, init, &config.densify, config.max_gaussians, config.near)
}

/// Whether the run uses the 3D smoothing filter (configured, or stored in the resumed state).
fn smoothing_on(config: &TrainConfig, state: &TrainState) -> bool {
    config.smoothing_3d > 0.0 || state.smoothing.is_some()
}

/// Checks that a state fits the configuration and the number of training views.
fn check_state(config: &TrainConfig, state: &TrainState, views: usize) -> Result<()> {
    state.gaussians.validate()?;
    let n = state.gaussians.len();
    if state.stats.len() != n || state.adam.groups.iter().any(|g| n.checked_mul(g.row_width) != Some(g.m.len())) {
        return Err(TrainError::InvalidConfig("state: statistics or optimiser rows do not match the Gaussians".into()));
    }
    let depths = state.source_depths.len();
    if depths != 0 && depths != views {
        return Err(TrainError::InvalidConfig(format!("state: {depths} source depths for {views} training views")));
    }
    match &state.exposure {
        Some(e) if !config.exposure || e.params.len() != views => Err(TrainError::InvalidConfig(format!(
            "state: {} exposure corrections for {views} training views (exposure {})",
            e.params.len(),
            if config.exposure { "on" } else { "off" }
        ))),
        None if config.exposure => Err(TrainError::InvalidConfig("state: exposure compensation is on but the state has none".into())),
        _ => Ok(()),
    }
}

impl<'s> Trainer<'s> {
    /// A fresh run: initial Gaussians from the scene (docs/method.md §Parameters), one optimiser group per
    /// [`crate::Param`], empty statistics. `train_views` index `scene.views`.
    pub fn new(scene: &'s Scene, train_views: Vec<usize>, config: TrainConfig) -> Result<Self> {
        config.validate()?;
        check_scene(scene, &train_views)?;
        let (gaussians, _) = initial_gaussians(scene, config.init, config.random_points, config.seed)?;
        if gaussians.len() > config.max_gaussians {
            return Err(TrainError::InvalidConfig(format!(
                "the initialisation has {} Gaussians, more than max_gaussians = {}",
                gaussians.len(),
                config.max_gaussians
            )));
        }
        let n = gaussians.len();
        let adam = crate::params::new_optimiser(&config.lr, n)?;
        let exposure = if config.exposure { Some(Exposure::new(train_views.len())?) } else { None };
        let budget = budget_of(scene, &train_views, &config, &gaussians);
        let source_depths = SourceDepths::default();
        let state = TrainState {
            iteration: 0,
            stats: DensifyStats::new(n),
            gaussians,
            adam,
            capped: false,
            exposure,
            source_depths,
            smoothing: None,
        };
        Self::assemble(scene, train_views, config, state, budget)
    }

    /// Continues from a checkpointed state (same scene, split and configuration).
    pub fn with_state(scene: &'s Scene, train_views: Vec<usize>, config: TrainConfig, state: TrainState) -> Result<Self> {
        config.validate()?;
        check_scene(scene, &train_views)?;
        // The budget depends only on the scene and the (deterministic) initialisation.
        let (init, _) = initial_gaussians(scene, config.init, config.random_points, config.seed)?;
        let budget = budget_of(scene, &train_views, &config, &init);
        Self::assemble(scene, train_views, config, state, budget)
    }

    /// The trainer around a checked configuration, scene and state.
    fn assemble(scene: &'s Scene, train_views: Vec<usize>, config: TrainConfig, mut state: TrainState, budget: Budget) -> Result<Self> {
        check_state(&config, &state, train_views.len())?;
        // A fresh run (or a checkpoint written with reuse off) starts with an empty memo.
        if config.source_depth_max_age > 0 && state.source_depths.is_empty() {
            state.source_depths = SourceDepths::new(train_views.len());
        }
        let cams = scene.cameras_of(&train_views);
        crate::smoothing::settle(&mut state, &cams, f64::from(config.near), config.smoothing_3d, false)?;
        let extent = scene.extent_of(&train_views).max(1e-9);
        let selector = SourceViewSelector::new(&cams, &NeighbourRule::default(), config.source_views, SourceSelection::RandomN)?;
        let test_views = (0..scene.views.len()).filter(|i| !train_views.contains(i)).collect();
        let smoothing = smoothing_on(&config, &state);
        Ok(Self {
            raster: config.raster_config(),
            executor: ReferenceExecutor::new(Rasterizer::new(Backend::Cpu)?, train_views.len(), TermsUsed::of(&config), smoothing),
            config,
            scene,
            train_views,
            train_cameras: cams,
            test_views,
            extent,
            selector,
            state,
            budget,
            profile: StepProfile::default(),
        })
    }

    /// The run's estimated peak memory ([`crate::training_memory`]), before training allocates its
    /// caches and grows the model.
    pub fn memory_estimate(&self) -> crate::training_memory::TrainMemoryEstimate {
        crate::training_memory::estimate(self.scene, &self.train_views, &self.config, &self.budget, self.state.gaussians.len())
    }

    /// The scene's Gaussian budget ([`crate::budget`]).
    pub fn budget(&self) -> &Budget {
        &self.budget
    }

    /// The configuration.
    pub fn config(&self) -> &TrainConfig {
        &self.config
    }

    /// The current state (parameters, optimiser, statistics), brought back from the device
    /// first where a resident model moved on there ([`StepExecutor::pull`]; the residency
    /// goes on). The host's copy is never handed out behind the device's.
    pub fn state(&mut self) -> Result<&TrainState> {
        self.executor.pull(&mut self.state)?;
        Ok(&self.state)
    }

    /// The current model, its parameters brought back from the device first where a resident
    /// model moved on there ([`StepExecutor::pull_parameters`]: not the moments, statistics
    /// and memo, which [`Trainer::state`] brings too).
    pub fn gaussians(&mut self) -> Result<&Gaussians> {
        self.executor.pull_parameters(&mut self.state)?;
        Ok(&self.state.gaussians)
    }

    /// Whether the Gaussian cap stopped growth at some point (kept on the host: no readback).
    pub fn capped(&self) -> bool {
        self.state.capped
    }

    /// The learned exposure corrections, with `exposure` on (optimised on the host: no readback).
    pub fn exposure(&self) -> Option<&Exposure> {
        self.state.exposure.as_ref()
    }

    /// How many Gaussians the model has (current without a readback: density control, on the
    /// device too, keeps the host's copy at the model's size).
    pub fn gaussian_count(&self) -> usize {
        self.state.gaussians.len()
    }

    /// The model's active SH degree (current without a readback, like the count).
    pub fn sh_degree(&self) -> u32 {
        self.state.gaussians.sh_degree
    }

    /// Whether the host's state holds the whole current model, so that [`Trainer::state`]
    /// needs no readback (always on the CPU).
    pub fn host_current(&self) -> bool {
        self.executor.host_current()
    }

    /// The current model with its scene, split and settings (for meshing, rendering and
    /// evaluating it), its parameters brought back from the device first (not the moments,
    /// statistics or memo that [`Trainer::state`] also brings).
    pub fn model(&mut self) -> Result<TrainedModel<'_>> {
        Ok(self.model_and_rasterizer()?.0)
    }

    /// The checkpoint of the current state ([`crate::checkpoint::encode`]), brought back from
    /// the device first.
    pub fn checkpoint(&mut self, elapsed: &crate::checkpoint::Elapsed) -> Result<Vec<u8>> {
        self.executor.pull(&mut self.state)?;
        Ok(crate::checkpoint::encode(&self.config, &self.state, elapsed))
    }

    /// Writes the checkpoint of the current state to `path` ([`crate::checkpoint::save`]),
    /// brought back from the device first.
    pub fn save_checkpoint(&mut self, path: &std::path::Path, elapsed: &crate::checkpoint::Elapsed) -> Result<()> {
        self.executor.pull(&mut self.state)?;
        crate::checkpoint::save(path, &self.config, &self.state, elapsed)
    }

    /// Iterations completed.
    pub fn iteration(&self) -> u64 {
        self.state.iteration
    }

    /// Scene extent r of the training cameras.
    pub fn extent(&self) -> f64 {
        self.extent
    }

    /// Switches the rasterizer backend (the CPU by default; `Auto` picks wgpu on a hardware
    /// GPU). On wgpu Adam runs on the device with the model resident there; whatever reads
    /// the model reads it back first ([`Trainer::state`]).
    pub fn set_backend(&mut self, backend: Backend) -> Result<()> {
        self.set_rasterizer(Rasterizer::new(backend)?)
    }

    /// Uses `rasterizer` from now on (see [`Trainer::set_backend`]); what the old one kept on
    /// its device comes back to the state first.
    pub fn set_rasterizer(&mut self, rasterizer: Rasterizer) -> Result<()> {
        let smoothing = smoothing_on(&self.config, &self.state);
        self.executor.set_rasterizer(rasterizer, TermsUsed::of(&self.config), smoothing, &mut self.state)
    }

    /// Where the loss terms run, in words (with the reason when the wgpu rasterizer's device
    /// could not take them).
    pub fn loss_executors(&self) -> String {
        self.executor.describe()
    }

    /// Where each part of an iteration runs ([`ReferenceExecutor::parts_on`]).
    pub fn parts_on(&self) -> Vec<crate::executor::PartPlace> {
        self.executor.parts_on()
    }

    /// The rasterizer in use.
    pub fn rasterizer(&self) -> &Rasterizer {
        self.executor.rasterizer()
    }

    /// The current model (brought back from the device) and the rasterizer, borrowed together.
    fn model_and_rasterizer(&mut self) -> Result<(TrainedModel<'_>, &mut Rasterizer)> {
        // The parameters alone: the moments, statistics and memo stay where they are.
        self.executor.pull_parameters(&mut self.state)?;
        let model = TrainedModel {
            scene: self.scene,
            train: &self.train_views,
            test: &self.test_views,
            raster: &self.raster,
            extent: self.extent,
            gaussians: &self.state.gaussians,
        };
        Ok((model, &mut self.executor.rasterizer))
    }

    /// [`crate::extract_mesh`] of the current model with this trainer's rasterizer.
    pub fn extract_mesh(&mut self, opts: &crate::MeshOptions) -> Result<(gs_core::TriangleMesh, crate::MeshReport)> {
        let (model, rasterizer) = self.model_and_rasterizer()?;
        crate::mesh::extract_mesh(&model, rasterizer, opts)
    }

    /// [`crate::evaluate_images`] of the current model on `views` (indices into the scene), on
    /// the whole images, with this trainer's rasterizer.
    pub fn evaluate_images(&mut self, views: &[usize], lpips: Option<&gs_losses::Lpips>) -> Result<crate::ImageMetrics> {
        let (model, rasterizer) = self.model_and_rasterizer()?;
        crate::evaluate::evaluate_images(&model, rasterizer, views, lpips, crate::PixelMasks::None)
    }

    /// The rasterizer settings used for training (and for rendering the result).
    pub fn raster_config(&self) -> &RasterConfig {
        &self.raster
    }

    /// Whether all iterations are done.
    pub fn finished(&self) -> bool {
        self.state.iteration >= self.config.iterations
    }

    /// Bytes held by the per-view caches (edge guides, grey images, feature maps, reused
    /// source-view depths).
    pub fn cache_bytes(&self) -> usize {
        self.executor.cache_bytes() + self.state.source_depths.bytes()
    }

    /// Supplies the grey GT images of L_p, one per training view in `train_views` order, at
    /// `config.ncc_scale` × the training resolution (required when that is above 1; with 1 the
    /// trainer derives them from the views itself).
    pub fn set_grey_images(&mut self, greys: Vec<Image>) -> Result<()> {
        if greys.len() != self.train_views.len() {
            return Err(TrainError::InvalidConfig(format!(
                "{} grey images for {} training views",
                greys.len(),
                self.train_views.len()
            )));
        }
        let s = self.config.ncc_scale as usize;
        for (g, &v) in greys.iter().zip(&self.train_views) {
            let view = &self.scene.views[v];
            let (w, h) = (view.camera.width as usize * s, view.camera.height as usize * s);
            if (g.width(), g.height(), g.channels()) != (w, h, 1) {
                return Err(TrainError::InvalidConfig(format!(
                    "grey image of {} is {}x{}x{}; ncc_scale {s} needs {w}x{h}x1",
                    view.name,
                    g.width(),
                    g.height(),
                    g.channels()
                )));
            }
        }
        self.executor.caches.set_greys(greys);
        Ok(())
    }

    /// The plan of the next iteration (pure: nothing changes until it is executed).
    pub fn plan(&self) -> StepPlan {
        plan_step(&self.config, &self.train_views, &self.selector, self.extent, self.state.iteration + 1)
    }

    /// One training iteration: plan it, set the SH degree, execute the plan, then refine.
    pub fn step(&mut self) -> Result<StepReport> {
        let mut whole = Clock::start();
        #[cfg(feature = "wgpu")]
        let traffic = self.executor.rasterizer().gpu_context().map(|c| c.transfers());
        let plan = self.plan();
        let run = RunInputs {
            config: &self.config,
            scene: self.scene,
            train_views: &self.train_views,
            extent: self.extent,
            raster: &self.raster,
            budget: &self.budget,
        };
        let degree = self.state.gaussians.sh_degree;
        if let Some(higher) = sh_policy::plain_rise(run.config, degree, plan.iteration) {
            // The SH rows widen where the model lives, the new bands at zero as on the host.
            self.executor.raise_sh_degree(&mut self.state, higher)?;
        } else if sh_policy::acts(run.config, degree, plan.iteration) {
            // A band judged: renders at two degrees and maybe its moments zeroed, on the host.
            self.executor.release(&mut self.state)?;
        }
        let (s, rasterizer) = (&mut self.state, &mut self.executor.rasterizer);
        let sh_band = sh_policy::update_sh_degree(run.config, &mut s.gaussians, &mut s.adam, plan.iteration, |g, degree| {
            sh_policy::judge_l1(g, degree, run.scene, run.train_views, rasterizer, run.raster)
        })?;
        let losses = self.executor.execute(&run, &mut self.state, &plan, &mut self.profile)?;
        let mut clock = Clock::start();
        let refined = self.executor.refine(&run, &mut self.state, &plan)?;
        let rows_changed = refined.densify.is_some() || refined.trimmed.is_some() || refined.floaters.is_some();
        let due = rows_changed || plan.iteration % crate::smoothing::RECOMPUTE_EVERY == 0;
        crate::smoothing::settle(&mut self.state, &self.train_cameras, f64::from(self.config.near), self.config.smoothing_3d, due)?;
        let phase = crate::checkpoint::Elapsed::phase_of(&self.config, plan.iteration);
        self.profile.add(phase, Part::Refine, clock.lap());
        self.state.iteration = plan.iteration;
        self.profile.finish_iteration(phase, whole.lap());
        #[cfg(feature = "wgpu")]
        if let (Some(before), Some(ctx)) = (traffic, self.executor.rasterizer().gpu_context()) {
            self.profile.add_transfers(phase, ctx.transfers() - before);
        }
        Ok(StepReport {
            iteration: plan.iteration,
            view: plan.view,
            phase: plan.phase,
            losses,
            gaussians: self.state.gaussians.len(),
            densify: refined.densify,
            trimmed: refined.trimmed,
            opacity_reset: refined.opacity_reset,
            floaters: refined.floaters,
            sh_band,
        })
    }

    /// Runs until `config.iterations`, calling `on_step` after every iteration; `on_step`
    /// returns `false` to stop early (e.g. on Ctrl-C, after which the caller checkpoints).
    pub fn run(&mut self, mut on_step: impl FnMut(&mut Self, &StepReport) -> bool) -> Result<()> {
        while !self.finished() {
            let r = self.step()?;
            if !on_step(self, &r) {
                break;
            }
        }
        Ok(())
    }

    /// Where this process's training time went, per phase and part of the iteration.
    pub fn profile(&self) -> &StepProfile {
        &self.profile
    }

    /// Consumes the trainer, returning its state (brought back from the device first).
    pub fn into_state(mut self) -> Result<TrainState> {
        self.executor.release(&mut self.state)?;
        Ok(self.state)
    }
}
