//! # gs-raster
//!
//! The differentiable 3D Gaussian splatting tile rasterizer of vagsl (CPU backend, plus a wgpu
//! backend behind the default `wgpu` feature), with the
//! PGSR / VA-GS geometry channels of method-spec §2: colour, accumulated alpha A, rendered
//! camera-space normal Ñ, rendered distance D, unbiased plane depth z = D / (−Ñ·K⁻¹p̄),
//! expected depth, per-Gaussian radii and "observed" counts — and the exact backward of all of
//! them into means, log-scales, quaternions, opacity logits and SH coefficients, plus the
//! screen-space densification accumulators.
//!
//! ```
//! use gs_core::{Camera, Gaussians, Intrinsics, glam::DVec3};
//! use gs_core::gaussians::rgb_to_sh_dc;
//! use gs_raster::{OutputGradients, RasterConfig, RenderRequest, backward, render};
//!
//! let cam = Camera::look_at(64, 48, Intrinsics::new(60.0, 60.0, 32.0, 24.0),
//!     DVec3::new(0.0, 0.0, -3.0), DVec3::ZERO, DVec3::new(0.0, -1.0, 0.0)).unwrap();
//! let mut g = Gaussians::with_len(1).unwrap();
//! g.log_scales[0] = [-1.5, -1.5, -4.0];
//! g.opacity_logits[0] = 2.0;
//! g.sh[0][0] = [rgb_to_sh_dc(0.9), rgb_to_sh_dc(0.2), rgb_to_sh_dc(0.1)];
//! let cfg = RasterConfig::default();
//! let req = RenderRequest { plane_depth: true, ..RenderRequest::default() };
//! let out = render(&g, &cam, &req, &cfg).unwrap();
//! let color = out.color.as_ref().unwrap();
//! assert!(color.get(32, 24, 0) > 0.5);                 // the centre is red
//! let depth = out.plane_depth.as_ref().unwrap();
//! assert!((depth.get(32, 24, 0) - 3.0).abs() < 1e-3);  // the plane z = 0 seen from 3 units
//!
//! // Backward of L = Σ colour.
//! let ones = gs_core::Image::filled(64, 48, 3, 1.0).unwrap();
//! let grads = backward(&g, &cam, &cfg, &out,
//!     &OutputGradients { color: Some(&ones), ..Default::default() }).unwrap();
//! assert!(grads.opacity_logits[0] > 0.0);              // more opacity, more colour
//! ```
//!
//! ## Backends
//! - **CPU** ([`render`], [`backward`]): rayon over tiles, deterministic, the numerical
//!   reference.
//! - **wgpu** ([`WgpuRasterizer`], feature `wgpu`, on by default): WGSL compute kernels on
//!   Vulkan / Metal / DX12 with the same inputs, outputs, errors and conventions; created once,
//!   it keeps its device, pipelines and (geometrically growing) buffers across calls. The
//!   forward state of its latest render stays on the device (`backward` right after `render`
//!   is the fast path; an older render's state is rebuilt by one extra forward); mixing
//!   backends or rasterizers is an [`RasterError::InvalidGradients`].
//!   Parity with the CPU backend (tests/wgpu_parity.rs): images within 1e-4, gradients within
//!   1e-3 relative (+ a 1e-5·max floor), apart from the rare pixel where an ulp-level
//!   difference flips a discrete decision (α ≥ 1/255, the transmittance stop, T > 0.5).
//!   `RenderStats::box_pairs` is a CPU-only work estimate (0 on wgpu).
//! - **Selection**: [`Rasterizer::new`]`(`[`Backend`]`)` with `"cpu" | "wgpu" | "auto"`;
//!   `auto` uses wgpu only on a hardware adapter (not a software one such as lavapipe) and
//!   the CPU otherwise. Built without the feature, `Backend::Wgpu` is a
//!   [`RasterError::BackendUnavailable`] error and `auto` is the CPU.
//!
//! ## Conventions (one choice per row of rasterizer-anchors.md §0)
//! - Pixel (i, j) is blended at its centre (i + 0.5, j + 0.5) (design.md §2).
//! - α = min(0.99, o·G); α < 1/255 skipped (tested as σ > ln(o·255), the identical decision
//!   everywhere); a pixel stops when T·(1−α) < 1e-4 and that Gaussian is not blended; the
//!   gradient through the 0.99 cap is zero (gsplat). Near 0.01, far 1e10, t_z ≤ near culled.
//! - Screen-space gradients ([`GaussianGradients::mean2d`], [`GaussianGradients::mean2d_abs`])
//!   are in NDC units (pixel gradient × W/2, × H/2) like 3DGS/PGSR, so PGSR's densification
//!   thresholds (2e-4, 8e-4) apply unchanged.
//! - Determinism: tiles run in parallel but every tile writes its own buffers, merged in tile
//!   order; results are bit-identical for any thread count.

