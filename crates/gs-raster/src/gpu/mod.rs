//! The wgpu (WGSL compute) backend: the same numbers as the CPU backend, on a GPU.
//!
//! Kernel structure of one [`WgpuRasterizer::render`] (one queue submission and one readback
//! for an image size rendered before; two for a new size, or when the guess below falls short):
//! 1. `project` (one thread per Gaussian, dispatched in chunks of 2¹⁸ Gaussians so that no
//!    binding exceeds the adapter's storage-binding limit): EWA projection, SH colour,
//!    normal/distance, tile rectangle, depth key (culled Gaussians get key `u32::MAX`).
//! 2. Radix sort of the depth keys (8 stable passes of 4 bits; per pass `radix_count` →
//!    exclusive `scan` of the digit-major histogram → `radix_scatter`), values = Gaussian ids in
//!    index order, so ties keep the CPU's (depth, index) order.
//! 3. `isect_count` (tiles per sorted Gaussian + an exact 64-bit total) and its `scan`. A render
//!    of a new size reads the totals back (8 + 4 bytes) to size the intersection buffers and
//!    check the cap; a render of a size rendered before sizes them, and the blend's window
//!    count, by the last render of that size plus a quarter, and its readback's counters say
//!    whether that held (else it renders again, counting first). `pad_keys` fills the unused
//!    entries with keys that sort last, so the guess changes no value.
//! 4. `isect_emit` writes (tile, emission index) pairs in depth order and each emission index's
//!    Gaussian, a stable radix sort on the tile key (⌈log₂ tiles / 4⌉ passes) groups them per
//!    tile, `tile_ranges` finds each tile's list (and `raster_fwd` the longest), `isect_link`
//!    turns the sorted emission indices into Gaussian ids (what the blends read) and records each emission index's list position.
//! 5. `raster_fwd`: one workgroup per 16×16 tile, each thread owning one or more of its pixels
//!    ([`TileSplit`]: a pixel each on a GPU, 16 on software Vulkan), front to back; writes
//!    the eight accumulators channel-planar, T_final, last contributor, observed counts and
//!    the pair counters (with the longest list position blended, an integer maximum: the
//!    backward's window count). Only what the request needs is read back: its planes, T_final
//!    where colour, alpha or expected depth need it, and both per-pixel states only for
//!    `RenderRequest::traversal`; the backward reads the device's copies.
//!
//! [`WgpuRasterizer::backward`] uploads the per-pixel channel gradients (folded on the host
//! with the CPU code), runs `raster_bwd` (one workgroup per tile of 32 threads on a GPU, 16 on
//! software Vulkan, each owning 8 or 16 pixels; reverse traversal; a workgroup reduction per
//! round of 4 or 8 Gaussians, each written as that intersection's `ScreenGrad` partial),
//! `grad_reduce` (per Gaussian, its partials summed in emission order) and `project_bwd`
//! (chunked like `project`), and reads back only the parameter gradients (SH only up to the
//! active degree). No float atomics anywhere: every sum has a fixed order, so
//! the same inputs give the same bits on every run.
//!
//! The device context, buffer pool, dispatch, readback, prefix scan and radix sort come from
//! gs-gpu; this module keeps the rasterizer's kernels (kernels.rs) and their orchestration
//! (forward.rs, backward.rs). Buffers live in a gs-gpu `BufferPool`: they grow geometrically
//! and shrink again when unneeded for a while (one pool frame per render); bind groups are
//! recreated per call (cheap). Kernels use at most 8 storage buffers and split 1D dispatches
//! beyond 65535 workgroups into 2D.

mod backward;
mod densify;
mod forward;
mod readback;
mod guess;
mod kernels;
mod adam_kernels;
mod resident;
mod resident_rows;
mod split;
pub use resident::PendingStep;
pub use split::TileSplit;

use crate::cpu::project::CamParams;
use crate::{RasterError, RenderRequest, Result};
use gs_gpu::{
    BufId, BufferPool, Dispatcher, GpuContext, GpuError, GpuOptions, RadixSort, ShrinkPolicy,
};
use gs_gpu::bytes_of;
use kernels::{BlendState, CamUniform, Kernels, PixelGrad};
use std::sync::atomic::{AtomicU64, Ordering};

pub use gs_gpu::{hardware_adapter_available, probe_adapter};

