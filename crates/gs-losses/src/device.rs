//! What the losses' device twins share (behind the `wgpu` feature): the passes of one WGSL
//! file compiled on a shared context, one pooled buffer per named binding, the pooled staging
//! buffer of their readback and the dispatcher (docs/architecture.md §GPU).

use crate::error::{LossError, Result};
use gs_gpu::{Binding, BufId, BufferPool, Dispatcher, GpuContext, Kernel, ShrinkPolicy};

/// The kernels and buffers of one loss executor with `B` storage bindings.
pub(crate) struct LossKernels<const B: usize> {
    pub ctx: GpuContext,
    pub pool: BufferPool,
    pub disp: Dispatcher,
    /// One kernel per pass, in the order given.
    pub kernels: Vec<Kernel>,
    /// One buffer per binding, in slot order.
    pub bufs: [BufId; B],
    /// The readback (pooled: a mappable buffer per call is costly to create).
    pub staging: BufId,
}

/// A device error as the crate's error.
pub(crate) fn gpu_error(e: gs_gpu::GpuError) -> LossError {
    LossError::Device(e.to_string())
}

impl<const B: usize> LossKernels<B> {
    /// Compiles `passes` (entry points of `source`, after the generated declarations `decls`:
    /// the frame struct's and the storage records') on `ctx`'s device with the storage
    /// `bindings`, for frames of `frame_bytes`.
    pub fn new(ctx: &GpuContext, decls: &str, frame_bytes: usize, source: &str, bindings: &[Binding<'static>; B], passes: &[&str]) -> Result<Self> {
        let ctx = ctx.clone();
        let kernels = passes
            .iter()
            .map(|entry| Kernel::new(&ctx, entry, &[decls, source], bindings).map_err(gpu_error))
            .collect::<Result<Vec<_>>>()?;
        let mut pool = BufferPool::new(&ctx, ShrinkPolicy::default());
        let bufs = bindings.map(|b| pool.add_storage(b.name));
        let staging = pool.add_staging("loss readback");
        let disp = Dispatcher::new(&ctx, frame_bytes as u64);
        Ok(Self { ctx, pool, disp, kernels, bufs, staging })
    }

    /// Starts a call: each binding's buffer holds at least its size in `sizes` (bytes), the
    /// staging buffer at least `readback` bytes.
    pub fn begin(&mut self, sizes: [u64; B], readback: u64) {
        self.pool.begin_frame();
        for (id, size) in self.bufs.iter().zip(sizes) {
            self.pool.ensure(*id, size.max(4));
        }
        self.pool.ensure(self.staging, readback);
    }
}