// `!(a > b)` is deliberate throughout: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]

mod backend;
#[cfg(feature = "wgpu")]
mod gpu;
mod project;
mod raster;

pub use backend::{Backend, Rasterizer};
#[cfg(feature = "wgpu")]
pub use gpu::{WgpuOptions, WgpuRasterizer, hardware_adapter_available, probe_adapter};

use gs_core::{Camera, Gaussians, Image};
use project::{CamParams, Features, Splat, SplatGrad};
use rayon::prelude::*;
use thiserror::Error;

pub use project::{JACOBIAN_CLAMP, LOW_PASS, MIN_COMPENSATION};

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

/// Rasterizer settings; the same values must be passed to [`render`] and [`backward`].
#[derive(Debug, Clone, PartialEq)]
pub struct RasterConfig {
    /// Near plane: Gaussians with camera z ≤ near are culled (method-spec §2: 0.01).
    pub near: f32,
    /// Far plane: camera z > far is culled.
    pub far: f32,
    /// Background colour added as T_final·background.
    pub background: [f32; 3],
    /// Mip-splatting / gsplat "antialiased" opacity compensation √(det Σ / det Σ').
    pub antialiased: bool,
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
            alpha_threshold: ALPHA_THRESHOLD,
            plane_depth_min_denominator: 1e-4,
            max_intersections: 1 << 27,
        }
    }
}

impl RasterConfig {
    fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(RasterError::InvalidConfig(m));
        if !(self.near > 0.0 && self.near.is_finite()) {
            return bad(format!("near = {} must be positive and finite", self.near));
        }
        if !(self.far > self.near) {
            return bad(format!(
                "far = {} must exceed near = {}",
                self.far, self.near
            ));
        }
        if !(self.alpha_threshold > 0.0 && self.alpha_threshold <= 0.5) {
            return bad(format!(
                "alpha_threshold = {} must lie in (0, 0.5]",
                self.alpha_threshold
            ));
        }
        if !(self.plane_depth_min_denominator >= 0.0
            && self.plane_depth_min_denominator.is_finite())
        {
            return bad(format!(
                "plane_depth_min_denominator = {} must be ≥ 0",
                self.plane_depth_min_denominator
            ));
        }
        if !self.background.iter().all(|v| v.is_finite()) {
            return bad("background colour is not finite".into());
        }
        Ok(())
    }
}

/// Which outputs to render. Geometry channels (Ñ, D) are blended only when normal, distance
/// or plane depth is requested; the depth sum only for expected depth.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
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
        }
    }
    fn geo(&self) -> bool {
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
pub struct ForwardState(StateInner);

#[derive(Debug, Clone)]
enum StateInner {
    Cpu(CpuState),
    #[cfg(feature = "wgpu")]
    Gpu(gpu::GpuState),
}

impl ForwardState {
    /// The CPU backend's state, if this came from the CPU backend.
    fn cpu(&self) -> Option<&CpuState> {
        match &self.0 {
            StateInner::Cpu(s) => Some(s),
            #[cfg(feature = "wgpu")]
            StateInner::Gpu(_) => None,
        }
    }
}

/// The CPU backend's forward state.
#[derive(Debug, Clone)]
struct CpuState {
    n_gaussians: usize,
    width: u32,
    height: u32,
    request: RenderRequest,
    /// Visible splats and features in depth order (`order[k]` is the Gaussian of entry k).
    splats: Vec<Splat>,
    features: Vec<Features>,
    order: Vec<u32>,
    bins: raster::Bins,
    final_t: Vec<f32>,
    last: Vec<u32>,
    /// Per pixel Ñ (3), D, Σ w t_z (empty when not blended).
    geo: Vec<[f32; 5]>,
}

impl std::fmt::Debug for raster::Bins {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "Bins({} tiles, {} intersections)",
            self.offsets.len().saturating_sub(1),
            self.ids.len()
        )
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
    state: ForwardState,
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
}