/// Gaussians per chunk of the per-Gaussian kernels (a power of two keeps chunk offsets aligned).
const CHUNK: u32 = 1 << 18;
/// Pixel rows per tile row.
const TILE_ROWS_PX: u64 = crate::TILE_SIZE as u64;
/// Entries per dispatch of the kernels that walk a Gaussian's tile rectangle (`isect_emit`,
/// `grad_reduce`): software Vulkan (llvmpipe) stops any invocation after 65535 loop
/// iterations in all. The blends' windows: [`TileSplit::forward_window`] and
/// `split::BWD_WINDOW`.
const ENTRY_WINDOW: u32 = 32768;
/// Largest per-pixel record bound to one kernel (`pixgrad` / `bstate`; the eight accumulator
/// planes take 32 bytes a pixel).
const MAX_PIXEL_BYTES: u64 = max_u64(bytes_of::<PixelGrad>(1), bytes_of::<BlendState>(1));

const fn max_u64(a: u64, b: u64) -> u64 {
    if a > b { a } else { b }
}

/// Distinguishes rasterizers, so that a render's state is never used by another one.
static NEXT_ID: AtomicU64 = AtomicU64::new(1);

/// Options of [`WgpuRasterizer::with_options`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct WgpuOptions {
    /// Refuse CPU (software) adapters such as lavapipe; `Backend::Auto` sets this.
    pub require_hardware: bool,
    /// Assume a smaller maximum storage-binding size than the adapter's (bytes; `None` = the
    /// adapter's). Large images are then processed in more bands of tile rows — tests use it
    /// to exercise the banded path on small images.
    pub max_storage_binding: Option<u64>,
    /// The blend kernels' threads per tile (`None`: [`TileSplit::for_adapter`]); tests use it
    /// to check the other adapter kind's split on lavapipe.
    pub tile_split: Option<TileSplit>,
}

/// The wgpu backend's forward state: a handle to the rasterizer's device-resident buffers
/// plus the few per-pixel values the host-side gradient folding needs.
#[derive(Debug, Clone)]
pub(crate) struct GpuState {
    rasterizer: u64,
    generation: u64,
    n: usize,
    width: u32,
    height: u32,
    request: RenderRequest,
    /// Intersections of the render (checked when the device state is rebuilt).
    total: u32,
    final_t: Vec<f32>,
    /// Per pixel Ñ (3), D, Σ w t_z when plane or expected depth was rendered and its planes
    /// came back, else empty (a backward that needs it reads it from the device).
    geo: Vec<[f32; 5]>,
}

/// The rasterizer's buffers in its pool.
struct Buffers {
    splat: BufId,
    proj: BufId,
    radii: BufId,
    keys_a: BufId,
    vals_a: BufId,
    keys_b: BufId,
    vals_b: BufId,
    keys_c: BufId,
    vals_c: BufId,
    isect_gid: BufId,
    gids: BufId,
    isect_pos: BufId,
    counts: BufId,
    counters: BufId,
    ranges: BufId,
    acc: BufId,
    /// The plane depth made on the device for a render that reads back nothing else of the
    /// geometry.
    depth_plane: BufId,
    final_t: BufId,
    last: BufId,
    observed: BufId,
    pixgrad: BufId,
    bstate: BufId,
    partials: BufId,
    gacc: BufId,
    gout: BufId,
    gout_sh: BufId,
    staging: BufId,
}

impl Buffers {
    fn new(pool: &mut BufferPool) -> Self {
        let mut b = |l| pool.add_storage(l);
        Self {
            splat: b("splat"),
            proj: b("proj"),
            radii: b("radii"),
            keys_a: b("keys_a"),
            vals_a: b("vals_a"),
            keys_b: b("keys_b"),
            vals_b: b("vals_b"),
            keys_c: b("keys_c"),
            vals_c: b("vals_c"),
            isect_gid: b("isect_gid"),
            gids: b("gids"),
            isect_pos: b("isect_pos"),
            counts: b("counts"),
            counters: b("counters"),
            ranges: b("ranges"),
            acc: b("acc"),
            depth_plane: b("depth_plane"),
            final_t: b("final_t"),
            last: b("last"),
            observed: b("observed"),
            pixgrad: b("pixgrad"),
            bstate: b("bstate"),
            partials: b("partials"),
            gacc: b("gacc"),
            gout: b("gout"),
            gout_sh: b("gout_sh"),
            staging: pool.add_staging("staging"),
        }
    }
}

/// What the last render left on the device.
#[derive(Debug, Clone, Copy)]
struct Frame {
    generation: u64,
    total: u32,
    /// Largest last-contributor count of any pixel (bounds the backward windows).
    max_last: u32,
}

