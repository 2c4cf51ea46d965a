//! The public data types of the rasterizer: constants, errors, configuration, requests,
//! outputs and gradients (shared by both backends).

use crate::cpu::CpuState;
use crate::cpu::project::LOW_PASS;
use gs_core::Image;
use thiserror::Error;

/// Tile edge in pixels.
pub const TILE_SIZE: u32 = 16;
/// Alpha cap.
pub const MAX_ALPHA: f32 = 0.99;
/// Transmittance stop: a pixel is done when T·(1−α) would fall below this.
pub const T_STOP: f32 = 1e-4;
/// Default alpha skip threshold 1/255.
pub const ALPHA_THRESHOLD: f32 = 1.0 / 255.0;
/// The constant added to the plane-depth denominator (PGSR).
pub const PLANE_DEPTH_EPS: f32 = 1e-8;
/// A Gaussian is "observed" by a pixel when it contributes while T is above this (PGSR).
pub const OBSERVE_T: f32 = 0.5;

/// Errors of the rasterizer (all caused by its inputs).
#[derive(Debug, Error, Clone, PartialEq)]
pub enum RasterError {
    /// Zero-sized or over-cap image, non-finite intrinsics.
    #[error("invalid camera: {0}")]
    InvalidCamera(String),
    /// Gaussian arrays of different lengths or an SH degree above 3.
    #[error("invalid Gaussians: {0}")]
    InvalidGaussians(String),
    /// A configuration value out of range.
    #[error("invalid raster config: {0}")]
    InvalidConfig(String),
    /// The Gaussians' tile footprints add up to more than the cap (huge or too many Gaussians).
    #[error(
        "{count} tile intersections exceed the cap of {cap}; raise RasterConfig::max_intersections or prune huge Gaussians"
    )]
    TooManyIntersections {
        /// Counted intersections.
        count: u64,
        /// The cap.
        cap: usize,
    },
    /// Output gradients that do not match the forward render (missing channel, wrong size),
    /// or a forward render from another backend / an older render of the same rasterizer.
    #[error("invalid output gradients: {0}")]
    InvalidGradients(String),
    /// The requested backend cannot be used here (no adapter, or built without the feature).
    #[error("backend unavailable: {0}")]
    BackendUnavailable(String),
    /// The GPU backend failed (device lost, out of memory, or an input beyond the adapter's
    /// limits, e.g. a buffer larger than its maximum storage binding).
    #[error("GPU backend error: {0}")]
    Gpu(String),
}

/// Result alias of gs-raster.
pub type Result<T> = std::result::Result<T, RasterError>;

/// Rasterizer settings; the same values must be passed to [`render`](crate::render) and [`backward`](crate::backward).
#[derive(Debug, Clone, PartialEq)]
pub struct RasterConfig {
    /// Near plane: Gaussians with camera z ≤ near are culled (docs/method.md §Rendering: 0.01).
    pub near: f32,
    /// Far plane: camera z > far is culled.
    pub far: f32,
    /// Background colour added as T_final·background.
    pub background: [f32; 3],
    /// Mip-splatting / gsplat "antialiased" opacity compensation √(det Σ / det Σ').
    pub antialiased: bool,
    /// Screen-space low-pass filter added to both diagonal entries of Σ' (px²; [`LOW_PASS`] =
    /// 0.3 of 3DGS by default, 0.1 is Mip-Splatting's 2D filter).
    pub low_pass: f32,
    /// Alpha skip threshold (1/255). It also sets the radius, so lowering it (tests do, to
    /// make the render continuous for finite differences) keeps everything consistent.
    pub alpha_threshold: f32,
    /// Plane depth is output only where −Ñ·r + 1e-8 exceeds this (background pixels with
    /// Ñ ≈ 0, grazing planes); elsewhere the depth is 0 (= "no depth") with zero gradient.
    pub plane_depth_min_denominator: f32,
    /// Cap on tile intersections (memory bound for huge or very many Gaussians).
    pub max_intersections: usize,
}

