//! The step plan: a pure function of the configuration, the split and the iteration that says
//! what one iteration does (docs/method.md §Schedule) — which view, which source views, which channels
//! to render, which loss terms with which weights, the means' learning rate, and which density
//! control runs after it. An executor carries it out ([`crate::Trainer::step`] on the CPU
//! reference path); the plan itself touches no state, so it can be inspected and tested alone.
//!
//! Determinism: every random choice of iteration `it` comes from `Rng::new(seed).fork(..)`
//! keyed by `it`, drawn here in a fixed order (view order per epoch; source views; L_p's pixel
//! sampling seed); the density control continues the same stream ([`StepPlan::refine_rng`]).

use crate::config::{Phase, TrainConfig};
use crate::config::LossWeights;
use crate::terms::{FeatureTerm, FlatnessTerm, ImageTerm, LossTerm, NormalTerms, OpacityTerm, PhotometricTerm};
use gs_core::{ExponentialLr, Rng};
use gs_losses::NormalLossConfig;
use gs_mvs::{PhotometricConfig, SourceViewSelector};
use gs_raster::RenderRequest;

/// RNG stream tags (xor-ed into the iteration) so the per-iteration draws are independent.
const STREAM_VIEW_ORDER: u64 = 1 << 40;
const STREAM_ITERATION: u64 = 2 << 40;

/// Which density control (docs/method.md §Densification) runs after the iteration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RefinePlan {
    /// Accumulate this view's screen-space gradients into the densification statistics.
    pub accumulate: bool,
    /// Clone / split / prune.
    pub densify: bool,
    /// Also prune Gaussians too large on screen or in the world.
    pub prune_big: bool,
    /// Reset the opacities.
    pub reset_opacity: bool,
    /// Multi-view trim.
    pub trim: bool,
    /// Free-space floater removal (before the opacity reset).
    pub remove_floaters: bool,
}

/// What iteration `iteration` does.
#[derive(Debug, Clone)]
pub struct StepPlan {
    /// 1-based iteration.
    pub iteration: u64,
    /// Training slot of the rendered view (index into the training views).
    pub slot: usize,
    /// Index of the rendered view in the scene.
    pub view: usize,
    /// Active terms.
    pub phase: Phase,
    /// Render at 1/scale of the training size (coarse-to-fine, colour warm-up only).
    pub scale: u32,
    /// Learning rate of the means this iteration.
    pub lr_means: f32,
    /// Training slots of the source views of L_p / L_f (empty when neither is on).
    pub sources: Vec<usize>,
    /// Channels to render.
    pub render: RenderRequest,
    /// Weights of the terms.
    pub weights: LossWeights,
    /// L_p's settings including its pixel-sampling seed (when L_p runs).
    pub photometric: Option<PhotometricConfig>,
    /// Density control after the step.
    pub refine: RefinePlan,
    /// The iteration's random stream after the step's draws, for the density control.
    pub refine_rng: Rng,
}

impl StepPlan {
    /// The loss terms to evaluate, in the order their gradients are accumulated.
    pub fn terms(&self, config: &TrainConfig) -> Vec<Box<dyn LossTerm>> {
        let p = &self.phase;
        let mut terms: Vec<Box<dyn LossTerm>> = vec![Box::new(ImageTerm { edge: p.edge })];
        if p.normal_consistency || p.normal_smoothing {
            terms.push(Box::new(NormalTerms {
                consistency: p.normal_consistency,
                smoothing: p.normal_smoothing,
                config: NormalLossConfig { tau: config.weights.tau, gate: config.ns_gate, ..NormalLossConfig::default() },
                with_alpha: self.render.alpha,
            }));
        }
        if let Some(pc) = &self.photometric {
            terms.push(Box::new(PhotometricTerm { config: pc.clone() }));
        }
        if p.features && !self.sources.is_empty() {
            terms.push(Box::new(FeatureTerm));
        }
        if self.weights.lambda_o > 0.0 {
            terms.push(Box::new(OpacityTerm));
        }
        if self.weights.lambda_s > 0.0 {
            terms.push(Box::new(FlatnessTerm));
        }
        terms
    }

    /// Whether the view's edge guide is needed.
    pub fn needs_guide(&self) -> bool {
        self.phase.needs_guide()
    }
}

/// Training slot of 1-based iteration `it`: a fresh seeded permutation of the `n` slots every
/// epoch, so every view is seen once per epoch.
pub fn view_slot(seed: u64, n: usize, it: u64) -> usize {
    let n = n as u64;
    let epoch = (it - 1) / n;
    let mut order: Vec<usize> = (0..n as usize).collect();
    Rng::new(seed).fork(STREAM_VIEW_ORDER ^ epoch).shuffle(&mut order);
    order[((it - 1) % n) as usize]
}

