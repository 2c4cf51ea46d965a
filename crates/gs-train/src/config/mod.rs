//! Training configuration: presets, the phase schedule of docs/method.md §Schedule, learning rates (§Parameters),
//! densification (§Densification) and loss switches for ablations. Serialised to `OUT/config.json`.

use serde::{Deserialize, Serialize};

mod file;
mod overrides;
mod resolution;
mod summary;
mod validate;

pub use file::{SettingsFile, parse_settings_file};
pub use resolution::CoarseToFine;


/// Named settings for typical scenes (docs/method.md §Densification, §Schedule).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// The default: the paper's surface schedule reshaped for a CPU
    /// ([`TrainConfig::cpu_schedule`]): 1,600 iterations, the colour warm-up then edge + L_nc +
    /// L_ns + L_p to the end, with no L_f phase and no opacity reset, source-view depths
    /// reused up to [`CPU_SOURCE_DEPTH_MAX_AGE`] iterations old, the model bounded by the
    /// scene's Gaussian budget (as in every preset). Coarse-to-fine and a sparser L_p / L_f
    /// (`coarse_to_fine`, `multiview_interval`) stay off: measured, both cost held-out PSNR
    /// (BENCHMARKS.md, issue #18).
    #[default]
    Standard,
    /// Object-scale scenes (DTU): the paper's surface schedule, 20,000 iterations,
    /// absolute-gradient split threshold 8e-4.
    Dtu,
    /// Large scenes (Tanks and Temples): as `dtu` with the absolute-gradient threshold 1.5e-4.
    Tnt,
    /// Novel-view synthesis (Mip-NeRF 360): the 20,000-iteration surface schedule, then 10,000
    /// more with L_I and the normal terms; absolute-gradient threshold 2e-4.
    Mip360,
    /// A quick look: `standard`'s schedule in [`FAST_ITERATIONS`] instead of
    /// [`STANDARD_ITERATIONS`], with 2 source views (L_p a fifth cheaper); its accuracy cost
    /// is measured in BENCHMARKS.md (issue #18).
    Fast,
}

gs_core::named_choices!(Preset, "preset", {
    Preset::Fast => "fast",
    Preset::Standard => "standard",
    Preset::Dtu => "dtu",
    Preset::Tnt => "tnt",
    Preset::Mip360 => "mip360",
});

/// Which initial Gaussians (docs/method.md §Parameters).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum InitMode {
    /// The sparse SfM points (falls back to `sphere` when the scene has none).
    #[default]
    Points,
    /// Uniform random points in the cameras' bounding cube.
    Cube,
    /// Random points on a sphere enclosing the scene.
    Sphere,
}

gs_core::named_choices!(InitMode, "initialisation", {
    InitMode::Points => "points",
    InitMode::Cube => "cube",
    InitMode::Sphere => "sphere",
});

/// On/off switches of the loss terms, for ablations (`--no-edge` …).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct LossSwitches {
    /// Edge term β2·L1(∇Ĩ, ∇I) of L_I.
    pub edge: bool,
    /// Normal consistency L_nc.
    pub normal_consistency: bool,
    /// Normal smoothing L_ns.
    pub normal_smoothing: bool,
    /// Multi-view photometric alignment L_p.
    pub photometric: bool,
    /// Multi-view feature alignment L_f.
    pub features: bool,
    /// The edge weight δ = (1 − ∇I)²; off = δ ≡ 1 in L_nc and L_ns.
    pub delta: bool,
}

impl Default for LossSwitches {
    fn default() -> Self {
        Self { edge: true, normal_consistency: true, normal_smoothing: true, photometric: true, features: true, delta: true }
    }
}

