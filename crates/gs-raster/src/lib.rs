//! # gs-raster
//!
//! The differentiable 3D Gaussian splatting tile rasterizer of vagsl (CPU backend, plus a wgpu
//! backend behind the default `wgpu` feature), with the
//! PGSR / VA-GS geometry channels of docs/method.md §Rendering: colour, accumulated alpha A, rendered
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
//!   backends or rasterizers is an [`RasterError::InvalidGradients`]. A training run can keep
//!   its model resident ([`WgpuRasterizer::make_resident`]): renders then bind the device's
//!   parameters without an upload, and [`WgpuRasterizer::backward_and_step`] runs the backward
//!   and the Adam step (the twin of gs-core's) on the device.
//!   Parity with the CPU backend (tests/wgpu_parity.rs): images within 1e-4, gradients within
//!   1e-3 relative (+ a 1e-5·max floor), apart from the rare pixel where an ulp-level
//!   difference flips a discrete decision (α ≥ 1/255, the transmittance stop, T > 0.5).
//!   `RenderStats::box_pairs` is a CPU-only work estimate (0 on wgpu).
//! - **Selection**: [`Rasterizer::new`]`(`[`Backend`]`)` with `"cpu" | "wgpu" | "auto"`;
//!   `auto` uses wgpu only on a hardware adapter (not a software one such as lavapipe) and
//!   the CPU otherwise. Built without the feature, `Backend::Wgpu` is a
//!   [`RasterError::BackendUnavailable`] error and `auto` is the CPU.
//!
//! ## Conventions (one choice per row of the table in docs/method.md §Rendering)
//! - Pixel (i, j) is blended at its centre (i + 0.5, j + 0.5) (docs/architecture.md §Conventions).
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
mod cpu;
#[cfg(feature = "wgpu")]
mod gpu;
mod pixel;
mod types;
mod validate;
pub use validate::MAX_LOW_PASS;

pub use backend::{Backend, Rasterizer, StartedStep, cpu_description, cpu_threads_in_words};
pub use cpu::project::{JACOBIAN_CLAMP, LOW_PASS, MIN_COMPENSATION};
pub use cpu::{backward, render, render_naive};
#[cfg(feature = "wgpu")]
pub use gpu::{
    CallTimings, GpuTimings, PendingStep, TileSplit, WgpuOptions, WgpuRasterizer,
    hardware_adapter_available, probe_adapter,
};
pub use types::{
    ALPHA_THRESHOLD, BornParent, DensifyCounts, TrimOnDevice, UnsureRows, DensifyRule, DeviceStep, ForwardState, GaussianGradients, MAX_ALPHA, OBSERVE_T, OutputGradients,
    PLANE_DEPTH_EPS, RasterConfig, RasterError, RenderOutput, RenderRequest, RenderStats,
    Result, StepExtras, T_STOP, TILE_SIZE, adam_step,
};
pub(crate) use types::StateInner;
#[cfg(feature = "wgpu")]
pub use types::{DeviceGeometryGrads, DevicePlaneGrads};

#[cfg(test)]
mod tests;