impl Default for RasterConfig {
    fn default() -> Self {
        Self {
            near: 0.01,
            far: 1e10,
            background: [0.0; 3],
            antialiased: false,
            low_pass: LOW_PASS,
            alpha_threshold: ALPHA_THRESHOLD,
            plane_depth_min_denominator: 1e-4,
            max_intersections: 1 << 27,
        }
    }
}

/// Which outputs to render. Geometry channels (Ñ, D) are blended only when normal, distance
/// or plane depth is requested; the depth sum only for expected depth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderRequest {
    /// Colour (3 channels, with background).
    pub color: bool,
    /// Accumulated alpha A = 1 − T_final.
    pub alpha: bool,
    /// Rendered camera-space normal Ñ = Σ wᵢ n_c,i (not normalised).
    pub normal: bool,
    /// Rendered distance D = Σ wᵢ dᵢ (not divided by A).
    pub distance: bool,
    /// Plane depth z = D / (−Ñ·K⁻¹p̄ + 1e-8) at pixel centres.
    pub plane_depth: bool,
    /// Expected depth Σ wᵢ t_z,i / A (0 where A = 0).
    pub expected_depth: bool,
    /// Per-Gaussian observed counts (pixels where it contributed while T > 0.5).
    pub observed: bool,
    /// Per-Gaussian screen radii ([`RenderOutput::radii`]) for the caller. The CPU backend fills
    /// them always; the wgpu backend keeps them on the device (where a resident step's
    /// statistics read them) and reads them back only when asked: 4 bytes a Gaussian.
    pub radii: bool,
    /// Per-pixel T_final and last contributor ([`RenderOutput::final_t`],
    /// [`RenderOutput::last_contributor`]) for the caller. The CPU backend fills them always (its
    /// backward needs them); the wgpu backend keeps them on the device and reads them back
    /// only when asked (T_final also when colour, alpha or expected depth need it).
    pub traversal: bool,
    /// Transmittance at which the geometry channels (Ñ, D, and so the plane depth) stop
    /// blending: contributions count only while T > `geometry_cut`, the one that crosses it in
    /// part (weight T − max(T', cut)). A pixel's geometry is then that of the front of its
    /// blend (docs/method.md §TSDF).
    /// 0 blends every contribution (training); in [0, 1). Forward only: a backward with
    /// geometry gradients of a cut render is refused.
    pub geometry_cut: f32,
    /// With `color`: the colour stays on the device. The wgpu backend writes it into a new
    /// `DeviceImage` ([`RenderOutput::device_color`], built with the `wgpu` feature) and leaves
    /// [`RenderOutput::color`] `None`, so that a loss kernel on the same device reads it
    /// without a round trip through the host (docs/architecture.md §GPU). The CPU backend
    /// renders the colour to the host as without it.
    pub color_on_device: bool,
    /// With any geometry channel (normal, distance or plane depth): the wgpu backend also
    /// writes the rendered surface (plane depth, Ñ, D, A per pixel: gs-gpu's `SurfaceTexel`)
    /// into a new `DeviceImage` ([`RenderOutput::device_surface`]), for the normal terms and
    /// L_p on the same device; the host images come back as asked (none of Ñ and D need to).
    /// The CPU backend ignores it.
    pub surface_on_device: bool,
    /// With `plane_depth` and `surface_on_device`: the plane depth stays in the surface (its
    /// z) and does not come back, so [`RenderOutput::plane_depth`] is `None` on the wgpu
    /// backend (e.g. a depth that L_p keeps on the device for later steps). The CPU backend
    /// ignores it.
    pub plane_depth_on_device: bool,
    /// With `observed`: the per-Gaussian counts stay on the device, where a resident step's
    /// statistics and the trim's view count read them ([`crate::Rasterizer::count_views_resident`]),
    /// so [`RenderOutput::observed`] is `None` on the wgpu backend. The CPU backend ignores it.
    pub observed_on_device: bool,
}