impl LossSwitches {
    /// The geometry terms that run after the warm-up to the last iteration, by name
    /// ([`term_name`](crate::terms::term_name)).
    pub fn geometry_terms(&self) -> [(&'static str, bool); 3] {
        use crate::terms::term_name as n;
        [(n::EDGE, self.edge), (n::NORMAL_CONSISTENCY, self.normal_consistency), (n::NORMAL_SMOOTHING, self.normal_smoothing)]
    }

    /// Every switch by name, in the order of L, δ last.
    pub fn named(&self) -> [(&'static str, bool); 6] {
        use crate::terms::term_name as n;
        let [edge, nc, ns] = self.geometry_terms();
        [edge, nc, ns, (n::PHOTOMETRIC, self.photometric), (n::FEATURES, self.features), (n::DELTA, self.delta)]
    }

    /// Only L_I's L1 + D-SSIM (≈ 3DGS).
    pub fn image_only() -> Self {
        Self { edge: false, normal_consistency: false, normal_smoothing: false, photometric: false, features: false, delta: true }
    }
}

/// λ3 of the paper: weight of L_p.
pub const LAMBDA_P: f32 = 0.15;
/// λ4 of the paper: weight of L_f.
pub const LAMBDA_F: f32 = 1.0;

/// Loss weights (docs/method.md §Losses); the defaults are the paper's, owned by the loss crates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LossWeights {
    /// β1, D-SSIM weight in L_I.
    pub beta1: f32,
    /// β2, edge-term weight in L_I.
    pub beta2: f32,
    /// λ1, L_nc.
    pub lambda_nc: f32,
    /// λ2, L_ns.
    pub lambda_ns: f32,
    /// λ3, L_p.
    pub lambda_p: f32,
    /// λ4, L_f.
    pub lambda_f: f32,
    /// τ of L_ns.
    pub tau: f32,
    /// λ_o, L_o (the opacity entropy; from the end of the colour warm-up on).
    #[serde(default)]
    pub lambda_o: f32,
    /// λ_s, L_s (PGSR's flattening term, the mean smallest scale; the whole run).
    #[serde(default)]
    pub lambda_s: f32,
}

impl Default for LossWeights {
    fn default() -> Self {
        use gs_losses::{image_loss, normal_loss};
        Self {
            beta1: image_loss::BETA1,
            beta2: image_loss::BETA2,
            lambda_nc: normal_loss::LAMBDA_NC,
            lambda_ns: normal_loss::LAMBDA_NS,
            lambda_p: LAMBDA_P,
            lambda_f: LAMBDA_F,
            tau: normal_loss::TAU,
            lambda_o: gs_losses::opacity::LAMBDA_O,
            lambda_s: gs_losses::flatness::LAMBDA_S,
        }
    }
}

/// Adam learning rates (docs/method.md §Parameters); positions are multiples of the scene extent r.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LearningRates {
    /// Means, at iteration 0, times r.
    pub position_init: f64,
    /// Means, at the last iteration, times r (log-linear decay).
    pub position_final: f64,
    /// SH DC.
    pub sh_dc: f32,
    /// SH degrees 1–3.
    pub sh_rest: f32,
    /// Opacity logits.
    pub opacity: f32,
    /// Log-scales.
    pub scaling: f32,
    /// Quaternions.
    pub rotation: f32,
}

impl Default for LearningRates {
    fn default() -> Self {
        Self { position_init: 1.6e-4, position_final: 1.6e-6, sh_dc: 2.5e-3, sh_rest: 1.25e-4, opacity: 0.05, scaling: 5e-3, rotation: 1e-3 }
    }
}

/// Densification and pruning (docs/method.md §Densification, PGSR defaults). Iteration values are those of
/// the 20,000-iteration schedule; [`TrainConfig::scaled`] rescales them.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DensifyConfig {
    /// First iteration that densifies.
    pub from: u64,
    /// Densification, opacity reset and trim stop here.
    pub until: u64,
    /// Densify every this many iterations.
    pub interval: u64,
    /// Mean screen-space gradient threshold for clone and split.
    pub grad_threshold: f32,
    /// Absolute-gradient (AbsGS) split threshold.
    pub abs_grad_threshold: f32,
    /// Clone if max scale ≤ percent_dense·r, else split.
    pub percent_dense: f32,
    /// At most this many absolute-gradient splits per step.
    pub max_abs_splits: usize,
    /// Prune below this opacity.
    pub min_opacity: f32,
    /// From this iteration on also prune by screen size / world size.
    pub prune_big_after: u64,
    /// Screen radius (px) above which a Gaussian is pruned (and abs-split candidates must exceed).
    pub max_screen_radius: f32,
    /// World size above which a Gaussian is pruned, times r.
    pub max_world_scale: f32,
    /// Opacity reset every this many iterations (0 = never).
    pub opacity_reset_interval: u64,
    /// Multi-view trim every this many iterations (0 = never).
    pub trim_interval: u64,
    /// Gaussians observed in fewer views than this are trimmed.
    pub trim_min_views: u32,
    /// ρ of the scene's budget B = ρ · training pixels ÷ views per surface point
    /// ([`crate::budget`]); 0 = no budget (the thresholds and `max_gaussians` alone).
    #[serde(default = "default_gaussians_per_surface_pixel")]
    pub gaussians_per_surface_pixel: f32,
    /// Growth reaches the budget after this fraction of [from, until] (Taming 3DGS' schedule).
    #[serde(default = "default_growth_window")]
    pub growth_window: f32,
    /// Free-space floater removal ([`crate::floaters`]), run with the multi-view trims of the
    /// geometry phases and after the last iteration.
    #[serde(default)]
    pub floaters: crate::floaters::FloaterRule,
    /// Where Gaussians may grow (a block of a partitioned run, [`crate::region`]); `null`:
    /// everywhere.
    #[serde(default)]
    pub region: Option<crate::region::GrowthRegion>,
    /// Pixel-GS's statistics: each view's screen-space gradient counts in proportion to the
    /// pixels where the Gaussian is seen in front (transmittance above ½) instead of once per
    /// view, so that a large Gaussian is judged by the views it covers, not diluted by those
    /// that graze it (docs/method.md §Densification). Off by default.
    #[serde(default)]
    pub pixel_weighted: bool,
}