/// Gradients of the Gaussian parameters (same layout as [`Gaussians`]) and the densification
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
    fn zeros(n: usize) -> Self {
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
        let [x, y] = self.mean2d[i];
        (x * x + y * y).sqrt()
    }

    /// ‖(Σ|∂L/∂x|, Σ|∂L/∂y|)‖ of Gaussian `i` (AbsGS, NDC units).
    pub fn mean2d_abs_norm(&self, i: usize) -> f32 {
        let [x, y] = self.mean2d_abs[i];
        (x * x + y * y).sqrt()
    }
}

fn check_inputs(g: &Gaussians, camera: &Camera, cfg: &RasterConfig) -> Result<CamParams> {
    cfg.validate()?;
    let n = g.means.len();
    let lens = [
        g.log_scales.len(),
        g.rotations.len(),
        g.opacity_logits.len(),
        g.sh.len(),
    ];
    if lens.iter().any(|&l| l != n) {
        return Err(RasterError::InvalidGaussians(format!(
            "array lengths differ: means {n}, log_scales {}, rotations {}, opacity {}, sh {}",
            lens[0], lens[1], lens[2], lens[3]
        )));
    }
    if n > u32::MAX as usize - 1 {
        return Err(RasterError::InvalidGaussians(format!(
            "{n} Gaussians exceed the u32 index range"
        )));
    }
    if g.sh_degree > gs_core::sh::MAX_SH_DEGREE {
        return Err(RasterError::InvalidGaussians(format!(
            "SH degree {} > 3",
            g.sh_degree
        )));
    }
    let (w, h) = (camera.width as usize, camera.height as usize);
    if w == 0 || h == 0 {
        return Err(RasterError::InvalidCamera(format!(
            "image size {w}x{h} is empty"
        )));
    }
    if w.saturating_mul(h) > gs_core::image::MAX_IMAGE_PIXELS {
        return Err(RasterError::InvalidCamera(format!(
            "image size {w}x{h} exceeds the cap of {} pixels",
            gs_core::image::MAX_IMAGE_PIXELS
        )));
    }
    let k = &camera.intrinsics;
    let finite = [k.fx, k.fy, k.cx, k.cy].iter().all(|v| v.is_finite()) && k.fx > 0.0 && k.fy > 0.0;
    if !finite || !camera.rotation.is_finite() || !camera.translation.is_finite() {
        return Err(RasterError::InvalidCamera(
            "non-finite pose or non-positive focal length".into(),
        ));
    }
    Ok(CamParams::new(camera))
}

/// Projects every Gaussian (in parallel): splats, features, radii, rects, depths.
struct Projection {
    splats: Vec<Splat>,
    features: Vec<Features>,
    radii: Vec<u32>,
    rects: Vec<[u32; 4]>,
    depths: Vec<f32>,
    visible: Vec<u32>,
}

fn project_all(g: &Gaussians, cam: &CamParams, cfg: &RasterConfig) -> Projection {
    let n = g.len();
    let mut p = Projection {
        splats: vec![Splat::default(); n],
        features: vec![[0.0; 8]; n],
        radii: vec![0; n],
        rects: vec![[0; 4]; n],
        depths: vec![0.0; n],
        visible: Vec::new(),
    };
    // Each task writes its own rows of the arrays in place (no per-Gaussian Option buffer to
    // allocate and copy out); culled rows keep radius 0.
    const ROWS: usize = 1024;
    p.splats
        .par_chunks_mut(ROWS)
        .zip(p.features.par_chunks_mut(ROWS))
        .zip(p.radii.par_chunks_mut(ROWS))
        .zip(p.rects.par_chunks_mut(ROWS))
        .zip(p.depths.par_chunks_mut(ROWS))
        .enumerate()
        .for_each(|(k, ((((splats, features), radii), rects), depths))| {
            for j in 0..splats.len() {
                if let Some(pr) = project::project(g, k * ROWS + j, cam, cfg) {
                    splats[j] = pr.splat;
                    features[j] = pr.features;
                    radii[j] = pr.radius;
                    rects[j] = pr.rect;
                    depths[j] = pr.depth;
                }
            }
        });
    // A projected Gaussian has radius ≥ 1 (culling requires a positive radius).
    p.visible = (0..n as u32).filter(|&i| p.radii[i as usize] > 0).collect();
    p
}

