//! # gs-gpu
//!
//! The shared wgpu layer of vagsl, below every GPU kernel crate (it depends on no gs-* crate):
//!
//! - [`GpuContext`]: adapter choice (hardware preferred, software such as lavapipe accepted
//!   unless [`GpuOptions::require_hardware`]), device, queue, limits (WebGPU defaults with the
//!   adapter's buffer sizes) and features (native `atomic<f32>` or not), error scopes and
//!   readback. [`probe_adapter`] / [`hardware_adapter_available`] answer cheaply whether a
//!   context could be made.
//! - [`BufferPool`]: named device buffers that grow geometrically and **shrink** again when a
//!   buffer was not needed for a while or is far larger than its recent need
//!   ([`ShrinkPolicy`]); one [`BufferPool::begin_frame`] per frame drives it.
//! - [`Kernel`] + [`Dispatcher`]: every kernel uses one bind-group convention — binding 0 the
//!   dispatcher's frame uniform (any [`WgslStruct`]), binding 1 the per-dispatch
//!   [`PassUniform`] (a dynamic-offset slot), bindings 2.. storage buffers declared from a Rust
//!   [`Binding`] table (the WGSL declarations and the bind-group layout come from the same
//!   table). 1D dispatches beyond 65535 workgroups are split into 2D ([`grid`]).
//! - [`PrefixScan`] (exclusive, in place, multi-level) and [`RadixSort`] (stable LSD, 4 bits a
//!   pass, key/value u32 pairs), each WGSL snippet in one file and composed, never copied.
//! - [`wgsl_struct!`]: a `#[repr(C)]` Rust struct and its WGSL declaration from one
//!   definition; [`check_layout`] verifies with naga that the WGSL offsets equal Rust's.
//!
//! ```no_run
//! use gs_gpu::{Binding, BufferPool, Dispatcher, GpuContext, GpuOptions, Kernel, PassUniform,
//!     ShrinkPolicy};
//!
//! # fn main() -> Result<(), gs_gpu::GpuError> {
//! let ctx = GpuContext::new(&GpuOptions::default())?;
//! let mut pool = BufferPool::new(&ctx, ShrinkPolicy::default());
//! let data = pool.add_storage("data");
//! // A kernel that doubles `data[i]`: the storage declaration is generated from the table.
//! let double = Kernel::new(&ctx, "double", &["@compute @workgroup_size(256)
//!     fn double(ids: Ids) { let i = thread_1d(ids); if (i < pass_.n) { data[i] *= 2u; } }"],
//!     &[Binding::write("data", "array<u32>")])?;
//! let disp = Dispatcher::new(&ctx, 16);
//! pool.begin_frame();
//! pool.ensure(data, 4 * 1000);
//! ctx.queue().write_buffer(pool.buffer(data), 0, bytemuck::cast_slice(&[1u32; 1000]));
//! let mut enc = disp.encoder();
//! disp.dispatch_1d(&mut enc, &double, &[pool.whole(data)],
//!     PassUniform { n: 1000, ..Default::default() })?;
//! disp.submit(enc);
//! let out: Vec<u32> = bytemuck::pod_collect_to_vec(&ctx.download(pool.buffer(data), 0, 4000)?);
//! assert!(out.iter().all(|&v| v == 2));
//! # Ok(()) }
//! ```

#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;

mod arena;
mod context;
mod dispatch;
mod image;
mod kernel;
mod layout;
mod ledger;
mod pool;
mod scan;
mod sort;

pub use arena::{Arena, ArenaKey};
pub use context::{GpuContext, GpuOptions, PendingRead, hardware_adapter_available, probe_adapter};
pub use dispatch::{Dispatcher, Encoder, MAX_SLOTS, SLOT, grid};
pub use image::{DeviceImage, PLANE_GRAD_CHANNELS, PlaneGrad, SURFACE_CHANNELS, SurfaceTexel};
pub use kernel::{Binding, Kernel, PassUniform, kernel_source};
pub use ledger::Transfers;
pub use layout::{GeneratedStruct, WgslField, WgslStruct, WgslType, bytes_of, check_layout, check_layouts, declarations, validate_kernel};
pub use pool::{Bind, BufId, BufferPool, ShrinkPolicy};
pub use scan::PrefixScan;
pub use sort::RadixSort;
/// The wgpu version gs-gpu is built on (callers use its types through this).
pub use wgpu;

/// The f64 value of a double-f32 pair `(hi, lo)` made on the device by the prelude's
/// `wide_add` (a total of row sums added in order there): exact, the pair holding no more
/// significant bits than an f64.
pub fn wide_value([hi, lo]: [f32; 2]) -> f64 {
    hi as f64 + lo as f64
}

use thiserror::Error;

/// Errors of the GPU layer.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum GpuError {
    /// No suitable adapter, or the device could not be created.
    #[error("{0}")]
    Unavailable(String),
    /// A device-side failure: validation error, out of memory, lost device, failed mapping.
    #[error("{0}")]
    Device(String),
    /// More dispatches were recorded into one submission than there are uniform slots.
    #[error("too many dispatches in one submission (at most {0})")]
    TooManyDispatches(usize),
    /// A kernel's scratch buffer is smaller than the work recorded needs: its owner's
    /// `reserve` was not called for this size in this frame.
    #[error("scratch buffer '{label}' holds {have} bytes but this pass needs {need}: call reserve for the size first")]
    NotReserved {
        /// The pool label of the scratch buffer.
        label: &'static str,
        /// Bytes the recorded pass needs.
        need: u64,
        /// Bytes the buffer has.
        have: u64,
    },
}

/// Result alias of gs-gpu.
pub type Result<T> = std::result::Result<T, GpuError>;