fn default_gaussians_per_surface_pixel() -> f32 {
    1.0
}

fn default_growth_window() -> f32 {
    0.6
}

impl Default for DensifyConfig {
    fn default() -> Self {
        Self {
            from: 500,
            until: 15_000,
            interval: 100,
            grad_threshold: 2e-4,
            abs_grad_threshold: 8e-4,
            percent_dense: 0.001,
            max_abs_splits: 50_000,
            min_opacity: 0.005,
            prune_big_after: 3000,
            max_screen_radius: 20.0,
            max_world_scale: 0.1,
            opacity_reset_interval: 3000,
            trim_interval: 1000,
            trim_min_views: 2,
            gaussians_per_surface_pixel: default_gaussians_per_surface_pixel(),
            growth_window: default_growth_window(),
            floaters: crate::floaters::FloaterRule::default(),
            region: None,
            pixel_weighted: false,
        }
    }
}

/// Everything that determines a training run. Same config + scene + seed + thread count →
/// bit-identical parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainConfig {
    /// The preset the values started from.
    pub preset: Preset,
    /// Total iterations.
    pub iterations: u64,
    /// Colour-only warm-up ends here (edge, L_nc, L_ns, L_p start).
    pub warmup_end: u64,
    /// L_p is on from `warmup_end` to here; L_f from here to `features_end`.
    pub photometric_end: u64,
    /// L_f ends here (= `iterations` except for mip360).
    pub features_end: u64,
    /// Keep L_p on during the L_f phase (`--overlap-mv`).
    pub overlap_mv: bool,
    /// Seed of every random choice.
    pub seed: u64,
    /// Loss switches.
    pub losses: LossSwitches,
    /// Loss weights.
    pub weights: LossWeights,
    /// L_ns gate reading.
    pub ns_gate: gs_losses::NsGate,
    /// NCC reading of L_p.
    pub ncc: gs_mvs::NccMode,
    /// Source views N per iteration.
    pub source_views: usize,
    /// NCC patch side (odd, 3–9).
    pub patch_size: usize,
    /// Per-view exposure compensation (affine colour correction learned per training view,
    /// see [`crate::exposure`]); off by default.
    #[serde(default)]
    pub exposure: bool,
    /// Grey images of L_p at this integer multiple (1–4) of the training resolution (PGSR's
    /// `ncc_scale` = 1/this): finer texture for the NCC at the same render cost. Above 1 the
    /// caller supplies them ([`crate::Trainer::set_grey_images`]); `vagsl train --ncc-scale`.
    #[serde(default = "one_u32")]
    pub ncc_scale: u32,
    /// L_p pixel cap per source.
    pub max_pixels_per_source: usize,
    /// VGG16 level of F.
    pub feature_layer: gs_features::FeatureLevel,
    /// Learning rates.
    pub lr: LearningRates,
    /// Highest SH degree.
    pub sh_degree_max: u32,
    /// The SH degree rises by one every this many iterations.
    pub sh_degree_interval: u64,
    /// When the SH degree rises: on the paper's schedule, or only while the last band paid.
    #[serde(default)]
    pub sh_policy: ShPolicy,
    /// [`ShPolicy::Adaptive`]: the smallest relative drop of the training views' L1 that band d
    /// must give (L1 at degree d−1 vs d) for band d+1 to be tried.
    #[serde(default = "default_sh_min_gain")]
    pub sh_min_gain: f32,
    /// Densification and pruning.
    pub densify: DensifyConfig,
    /// Hard cap on the number of Gaussians; densification stops there with a warning.
    pub max_gaussians: usize,
    /// Initialisation.
    pub init: InitMode,
    /// Number of random initial points (cube/sphere init).
    pub random_points: usize,
    /// Background colour of the renders.
    pub background: [f32; 3],
    /// Near plane of the rasterizer.
    pub near: f32,
    /// Mip-Splatting's opacity compensation √(det Σ / det Σ') for the screen-space low-pass
    /// filter, in every render of the run (docs/method.md §Projection): on in the CPU presets
    /// (`standard`, `fast`), off in the paper's. A config.json without it predates the
    /// setting and was trained without.
    #[serde(default)]
    pub antialiased: bool,
    /// The screen-space low-pass filter of every render of the run (px²; docs/method.md
    /// §Projection): [`CPU_LOW_PASS`] in the CPU presets, 3DGS' 0.3 in the paper's and in a
    /// config.json written before the setting existed.
    #[serde(default = "default_low_pass")]
    pub low_pass: f32,
    /// Mip-Splatting's 3D smoothing filter ([`crate::smoothing`], docs/method.md §3D
    /// smoothing): each Gaussian is widened by the variance k·(z/f)² of the finest sampling
    /// interval z/f any training view has of it, with k this value (Mip-Splatting's 0.2); 0 is
    /// off, as in every preset and in a config.json written before the setting existed.
    #[serde(default)]
    pub smoothing_3d: f32,
    /// Render resolution of the colour warm-up (coarse-to-fine); off = full size throughout.
    #[serde(default)]
    pub coarse_to_fine: CoarseToFine,
    /// L_p and L_f run on every this-many-th iteration of their phases (1 = every iteration,
    /// the paper); the other iterations skip the source views.
    #[serde(default = "one_u64")]
    pub multiview_interval: u64,
    /// L_p and L_f take a source view's plane depth (visibility only, no gradient) from its last
    /// render while it is at most this many iterations old, instead of rendering it again
    /// ([`crate::source_depths`]); 0 renders every source every iteration (the paper).
    #[serde(default)]
    pub source_depth_max_age: u64,
    /// L_p and L_f render a source view's plane depth (visibility only, no gradient) at
    /// 1/this of its size and upsample it bilinearly ([`crate::source_depths::upsample_depth`]);
    /// 1 renders it at full size (the paper), as every preset does: 2 made the default's L_p
    /// phase 16 % faster on synth-bunny at full resolution but its mesh much worse (Chamfer
    /// 0.0070 → 0.0105, BENCHMARKS.md issue #18, stop 30).
    #[serde(default = "one_u32")]
    pub source_depth_downscale: u32,
}