impl Default for RenderRequest {
    /// Colour and alpha.
    fn default() -> Self {
        Self {
            color: true,
            alpha: true,
            normal: false,
            distance: false,
            plane_depth: false,
            expected_depth: false,
            observed: false,
            radii: true,
            traversal: false,
            geometry_cut: 0.0,
            color_on_device: false,
            surface_on_device: false,
            plane_depth_on_device: false,
            observed_on_device: false,
        }
    }
}

impl RenderRequest {
    /// Every output.
    pub fn all() -> Self {
        Self {
            color: true,
            alpha: true,
            normal: true,
            distance: true,
            plane_depth: true,
            expected_depth: true,
            observed: true,
            radii: true,
            traversal: true,
            geometry_cut: 0.0,
            color_on_device: false,
            surface_on_device: false,
            plane_depth_on_device: false,
            observed_on_device: false,
        }
    }
    /// Whether the per-Gaussian observed counts come back to the host.
    #[cfg(feature = "wgpu")]
    pub(crate) fn observed_back(&self) -> bool {
        self.observed && !self.observed_on_device
    }
    /// The transmittance cut the geometry accumulators apply ([`Self::geometry_cut`]; 0 when
    /// no geometry is blended).
    pub(crate) fn applied_cut(&self) -> f32 {
        if self.geo() { self.geometry_cut } else { 0.0 }
    }
    /// What of this request a device backend brings to the host: all of it but a plane
    /// depth that stays in the surface ([`Self::plane_depth_on_device`]).
    #[cfg(feature = "wgpu")]
    pub(crate) fn host_outputs(self) -> Self {
        let kept = self.surface_on_device && self.plane_depth_on_device;
        Self { plane_depth: self.plane_depth && !kept, ..self }
    }
    /// Whether the geometry accumulators (Ñ, D) are blended.
    pub(crate) fn geo(&self) -> bool {
        self.normal || self.distance || self.plane_depth
    }
}

/// Work counters of a render (for benches and logs).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RenderStats {
    /// Gaussians that survived culling.
    pub visible: usize,
    /// (tile, Gaussian) intersections.
    pub intersections: usize,
    /// Σ over pixels of the tile-list entries the pixel went through before it saturated (the
    /// forward's Gaussian-pixel pairs, GPU semantics: one thread per pixel).
    pub forward_pairs: u64,
    /// Σ over pixels of the entries up to the last contributor (the backward's pairs).
    pub backward_pairs: u64,
    /// Σ over (tile, Gaussian) of the pixel box actually visited inside the tile (CPU work).
    pub box_pairs: u64,
}

/// What the backward needs from the forward: the CPU backend's per-pixel and per-Gaussian
/// state, or a handle to the wgpu backend's device-resident state.
#[derive(Debug, Clone)]
pub struct ForwardState(pub(crate) StateInner);

#[derive(Debug, Clone)]
pub(crate) enum StateInner {
    Cpu(CpuState),
    #[cfg(feature = "wgpu")]
    Gpu(crate::gpu::GpuState),
}

impl ForwardState {
    /// The CPU backend's state, if this came from the CPU backend.
    pub(crate) fn cpu(&self) -> Option<&CpuState> {
        match &self.0 {
            StateInner::Cpu(s) => Some(s),
            #[cfg(feature = "wgpu")]
            StateInner::Gpu(_) => None,
        }
    }
}