/// Camera-space ray K⁻¹(u, v, 1) at the centre of pixel (x, y), in f32.
#[inline]
fn pixel_ray(cam: &CamParams, x: usize, y: usize) -> [f32; 3] {
    [
        ((x as f32 + 0.5) - cam.cx) / cam.fx,
        ((y as f32 + 0.5) - cam.cy) / cam.fy,
        1.0,
    ]
}

/// Plane depth and its denominator at one pixel; `None` where the denominator is at or below
/// the guard.
#[inline]
fn plane_depth_at(n: [f32; 3], d: f32, ray: [f32; 3], min_den: f32) -> Option<(f32, f32)> {
    let den = -(n[0] * ray[0] + n[1] * ray[1] + n[2] * ray[2]) + PLANE_DEPTH_EPS;
    if den > min_den && den.is_finite() {
        Some((d / den, den))
    } else {
        None
    }
}

/// Renders the requested maps of `gaussians` seen by `camera` (tiled, parallel over tiles).
pub fn render(
    gaussians: &Gaussians,
    camera: &Camera,
    request: &RenderRequest,
    config: &RasterConfig,
) -> Result<RenderOutput> {
    let cam = check_inputs(gaussians, camera, config)?;
    let proj = project_all(gaussians, &cam, config);
    let (order, bins) = raster::bin(
        &proj.visible,
        &proj.depths,
        &proj.rects,
        cam.tiles_x,
        cam.tiles_y,
        config.max_intersections,
    )?;
    // Compact the visible splats in depth order (tile lists then read them sequentially).
    let splats: Vec<Splat> = order.iter().map(|&i| proj.splats[i as usize]).collect();
    let features: Vec<Features> = order.iter().map(|&i| proj.features[i as usize]).collect();
    let ctx = raster::Ctx {
        splats: &splats,
        features: &features,
        bins: &bins,
        width: cam.width,
        height: cam.height,
        tiles_x: cam.tiles_x,
        threshold: config.alpha_threshold,
    };
    let geo = request.geo();
    let tiles = raster::forward_tiles(
        &ctx,
        request.color,
        geo,
        request.expected_depth,
        request.observed,
    );
    // Scatter tile results into image-sized buffers (serial, in tile order).
    let (w, h) = (cam.width as usize, cam.height as usize);
    let npix = w * h;
    let mut acc = vec![[0.0f32; 8]; npix];
    let mut final_t = vec![1.0f32; npix];
    let mut last = vec![0u32; npix];
    let mut stats = RenderStats {
        visible: proj.visible.len(),
        intersections: bins.ids.len(),
        ..Default::default()
    };
    let mut observed = request.observed.then(|| vec![0u32; gaussians.len()]);
    for (tile, out) in tiles.iter().enumerate() {
        let tx = tile % cam.tiles_x as usize;
        let ty = tile / cam.tiles_x as usize;
        let (x0, y0) = (tx * TILE_SIZE as usize, ty * TILE_SIZE as usize);
        let tw = (w - x0).min(TILE_SIZE as usize);
        for (lp, a) in out.acc.iter().enumerate() {
            let (lx, ly) = (lp % tw, lp / tw);
            let gp = (y0 + ly) * w + x0 + lx;
            acc[gp] = *a;
            final_t[gp] = out.final_t[lp];
            last[gp] = out.last[lp];
            stats.forward_pairs += out.traversed[lp] as u64;
            stats.backward_pairs += out.last[lp] as u64;
        }
        stats.box_pairs += out.box_pairs;
        if let Some(obs) = observed.as_mut() {
            for (k, &cid) in bins.tile(tile).iter().enumerate() {
                obs[order[cid as usize] as usize] += out.observed[k];
            }
        }
    }
    drop(tiles);
    let mut out = assemble(&cam, config, request, &acc, &final_t)?;
    out.radii = proj.radii;
    out.observed = observed;
    out.stats = stats;
    let geo_state = if geo || request.expected_depth {
        acc.iter().map(|a| [a[3], a[4], a[5], a[6], a[7]]).collect()
    } else {
        Vec::new()
    };
    out.state = ForwardState(StateInner::Cpu(CpuState {
        n_gaussians: gaussians.len(),
        width: cam.width,
        height: cam.height,
        request: *request,
        splats,
        features,
        order,
        bins,
        final_t: final_t.clone(),
        last: last.clone(),
        geo: geo_state,
    }));
    out.final_t = final_t;
    out.last_contributor = last;
    Ok(out)
}