fn one_u64() -> u64 {
    1
}

fn one_u32() -> u32 {
    1
}

fn default_low_pass() -> f32 {
    gs_raster::LOW_PASS
}

fn default_sh_min_gain() -> f32 {
    0.01
}

/// How the SH degree rises ("model only what a scene requires").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum ShPolicy {
    /// The paper's schedule: one band more every `sh_degree_interval` iterations up to
    /// `sh_degree_max`.
    #[default]
    Schedule,
    /// On the same schedule, but at each rise the newest band d is first judged: the training
    /// views are rendered at degree d and d−1, and unless band d lowers their L1 by at least
    /// `sh_min_gain` (relative), band d is dropped (its coefficients and moments zeroed) and the
    /// degree stays at d−1 for the rest of the run. Band 1 is always tried; the last band
    /// reached is kept.
    Adaptive,
}

gs_core::named_choices!(ShPolicy, "SH policy", { ShPolicy::Schedule => "schedule", ShPolicy::Adaptive => "adaptive" });

/// The `dtu` preset: the paper's schedule, which library users and the conformance tests start
/// from. The CLI's default is [`Preset::default`] (`standard`).
impl Default for TrainConfig {
    fn default() -> Self {
        Self::preset(Preset::Dtu)
    }
}


/// Iterations of the `standard` preset. On synth-bunny at full resolution (2 threads) 1,600
/// gave the mesh of 2,000 (Chamfer 0.00703 / F1 0.928 against 0.00700 / 0.930) and a better
/// held-out PSNR (26.20 against 25.69 dB) in 15.5 instead of 20.8 minutes: growth stops at
/// 1,200, residual-bound, and the last quarter of the run settles it; 1,500 gave the same mesh
/// but 24.13 dB (BENCHMARKS.md, issue #18).
pub const STANDARD_ITERATIONS: u64 = 1_600;
/// Iterations of the `fast` preset (with 2 source views instead of [`CPU_SOURCE_VIEWS`]).
pub const FAST_ITERATIONS: u64 = 1_200;
/// Oldest reused source-view depth of the CPU presets, in iterations (0: every source is
/// rendered, as in the paper). On synth-bunny at full resolution (BENCHMARKS.md issue #18,
/// stop 31) 10 kept the default's mesh and held-out PSNR (Chamfer 0.00701 / F1 0.926 /
/// 26.05 dB against 0.00703 / 0.928 / 26.20 dB) with the L_p phase 0.79× the time (12.0
/// against 14.8 minutes in all, 2 threads); 20 let the mesh drift off the surface in the last
/// 300 iterations (Chamfer 0.0117), and 100 made it worse while the surface still moves
/// (stop 27).
pub const CPU_SOURCE_DEPTH_MAX_AGE: u64 = 10;