/// The wgpu rasterizer: created once (adapter, device, pipelines), then `render` /
/// `backward` as often as needed with the same argument and result types as the CPU
/// [`crate::render`] / [`crate::backward`]. Device buffers persist across calls; they grow
/// geometrically and are given back when unneeded for a while. The device keeps the state
/// of the latest render; the backward of an older render of the same rasterizer first
/// rebuilds that state (one extra forward, same result), and a render from the CPU backend
/// or another rasterizer is a [`RasterError::InvalidGradients`] error.
pub struct WgpuRasterizer {
    ctx: GpuContext,
    disp: Dispatcher,
    pool: BufferPool,
    bufs: Buffers,
    kernels: Kernels,
    /// How the blend kernels share a tile's pixels among threads (and their windows).
    split: TileSplit,
    sort: RadixSort,
    id: u64,
    generation: u64,
    frame: Option<Frame>,
    timings: CallTimings,
    /// The parameters the kernels read, resident between iterations in a training run.
    model: resident::Model,
    /// Density control on the resident model, made when first needed.
    densify: Option<densify::Densify>,
    /// What the last renders of a few image sizes found: the next render of such a size
    /// guesses its buffers from it and runs in one submission (`forward.rs`).
    guesses: Vec<guess::SizeGuess>,
    /// The staging buffers of renders read back together (`render_views`), one per render
    /// in flight, made when first needed (in `pool`).
    batch_staging: Vec<BufId>,
}

/// Host-measured wall time of the phases of one call (see [`WgpuRasterizer::timings`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GpuTimings {
    /// Packing and queueing the uploads (parameters and SH for a render, the per-pixel
    /// gradients for a backward).
    pub upload: std::time::Duration,
    /// From the first submission until the last readback is mapped: the kernels, the
    /// transfers and the waits.
    pub device: std::time::Duration,
    /// Turning the readbacks into the result on the host.
    pub unpack: std::time::Duration,
}

/// [`GpuTimings`] of the latest render and the latest backward.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CallTimings {
    /// The latest [`WgpuRasterizer::render`].
    pub render: GpuTimings,
    /// The latest [`WgpuRasterizer::backward`].
    pub backward: GpuTimings,
}

impl std::fmt::Debug for WgpuRasterizer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WgpuRasterizer")
            .field("adapter", &self.adapter_description())
            .finish()
    }
}

/// gs-gpu errors as rasterizer errors: no adapter or device is `BackendUnavailable`,
/// everything else `Gpu`.
impl From<GpuError> for RasterError {
    fn from(e: GpuError) -> Self {
        match e {
            GpuError::Unavailable(m) => RasterError::BackendUnavailable(m),
            other => RasterError::Gpu(other.to_string()),
        }
    }
}

/// `(first, count)` of each chunk of at most [`CHUNK`] Gaussians.
fn chunks(n: u32) -> impl Iterator<Item = (u64, u64)> {
    (0..n.div_ceil(CHUNK)).map(move |c| {
        let base = c * CHUNK;
        (base as u64, (n - base).min(CHUNK) as u64)
    })
}

impl WgpuRasterizer {
    /// Creates the rasterizer on the best adapter (hardware preferred, software accepted).
    pub fn new() -> Result<Self> {
        Self::with_options(WgpuOptions::default())
    }

    /// Creates the rasterizer with explicit options.
    pub fn with_options(opts: WgpuOptions) -> Result<Self> {
        if let Some(split) = opts.tile_split {
            split.check()?;
        }
        let ctx = GpuContext::new(&GpuOptions {
            require_hardware: opts.require_hardware,
            // No kernel uses float atomics (sums have a fixed order).
            disable_f32_atomics: true,
            max_storage_binding: opts.max_storage_binding,
        })?;
        let split = opts.tile_split.unwrap_or_else(|| TileSplit::for_adapter(ctx.is_software()));
        let kernels = Kernels::new(&ctx, split)?;
        let mut pool = BufferPool::new(&ctx, ShrinkPolicy::default());
        let sort = RadixSort::new(&ctx, &mut pool)?;
        let bufs = Buffers::new(&mut pool);
        let disp = Dispatcher::new(&ctx, std::mem::size_of::<CamUniform>() as u64);
        let model = resident::Model::new(&ctx)?;
        Ok(Self {
            ctx,
            disp,
            pool,
            bufs,
            kernels,
            split,
            sort,
            id: NEXT_ID.fetch_add(1, Ordering::Relaxed),
            generation: 0,
            frame: None,
            guesses: Vec::new(),
            batch_staging: Vec::new(),
            timings: CallTimings::default(),
            model,
            densify: None,
        })
    }

    /// "name (device type, backend, driver)" of the adapter in use.
    pub fn adapter_description(&self) -> String {
        self.ctx.description()
    }

    /// How the blend kernels share a tile's pixels among threads.
    pub fn tile_split(&self) -> TileSplit {
        self.split
    }

    /// Whether the adapter is a CPU (software) implementation such as lavapipe.
    pub fn is_software(&self) -> bool {
        self.ctx.is_software()
    }