/// Builds the requested images from per-pixel accumulators (shared by tiled and naive paths).
fn assemble(
    cam: &CamParams,
    cfg: &RasterConfig,
    req: &RenderRequest,
    acc: &[[f32; 8]],
    final_t: &[f32],
) -> Result<RenderOutput> {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let img = |c: usize, f: &dyn Fn(usize, usize, usize) -> f32| -> Result<Image> {
        let mut data = Vec::with_capacity(w * h * c);
        for y in 0..h {
            for x in 0..w {
                for ch in 0..c {
                    data.push(f(x, y, ch));
                }
            }
        }
        Image::from_vec(w, h, c, data).map_err(|e| RasterError::InvalidCamera(e.to_string()))
    };
    let bg = cfg.background;
    let color = if req.color {
        Some(img(3, &|x, y, c| {
            acc[y * w + x][c] + final_t[y * w + x] * bg[c]
        })?)
    } else {
        None
    };
    let alpha = if req.alpha {
        Some(img(1, &|x, y, _| 1.0 - final_t[y * w + x])?)
    } else {
        None
    };
    let normal = if req.normal {
        Some(img(3, &|x, y, c| acc[y * w + x][3 + c])?)
    } else {
        None
    };
    let distance = if req.distance {
        Some(img(1, &|x, y, _| acc[y * w + x][6])?)
    } else {
        None
    };
    let plane_depth = if req.plane_depth {
        Some(img(1, &|x, y, _| {
            let a = &acc[y * w + x];
            plane_depth_at(
                [a[3], a[4], a[5]],
                a[6],
                pixel_ray(cam, x, y),
                cfg.plane_depth_min_denominator,
            )
            .map_or(0.0, |v| v.0)
        })?)
    } else {
        None
    };
    let expected_depth = if req.expected_depth {
        Some(img(1, &|x, y, _| {
            let a_sum = 1.0 - final_t[y * w + x];
            if a_sum > 0.0 {
                acc[y * w + x][7] / a_sum
            } else {
                0.0
            }
        })?)
    } else {
        None
    };
    Ok(RenderOutput {
        color,
        alpha,
        normal,
        distance,
        plane_depth,
        expected_depth,
        radii: Vec::new(),
        observed: None,
        stats: RenderStats::default(),
        final_t: Vec::new(),
        last_contributor: Vec::new(),
        state: ForwardState(StateInner::Cpu(CpuState {
            n_gaussians: 0,
            width: cam.width,
            height: cam.height,
            request: *req,
            splats: Vec::new(),
            features: Vec::new(),
            order: Vec::new(),
            bins: raster::Bins::default(),
            final_t: Vec::new(),
            last: Vec::new(),
            geo: Vec::new(),
        })),
    })
}

/// Naive per-pixel reference: for every pixel, every visible Gaussian in (depth, index) order,
/// no tiles, single-threaded. Same projection and blending constants as [`render`]; used by
/// tests (tiled == naive) and by the bench for the speed ratio. Forward only.
pub fn render_naive(
    gaussians: &Gaussians,
    camera: &Camera,
    request: &RenderRequest,
    config: &RasterConfig,
) -> Result<RenderOutput> {
    let cam = check_inputs(gaussians, camera, config)?;
    let proj = project_all(gaussians, &cam, config);
    let mut order = proj.visible.clone();
    order.sort_by(|&a, &b| {
        proj.depths[a as usize]
            .total_cmp(&proj.depths[b as usize])
            .then(a.cmp(&b))
    });
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut acc = vec![[0.0f32; 8]; w * h];
    let mut final_t = vec![1.0f32; w * h];
    let mut observed = vec![0u32; gaussians.len()];
    for y in 0..h {
        for x in 0..w {
            let (a, t) = raster::naive_pixel(
                &proj.splats,
                &proj.features,
                &order,
                x as f32 + 0.5,
                y as f32 + 0.5,
                config.alpha_threshold,
                &mut observed,
            );
            acc[y * w + x] = a;
            final_t[y * w + x] = t;
        }
    }
    let mut out = assemble(&cam, config, request, &acc, &final_t)?;
    out.radii = proj.radii;
    out.observed = request.observed.then_some(observed);
    out.stats.visible = proj.visible.len();
    out.final_t = final_t;
    Ok(out)
}