/// Screen-space low-pass filter of the CPU presets (px², with `antialiased` opacity
/// compensation; the paper presets keep 3DGS' [`gs_raster::LOW_PASS`] without it). On the
/// nine quick suite scenes (BENCHMARKS.md §Validation suite, issue #33, stops 44–45) it raised
/// F1 ÷ floor on every scene (mean 0.648 → 0.690, worst 0.329 → 0.500), mean × floor 2.05 →
/// 2.02, held-out PSNR 25.26 → 25.47 dB and the worst view 18.65 → 19.09 dB at the same
/// training time; the one scene it left worse (window, 2.94 → 2.98×) it left better with
/// another training seed (3.01 → 2.92×). synth-bunny: Chamfer 0.00694 → 0.00692, 26.36 →
/// 26.69 dB.
pub const CPU_LOW_PASS: f32 = 0.1;

/// L_p source views per iteration in the paper's presets (N, docs/method.md §Losses).
pub const PAPER_SOURCE_VIEWS: usize = 3;
/// L_p source views per iteration of the CPU presets (the paper's N is [`PAPER_SOURCE_VIEWS`]). A view whose
/// concavity only its own ring of cameras sees has 2–3 such sources among its 4–8
/// candidates, and a random 3 of them often miss it; 5 draws every candidate of most views.
/// On the nine full-size suite scenes (docs/suite-full.md, stop 48), with
/// [`CPU_MAX_PIXELS_PER_SOURCE`] keeping L_p's patches per iteration: every mesh as close to
/// its floor or closer (mean 1.52 → 1.46×, worst 2.31 → 2.28×, cup 2.00 → 1.71×), held-out
/// PSNR 27.05 → 27.16 dB and the worst view 19.00 → 19.62 dB, at the same iteration cost
/// within what the loads could tell.
pub const CPU_SOURCE_VIEWS: usize = 5;
/// Weight of L_p in the `standard` preset (the paper's λ3 is [`LAMBDA_P`]). The CPU schedule
/// gives L_p 1,040 iterations where the paper gives it tens of thousands, and at the paper's
/// weight the surfaces that few views see, or that curve more tightly than a Gaussian's extent
/// (a spring's tube, a cup's inner wall), stay where the silhouettes put them. On the nine
/// full-size suite scenes (docs/suite-full.md, stop 51) twice the weight brought the worst
/// mesh from 2.28× to 1.95× its floor and the cup's from 1.71× to 1.34×. `fast` keeps the
/// paper's weight (not measured).
pub const STANDARD_LAMBDA_P: f32 = 0.3;
/// L_p pixel cap per source of the CPU presets: the paper's patches per iteration
/// ([`PAPER_SOURCE_VIEWS`] × [`gs_mvs::DEFAULT_MAX_PIXELS_PER_SOURCE`]) spread over [`CPU_SOURCE_VIEWS`], so that
/// five sources cost about what three did (+6 % per L_p iteration on the cup, against +34 %
/// uncapped).
pub const CPU_MAX_PIXELS_PER_SOURCE: usize = PAPER_SOURCE_VIEWS * gs_mvs::DEFAULT_MAX_PIXELS_PER_SOURCE / CPU_SOURCE_VIEWS;

/// Fewest iterations between two densification steps of a scaled schedule: a step judges the
/// gradients accumulated since the last one, and fewer than this many iterations give noisy
/// means that clone and split most of the model every step (a 20-iteration run once grew
/// 12k Gaussians to 576k).
pub const MIN_DENSIFY_INTERVAL: u64 = 25;

impl TrainConfig {
    /// The values of a preset.
    pub fn preset(preset: Preset) -> Self {
        let base = Self {
            preset,
            iterations: 20_000,
            warmup_end: 7_000,
            photometric_end: 15_000,
            features_end: 20_000,
            overlap_mv: false,
            seed: 0,
            losses: LossSwitches::default(),
            weights: LossWeights::default(),
            ns_gate: gs_losses::NsGate::Above,
            ncc: gs_mvs::NccMode::Pgsr,
            source_views: PAPER_SOURCE_VIEWS,
            patch_size: 7,
            ncc_scale: 1,
            exposure: false,
            max_pixels_per_source: gs_mvs::DEFAULT_MAX_PIXELS_PER_SOURCE,
            feature_layer: gs_features::FeatureLevel::Conv2_2,
            lr: LearningRates::default(),
            sh_degree_max: 3,
            sh_degree_interval: 1000,
            sh_policy: ShPolicy::Schedule,
            sh_min_gain: default_sh_min_gain(),
            densify: DensifyConfig::default(),
            max_gaussians: 3_000_000,
            init: InitMode::Points,
            random_points: 100_000,
            background: [0.0; 3],
            near: 0.01,
            antialiased: false,
            low_pass: default_low_pass(),
            smoothing_3d: 0.0,
            coarse_to_fine: CoarseToFine::default(),
            multiview_interval: 1,
            source_depth_max_age: 0,
            source_depth_downscale: 1,
        };
        match preset {
            Preset::Dtu => base,
            Preset::Tnt => Self { densify: DensifyConfig { abs_grad_threshold: 1.5e-4, ..base.densify }, ..base },
            Preset::Mip360 => Self {
                iterations: 30_000,
                densify: DensifyConfig { abs_grad_threshold: 2e-4, ..base.densify },
                ..base
            },
            Preset::Standard => Self {
                weights: LossWeights { lambda_p: STANDARD_LAMBDA_P, ..base.weights },
                ..base.cpu_schedule()
            }
            .scaled(STANDARD_ITERATIONS),
            Preset::Fast => Self {
                source_views: 2,
                max_pixels_per_source: gs_mvs::DEFAULT_MAX_PIXELS_PER_SOURCE,
                ..base.cpu_schedule()
            }
            .scaled(FAST_ITERATIONS),
        }
    }