    /// One dispatch of `kernel` per band of tile rows, a thread per pixel: `binds(p0, bp)`
    /// gives the band's bindings (its first pixel `p0`, `bp` pixels); the pass carries the band
    /// with `pass`'s other fields.
    pub(super) fn per_band<'b, const N: usize>(
        &self,
        enc: &mut gs_gpu::Encoder,
        bands: &[(u32, u32, u64, u64)],
        kernel: &gs_gpu::Kernel,
        pass: gs_gpu::PassUniform,
        binds: impl Fn(u64, u64) -> [gs_gpu::Bind<'b>; N],
    ) -> Result<()> {
        for &(_, _, p0, bp) in bands {
            self.disp.make_room(enc, 1);
            let band = gs_gpu::PassUniform { n: bp as u32, base: p0 as u32, ..pass };
            self.disp.dispatch_1d(enc, kernel, &binds(p0, bp), band)?;
        }
        Ok(())
    }

    /// The device context, for kernels that share this rasterizer's device (the loss terms').
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// Where the latest render and backward spent their wall time (host clock): what the
    /// raster bench reports, to tell transfers from kernels.
    pub fn timings(&self) -> CallTimings {
        self.timings
    }

    fn check_binding(&self, what: &str, bytes: u64) -> Result<()> {
        let max = self.ctx.max_storage_binding();
        if bytes > max {
            return Err(RasterError::Gpu(format!(
                "{what} needs {bytes} bytes in one storage binding, above this adapter's limit of {max} bytes; use the CPU backend (or a GPU with a larger limit)"
            )));
        }
        Ok(())
    }

    /// Runs `f` inside device error scopes: a validation or out-of-memory error of the
    /// recorded work becomes `RasterError::Gpu` (and wins over `f`'s own result).
    fn scoped<T>(&mut self, f: impl FnOnce(&mut Self) -> Result<T>) -> Result<T> {
        self.ctx.push_error_scopes();
        let res = f(self);
        self.ctx.pop_error_scopes()?;
        res
    }

    /// Bands of tile rows `(first row, rows, first pixel, pixels)` such that every per-pixel
    /// buffer of a band fits one storage binding (one band unless the image is huge for this
    /// adapter). Band starts are multiples of 4 tile rows, which keeps binding offsets
    /// 256-byte aligned.
    fn bands(&self, cam: &CamParams) -> Result<Vec<(u32, u32, u64, u64)>> {
        let max_binding = self.ctx.max_storage_binding();
        let w = cam.width as u64;
        let per_row = TILE_ROWS_PX * w * MAX_PIXEL_BYTES;
        let fit = (max_binding / per_row) as u32;
        // At most 65532 tile rows per dispatch (the workgroup-count limit, a multiple of 4).
        let rows = if fit >= cam.tiles_y && cam.tiles_y <= 65535 {
            cam.tiles_y
        } else {
            fit.min(65532) / 4 * 4
        };
        if rows == 0 {
            return Err(RasterError::Gpu(format!(
                "an image {} pixels wide needs more than this adapter's {}-byte storage binding for 4 tile rows; use the CPU backend",
                cam.width, max_binding
            )));
        }
        let mut out = Vec::new();
        let mut r0 = 0;
        while r0 < cam.tiles_y {
            let r = rows.min(cam.tiles_y - r0);
            let y0 = (r0 * TILE_ROWS_PX as u32) as u64;
            let y1 = ((r0 + r) * TILE_ROWS_PX as u32).min(cam.height) as u64;
            out.push((r0, r, y0 * w, (y1 - y0) * w));
            r0 += r;
        }
        Ok(out)
    }
}

/// Writes `len` records produced by `fill` to the start of pool buffer `id` (grown first, to
/// at least one record: a kernel's binding holds at least one).
fn upload_with<T: bytemuck::Pod>(
    ctx: &GpuContext,
    pool: &mut BufferPool,
    id: BufId,
    len: usize,
    fill: impl Fn(&mut [T]),
) {
    let bytes = len as u64 * bytes_of::<T>(1);
    pool.ensure(id, bytes.max(bytes_of::<T>(1)));
    ctx.write_with(pool.buffer(id), bytes, |b| match bytemuck::try_cast_slice_mut::<u8, T>(b) {
        Ok(f) => fill(f),
        Err(_) => {
            let mut v = vec![T::zeroed(); len];
            fill(&mut v);
            b.copy_from_slice(bytemuck::cast_slice(&v));
        }
    });
}

/// Records of type `T` from read-back bytes (copied only where the mapping is misaligned).
fn pod_vec<T: bytemuck::Pod>(bytes: &[u8]) -> std::borrow::Cow<'_, [T]> {
    match bytemuck::try_cast_slice::<u8, T>(bytes) {
        Ok(v) => std::borrow::Cow::Borrowed(v),
        Err(_) => std::borrow::Cow::Owned(bytemuck::pod_collect_to_vec(bytes)),
    }
}