fn check_grad(
    img: Option<&Image>,
    rendered: bool,
    name: &str,
    w: u32,
    h: u32,
    c: usize,
) -> Result<()> {
    if let Some(im) = img {
        if !rendered {
            return Err(RasterError::InvalidGradients(format!(
                "gradient for {name} given but {name} was not rendered"
            )));
        }
        if im.width() != w as usize || im.height() != h as usize || im.channels() != c {
            return Err(RasterError::InvalidGradients(format!(
                "{name} gradient is {}x{}x{}, the render is {w}x{h}x{c}",
                im.width(),
                im.height(),
                im.channels()
            )));
        }
    }
    Ok(())
}

/// Checks every given output gradient against the rendered channels and the image size.
fn check_all_grads(grads: &OutputGradients, req: &RenderRequest, w: u32, h: u32) -> Result<()> {
    check_grad(grads.color, req.color, "color", w, h, 3)?;
    check_grad(grads.alpha, req.alpha, "alpha", w, h, 1)?;
    check_grad(grads.normal, req.normal, "normal", w, h, 3)?;
    check_grad(grads.distance, req.distance, "distance", w, h, 1)?;
    check_grad(grads.plane_depth, req.plane_depth, "plane_depth", w, h, 1)?;
    check_grad(
        grads.expected_depth,
        req.expected_depth,
        "expected_depth",
        w,
        h,
        1,
    )
}

/// Per-pixel channel gradients of pixel (x, y) for the backward traversal (shared by both
/// backends): ∂L/∂(colour, Ñ, D, Σ w t_z) with plane depth folded into Ñ and D and expected
/// depth into the depth sum and alpha, and the coefficient of the T_final term
/// (g_A − bg·g_C − expected-depth term). `geo` holds per pixel Ñ (3), D, Σ w t_z (it may be
/// empty when neither plane depth nor expected depth gradients are given).
fn pixel_grads(
    cam: &CamParams,
    config: &RasterConfig,
    grads: &OutputGradients,
    final_t: &[f32],
    geo: &[[f32; 5]],
    x: usize,
    y: usize,
) -> ([f32; 8], f32) {
    let p = y * cam.width as usize + x;
    let bg = config.background;
    let min_den = config.plane_depth_min_denominator;
    let mut gc = [0.0f32; 8];
    let mut g_alpha = grads.alpha.map_or(0.0, |im| im.get(x, y, 0));
    if let Some(im) = grads.color {
        for c in 0..3 {
            gc[c] = im.get(x, y, c);
        }
        g_alpha -= bg[0] * gc[0] + bg[1] * gc[1] + bg[2] * gc[2];
    }
    if let Some(im) = grads.normal {
        for c in 0..3 {
            gc[3 + c] = im.get(x, y, c);
        }
    }
    if let Some(im) = grads.distance {
        gc[6] = im.get(x, y, 0);
    }
    if let Some(im) = grads.plane_depth {
        let gz = im.get(x, y, 0);
        let gs = &geo[p];
        let ray = pixel_ray(cam, x, y);
        if let Some((_, den)) = plane_depth_at([gs[0], gs[1], gs[2]], gs[3], ray, min_den) {
            // z = D / den, den = −Ñ·r + ε: ∂z/∂D = 1/den, ∂z/∂Ñ = D·r/den².
            gc[6] += gz / den;
            let k = gz * gs[3] / (den * den);
            for c in 0..3 {
                gc[3 + c] += k * ray[c];
            }
        }
    }
    if let Some(im) = grads.expected_depth {
        let a = 1.0 - final_t[p];
        if a > 0.0 {
            let ge = im.get(x, y, 0);
            let s = geo[p][4];
            gc[7] = ge / a;
            g_alpha -= ge * s / (a * a);
        }
    }
    (gc, g_alpha)
}

