//! The VA-GS training loop (method-spec §3–§7): one [`Trainer::step`] renders a training view,
//! evaluates the losses of the current phase, back-propagates through the rasterizer, takes an
//! Adam step and runs the density control on schedule.
//!
//! Determinism: every random choice of iteration `it` comes from `Rng::new(seed).fork(..)`
//! keyed by `it` (view order per epoch, source views, L_p sampling, densification), so the
//! state to checkpoint is only the parameters, the optimiser and the statistics — and a
//! resumed run continues bit-identically.

use crate::config::{FeatureLayer, GateReading, NccReading, Phase, TrainConfig};
use crate::densify::{self, DensifyReport, DensifyStats, GROUPS};
use crate::error::{Result, TrainError};
use crate::exposure::Exposure;
use crate::init::initial_gaussians;
use gs_core::{Adam, AdamConfig, ExponentialLr, Gaussians, Image, NeighbourRule, Rng, Scene};
use gs_features::{FeatureMap, Vgg16};
use gs_losses::{EdgeGuide, ImageLossConfig, NormalLossConfig, NsGate, image_loss, normal_losses};
use gs_mvs::{
    FeatureReference, FeatureSource, NccMode, PhotometricConfig, PhotometricReference,
    PhotometricSource, SourceSelection, SourceViewSelector, feature_loss, photometric_loss,
};
use gs_raster::{Backend, OutputGradients, RasterConfig, Rasterizer, RenderRequest};
use serde::Serialize;

/// RNG stream tags (xor-ed into the iteration) so the per-iteration draws are independent.
const STREAM_VIEW_ORDER: u64 = 1 << 40;
const STREAM_ITERATION: u64 = 2 << 40;

/// Loss values of one iteration (unweighted terms; `None` when the term was off).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct LossValues {
    /// L1(Ĩ, I).
    pub l1: f64,
    /// SSIM(Ĩ, I).
    pub ssim: f64,
    /// L1(∇Ĩ, ∇I).
    pub edge: Option<f64>,
    /// L_nc.
    pub normal_consistency: Option<f64>,
    /// L_ns.
    pub normal_smoothing: Option<f64>,
    /// L_p (summed over sources).
    pub photometric: Option<f64>,
    /// L_f (averaged over sources).
    pub features: Option<f64>,
    /// The weighted total L.
    pub total: f64,
}

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
    /// The judgement of an SH band ([`crate::ShPolicy::Adaptive`]), when one was made.
    pub sh_band: Option<ShBandDecision>,
}

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

/// Training views rendered to judge an SH band (evenly spread over the training set).
const SH_JUDGE_VIEWS: usize = 8;

/// The training state that a checkpoint stores (everything else is derived from the scene
/// and the configuration).
#[derive(Debug, Clone, PartialEq)]
pub struct TrainState {
    /// Iterations completed.
    pub iteration: u64,
    /// The model.
    pub gaussians: Gaussians,
    /// Adam moments and steps.
    pub adam: Adam,
    /// Densification statistics since the last densification.
    pub stats: DensifyStats,
    /// Whether the Gaussian cap has been reached (warned once).
    pub capped: bool,
    /// Per-view exposure corrections (when `config.exposure`).
    pub exposure: Option<Exposure>,
}

/// The trainer: a scene, its split, the configuration and the [`TrainState`].
pub struct Trainer<'s> {
    config: TrainConfig,
    scene: &'s Scene,
    train_views: Vec<usize>,
    extent: f64,
    raster: RasterConfig,
    rasterizer: Rasterizer,
    selector: SourceViewSelector,
    state: TrainState,
    guides: Vec<Option<EdgeGuide>>,
    greys: Vec<Option<Image>>,
    vgg: Option<Vgg16>,
    features: Vec<Option<FeatureMap>>,
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