    /// The paper's surface schedule reshaped for short CPU runs, as measured on synth-bunny at
    /// full resolution with `train --track-gt` (BENCHMARKS.md, issue #18): the mesh is made by
    /// L_p, so after the colour warm-up L_p runs to the last iteration (L_f, which left the
    /// mesh no better at full resolution and worse at half, has no phase); no opacity reset
    /// (each one made the model transparent and cost hundreds of iterations of recovery); and
    /// source-view depths reused up to [`CPU_SOURCE_DEPTH_MAX_AGE`] iterations old; and
    /// Mip-Splatting's screen filter ([`CPU_LOW_PASS`] px² with opacity compensation), which
    /// pulls convex surfaces in less at the silhouettes (docs/method.md §Projection); and
    /// [`CPU_SOURCE_VIEWS`] L_p sources at [`CPU_MAX_PIXELS_PER_SOURCE`] pixels each, which
    /// reach concavities that few views see (docs/method.md §Schedule).
    /// Phase boundaries scale with [`TrainConfig::scaled`] as before.
    pub fn cpu_schedule(&self) -> Self {
        Self {
            photometric_end: self.iterations,
            features_end: self.iterations,
            source_depth_max_age: CPU_SOURCE_DEPTH_MAX_AGE,
            antialiased: true,
            low_pass: CPU_LOW_PASS,
            source_views: CPU_SOURCE_VIEWS,
            max_pixels_per_source: CPU_MAX_PIXELS_PER_SOURCE,
            densify: DensifyConfig { opacity_reset_interval: 0, ..self.densify },
            ..self.clone()
        }
    }

    /// The same schedule with `iterations` total: the phase boundaries (warm-up, L_p, L_f, end
    /// of densification, large-Gaussian pruning) and the SH, opacity-reset and trim intervals
    /// scale by `iterations / self.iterations`. The densification cadence does not: new
    /// Gaussians need about a hundred iterations to settle before the next step judges them,
    /// so densification starts at `from` and runs every `interval` iterations whatever the
    /// length (both capped to fit the run, the interval never below
    /// [`MIN_DENSIFY_INTERVAL`]), and opacity resets / trims are at least 1000 / 200 iterations
    /// apart.
    pub fn scaled(&self, iterations: u64) -> Self {
        let f = iterations as f64 / self.iterations.max(1) as f64;
        let s = |v: u64| (v as f64 * f).round() as u64;
        let si = |v: u64, min: u64| if v == 0 { 0 } else { s(v).max(min) };
        let until = s(self.densify.until);
        Self {
            iterations,
            warmup_end: s(self.warmup_end),
            photometric_end: s(self.photometric_end),
            features_end: s(self.features_end),
            sh_degree_interval: si(self.sh_degree_interval, 1),
            coarse_to_fine: CoarseToFine { until: s(self.coarse_to_fine.until), ..self.coarse_to_fine },
            densify: DensifyConfig {
                from: self.densify.from.min(until / 4),
                until,
                interval: self.densify.interval.min((until / 10).max(MIN_DENSIFY_INTERVAL)),
                prune_big_after: s(self.densify.prune_big_after),
                opacity_reset_interval: si(self.densify.opacity_reset_interval, 1000),
                trim_interval: si(self.densify.trim_interval, 200),
                ..self.densify
            },
            ..self.clone()
        }
    }

    /// The losses active at 1-based iteration `it` (docs/method.md §Schedule).
    pub fn phase(&self, it: u64) -> Phase {
        let l = &self.losses;
        let geometry = it > self.warmup_end;
        let photometric_window = geometry && it <= self.photometric_end;
        let feature_window = it > self.photometric_end && it <= self.features_end;
        Phase {
            edge: geometry && l.edge,
            normal_consistency: geometry && l.normal_consistency,
            normal_smoothing: geometry && l.normal_smoothing,
            photometric: l.photometric && (photometric_window || (self.overlap_mv && feature_window)),
            features: l.features && feature_window,
        }
    }