/// Backward pass: gradients of the Gaussian parameters given gradients of the rendered maps.
/// `gaussians`, `camera` and `config` must be those of the `forward` render.
pub fn backward(
    gaussians: &Gaussians,
    camera: &Camera,
    config: &RasterConfig,
    forward: &RenderOutput,
    grads: &OutputGradients,
) -> Result<GaussianGradients> {
    let cam = check_inputs(gaussians, camera, config)?;
    let Some(st) = forward.state.cpu() else {
        return Err(RasterError::InvalidGradients(
            "the forward render came from the wgpu backend; call backward on the same WgpuRasterizer".into(),
        ));
    };
    if st.n_gaussians != gaussians.len()
        || st.width != cam.width
        || st.height != cam.height
        || st.final_t.is_empty()
    {
        return Err(RasterError::InvalidGradients(format!(
            "forward state ({} Gaussians, {}x{}) does not match the inputs ({} Gaussians, {}x{}) or is not from render()",
            st.n_gaussians,
            st.width,
            st.height,
            gaussians.len(),
            cam.width,
            cam.height
        )));
    }
    let (w, h) = (cam.width, cam.height);
    check_all_grads(grads, &st.request, w, h)?;
    let color = grads.color.is_some();
    let geo = grads.normal.is_some() || grads.distance.is_some() || grads.plane_depth.is_some();
    let depth = grads.expected_depth.is_some();
    let n = gaussians.len();
    let mut out = GaussianGradients::zeros(n);
    if st.bins.ids.is_empty() || !(color || geo || depth || grads.alpha.is_some()) {
        return Ok(out);
    }
    let ctx = raster::Ctx {
        splats: &st.splats,
        features: &st.features,
        bins: &st.bins,
        width: w,
        height: h,
        tiles_x: cam.tiles_x,
        threshold: config.alpha_threshold,
    };
    let wu = w as usize;
    let pixel_grads =
        |x: usize, y: usize| pixel_grads(&cam, config, grads, &st.final_t, &st.geo, x, y);
    let ts = TILE_SIZE as usize;
    let gin = |tile: usize| -> raster::TileGradIn {
        let tx = tile % cam.tiles_x as usize;
        let ty = tile / cam.tiles_x as usize;
        let (x0, y0) = (tx * ts, ty * ts);
        let tw = (wu - x0).min(ts);
        let th = (h as usize - y0).min(ts);
        let mut g_ch = Vec::with_capacity(tw * th);
        let mut g_final = Vec::with_capacity(tw * th);
        for ly in 0..th {
            for lx in 0..tw {
                let (gc, ga) = pixel_grads(x0 + lx, y0 + ly);
                g_ch.push(gc);
                g_final.push(ga);
            }
        }
        raster::TileGradIn { g_ch, g_final }
    };
    let px = raster::PixelState {
        final_t: &st.final_t,
        last: &st.last,
    };
    let per_tile = raster::backward_tiles(&ctx, &px, &gin, color, geo, depth);
    // Deterministic merge in tile order.
    let mut sg = vec![SplatGrad::default(); n];
    let mut touched = vec![false; n];
    for list in &per_tile {
        for (cid, g) in list {
            let gid = st.order[*cid as usize] as usize;
            sg[gid].add(g);
            touched[gid] = true;
        }
    }
    drop(per_tile);
    // Projection backward, written in place chunk by chunk (disjoint slices, no atomics).
    let (sx, sy) = (0.5 * w as f32, 0.5 * h as f32);
    const CHUNK: usize = 512;
    let GaussianGradients {
        means,
        log_scales,
        rotations,
        opacity_logits,
        sh,
        mean2d,
        mean2d_abs,
    } = &mut out;
    means
        .par_chunks_mut(CHUNK)
        .zip(log_scales.par_chunks_mut(CHUNK))
        .zip(rotations.par_chunks_mut(CHUNK))
        .zip(opacity_logits.par_chunks_mut(CHUNK))
        .zip(sh.par_chunks_mut(CHUNK))
        .zip(mean2d.par_chunks_mut(CHUNK))
        .zip(mean2d_abs.par_chunks_mut(CHUNK))
        .enumerate()
        .for_each(|(c, ((((((gm, gl), gr), go), gs), g2), ga))| {
            for j in 0..gm.len() {
                let i = c * CHUNK + j;
                if !touched[i] {
                    continue;
                }
                if let Some(pg) = project::project_backward(gaussians, i, &cam, config, &sg[i]) {
                    gm[j] = pg.mean;
                    gl[j] = pg.log_scale;
                    gr[j] = pg.rotation;
                    go[j] = pg.opacity_logit;
                    gs[j] = pg.sh;
                    g2[j] = [sg[i].xy[0] * sx, sg[i].xy[1] * sy];
                    ga[j] = [sg[i].abs_xy[0] * sx, sg[i].abs_xy[1] * sy];
                }
            }
        });
    Ok(out)
}

#[cfg(test)]
mod tests;
