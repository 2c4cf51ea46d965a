//! `--backend auto` by measurement (docs/architecture.md §GPU): where a GPU is at hand, one
//! training step of the run at hand is timed on it and on the CPU, and the run uses the faster.
//! The step is the first that runs the multi-view terms (they set a run's pace), on a copy of
//! the run's initial state, each executor running it once to fill its caches and upload its
//! constants and then once timed; the copies are dropped, so the run itself is the run of the
//! chosen backend, byte for byte.

use super::{Trainer, smoothing_on};
use crate::devices::TermsUsed;
use crate::error::Result;
use crate::executor::{ReferenceExecutor, RunInputs, StepExecutor};
use crate::plan::plan_step;
use crate::profile::StepProfile;
use gs_raster::{Backend, Rasterizer};
use serde::Serialize;
use std::time::Instant;

/// How [`Trainer::choose_backend`] chose the rasterizer (report.json `backend_choice`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BackendChoice {
    /// The backend chosen: `cpu` or `wgpu`.
    pub chosen: String,
    /// Where it runs, in words.
    pub device: String,
    /// The step timed on each backend, where a GPU could run (none without one).
    pub probe: Option<BackendProbe>,
    /// Why the GPU was not timed although one is at hand (its step failed), in words.
    pub gpu_failed: Option<String>,
}

/// One training step timed on each backend by [`Trainer::choose_backend`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BackendProbe {
    /// The iteration whose plan was timed: the first with the multi-view terms, where the run
    /// has them.
    pub iteration: u64,
    /// Gaussians of the model it was timed on (the run's state when choosing).
    pub gaussians: usize,
    /// Its time on the CPU (ms), after a first run of it.
    pub cpu_ms: f64,
    /// Its time on the GPU (ms), after a first run of it.
    pub wgpu_ms: f64,
}

impl BackendChoice {
    /// The choice in one sentence.
    pub fn in_words(&self) -> String {
        match (&self.probe, &self.gpu_failed) {
            (None, Some(why)) => format!("{}: the step failed on the GPU ({why})", self.device),
            (None, None) => format!("{}: no GPU to compare with", self.device),
            (Some(p), _) => format!(
                "{}: the step of iteration {} on {} Gaussians took {:.1} ms on wgpu and {:.1} ms on the CPU",
                self.device, p.iteration, p.gaussians, p.wgpu_ms, p.cpu_ms
            ),
        }
    }
}

impl Trainer<'_> {
    /// Uses the faster of the CPU and the GPU for this run: where a wgpu adapter is at hand
    /// (a hardware one, or with `software` a CPU adapter such as lavapipe, which tests use),
    /// times one step on each ([`BackendProbe`]) and keeps the faster; without one, or where
    /// the GPU's step fails, the CPU. The run's state is not changed by the timing.
    pub fn choose_backend(&mut self, software: bool) -> Result<BackendChoice> {
        // The state as the current executor holds it (a resident model comes back first).
        self.executor.pull(&mut self.state)?;
        let Some(gpu) = gpu_rasterizer(software) else {
            return self.use_backend(Rasterizer::new(Backend::Cpu)?, None, None);
        };
        let iteration = self.probe_iteration();
        let cpu_ms = self.time_step(Rasterizer::new(Backend::Cpu)?, iteration)?;
        // A GPU whose step fails leaves the run to the CPU, and says why.
        let wgpu_ms = match self.time_step(gpu, iteration) {
            Ok(ms) => ms,
            Err(e) => return self.use_backend(Rasterizer::new(Backend::Cpu)?, None, Some(e.to_string())),
        };
        let probe = BackendProbe { iteration, gaussians: self.state.gaussians.len(), cpu_ms, wgpu_ms };
        let chosen = match (wgpu_ms < cpu_ms).then(|| gpu_rasterizer(software)).flatten() {
            Some(gpu) => gpu,
            None => Rasterizer::new(Backend::Cpu)?,
        };
        self.use_backend(chosen, Some(probe), None)
    }

    fn use_backend(&mut self, rasterizer: Rasterizer, probe: Option<BackendProbe>, gpu_failed: Option<String>) -> Result<BackendChoice> {
        let choice = BackendChoice { chosen: rasterizer.backend_name().into(), device: rasterizer.description(), probe, gpu_failed };
        self.set_rasterizer(rasterizer)?;
        Ok(choice)
    }

    /// The first iteration from here whose plan runs L_p or L_f, or the next one.
    fn probe_iteration(&self) -> u64 {
        let next = self.state.iteration + 1;
        if !self.config.losses.photometric && !self.config.has_feature_phase() {
            return next;
        }
        let first_mv = next.max(self.config.warmup_end + 1);
        let multiview = |it: &u64| {
            let plan = plan_step(&self.config, &self.train_views, &self.selector, self.extent, *it);
            plan.photometric.is_some() || plan.weights.lambda_f > 0.0
        };
        (first_mv..=self.config.iterations).find(multiview).unwrap_or(next)
    }

    /// Milliseconds of the step of `iteration` on `rasterizer`, run on a copy of the state
    /// after a first run of it; the device's work waited for.
    fn time_step(&self, rasterizer: Rasterizer, iteration: u64) -> Result<f64> {
        let smoothing = smoothing_on(&self.config, &self.state);
        let mut executor = ReferenceExecutor::new(rasterizer, self.train_views.len(), TermsUsed::of(&self.config), smoothing);
        executor.caches = self.executor.caches.greys_copy();
        let mut state = self.state.clone();
        let plan = plan_step(&self.config, &self.train_views, &self.selector, self.extent, iteration);
        let run = RunInputs { config: &self.config, scene: self.scene, train_views: &self.train_views, extent: self.extent, raster: &self.raster, budget: &self.budget };
        let mut profile = StepProfile::default();
        executor.execute(&run, &mut state, &plan, &mut profile)?;
        executor.finish_device_work()?;
        let t = Instant::now();
        executor.execute(&run, &mut state, &plan, &mut profile)?;
        executor.finish_device_work()?;
        Ok(t.elapsed().as_secs_f64() * 1e3)
    }
}

/// A wgpu rasterizer on a hardware adapter (or, with `software`, any), if one is at hand.
fn gpu_rasterizer(software: bool) -> Option<Rasterizer> {
    #[cfg(feature = "wgpu")]
    {
        let options = gs_raster::WgpuOptions { require_hardware: !software, ..Default::default() };
        Rasterizer::with_wgpu_options(options).ok()
    }
    #[cfg(not(feature = "wgpu"))]
    {
        let _ = software;
        None
    }
}