/// Rendered maps (only the requested ones are `Some`) and per-Gaussian outputs.
#[derive(Debug, Clone)]
pub struct RenderOutput {
    /// Colour + T_final·background, 3 channels.
    pub color: Option<Image>,
    /// Accumulated alpha A, 1 channel.
    pub alpha: Option<Image>,
    /// Rendered camera-space normal Ñ, 3 channels.
    pub normal: Option<Image>,
    /// Rendered distance D, 1 channel.
    pub distance: Option<Image>,
    /// Plane depth z, 1 channel (0 = no depth).
    pub plane_depth: Option<Image>,
    /// Expected depth, 1 channel (0 where A = 0).
    pub expected_depth: Option<Image>,
    /// Screen radius in pixels per Gaussian (0 = culled).
    pub radii: Vec<u32>,
    /// Per-Gaussian observed counts (when requested).
    pub observed: Option<Vec<u32>>,
    /// Work counters.
    pub stats: RenderStats,
    /// Per-pixel final transmittance (the backward starts from it).
    pub final_t: Vec<f32>,
    /// Per pixel: 1 + index (in its tile list) of the last contributing Gaussian, 0 if none.
    pub last_contributor: Vec<u32>,
    /// The colour kept on the device ([`RenderRequest::color_on_device`], wgpu backend):
    /// `[H][W][3]` like [`RenderOutput::color`], which is then `None`.
    #[cfg(feature = "wgpu")]
    pub device_color: Option<gs_gpu::DeviceImage>,
    /// The rendered surface kept on the device ([`RenderRequest::surface_on_device`], wgpu
    /// backend): `[H][W]` gs-gpu `SurfaceTexel`s (6 channels).
    #[cfg(feature = "wgpu")]
    pub device_surface: Option<gs_gpu::DeviceImage>,
    pub(crate) state: ForwardState,
}

/// Gradients w.r.t. the rendered maps (each optional; `None` = zero). Each must match the
/// size and channel count of the corresponding output, which must have been rendered.
#[derive(Debug, Clone, Copy, Default)]
pub struct OutputGradients<'a> {
    /// ∂L/∂colour.
    pub color: Option<&'a Image>,
    /// ∂L/∂A.
    pub alpha: Option<&'a Image>,
    /// ∂L/∂Ñ.
    pub normal: Option<&'a Image>,
    /// ∂L/∂D.
    pub distance: Option<&'a Image>,
    /// ∂L/∂plane depth (folded into Ñ and D per pixel).
    pub plane_depth: Option<&'a Image>,
    /// ∂L/∂expected depth.
    pub expected_depth: Option<&'a Image>,
    /// ∂L/∂colour on the device (`[H][W][3]`), for a render whose colour stayed there
    /// ([`RenderRequest::color_on_device`]): the wgpu backward reads it there; the CPU
    /// backward refuses it. At most one of it and `color`.
    #[cfg(feature = "wgpu")]
    pub device_color: Option<&'a gs_gpu::DeviceImage>,
    /// ∂L/∂Ñ and ∂L/∂(plane depth) on the device, for a render with geometry (the normal
    /// terms' gradients of its surface): the wgpu backward adds them into each
    /// pixel's gradients there, beside `normal` and `plane_depth` from the host; the CPU
    /// backward refuses them.
    #[cfg(feature = "wgpu")]
    pub device_geometry: Option<DeviceGeometryGrads<'a>>,
    /// A loss's gradient of Ñ and D on the device (L_p's), for a render with geometry: the wgpu backward adds it, times its weight, into each pixel's gradients there;
    /// the CPU backward refuses it.
    #[cfg(feature = "wgpu")]
    pub device_plane: Option<DevicePlaneGrads<'a>>,
}

/// A gradient of the rendered plane kept on the device ([`OutputGradients::device_plane`]).
#[cfg(feature = "wgpu")]
#[derive(Debug, Clone, Copy)]
pub struct DevicePlaneGrads<'a> {
    /// ∂/∂Ñ and ∂/∂D per pixel: `[H][W]` gs-gpu `PlaneGrad`s (4 channels).
    pub gradient: &'a gs_gpu::DeviceImage,
    /// The weight it counts with in L (L_p's λ3).
    pub weight: f32,
}

/// Gradients of the geometry channels kept on the device ([`OutputGradients::device_geometry`]).
#[cfg(feature = "wgpu")]
#[derive(Debug, Clone, Copy)]
pub struct DeviceGeometryGrads<'a> {
    /// ∂L/∂Ñ, `[H][W][3]`.
    pub normal: &'a gs_gpu::DeviceImage,
    /// ∂L/∂(plane depth), `[H][W][1]`.
    pub plane_depth: &'a gs_gpu::DeviceImage,
}