    /// Whether any iteration runs L_f (the switch is on and its phase is not empty): the
    /// VGG feature maps are only needed then.
    pub fn has_feature_phase(&self) -> bool {
        self.losses.features && self.features_end > self.photometric_end
    }

    /// The rasterizer settings of a run (near plane, background, antialiasing and low-pass filter);
    /// training, rendering and meshing a run all use these.
    pub fn raster_config(&self) -> gs_raster::RasterConfig {
        gs_raster::RasterConfig {
            near: self.near,
            background: self.background,
            antialiased: self.antialiased,
            low_pass: self.low_pass,
            ..Default::default()
        }
    }

    /// The SH degree at 1-based iteration `it`.
    pub fn sh_degree(&self, it: u64) -> u32 {
        if self.sh_degree_interval == 0 {
            return self.sh_degree_max;
        }
        ((it.saturating_sub(1) / self.sh_degree_interval) as u32).min(self.sh_degree_max)
    }
}

/// Which loss terms one iteration evaluates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct Phase {
    /// Edge term of L_I.
    pub edge: bool,
    /// L_nc.
    pub normal_consistency: bool,
    /// L_ns.
    pub normal_smoothing: bool,
    /// L_p.
    pub photometric: bool,
    /// L_f.
    pub features: bool,
}