impl<'s> Trainer<'s> {
    /// A fresh run: initial Gaussians from the scene (method-spec §3), Adam groups, empty
    /// statistics. `train_views` index `scene.views`.
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
        let mut adam = Adam::new(AdamConfig::default());
        let lr = &config.lr;
        let n = gaussians.len();
        for ((name, width), rate) in GROUPS.iter().zip([0.0, lr.sh_dc, lr.sh_rest, lr.opacity, lr.scaling, lr.rotation]) {
            adam.add_group(name, rate, n, *width)?;
        }
        let exposure = if config.exposure { Some(Exposure::new(train_views.len())?) } else { None };
        let state = TrainState { iteration: 0, stats: DensifyStats::new(n), gaussians, adam, capped: false, exposure };
        Self::with_state(scene, train_views, config, state)
    }

    /// Continues from a checkpointed state (same scene, split and configuration).
    pub fn with_state(scene: &'s Scene, train_views: Vec<usize>, config: TrainConfig, state: TrainState) -> Result<Self> {
        config.validate()?;
        check_scene(scene, &train_views)?;
        state.gaussians.validate()?;
        let n = state.gaussians.len();
        if state.stats.len() != n || state.adam.groups.iter().any(|g| g.m.len() != n * g.row_width) {
            return Err(TrainError::InvalidConfig("state: statistics or optimiser rows do not match the Gaussians".into()));
        }
        match &state.exposure {
            Some(e) if !config.exposure || e.params.len() != train_views.len() => {
                return Err(TrainError::InvalidConfig(format!(
                    "state: {} exposure corrections for {} training views (exposure {})",
                    e.params.len(),
                    train_views.len(),
                    if config.exposure { "on" } else { "off" }
                )));
            }
            None if config.exposure => {
                return Err(TrainError::InvalidConfig("state: exposure compensation is on but the state has none".into()));
            }
            _ => {}
        }
        let cams: Vec<&gs_core::Camera> = train_views.iter().map(|&i| &scene.views[i].camera).collect();
        let extent = gs_core::scene_extent(&cams).max(1e-9);
        let selector = SourceViewSelector::new(&cams, &NeighbourRule::default(), config.source_views, SourceSelection::RandomN)?;
        let raster = config.raster_config();
        let k = train_views.len();
        Ok(Self {
            config,
            scene,
            train_views,
            extent,
            raster,
            rasterizer: Rasterizer::new(Backend::Cpu)?,
            selector,
            state,
            guides: (0..k).map(|_| None).collect(),
            greys: (0..k).map(|_| None).collect(),
            vgg: None,
            features: (0..k).map(|_| None).collect(),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &TrainConfig {
        &self.config
    }

    /// The current state (parameters, optimiser, statistics).
    pub fn state(&self) -> &TrainState {
        &self.state
    }

    /// The current model.
    pub fn gaussians(&self) -> &Gaussians {
        &self.state.gaussians
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
    /// GPU). Bit-identical resume holds for the CPU backend; wgpu's atomics make its gradient
    /// sums order-dependent.
    pub fn set_backend(&mut self, backend: Backend) -> Result<()> {
        self.set_rasterizer(Rasterizer::new(backend)?);
        Ok(())
    }

    /// Uses `rasterizer` from now on (see [`Trainer::set_backend`]).
    pub fn set_rasterizer(&mut self, rasterizer: Rasterizer) {
        self.rasterizer = rasterizer;
    }

    /// The rasterizer in use.
    pub fn rasterizer(&self) -> &Rasterizer {
        &self.rasterizer
    }

    /// The rasterizer in use, for rendering the result ([`crate::extract_mesh`] …).
    pub fn rasterizer_mut(&mut self) -> &mut Rasterizer {
        &mut self.rasterizer
    }

    /// [`crate::extract_mesh`] of the current model over `views` (indices into the scene) with
    /// this trainer's rasterizer and settings.
    pub fn extract_mesh(&mut self, views: &[usize], opts: &crate::MeshOptions) -> Result<(gs_core::TriangleMesh, crate::MeshReport)> {
        crate::output::extract_mesh(&self.state.gaussians, self.scene, views, &mut self.rasterizer, &self.raster, self.extent, opts)
    }

    /// [`crate::evaluate_images`] of the current model on `views` (indices into the scene), on
    /// the whole images.
    pub fn evaluate_images(&mut self, views: &[usize], lpips: Option<&gs_losses::Lpips>) -> Result<crate::ImageMetrics> {
        crate::output::evaluate_images(&self.state.gaussians, self.scene, views, &mut self.rasterizer, &self.raster, lpips, false)
    }

    /// The rasterizer settings used for training (and for rendering the result).
    pub fn raster_config(&self) -> &RasterConfig {
        &self.raster
    }

    /// Whether all iterations are done.
    pub fn finished(&self) -> bool {
        self.state.iteration >= self.config.iterations
    }

    /// Bytes held by the per-view caches (edge guides, grey images, feature maps).
    pub fn cache_bytes(&self) -> usize {
        let img = |i: &Image| i.data().len() * 4;
        self.guides.iter().flatten().map(|g| img(&g.gradient) + img(&g.delta)).sum::<usize>()
            + self.greys.iter().flatten().map(img).sum::<usize>()
            + self.features.iter().flatten().map(|f| f.memory_bytes()).sum::<usize>()
    }

    /// Training-view slot (index into `train_views`) of 1-based iteration `it`: a fresh
    /// seeded permutation every epoch, so every view is seen once per epoch.
    fn view_slot(&self, it: u64) -> usize {
        let n = self.train_views.len() as u64;
        let epoch = (it - 1) / n;
        let mut order: Vec<usize> = (0..n as usize).collect();
        Rng::new(self.config.seed).fork(STREAM_VIEW_ORDER ^ epoch).shuffle(&mut order);
        order[((it - 1) % n) as usize]
    }

    fn ensure_guide(&mut self, slot: usize) -> Result<()> {
        if self.guides[slot].is_none() {
            let v = &self.scene.views[self.train_views[slot]];
            let mut guide = EdgeGuide::from_gt(&v.image)?;
            if !self.config.losses.delta {
                // δ ≡ 1 inside, 0 on the border (where N̂ is undefined), for `--no-delta`.
                let (w, h) = (guide.delta.width(), guide.delta.height());
                for y in 0..h {
                    for x in 0..w {
                        let inside = x > 0 && y > 0 && x + 1 < w && y + 1 < h;
                        guide.delta.set(x, y, 0, if inside { 1.0 } else { 0.0 });
                    }
                }
            }
            self.guides[slot] = Some(guide);
        }
        Ok(())
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
        self.greys = greys.into_iter().map(Some).collect();
        Ok(())
    }

    fn ensure_grey(&mut self, slot: usize) -> Result<()> {
        if self.greys[slot].is_none() {
            if self.config.ncc_scale != 1 {
                return Err(TrainError::InvalidConfig(format!(
                    "ncc_scale = {} needs the high-resolution grey images (Trainer::set_grey_images)",
                    self.config.ncc_scale
                )));
            }
            self.greys[slot] = Some(self.scene.views[self.train_views[slot]].image.to_grey()?);
        }
        Ok(())
    }

    fn ensure_features(&mut self, slot: usize) -> Result<()> {
        if self.features[slot].is_none() {
            if self.vgg.is_none() {
                self.vgg = Some(Vgg16::bundled()?);
            }
            let level = match self.config.feature_layer {
                FeatureLayer::Conv2_2 => gs_features::FeatureLevel::Conv2_2,
                FeatureLayer::Conv3_3 => gs_features::FeatureLevel::Conv3_3,
            };
            let net = self.vgg.as_ref().expect("set above");
            self.features[slot] = Some(net.extract(&self.scene.views[self.train_views[slot]].image, level)?);
        }
        Ok(())
    }

    /// Renders the plane depth of training slot `slot` without gradients (source views).
    fn source_plane_depth(&mut self, slot: usize) -> Result<Image> {
        let req = RenderRequest { color: false, alpha: false, plane_depth: true, ..RenderRequest::default() };
        let out =
            self.rasterizer.render(&self.state.gaussians, &self.scene.views[self.train_views[slot]].camera, &req, &self.raster)?;
        Ok(out.plane_depth.expect("requested"))
    }

    /// One training iteration.
    pub fn step(&mut self) -> Result<StepReport> {
        let it = self.state.iteration + 1;
        let cfg = self.config.clone();
        let extent = self.extent as f32;
        let mut rng = Rng::new(cfg.seed).fork(STREAM_ITERATION ^ it);

        // Learning rate of the means and SH degree for this iteration.
        let lr_means = if cfg.lr.position_init > 0.0 {
            ExponentialLr::new(cfg.lr.position_init * self.extent, cfg.lr.position_final * self.extent, cfg.iterations).at(it)
        } else {
            0.0
        };
        self.state.adam.group_mut("means")?.lr = lr_means as f32;
        let sh_band = self.update_sh_degree(it)?;

        let slot = self.view_slot(it);
        let view_index = self.train_views[slot];
        let phase = cfg.phase(it);
        if phase.needs_guide() {
            self.ensure_guide(slot)?;
        }
        let sources: Vec<usize> =
            if phase.photometric || phase.features { self.selector.select(slot, &mut rng) } else { Vec::new() };
        if phase.photometric && !sources.is_empty() {
            self.ensure_grey(slot)?;
            for &s in &sources {
                self.ensure_grey(s)?;
            }
        }
        if phase.features && !sources.is_empty() {
            self.ensure_features(slot)?;
            for &s in &sources {
                self.ensure_features(s)?;
            }
        }

        let view = &self.scene.views[view_index];
        let camera = &view.camera;
        let geometry = phase.needs_geometry();
        let request = RenderRequest {
            color: true,
            alpha: phase.normal_consistency || phase.normal_smoothing,
            normal: geometry,
            distance: geometry,
            plane_depth: geometry,
            expected_depth: false,
            observed: false,
        };
        let out = self.rasterizer.render(&self.state.gaussians, camera, &request, &self.raster)?;
        // Exposure compensation: the loss sees exp(a)·c + b of this view.
        let corrected = match &self.state.exposure {
            Some(e) => Some(crate::exposure::apply(out.color.as_ref().expect("requested"), &e.params[slot])?),
            None => None,
        };
        let color = corrected.as_ref().or(out.color.as_ref()).expect("requested");
        let guide = self.guides[slot].as_ref();
        let li = image_loss(
            color,
            &view.image,
            guide,
            &ImageLossConfig { beta1: cfg.weights.beta1, beta2: cfg.weights.beta2, edge: phase.edge },
        )?;
        let mut losses =
            LossValues { l1: li.l1, ssim: li.ssim, edge: li.edge, total: li.total, ..Default::default() };

        let (mut grad_normal, mut grad_distance, mut grad_plane_depth): (Option<Image>, Option<Image>, Option<Image>) =
            (None, None, None);
        if phase.normal_consistency || phase.normal_smoothing {
            let nl = normal_losses(
                out.plane_depth.as_ref().expect("requested"),
                out.normal.as_ref().expect("requested"),
                out.alpha.as_ref(),
                guide.expect("ensured"),
                &camera.intrinsics,
                &NormalLossConfig {
                    lambda_nc: if phase.normal_consistency { cfg.weights.lambda_nc } else { 0.0 },
                    lambda_ns: if phase.normal_smoothing { cfg.weights.lambda_ns } else { 0.0 },
                    tau: cfg.weights.tau,
                    gate: match cfg.ns_gate {
                        GateReading::Above => NsGate::Above,
                        GateReading::Below => NsGate::Below,
                    },
                    ..NormalLossConfig::default()
                },
            )?;
            losses.normal_consistency = phase.normal_consistency.then_some(nl.l_nc);
            losses.normal_smoothing = phase.normal_smoothing.then_some(nl.l_ns);
            losses.total += nl.total;
            grad_normal = Some(nl.grad_normal);
            grad_plane_depth = Some(nl.grad_plane_depth);
        }

        let source_depths: Vec<Image> = if sources.is_empty() {
            Vec::new()
        } else {
            sources.iter().map(|&s| self.source_plane_depth(s)).collect::<Result<_>>()?
        };
        if phase.photometric && !sources.is_empty() {
            let reference = PhotometricReference {
                camera,
                normal: out.normal.as_ref().expect("requested").into(),
                distance: out.distance.as_ref().expect("requested").into(),
                plane_depth: out.plane_depth.as_ref().expect("requested").into(),
                grey: self.greys[slot].as_ref().expect("ensured").into(),
            };
            let srcs: Vec<PhotometricSource<f32>> = sources
                .iter()
                .zip(&source_depths)
                .map(|(&s, d)| PhotometricSource {
                    camera: &self.scene.views[self.train_views[s]].camera,
                    plane_depth: d.into(),
                    grey: self.greys[s].as_ref().expect("ensured").into(),
                })
                .collect();
            let pc = PhotometricConfig {
                patch_size: cfg.patch_size,
                ncc: match cfg.ncc {
                    NccReading::Pgsr => NccMode::Pgsr,
                    NccReading::Plain => NccMode::Plain,
                },
                max_pixels_per_source: Some(cfg.max_pixels_per_source),
                seed: rng.next_u64(),
            };
            let lp = photometric_loss(&reference, &srcs, &pc)?;
            losses.photometric = Some(lp.loss);
            losses.total += cfg.weights.lambda_p as f64 * lp.loss;
            let (gn, gd) = lp.grad_images();
            add_scaled(&mut grad_normal, &gn, cfg.weights.lambda_p);
            add_scaled(&mut grad_distance, &gd, cfg.weights.lambda_p);
        }
        if phase.features && !sources.is_empty() {
            let fr = self.features[slot].as_ref().expect("ensured");
            let fs: Vec<&FeatureMap> = sources.iter().map(|&s| self.features[s].as_ref().expect("ensured")).collect();
            let reference =
                FeatureReference { camera, plane_depth: out.plane_depth.as_ref().expect("requested").into(), features: fr };
            let srcs: Vec<FeatureSource<f32>> = sources
                .iter()
                .zip(&source_depths)
                .zip(&fs)
                .map(|((&s, d), f)| FeatureSource {
                    camera: &self.scene.views[self.train_views[s]].camera,
                    plane_depth: d.into(),
                    features: *f,
                })
                .collect();
            let lf = feature_loss(&reference, &srcs)?;
            losses.features = Some(lf.loss);
            losses.total += cfg.weights.lambda_f as f64 * lf.loss;
            let g = Image::from_vec(lf.width, lf.height, 1, lf.grad_plane_depth)?;
            add_scaled(&mut grad_plane_depth, &g, cfg.weights.lambda_f);
        }
        if !losses.total.is_finite() {
            return Err(TrainError::Diverged { iteration: it, problem: format!("loss is {:?}", losses) });
        }

        let grad_color = match &mut self.state.exposure {
            Some(e) => {
                let (gc, ge) = crate::exposure::backward(out.color.as_ref().expect("requested"), &e.params[slot], &li.grad_rendered)?;
                e.step(slot, &ge, it, cfg.iterations)?;
                gc
            }
            None => li.grad_rendered,
        };
        let grads = self.rasterizer.backward(
            &self.state.gaussians,
            camera,
            &self.raster,
            &out,
            &OutputGradients {
                color: Some(&grad_color),
                normal: grad_normal.as_ref(),
                distance: grad_distance.as_ref(),
                plane_depth: grad_plane_depth.as_ref(),
                ..Default::default()
            },
        )?;
        if it <= cfg.densify.until {
            self.state.stats.accumulate(&out.radii, &grads);
        }
        self.adam_step(&grads)?;
        drop(out);

        // Density control (method-spec §4).
        let d = cfg.densify;
        let mut report = StepReport {
            iteration: it,
            view: view_index,
            phase,
            losses,
            gaussians: 0,
            densify: None,
            trimmed: None,
            opacity_reset: false,
            sh_band,
        };
        if it <= d.until {
            if it > d.from && it % d.interval == 0 {
                let prune_big = it > d.prune_big_after;
                let r = densify::densify_and_prune(
                    &mut self.state.gaussians,
                    &mut self.state.adam,
                    &mut self.state.stats,
                    &d,
                    extent,
                    prune_big,
                    cfg.max_gaussians,
                    &mut rng,
                )?;
                self.state.capped |= r.capped;
                report.densify = Some(r);
            }
            if d.opacity_reset_interval > 0 && it % d.opacity_reset_interval == 0 && it < d.until {
                densify::reset_opacity(&mut self.state.gaussians, &mut self.state.adam)?;
                report.opacity_reset = true;
            }
            if d.trim_interval > 0 && it % d.trim_interval == 0 {
                let counts = self.views_observed()?;
                report.trimmed = Some(densify::trim_unobserved(
                    &mut self.state.gaussians,
                    &mut self.state.adam,
                    &mut self.state.stats,
                    &counts,
                    d.trim_min_views,
                )?);
            }
        }
        self.state.iteration = it;
        report.gaussians = self.state.gaussians.len();
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

    /// Sets the SH degree of iteration `it` from the schedule and, under
    /// [`crate::ShPolicy::Adaptive`], judges the newest band at a scheduled rise. The rule only
    /// reads the degree of the previous iteration (stored in checkpoints), so a resumed run
    /// takes the same decisions.
    fn update_sh_degree(&mut self, it: u64) -> Result<Option<ShBandDecision>> {
        let cfg = &self.config;
        let scheduled = cfg.sh_degree(it);
        let current = self.state.gaussians.sh_degree;
        let adaptive = cfg.sh_policy == crate::config::ShPolicy::Adaptive && cfg.sh_degree_interval > 0 && it > 1;
        if !adaptive || scheduled <= current {
            self.state.gaussians.sh_degree = scheduled;
            return Ok(None);
        }
        if scheduled > current + 1 || current == 0 {
            // Behind the schedule: an earlier band did not pay, the degree stays. Degree 0 → 1:
            // band 1 is always tried.
            if current == 0 && scheduled == 1 {
                self.state.gaussians.sh_degree = 1;
            }
            return Ok(None);
        }
        // A scheduled rise from `band` to `band + 1`: does band `band` pay on the training views?
        let band = current;
        let views: Vec<usize> = (0..SH_JUDGE_VIEWS.min(self.train_views.len()))
            .map(|k| self.train_views[k * self.train_views.len() / SH_JUDGE_VIEWS.min(self.train_views.len())])
            .collect();
        let req = RenderRequest { color: true, alpha: false, ..RenderRequest::default() };
        let mut l1 = [0.0f64; 2];
        for (slot, degree) in [band - 1, band].into_iter().enumerate() {
            self.state.gaussians.sh_degree = degree;
            for &v in &views {
                let view = &self.scene.views[v];
                let img = self.rasterizer.render(&self.state.gaussians, &view.camera, &req, &self.raster)?.color.expect("requested");
                let sum: f64 = img.data().iter().zip(view.image.data()).map(|(a, b)| (a - b).abs() as f64).sum();
                l1[slot] += sum / img.data().len() as f64 / views.len() as f64;
            }
        }
        let [l1_without, l1_with] = l1;
        let gain = if l1_without > 0.0 { (l1_without - l1_with) / l1_without } else { 0.0 };
        let kept = gain >= cfg.sh_min_gain as f64;
        let degree = if kept {
            band + 1
        } else {
            // Drop band `band`: zero its coefficients and moments so nothing drifts there.
            let coeffs = (band * band) as usize..((band + 1) * (band + 1)) as usize;
            for sh in &mut self.state.gaussians.sh {
                sh[coeffs.clone()].iter_mut().for_each(|c| *c = [0.0; 3]);
            }
            // sh_rest rows hold coefficients 1..16, three floats each.
            self.state.adam.zero_columns("sh_rest", (coeffs.start - 1) * 3..(coeffs.end - 1) * 3)?;
            band - 1
        };
        self.state.gaussians.sh_degree = degree;
        Ok(Some(ShBandDecision { band, l1_without, l1_with, gain, kept, degree }))
    }

    fn adam_step(&mut self, grads: &gs_raster::GaussianGradients) -> Result<()> {
        let g = &mut self.state.gaussians;
        let adam = &mut self.state.adam;
        check_finite(self.state.iteration + 1, "means", grads.means.as_flattened())?;
        adam.step("means", g.means.as_flattened_mut(), grads.means.as_flattened())?;
        // SH: DC and the rest are separate groups with their own learning rates, both updated in
        // place inside the 48-float SH records.
        let stride = 3 * gs_core::sh::SH_COEFFS;
        let (sh, sh_grads) = (g.sh.as_flattened_mut().as_flattened_mut(), grads.sh.as_flattened().as_flattened());
        adam.step_strided("sh_dc", sh, sh_grads, stride, 0)?;
        adam.step_strided("sh_rest", sh, sh_grads, stride, 3)?;
        adam.step("opacity", &mut g.opacity_logits, &grads.opacity_logits)?;
        adam.step("log_scales", g.log_scales.as_flattened_mut(), grads.log_scales.as_flattened())?;
        adam.step("rotations", g.rotations.as_flattened_mut(), grads.rotations.as_flattened())?;
        Ok(())
    }

    /// Runs until `config.iterations`, calling `on_step` after every iteration; `on_step`
    /// returns `false` to stop early (e.g. on Ctrl-C, after which the caller checkpoints).
    pub fn run(&mut self, mut on_step: impl FnMut(&Self, &StepReport) -> bool) -> Result<()> {
        while !self.finished() {
            let r = self.step()?;
            if !on_step(self, &r) {
                break;
            }
        }
        Ok(())
    }

    /// Consumes the trainer, returning its state.
    pub fn into_state(self) -> TrainState {
        self.state
    }
}

fn check_finite(iteration: u64, what: &str, v: &[f32]) -> Result<()> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(TrainError::Diverged { iteration, problem: format!("gradient of the {what} is not finite") })
    }
}

/// `acc += scale·g`, creating `acc` when absent.
fn add_scaled(acc: &mut Option<Image>, g: &Image, scale: f32) {
    match acc {
        Some(a) => {
            for (x, y) in a.data_mut().iter_mut().zip(g.data()) {
                *x += scale * y;
            }
        }
        None => {
            let mut a = g.clone();
            a.data_mut().iter_mut().for_each(|x| *x *= scale);
            *acc = Some(a);
        }
    }
}