/// Gradients of the Gaussian parameters (same layout as [`Gaussians`](gs_core::Gaussians)) and the densification
/// accumulators of this view.
#[derive(Debug, Clone, PartialEq)]
pub struct GaussianGradients {
    /// ∂L/∂μ.
    pub means: Vec<[f32; 3]>,
    /// ∂L/∂log-scales.
    pub log_scales: Vec<[f32; 3]>,
    /// ∂L/∂quaternion (w, x, y, z), through the normalisation.
    pub rotations: Vec<[f32; 4]>,
    /// ∂L/∂opacity logit.
    pub opacity_logits: Vec<f32>,
    /// ∂L/∂SH coefficients (zero above the active degree).
    pub sh: Vec<[[f32; 3]; 16]>,
    /// ∂L/∂mean2d summed over pixels (signed), NDC units; ‖·‖ is 3DGS's densification signal.
    pub mean2d: Vec<[f32; 2]>,
    /// Σ over pixels of |∂L/∂x|, |∂L/∂y| (AbsGS), NDC units.
    pub mean2d_abs: Vec<[f32; 2]>,
}

impl GaussianGradients {
    /// All-zero gradients of `n` Gaussians.
    pub fn zeros(n: usize) -> Self {
        Self {
            means: vec![[0.0; 3]; n],
            log_scales: vec![[0.0; 3]; n],
            rotations: vec![[0.0; 4]; n],
            opacity_logits: vec![0.0; n],
            sh: vec![[[0.0; 3]; 16]; n],
            mean2d: vec![[0.0; 2]; n],
            mean2d_abs: vec![[0.0; 2]; n],
        }
    }

    /// ‖∂L/∂mean2d‖ of Gaussian `i` (NDC units).
    pub fn mean2d_norm(&self, i: usize) -> f32 {
        gs_core::screen_norm(self.mean2d[i])
    }

    /// ‖(Σ|∂L/∂x|, Σ|∂L/∂y|)‖ of Gaussian `i` (AbsGS, NDC units).
    pub fn mean2d_abs_norm(&self, i: usize) -> f32 {
        gs_core::screen_norm(self.mean2d_abs[i])
    }
}

/// What a device step (`WgpuRasterizer::backward_and_step`) reads back: a few bytes.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DeviceStep {
    /// Whether every gradient of the means was finite (the host's step refuses a non-finite
    /// one before stepping; here the step has run and the caller stops the run).
    pub means_finite: bool,
}

/// What a device step takes besides the render and its gradients.
#[derive(Debug, Clone, Copy, Default)]
pub struct StepExtras<'a> {
    /// A loss term's own ∂L/∂ opacity logit per Gaussian (L_o), added to the rasterizer's.
    pub extra_opacity: Option<&'a [f32]>,
    /// A loss term's own ∂L/∂ log-scale per Gaussian (L_s), added to the rasterizer's.
    pub extra_log_scales: Option<&'a [[f32; 3]]>,
    /// Accumulate the densification statistics of this view on the device
    /// ([`gs_core::DensifyStats::accumulate`]), its radii counting this many times (the
    /// render's downscale); pixel-weighted when the render counted pixels (`observed`).
    pub accumulate: Option<f32>,
}

impl StepExtras<'_> {
    /// Whether a loss term adds parameter gradients of its own.
    pub fn any_extra(&self) -> bool {
        self.extra_opacity.is_some() || self.extra_log_scales.is_some()
    }
}