impl Phase {
    /// Whether the geometry channels (Ñ, D, plane depth) must be rendered.
    pub fn needs_geometry(&self) -> bool {
        self.normal_consistency || self.normal_smoothing || self.photometric || self.features
    }
    /// Whether the view's edge guide (∇I, δ) is needed.
    pub fn needs_guide(&self) -> bool {
        self.edge || self.normal_consistency || self.normal_smoothing
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_schedule() {
        let c = TrainConfig::default();
        c.validate().unwrap();
        assert_eq!(c.phase(7000), Phase::default());
        let p = c.phase(7001);
        assert!(p.edge && p.normal_consistency && p.normal_smoothing && p.photometric && !p.features);
        let p = c.phase(15_001);
        assert!(p.edge && !p.photometric && p.features);
        assert!(TrainConfig { overlap_mv: true, ..c.clone() }.phase(15_001).photometric);
        assert_eq!((c.sh_degree(1), c.sh_degree(1000), c.sh_degree(1001), c.sh_degree(19_999)), (0, 0, 1, 3));
    }

    #[test]
    fn scaling_keeps_proportions() {
        let c = TrainConfig::default().scaled(2000);
        assert_eq!((c.warmup_end, c.photometric_end, c.features_end), (700, 1500, 2000));
        assert_eq!((c.densify.from, c.densify.until, c.densify.interval), (375, 1500, 100));
        assert_eq!((c.densify.opacity_reset_interval, c.densify.trim_interval, c.sh_degree_interval), (1000, 200, 100));
        let c = TrainConfig::default().scaled(6000);
        assert_eq!((c.densify.from, c.densify.until, c.densify.interval), (500, 4500, 100));
        // Short runs: the cadence stops shrinking at MIN_DENSIFY_INTERVAL, so a 20-iteration run
        // (densification until 15) never densifies and 300 iterations densify every 25.
        let c = TrainConfig::default().scaled(300);
        assert_eq!((c.densify.from, c.densify.until, c.densify.interval), (56, 225, MIN_DENSIFY_INTERVAL));
        let c = TrainConfig::default().scaled(20);
        assert!(c.densify.until < c.densify.from + c.densify.interval, "{:?}", c.densify);
        c.validate().unwrap();
        let m = TrainConfig::preset(Preset::Mip360);
        let p = m.phase(25_000);
        assert!(p.normal_consistency && !p.features && !p.photometric);
    }

    #[test]
    fn the_cpu_presets_run_l_p_to_the_end_without_resets() {
        let (s, f) = (TrainConfig::preset(Preset::Standard), TrainConfig::preset(Preset::Fast));
        for (c, n, sources) in [(&s, STANDARD_ITERATIONS, CPU_SOURCE_VIEWS), (&f, FAST_ITERATIONS, 2)] {
            c.validate().unwrap();
            assert_eq!((c.iterations, c.source_views, c.densify.opacity_reset_interval), (n, sources, 0));
            // No more L_p patches per iteration than the paper's three sources.
            assert!(c.source_views * c.max_pixels_per_source <= PAPER_SOURCE_VIEWS * gs_mvs::DEFAULT_MAX_PIXELS_PER_SOURCE);
            assert_eq!((c.photometric_end, c.features_end, c.source_depth_max_age), (n, n, CPU_SOURCE_DEPTH_MAX_AGE));
            assert!(!c.has_feature_phase() && c.phase(n).photometric && !c.phase(c.warmup_end).photometric);
            assert!(c.warmup_end > 0 && c.densify.until < n);
        }
        assert_eq!((s.weights.lambda_p, f.weights.lambda_p), (STANDARD_LAMBDA_P, LAMBDA_P));
        // --iterations keeps the shape; the paper's presets keep L_f and render every source.
        let long = s.scaled(9000);
        assert_eq!((long.photometric_end, long.features_end, long.densify.opacity_reset_interval), (9000, 9000, 0));
        let dtu = TrainConfig::preset(Preset::Dtu);
        assert!(dtu.has_feature_phase() && dtu.source_depth_max_age == 0 && dtu.source_views == 3);
        assert!(!TrainConfig { losses: LossSwitches { features: false, ..dtu.losses }, ..dtu }.has_feature_phase());
    }

    #[test]
    fn absurd_values_are_named() {
        for (c, name) in [
            (TrainConfig { iterations: 0, ..Default::default() }, "iterations"),
            (TrainConfig { patch_size: 4, ..Default::default() }, "patch_size"),
            (TrainConfig { source_views: 0, ..Default::default() }, "source_views"),
            (TrainConfig { weights: LossWeights { lambda_p: f32::NAN, ..Default::default() }, ..Default::default() }, "lambda_p"),
            (TrainConfig { weights: LossWeights { lambda_o: -1.0, ..Default::default() }, ..Default::default() }, "lambda_o = -1"),
            (TrainConfig { max_gaussians: 0, ..Default::default() }, "max_gaussians"),
            (TrainConfig { low_pass: f32::NAN, ..Default::default() }, "low_pass = NaN"),
            (TrainConfig { sh_min_gain: f32::NAN, ..Default::default() }, "sh_min_gain"),
            // A schedule longer than the run (`--set iterations=20`) names its boundaries.
            (TrainConfig { iterations: 20, ..Default::default() }, "warmup_end = 7000 (the colour warm-up), photometric_end = 15000"),
            (TrainConfig { iterations: 20, ..Default::default() }, "--iterations 20"),
        ] {
            let e = c.validate().unwrap_err().to_string();
            assert!(e.contains(name), "{e}");
        }
        for p in [Preset::Fast, Preset::Standard, Preset::Dtu, Preset::Tnt, Preset::Mip360] {
            TrainConfig::preset(p).validate().unwrap();
            for n in [1, 4, 20, 100_000] {
                TrainConfig::preset(p).scaled(n).validate().unwrap();
            }
        }
        assert!("bogus".parse::<Preset>().is_err());
        assert_eq!("mip360".parse::<Preset>(), Ok(Preset::Mip360));
        let round: TrainConfig = serde_json::from_str(&serde_json::to_string(&TrainConfig::preset(Preset::Fast)).unwrap()).unwrap();
        assert_eq!(round, TrainConfig::preset(Preset::Fast));
    }

    #[test]
    fn runs_written_before_a_setting_existed_still_read() {
        // λ_o and the run's screen filter came later: a config.json without them reads as it
        // was trained (no L_o, 3DGS' filter without compensation) whatever its preset, and the
        // run's renders follow the setting.
        let without = |preset: Preset| {
            let mut v = serde_json::to_value(TrainConfig::preset(preset)).unwrap();
            v["weights"].as_object_mut().unwrap().remove("lambda_o");
            v.as_object_mut().unwrap().remove("antialiased");
            v.as_object_mut().unwrap().remove("low_pass");
            serde_json::from_value::<TrainConfig>(v).unwrap()
        };
        let old = without(Preset::Dtu);
        assert_eq!(old, TrainConfig::default());
        assert!(!old.raster_config().antialiased);
        assert!(TrainConfig { antialiased: true, ..old.clone() }.raster_config().antialiased);
        assert_eq!(TrainConfig { low_pass: 0.1, ..old }.raster_config().low_pass, 0.1);
        // A `standard` run trained before its presets took the Mip filter renders as trained.
        let old = without(Preset::Standard);
        assert_eq!((old.antialiased, old.low_pass), (false, gs_raster::LOW_PASS));
    }

    #[test]
    fn the_cpu_presets_render_with_the_mip_filter_and_the_paper_presets_without() {
        for p in [Preset::Standard, Preset::Fast] {
            let r = TrainConfig::preset(p).raster_config();
            assert!(r.antialiased && r.low_pass == CPU_LOW_PASS, "{p:?}");
        }
        for p in [Preset::Dtu, Preset::Tnt, Preset::Mip360] {
            let r = TrainConfig::preset(p).raster_config();
            assert!(!r.antialiased && r.low_pass == gs_raster::LOW_PASS, "{p:?}");
        }
    }
}