/// The plan of 1-based iteration `it` of a run over `train_views` with scene extent `extent`.
pub fn plan_step(config: &TrainConfig, train_views: &[usize], selector: &SourceViewSelector, extent: f64, it: u64) -> StepPlan {
    let mut rng = Rng::new(config.seed).fork(STREAM_ITERATION ^ it);
    let lr = &config.lr;
    let lr_means = if lr.position_init > 0.0 {
        ExponentialLr::new(lr.position_init * extent, lr.position_final * extent, config.iterations).at(it)
    } else {
        0.0
    };
    let slot = view_slot(config.seed, train_views.len(), it);
    let phase = config.phase(it);
    let multiview_now = it % config.multiview_interval == 0;
    let sources =
        if (phase.photometric || phase.features) && multiview_now { selector.select(slot, &mut rng) } else { Vec::new() };
    let photometric = (phase.photometric && !sources.is_empty()).then(|| PhotometricConfig {
        patch_size: config.patch_size,
        ncc: config.ncc,
        max_pixels_per_source: Some(config.max_pixels_per_source),
        seed: rng.next_u64(),
    });
    let geometry = phase.needs_geometry();
    let d = &config.densify;
    // Density control gathers its statistics up to `until`.
    let gathering = it <= d.until;
    let render = RenderRequest {
        color: true,
        alpha: phase.normal_consistency || phase.normal_smoothing,
        normal: geometry,
        distance: geometry,
        plane_depth: geometry,
        expected_depth: false,
        // Pixel-GS's weights ([`crate::densify::DensifyStats::accumulate`]).
        observed: d.pixel_weighted && gathering,
        // The host's statistics read them; a device step drops them (`executor`).
        radii: true,
        traversal: false,
        geometry_cut: 0.0,
        color_on_device: false,
        surface_on_device: false,
        plane_depth_on_device: false,
        observed_on_device: false,
    };
    let w = &config.weights;
    let weights = LossWeights {
        beta1: w.beta1,
        beta2: if phase.edge { w.beta2 } else { 0.0 },
        lambda_nc: if phase.normal_consistency { w.lambda_nc } else { 0.0 },
        lambda_ns: if phase.normal_smoothing { w.lambda_ns } else { 0.0 },
        lambda_p: if photometric.is_some() { w.lambda_p } else { 0.0 },
        lambda_f: if phase.features && !sources.is_empty() { w.lambda_f } else { 0.0 },
        tau: w.tau,
        lambda_o: if it > config.warmup_end { w.lambda_o } else { 0.0 },
        lambda_s: w.lambda_s,
    };
    let mut refine = if gathering {
        RefinePlan {
            accumulate: true,
            densify: it > d.from && it % d.interval == 0,
            prune_big: it > d.prune_big_after,
            reset_opacity: d.opacity_reset_interval > 0 && it % d.opacity_reset_interval == 0 && it < d.until,
            trim: d.trim_interval > 0 && it % d.trim_interval == 0,
            remove_floaters: false,
        }
    } else {
        RefinePlan::default()
    };
    // Floaters: with the trims once the surfaces have formed (after the colour warm-up), and
    // after the last iteration so the model handed out carries none.
    refine.remove_floaters = (d.floaters.enabled || d.floaters.capture_path) && ((refine.trim && it > config.warmup_end) || it == config.iterations);
    StepPlan {
        iteration: it,
        slot,
        view: train_views[slot],
        phase,
        scale: if geometry { 1 } else { config.coarse_to_fine.scale(it) },
        lr_means: lr_means as f32,
        sources,
        render,
        weights,
        photometric,
        refine,
        refine_rng: rng,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gs_core::NeighbourRule;
    use gs_mvs::SourceSelection;

    fn selector(n: usize) -> SourceViewSelector {
        let cams = gs_core::scene::camera_ring(n);
        let refs: Vec<&gs_core::Camera> = cams.iter().collect();
        SourceViewSelector::new(&refs, &NeighbourRule::default(), 3, SourceSelection::RandomN).unwrap()
    }

    #[test]
    fn the_plan_follows_the_phases_and_is_pure() {
        let c = TrainConfig::default().scaled(60);
        let (views, sel) = ((10..34).collect::<Vec<usize>>(), selector(24));
        let warm = plan_step(&c, &views, &sel, 2.0, 5);
        assert!(warm.sources.is_empty() && warm.photometric.is_none() && !warm.render.plane_depth);
        assert_eq!(warm.weights.lambda_nc, 0.0);
        assert_eq!(warm.terms(&c).len(), 1, "colour warm-up: L_I only");
        let mv = plan_step(&c, &views, &sel, 2.0, 30);
        assert!(mv.render.plane_depth && mv.render.alpha && mv.photometric.is_some() && !mv.sources.is_empty());
        assert_eq!((mv.weights.lambda_p, mv.weights.lambda_f), (c.weights.lambda_p, 0.0));
        assert_eq!(mv.terms(&c).len(), 3, "L_I, normal terms, L_p");
        let f = plan_step(&c, &views, &sel, 2.0, 55);
        assert!(f.photometric.is_none() && f.weights.lambda_f > 0.0 && !f.refine.accumulate);
        assert_eq!(f.view, views[f.slot]);
        // Pure: the same inputs give the same plan, to the seeds.
        let again = plan_step(&c, &views, &sel, 2.0, 30);
        assert_eq!((again.sources, again.photometric.map(|p| p.seed)), (mv.sources.clone(), mv.photometric.as_ref().map(|p| p.seed)));
        // Density control on its cadence.
        let d = &c.densify;
        let at = d.from + d.interval - (d.from % d.interval);
        assert!(plan_step(&c, &views, &sel, 2.0, at).refine.densify);
        assert!(!plan_step(&c, &views, &sel, 2.0, at + 1).refine.densify);
    }
}