/// Density control's rule for one step on a resident model
/// ([`crate::Rasterizer::densify_resident`]): gs-train's densification settings resolved for
/// the scene (docs/method.md §Densification).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DensifyRule {
    /// Clone or split at a mean screen-space gradient of at least this.
    pub grad_threshold: f32,
    /// AbsGS: split large Gaussians at a mean absolute gradient of at least this.
    pub abs_grad_threshold: f32,
    /// Largest scale of a Gaussian that clones rather than splits (percent_dense × extent).
    pub small_limit: f32,
    /// Screen radius (pixels) above which an AbsGS split applies and `prune_big` prunes.
    pub max_screen_radius: f32,
    /// At most this many AbsGS splits (the first in index order).
    pub max_abs_splits: usize,
    /// Prune below this opacity.
    pub min_opacity: f32,
    /// With `prune_big`: prune a largest scale above this (max world scale × extent).
    pub max_world: f32,
    /// Also prune Gaussians too large on screen or in the world.
    pub prune_big: bool,
    /// A split child's scales are its parent's divided by this.
    pub split_divisor: f32,
    /// How many candidates may grow (clones and splits each add one Gaussian); the highest
    /// scores are taken when more pass the thresholds.
    pub room: usize,
}

/// The parent of a row born on the device, as [`crate::Rasterizer::densify_resident`] hands
/// it to the host's sampler of positions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BornParent {
    /// The parent's mean.
    pub mean: [f32; 3],
    /// The parent's log-scales.
    pub log_scale: [f32; 3],
    /// The parent's quaternion (w, x, y, z), unnormalised.
    pub rotation: [f32; 4],
}

/// The rows of a resident model whose mark against capsules f32 could not settle, with their
/// means ([`crate::Rasterizer::mark_capsules_resident`]): for the host's own test.
pub type UnsureRows = Vec<(usize, [f32; 3])>;

/// What a removal by a mask made on the device did: the multi-view trim
/// ([`crate::Rasterizer::retain_observed_resident`]) or the capture path's floater rule
/// ([`crate::Rasterizer::retain_outside_resident`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrimOnDevice {
    /// The Gaussians left (all of them where none was removed).
    Kept(usize),
    /// The mask would keep no Gaussian: nothing changed (the caller keeps the most opaque
    /// one, as the host's rule does; the trim's counts stay for it,
    /// [`crate::Rasterizer::read_view_counts`]).
    NoneKept,
}

/// What density control on a resident model did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DensifyCounts {
    /// Candidates over the thresholds, before the budget's choice.
    pub candidates: usize,
    /// Gaussians cloned.
    pub cloned: usize,
    /// Gaussians split (each replaced by two).
    pub split: usize,
    /// Rows removed: split parents and pruned Gaussians.
    pub removed: usize,
    /// Gaussians after the step.
    pub len: usize,
}

/// One Adam step of every parameter of `g` on the host with the gradients `grads`: the CPU
/// twin of the wgpu backend's resident step (`WgpuRasterizer::backward_and_step`). `adam` has
/// one group per [`gs_core::Param`], by name; the SH DC and SH rest groups are updated in
/// place inside the Gaussians' 48-float SH records.
pub fn adam_step(adam: &mut gs_core::Adam, g: &mut gs_core::Gaussians, grads: &GaussianGradients) -> gs_core::Result<()> {
    use gs_core::Param;
    adam.step(Param::Means.name(), g.means.as_flattened_mut(), grads.means.as_flattened())?;
    let stride = 3 * gs_core::sh::SH_COEFFS;
    let (sh, sh_grads) = (g.sh.as_flattened_mut().as_flattened_mut(), grads.sh.as_flattened().as_flattened());
    adam.step_strided(Param::ShDc.name(), sh, sh_grads, stride, 0)?;
    adam.step_strided(Param::ShRest.name(), sh, sh_grads, stride, 3)?;
    adam.step(Param::Opacity.name(), &mut g.opacity_logits, &grads.opacity_logits)?;
    adam.step(Param::LogScales.name(), g.log_scales.as_flattened_mut(), grads.log_scales.as_flattened())?;
    adam.step(Param::Rotations.name(), g.rotations.as_flattened_mut(), grads.rotations.as_flattened())
}

