//! The wgpu (WGSL compute) backend: the same numbers as the CPU backend, on a GPU.
//!
//! Kernel structure of one [`WgpuRasterizer::render`] (two queue submissions, two readbacks):
//! 1. `project` (one thread per Gaussian, dispatched in chunks of 2¹⁸ Gaussians so that no
//!    binding exceeds the adapter's storage-binding limit): EWA projection, SH colour,
//!    normal/distance, tile rectangle, depth key (culled Gaussians get key `u32::MAX`).
//! 2. Radix sort of the depth keys (8 stable passes of 4 bits; per pass `radix_count` →
//!    exclusive `scan` of the digit-major histogram → `radix_scatter`), values = Gaussian ids in
//!    index order, so ties keep the CPU's (depth, index) order.
//! 3. `isect_count` (tiles per sorted Gaussian + an exact 64-bit total) and its `scan`; the
//!    totals are read back (8 + 4 bytes) to size the intersection buffers and check the cap.
//! 4. `isect_emit` writes (tile, id) pairs in depth order, a stable radix sort on the tile key
//!    (⌈log₂ tiles / 4⌉ passes) groups them per tile, `tile_ranges` finds each tile's list.
//! 5. `raster_fwd`: one workgroup per 16×16 tile, one thread per pixel, front to back; writes
//!    the eight accumulators channel-planar, T_final, last contributor, observed counts and
//!    the pair counters. Only the planes the request needs are read back.
//!
//! [`WgpuRasterizer::backward`] uploads the per-pixel channel gradients (folded on the host
//! with the CPU code), runs `raster_bwd` (one workgroup of 128 threads per tile, reverse
//! traversal, per-Gaussian workgroup reduction, one global atomic add per gradient component:
//! native `atomic<f32>` when the adapter has `SHADER_FLOAT32_ATOMIC`, else a compare-exchange
//! loop on `atomic<u32>`) and `project_bwd` (chunked like `project`), and reads back only the
//! parameter gradients (SH only up to the active degree).
//!
//! Buffers live in the rasterizer and grow geometrically (never shrink); bind groups are
//! recreated per call (cheap). Kernels use at most 8 storage buffers and split 1D dispatches
//! beyond 65535 workgroups into 2D.

use crate::cpu::project::CamParams;
use crate::{
    GaussianGradients, OutputGradients, RasterConfig, RasterError, RenderOutput, RenderRequest,
    RenderStats, Result,
};
use gs_core::sh::coeffs_for_degree;
use gs_core::{Camera, Gaussians};
use std::num::NonZeroU64;
use std::sync::atomic::{AtomicU64, Ordering};

/// Gaussians per chunk of the per-Gaussian kernels (a power of two keeps chunk offsets aligned).
const CHUNK: u32 = 1 << 18;
/// Floats per splat record (x, y, conic 3, opacity, σ_max, ext 2, features 8).
const SPLAT_STRIDE: u64 = 17;
/// Floats per parameter record (mean 3, log-scale 3, quaternion 4, opacity logit).
const PARAM_STRIDE: u64 = 11;
/// Pixel rows per tile row.
const TILE_ROWS_PX: u64 = crate::TILE_SIZE as u64;
/// Bytes between two per-dispatch uniform slots.
const SLOT: u64 = 256;
/// Uniform slots per submission.
const MAX_SLOTS: usize = 512;
/// Elements per radix-sort / scan block.
const BLOCK: u32 = 1024;
/// Tile-list positions per forward dispatch and per backward dispatch. Software Vulkan
/// (llvmpipe) stops any invocation after 65535 loop iterations in total, so long tile lists
/// are walked in windows with the per-pixel state kept in buffers between dispatches.
const FWD_WINDOW: u32 = 32768;
const BWD_WINDOW: u32 = 256;
/// Largest per-pixel record bound to one kernel (the 9 floats of `pixgrad` / `bstate`).
const MAX_PIXEL_BYTES: u64 = 36;

static NEXT_ID: AtomicU64 = AtomicU64::new(1);

/// Options of [`WgpuRasterizer::with_options`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct WgpuOptions {
    /// Use the u32 compare-exchange loop for gradient accumulation even when the adapter has
    /// native f32 atomics (tests exercise both paths with it).
    pub force_cas_atomics: bool,
    /// Refuse CPU (software) adapters such as lavapipe; `Backend::Auto` sets this.
    pub require_hardware: bool,
    /// Assume a smaller maximum storage-binding size than the adapter's (bytes; `None` = the
    /// adapter's). Large images are then processed in more bands of tile rows — tests use it
    /// to exercise the banded path on small images.
    pub max_storage_binding: Option<u64>,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct CamUniform {
    r0: [f32; 4],
    r1: [f32; 4],
    r2: [f32; 4],
    tc: [f32; 4],
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    lim_x: f32,
    lim_y: f32,
    near: f32,
    far: f32,
    threshold: f32,
    antialiased: u32,
    sh_degree: u32,
    nc: u32,
    width: u32,
    height: u32,
    tiles_x: u32,
    tiles_y: u32,
    flags: u32,
    n: u32,
    pad0: u32,
    pad1: u32,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct PassUniform {
    n: u32,
    shift: u32,
    nb: u32,
    base: u32,
    mode: u32,
    pad: [u32; 3],
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
    /// Per pixel Ñ (3), D, Σ w t_z when plane or expected depth was rendered, else empty.
    geo: Vec<[f32; 5]>,
}

/// One compute pipeline and its bind-group layout (binding 0: camera uniform, 1: pass uniform
/// with dynamic offset, 2..: storage buffers).
struct Kernel {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

struct Kernels {
    project: Kernel,
    project_bwd: Kernel,
    scan_reduce: Kernel,
    scan_apply: Kernel,
    radix_count: Kernel,
    radix_scatter: Kernel,
    isect_count: Kernel,
    isect_emit: Kernel,
    tile_ranges: Kernel,
    raster_fwd: Kernel,
    raster_bwd: Kernel,
}

/// A device buffer that grows geometrically and never shrinks.
struct GrowBuf {
    buf: wgpu::Buffer,
    cap: u64,
    usage: wgpu::BufferUsages,
    label: &'static str,
    /// Geometric growth stops here (the storage-binding limit: buffers are bound whole).
    limit: u64,
}

impl GrowBuf {
    fn new(device: &wgpu::Device, label: &'static str, usage: wgpu::BufferUsages, limit: u64) -> Self {
        let cap = 256;
        let buf = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: cap,
            usage,
            mapped_at_creation: false,
        });
        Self {
            buf,
            cap,
            usage,
            label,
            limit,
        }
    }

    /// Makes room for `bytes` (contents are lost when it grows).
    fn ensure(&mut self, device: &wgpu::Device, bytes: u64) {
        if bytes <= self.cap {
            return;
        }
        let grown = self.cap.saturating_mul(2).min(self.limit / 256 * 256);
        let cap = bytes.next_multiple_of(4).max(grown);
        self.buf = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(self.label),
            size: cap,
            usage: self.usage,
            mapped_at_creation: false,
        });
        self.cap = cap;
    }
}

struct Buffers {
    params: GrowBuf,
    sh: GrowBuf,
    splat: GrowBuf,
    proj: GrowBuf,
    radii: GrowBuf,
    keys_a: GrowBuf,
    vals_a: GrowBuf,
    keys_b: GrowBuf,
    vals_b: GrowBuf,
    keys_c: GrowBuf,
    vals_c: GrowBuf,
    hist: GrowBuf,
    scan_tmp: GrowBuf,
    counts: GrowBuf,
    counters: GrowBuf,
    ranges: GrowBuf,
    acc: GrowBuf,
    final_t: GrowBuf,
    last: GrowBuf,
    observed: GrowBuf,
    pixgrad: GrowBuf,
    bstate: GrowBuf,
    gacc: GrowBuf,
    gout: GrowBuf,
    staging: GrowBuf,
    pass: GrowBuf,
}

/// What the last render left on the device.
#[derive(Debug, Clone, Copy)]
struct Frame {
    generation: u64,
    total: u32,
    /// Largest last-contributor count of any pixel (bounds the backward windows).
    max_last: u32,
    /// Whether the tile-sorted intersections ended in the `c` pair (else `b`).
    tiles_in_c: bool,
}

/// A buffer range bound to a storage slot.
#[derive(Clone, Copy)]
struct Bind<'a> {
    buf: &'a wgpu::Buffer,
    offset: u64,
    size: u64,
}

fn whole(b: &GrowBuf) -> Bind<'_> {
    Bind {
        buf: &b.buf,
        offset: 0,
        size: b.cap,
    }
}

fn range(b: &GrowBuf, offset: u64, size: u64) -> Bind<'_> {
    Bind {
        buf: &b.buf,
        offset,
        size: size.max(4),
    }
}

/// A command encoder plus the per-dispatch uniform slots written before its submission.
struct Enc {
    encoder: wgpu::CommandEncoder,
    slots: Vec<PassUniform>,
}

/// Splits `groups` workgroups into an (x, y) grid with x ≤ 65535.
fn grid(groups: u32) -> (u32, u32) {
    if groups <= 65535 {
        (groups.max(1), 1)
    } else {
        (65535, groups.div_ceil(65535))
    }
}

/// The wgpu rasterizer: created once (adapter, device, pipelines), then `render` /
/// `backward` as often as needed with the same argument and result types as the CPU
/// [`crate::render`] / [`crate::backward`]. Device buffers persist across calls and grow
/// geometrically. The device keeps the state of the latest render; the backward of an older
/// render of the same rasterizer first rebuilds that state (one extra forward, same result),
/// and a render from the CPU backend or another rasterizer is a
/// [`RasterError::InvalidGradients`] error.
pub struct WgpuRasterizer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
    native_atomics: bool,
    max_binding: u64,
    kernels: Kernels,
    bufs: Buffers,
    cam_buf: wgpu::Buffer,
    id: u64,
    generation: u64,
    frame: Option<Frame>,
    /// Host scratch reused across calls (parameter and SH upload, per-pixel gradients).
    scratch: Vec<f32>,
    scratch_px: Vec<f32>,
}

impl std::fmt::Debug for WgpuRasterizer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WgpuRasterizer")
            .field("adapter", &self.adapter_description())
            .field("native_f32_atomics", &self.native_atomics)
            .finish()
    }
}

fn gpu_err(e: impl std::fmt::Display) -> RasterError {
    RasterError::Gpu(e.to_string())
}

/// Ranks adapters: discrete > integrated > virtual > other > CPU.
fn adapter_rank(t: wgpu::DeviceType) -> u32 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    }
}

/// The best adapter of this machine that supports compute, if any.
fn pick_adapter(require_hardware: bool) -> Option<(wgpu::Instance, wgpu::Adapter)> {
    // `Instance::new` panics when no backend is compiled in for this platform.
    if wgpu::Instance::enabled_backend_features().is_empty() {
        return None;
    }
    let instance = wgpu::Instance::new(&wgpu::InstanceDescriptor {
        backends: wgpu::Backends::PRIMARY,
        ..Default::default()
    });
    let mut adapters = instance.enumerate_adapters(wgpu::Backends::PRIMARY);
    adapters.retain(|a| {
        let info = a.get_info();
        !(require_hardware && info.device_type == wgpu::DeviceType::Cpu)
            && a.get_downlevel_capabilities()
                .flags
                .contains(wgpu::DownlevelFlags::COMPUTE_SHADERS)
    });
    adapters.sort_by_key(|a| adapter_rank(a.get_info().device_type));
    let a = adapters.into_iter().next()?;
    Some((instance, a))
}

/// Description of the adapter the wgpu backend would use here (`None` when there is none);
/// cheap enough for logging and for tests that decide whether to skip.
pub fn probe_adapter() -> Option<String> {
    pick_adapter(false).map(|(_, a)| describe(&a.get_info()))
}

/// Whether a hardware (non-CPU) adapter exists (what `Backend::Auto` checks).
pub fn hardware_adapter_available() -> bool {
    pick_adapter(true).is_some()
}

fn describe(info: &wgpu::AdapterInfo) -> String {
    format!(
        "{} ({:?}, {:?}, driver {} {})",
        info.name, info.device_type, info.backend, info.driver, info.driver_info
    )
}

impl WgpuRasterizer {
    /// Creates the rasterizer on the best adapter (hardware preferred, software accepted).
    pub fn new() -> Result<Self> {
        Self::with_options(WgpuOptions::default())
    }

    /// Creates the rasterizer with explicit options.
    pub fn with_options(opts: WgpuOptions) -> Result<Self> {
        let (_instance, adapter) = pick_adapter(opts.require_hardware).ok_or_else(|| {
            RasterError::BackendUnavailable(if opts.require_hardware {
                "no hardware GPU adapter (Vulkan/Metal/DX12) found".into()
            } else {
                "no wgpu adapter (Vulkan/Metal/DX12) found".into()
            })
        })?;
        let info = adapter.get_info();
        let native_atomics = !opts.force_cas_atomics
            && adapter
                .features()
                .contains(wgpu::Features::SHADER_FLOAT32_ATOMIC);
        let required_features = if native_atomics {
            wgpu::Features::SHADER_FLOAT32_ATOMIC
        } else {
            wgpu::Features::empty()
        };
        let al = adapter.limits();
        // WebGPU's default limits (8 storage buffers per stage, 16 KiB workgroup memory, 256
        // invocations, 65535 workgroups per dimension), with the adapter's buffer sizes.
        let limits = wgpu::Limits {
            max_storage_buffer_binding_size: al.max_storage_buffer_binding_size,
            max_buffer_size: al.max_buffer_size,
            ..wgpu::Limits::default()
        };
        if !limits.check_limits(&al) {
            return Err(RasterError::BackendUnavailable(format!(
                "adapter {} does not meet WebGPU's default limits",
                describe(&info)
            )));
        }
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("gs-raster"),
            required_features,
            required_limits: limits,
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| RasterError::BackendUnavailable(format!("{}: {e}", describe(&info))))?;
        // Errors of render/backward are caught by error scopes and returned; anything else
        // (e.g. a lost device) is logged instead of wgpu's default panic.
        device.on_uncaptured_error(std::sync::Arc::new(|e| {
            eprintln!("gs-raster wgpu: uncaptured device error: {e}");
        }));
        device.push_error_scope(wgpu::ErrorFilter::Validation);
        let kernels = Kernels::new(&device, native_atomics);
        if let Some(e) = pollster::block_on(device.pop_error_scope()) {
            return Err(gpu_err(format!("shader or pipeline creation failed: {e}")));
        }
        let st = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC;
        let max_binding = (al.max_storage_buffer_binding_size as u64)
            .min(opts.max_storage_binding.unwrap_or(u64::MAX))
            .max(1 << 16);
        let b = |l| GrowBuf::new(&device, l, st, max_binding);
        let bufs = Buffers {
            params: b("params"),
            sh: b("sh"),
            splat: b("splat"),
            proj: b("proj"),
            radii: b("radii"),
            keys_a: b("keys_a"),
            vals_a: b("vals_a"),
            keys_b: b("keys_b"),
            vals_b: b("vals_b"),
            keys_c: b("keys_c"),
            vals_c: b("vals_c"),
            hist: b("hist"),
            scan_tmp: b("scan_tmp"),
            counts: b("counts"),
            counters: b("counters"),
            ranges: b("ranges"),
            acc: b("acc"),
            final_t: b("final_t"),
            last: b("last"),
            observed: b("observed"),
            pixgrad: b("pixgrad"),
            bstate: b("bstate"),
            gacc: b("gacc"),
            gout: b("gout"),
            staging: GrowBuf::new(
                &device,
                "staging",
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                u64::MAX,
            ),
            pass: GrowBuf::new(
                &device,
                "pass",
                wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                u64::MAX,
            ),
        };
        let cam_buf = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("cam"),
            size: std::mem::size_of::<CamUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut r = Self {
            device,
            queue,
            info,
            native_atomics,
            max_binding,
            kernels,
            bufs,
            cam_buf,
            id: NEXT_ID.fetch_add(1, Ordering::Relaxed),
            generation: 0,
            frame: None,
            scratch: Vec::new(),
            scratch_px: Vec::new(),
        };
        r.bufs.pass.ensure(&r.device, SLOT * MAX_SLOTS as u64);
        r.bufs.counters.ensure(&r.device, 64);
        Ok(r)
    }

    /// "name (device type, backend, driver)" of the adapter in use.
    pub fn adapter_description(&self) -> String {
        describe(&self.info)
    }

    /// Whether the adapter is a CPU (software) implementation such as lavapipe.
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// Whether gradients accumulate with native f32 atomics (else the u32 CAS loop).
    pub fn native_f32_atomics(&self) -> bool {
        self.native_atomics
    }

    fn cam_uniform(&self, cam: &CamParams, cfg: &RasterConfig, g: &Gaussians, flags: u32) -> CamUniform {
        let r = cam.r;
        CamUniform {
            r0: [r.x_axis.x, r.x_axis.y, r.x_axis.z, 0.0],
            r1: [r.y_axis.x, r.y_axis.y, r.y_axis.z, 0.0],
            r2: [r.z_axis.x, r.z_axis.y, r.z_axis.z, 0.0],
            tc: [cam.t.x, cam.t.y, cam.t.z, 0.0],
            fx: cam.fx,
            fy: cam.fy,
            cx: cam.cx,
            cy: cam.cy,
            lim_x: cam.lim_x,
            lim_y: cam.lim_y,
            near: cfg.near,
            far: cfg.far,
            threshold: cfg.alpha_threshold,
            antialiased: cfg.antialiased as u32,
            sh_degree: g.sh_degree,
            nc: coeffs_for_degree(g.sh_degree) as u32,
            width: cam.width,
            height: cam.height,
            tiles_x: cam.tiles_x,
            tiles_y: cam.tiles_y,
            flags,
            n: g.len() as u32,
            pad0: 0,
            pad1: 0,
        }
    }

    fn check_binding(&self, what: &str, bytes: u64) -> Result<()> {
        if bytes > self.max_binding {
            return Err(RasterError::Gpu(format!(
                "{what} needs {bytes} bytes in one storage binding, above this adapter's limit of {} bytes; use the CPU backend (or a GPU with a larger limit)",
                self.max_binding
            )));
        }
        Ok(())
    }

    /// Bands of tile rows `(first row, rows, first pixel, pixels)` such that every per-pixel
    /// buffer of a band fits one storage binding (one band unless the image is huge for this
    /// adapter). Band starts are multiples of 4 tile rows, which keeps binding offsets
    /// 256-byte aligned.
    fn bands(&self, cam: &CamParams) -> Result<Vec<(u32, u32, u64, u64)>> {
        let w = cam.width as u64;
        let per_row = TILE_ROWS_PX * w * MAX_PIXEL_BYTES;
        let fit = (self.max_binding / per_row) as u32;
        // At most 65532 tile rows per dispatch (the workgroup-count limit, a multiple of 4).
        let rows = if fit >= cam.tiles_y && cam.tiles_y <= 65535 {
            cam.tiles_y
        } else {
            fit.min(65532) / 4 * 4
        };
        if rows == 0 {
            return Err(RasterError::Gpu(format!(
                "an image {} pixels wide needs more than this adapter's {}-byte storage binding for 4 tile rows; use the CPU backend",
                cam.width, self.max_binding
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

    /// Uploads parameters and SH (packed, only the active degree's coefficients).
    fn upload_gaussians(&mut self, g: &Gaussians) {
        let n = g.len();
        let nc = coeffs_for_degree(g.sh_degree);
        let s = &mut self.scratch;
        s.clear();
        s.reserve(n * PARAM_STRIDE as usize);
        for i in 0..n {
            s.extend_from_slice(&g.means[i]);
            s.extend_from_slice(&g.log_scales[i]);
            s.extend_from_slice(&g.rotations[i]);
            s.push(g.opacity_logits[i]);
        }
        let bytes = (s.len() * 4) as u64;
        self.bufs.params.ensure(&self.device, bytes.max(4));
        if bytes > 0 {
            self.queue
                .write_buffer(&self.bufs.params.buf, 0, bytemuck::cast_slice(s));
        }
        s.clear();
        s.reserve(n * nc * 3);
        for c in &g.sh {
            for k in c.iter().take(nc) {
                s.extend_from_slice(k);
            }
        }
        let bytes = (s.len() * 4) as u64;
        self.bufs.sh.ensure(&self.device, bytes.max(4));
        if bytes > 0 {
            self.queue
                .write_buffer(&self.bufs.sh.buf, 0, bytemuck::cast_slice(s));
        }
    }

    fn encoder(&self) -> Enc {
        Enc {
            encoder: self
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None }),
            slots: Vec::new(),
        }
    }

    /// Records one dispatch of `kernel` with storage bindings `binds` (slots 2..).
    fn dispatch(
        &self,
        enc: &mut Enc,
        kernel: &Kernel,
        binds: &[Bind],
        pass: PassUniform,
        groups: (u32, u32),
    ) -> Result<()> {
        if enc.slots.len() >= MAX_SLOTS {
            return Err(gpu_err("too many dispatches in one submission"));
        }
        let slot = enc.slots.len();
        enc.slots.push(pass);
        let mut entries = vec![
            wgpu::BindGroupEntry {
                binding: 0,
                resource: self.cam_buf.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &self.bufs.pass.buf,
                    offset: 0,
                    size: NonZeroU64::new(std::mem::size_of::<PassUniform>() as u64),
                }),
            },
        ];
        for (k, b) in binds.iter().enumerate() {
            entries.push(wgpu::BindGroupEntry {
                binding: 2 + k as u32,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: b.buf,
                    offset: b.offset,
                    size: NonZeroU64::new(b.size),
                }),
            });
        }
        let bg = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &kernel.layout,
            entries: &entries,
        });
        let mut cp = enc
            .encoder
            .begin_compute_pass(&wgpu::ComputePassDescriptor::default());
        cp.set_pipeline(&kernel.pipeline);
        cp.set_bind_group(0, &bg, &[(slot as u64 * SLOT) as u32]);
        cp.dispatch_workgroups(groups.0, groups.1, 1);
        Ok(())
    }

    /// Submits `enc` and starts a new encoder when fewer than `k` uniform slots are left
    /// (the recorded dispatches keep their order across submissions).
    fn make_room(&self, enc: &mut Enc, k: usize) -> Result<()> {
        if enc.slots.len() + k > MAX_SLOTS {
            let full = std::mem::replace(enc, self.encoder());
            self.submit(full)?;
        }
        Ok(())
    }

    /// Per-element dispatch of `n` threads in workgroups of 256.
    fn dispatch_1d(&self, enc: &mut Enc, kernel: &Kernel, binds: &[Bind], pass: PassUniform) -> Result<()> {
        if pass.n == 0 {
            return Ok(());
        }
        self.dispatch(enc, kernel, binds, pass, grid(pass.n.div_ceil(256)))
    }

    /// Writes the uniform slots and submits; returns after the device finished when `wait`.
    fn submit(&self, enc: Enc) -> Result<()> {
        if !enc.slots.is_empty() {
            let mut bytes = vec![0u8; enc.slots.len() * SLOT as usize];
            for (k, s) in enc.slots.iter().enumerate() {
                let o = k * SLOT as usize;
                bytes[o..o + std::mem::size_of::<PassUniform>()]
                    .copy_from_slice(bytemuck::bytes_of(s));
            }
            self.queue.write_buffer(&self.bufs.pass.buf, 0, &bytes);
        }
        self.queue.submit(Some(enc.encoder.finish()));
        Ok(())
    }

    /// Maps the first `bytes` of the staging buffer and returns a copy.
    fn read_staging(&self, bytes: u64) -> Result<Vec<u8>> {
        if bytes == 0 {
            return Ok(Vec::new());
        }
        let slice = self.bufs.staging.buf.slice(0..bytes);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(gpu_err)?;
        rx.recv().map_err(gpu_err)?.map_err(gpu_err)?;
        let out = slice.get_mapped_range().to_vec();
        self.bufs.staging.buf.unmap();
        Ok(out)
    }

    /// Exclusive scan of `n` u32 of `data` (from byte `offset`), in place, multi-level.
    fn scan(&self, enc: &mut Enc, data: Bind, n: u32, tmp_off: u64) -> Result<()> {
        let nb = n.div_ceil(BLOCK);
        if nb <= 1 {
            let pass = PassUniform {
                n,
                nb: 1,
                ..Default::default()
            };
            let dummy = range(&self.bufs.scan_tmp, tmp_off, 4);
            return self.dispatch(enc, &self.kernels.scan_apply, &[data, dummy], pass, (1, 1));
        }
        let sums = range(&self.bufs.scan_tmp, tmp_off, nb as u64 * 4);
        let pass = PassUniform {
            n,
            nb,
            ..Default::default()
        };
        self.dispatch(enc, &self.kernels.scan_reduce, &[data, sums], pass, grid(nb))?;
        let next = tmp_off + (nb as u64 * 4).next_multiple_of(256);
        self.scan(enc, sums, nb, next)?;
        let pass = PassUniform {
            n,
            nb,
            mode: 1,
            ..Default::default()
        };
        self.dispatch(enc, &self.kernels.scan_apply, &[data, sums], pass, grid(nb))
    }

    /// Bytes of scan scratch for `n` elements (all levels).
    fn scan_tmp_bytes(n: u64) -> u64 {
        let mut total = 256;
        let mut m = n;
        while m > BLOCK as u64 {
            m = m.div_ceil(BLOCK as u64);
            total += (m * 4).next_multiple_of(256);
        }
        total
    }

    /// Stable LSD radix sort of `n` (key, value) pairs over the low `bits` bits, ping-ponging
    /// between pair `(ka, va)` and `(kb, vb)`; returns true when the result is in `(kb, vb)`.
    #[allow(clippy::too_many_arguments)]
    fn radix_sort(
        &self,
        enc: &mut Enc,
        ka: &GrowBuf,
        va: &GrowBuf,
        kb: &GrowBuf,
        vb: &GrowBuf,
        n: u32,
        bits: u32,
    ) -> Result<bool> {
        let nb = n.div_ceil(BLOCK);
        let passes = bits.div_ceil(4);
        let mut in_b = false;
        if n == 0 {
            return Ok(false);
        }
        for p in 0..passes {
            let (ki, vi, ko, vo) = if in_b { (kb, vb, ka, va) } else { (ka, va, kb, vb) };
            let pass = PassUniform {
                n,
                shift: 4 * p,
                nb,
                ..Default::default()
            };
            let hist = range(&self.bufs.hist, 0, 16 * nb as u64 * 4);
            self.dispatch(enc, &self.kernels.radix_count, &[whole(ki), hist], pass, grid(nb))?;
            self.scan(enc, hist, 16 * nb, 0)?;
            self.dispatch(
                enc,
                &self.kernels.radix_scatter,
                &[whole(ki), whole(vi), hist, whole(ko), whole(vo)],
                pass,
                grid(nb),
            )?;
            in_b = !in_b;
        }
        Ok(in_b)
    }

    /// Renders like [`crate::render`] (same inputs, errors and outputs; `stats.box_pairs` is a
    /// CPU-only work estimate and stays 0 here).
    pub fn render(
        &mut self,
        gaussians: &Gaussians,
        camera: &Camera,
        request: &RenderRequest,
        config: &RasterConfig,
    ) -> Result<RenderOutput> {
        let cam = crate::validate::check_inputs(gaussians, camera, config)?;
        self.frame = None;
        self.generation += 1;
        self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let res = self.render_inner(gaussians, &cam, request, config);
        let validation = pollster::block_on(self.device.pop_error_scope());
        let oom = pollster::block_on(self.device.pop_error_scope());
        if let Some(e) = validation.or(oom) {
            self.frame = None;
            return Err(gpu_err(e));
        }
        res
    }

    fn render_inner(
        &mut self,
        g: &Gaussians,
        cam: &CamParams,
        request: &RenderRequest,
        config: &RasterConfig,
    ) -> Result<RenderOutput> {
        let n = g.len();
        let n32 = n as u32;
        let nc = coeffs_for_degree(g.sh_degree) as u64;
        let (w, h) = (cam.width as usize, cam.height as usize);
        let npix = w * h;
        let n_tiles = (cam.tiles_x * cam.tiles_y) as u64;
        let nn = n as u64;
        self.check_binding("the splat buffer", nn * SPLAT_STRIDE * 4)?;
        let bands = self.bands(cam)?;
        self.check_binding("the tile ranges", n_tiles * 8)?;
        if cam.tiles_x > 65535 {
            return Err(RasterError::Gpu(format!(
                "{} tile columns exceed 65535 workgroups per dimension",
                cam.tiles_x
            )));
        }
        let flags = request.color as u32
            | (request.geo() as u32) << 1
            | (request.expected_depth as u32) << 2
            | (request.observed as u32) << 3;
        let cu = self.cam_uniform(cam, config, g, flags);
        self.queue
            .write_buffer(&self.cam_buf, 0, bytemuck::bytes_of(&cu));
        self.upload_gaussians(g);
        let dev = self.device.clone();
        {
            let b = &mut self.bufs;
            b.splat.ensure(&dev, nn * SPLAT_STRIDE * 4 + 4);
            b.proj.ensure(&dev, nn * 20 + 4);
            b.radii.ensure(&dev, nn * 4 + 4);
            for k in [&mut b.keys_a, &mut b.vals_a, &mut b.keys_b, &mut b.vals_b] {
                k.ensure(&dev, nn * 4 + 4);
            }
            b.counts.ensure(&dev, nn * 4 + 4);
            b.hist.ensure(&dev, 16 * (nn.div_ceil(BLOCK as u64) + 1) * 4);
            b.scan_tmp
                .ensure(&dev, Self::scan_tmp_bytes(16 * nn.div_ceil(BLOCK as u64) + nn + 1));
            b.ranges.ensure(&dev, n_tiles * 8);
            b.acc.ensure(&dev, npix as u64 * 32);
            b.final_t.ensure(&dev, npix as u64 * 4);
            b.last.ensure(&dev, npix as u64 * 4);
            b.observed.ensure(&dev, nn * 4 + 4);
            b.staging.ensure(&dev, 64);
        }
        // Phase 1: projection, depth sort, intersection counts.
        let mut enc = self.encoder();
        enc.encoder.clear_buffer(&self.bufs.counters.buf, 0, Some(64));
        let b = &self.bufs;
        let mut base = 0u32;
        while base < n32 {
            let m = (n32 - base).min(CHUNK) as u64;
            let bb = base as u64;
            let pass = PassUniform {
                n: m as u32,
                base,
                ..Default::default()
            };
            self.dispatch_1d(
                &mut enc,
                &self.kernels.project,
                &[
                    range(&b.params, bb * PARAM_STRIDE * 4, m * PARAM_STRIDE * 4),
                    range(&b.sh, bb * nc * 12, m * nc * 12),
                    range(&b.splat, bb * SPLAT_STRIDE * 4, m * SPLAT_STRIDE * 4),
                    range(&b.proj, bb * 20, m * 20),
                    whole(&b.keys_a),
                    whole(&b.vals_a),
                    whole(&b.counters),
                    range(&b.radii, bb * 4, m * 4),
                ],
                pass,
            )?;
            base += m as u32;
        }
        let in_b = self.radix_sort(&mut enc, &b.keys_a, &b.vals_a, &b.keys_b, &b.vals_b, n32, 32)?;
        debug_assert!(!in_b);
        let pass = PassUniform {
            n: n32,
            ..Default::default()
        };
        self.dispatch_1d(
            &mut enc,
            &self.kernels.isect_count,
            &[
                whole(&b.keys_a),
                whole(&b.vals_a),
                whole(&b.proj),
                whole(&b.counts),
                whole(&b.counters),
            ],
            pass,
        )?;
        enc.encoder
            .clear_buffer(&b.counts.buf, nn * 4, Some(4));
        self.scan(&mut enc, range(&b.counts, 0, nn * 4 + 4), n32 + 1, 0)?;
        enc.encoder
            .copy_buffer_to_buffer(&b.counters.buf, 0, &b.staging.buf, 0, 32);
        self.submit(enc)?;
        let head: Vec<u32> = bytemuck::pod_collect_to_vec(&self.read_staging(32)?);
        let visible = head[0] as usize;
        let total = head[2] as u64 | (head[3] as u64) << 32;
        if total > config.max_intersections as u64 || total > u32::MAX as u64 {
            return Err(RasterError::TooManyIntersections {
                count: total,
                cap: config.max_intersections,
            });
        }
        self.check_binding("the tile intersections", total * 4)?;
        let total32 = total as u32;
        // Phase 2: emit, tile sort, ranges, blend, readback.
        {
            let b = &mut self.bufs;
            for k in [&mut b.keys_b, &mut b.vals_b, &mut b.keys_c, &mut b.vals_c] {
                k.ensure(&dev, total * 4 + 4);
            }
            b.hist.ensure(&dev, 16 * (total.div_ceil(BLOCK as u64) + 1) * 4);
            b.scan_tmp
                .ensure(&dev, Self::scan_tmp_bytes(16 * total.div_ceil(BLOCK as u64) + 1));
        }
        let planes: Vec<usize> = {
            let mut p = Vec::new();
            if request.color {
                p.extend(0..3);
            }
            if request.geo() || request.plane_depth {
                p.extend(3..7);
            }
            if request.expected_depth {
                p.push(7);
            }
            p
        };
        let radii_off = 0u64;
        let ft_off = radii_off + (nn * 4).next_multiple_of(8);
        let last_off = ft_off + npix as u64 * 4;
        let cnt_off = last_off + npix as u64 * 4;
        let obs_off = cnt_off + 64;
        let obs_bytes = if request.observed { nn * 4 } else { 0 };
        let planes_off = (obs_off + obs_bytes).next_multiple_of(8);
        let staging_bytes = planes_off + planes.len() as u64 * npix as u64 * 4;
        self.bufs.staging.ensure(&dev, staging_bytes);
        let mut enc = self.encoder();
        let b = &self.bufs;
        let mut tiles_in_c = false;
        if total32 > 0 {
            // No rectangle has more entries than there are tiles.
            for wi in 0..(n_tiles as u32).div_ceil(FWD_WINDOW) {
                self.dispatch_1d(
                    &mut enc,
                    &self.kernels.isect_emit,
                    &[
                        whole(&b.keys_a),
                        whole(&b.vals_a),
                        whole(&b.proj),
                        whole(&b.counts),
                        whole(&b.keys_b),
                        whole(&b.vals_b),
                    ],
                    PassUniform {
                        n: n32,
                        shift: wi * FWD_WINDOW,
                        nb: (wi + 1).saturating_mul(FWD_WINDOW),
                        ..Default::default()
                    },
                )?;
            }
            let bits = (32 - (n_tiles.max(2) as u32 - 1).leading_zeros()).max(1);
            tiles_in_c =
                self.radix_sort(&mut enc, &b.keys_b, &b.vals_b, &b.keys_c, &b.vals_c, total32, bits)?;
            enc.encoder.clear_buffer(&b.ranges.buf, 0, Some(n_tiles * 8));
            let (tk, tv) = if tiles_in_c { (&b.keys_c, &b.vals_c) } else { (&b.keys_b, &b.vals_b) };
            self.dispatch_1d(
                &mut enc,
                &self.kernels.tile_ranges,
                &[whole(tk), whole(&b.ranges)],
                PassUniform {
                    n: total32,
                    ..Default::default()
                },
            )?;
            if request.observed {
                enc.encoder.clear_buffer(&b.observed.buf, 0, Some(nn * 4 + 4));
            }
            // No tile list is longer than the visible Gaussians or the intersections.
            let longest = total32.min(visible as u32).max(1);
            let windows = longest.div_ceil(FWD_WINDOW);
            for &(r0, rows, p0, bp) in &bands {
                for wi in 0..windows {
                    self.make_room(&mut enc, 1)?;
                    self.dispatch(
                        &mut enc,
                        &self.kernels.raster_fwd,
                        &[
                            whole(&b.ranges),
                            whole(tv),
                            whole(&b.splat),
                            range(&b.acc, p0 * 32, bp * 32),
                            range(&b.final_t, p0 * 4, bp * 4),
                            range(&b.last, p0 * 4, bp * 4),
                            whole(&b.observed),
                            whole(&b.counters),
                        ],
                        PassUniform {
                            n: bp as u32,
                            shift: wi * FWD_WINDOW,
                            nb: (wi + 1).saturating_mul(FWD_WINDOW),
                            base: r0,
                            mode: (wi == 0) as u32 | ((wi + 1 == windows) as u32) << 1,
                            ..Default::default()
                        },
                        (cam.tiles_x, rows),
                    )?;
                }
            }
            let e = &mut enc.encoder;
            e.copy_buffer_to_buffer(&b.final_t.buf, 0, &b.staging.buf, ft_off, npix as u64 * 4);
            e.copy_buffer_to_buffer(&b.last.buf, 0, &b.staging.buf, last_off, npix as u64 * 4);
            e.copy_buffer_to_buffer(&b.counters.buf, 0, &b.staging.buf, cnt_off, 64);
            if request.observed && nn > 0 {
                e.copy_buffer_to_buffer(&b.observed.buf, 0, &b.staging.buf, obs_off, nn * 4);
            }
            for (k, &p) in planes.iter().enumerate() {
                for &(_, _, p0, bp) in &bands {
                    e.copy_buffer_to_buffer(
                        &b.acc.buf,
                        p0 * 32 + p as u64 * bp * 4,
                        &b.staging.buf,
                        planes_off + (k as u64 * npix as u64 + p0) * 4,
                        bp * 4,
                    );
                }
            }
        }
        if nn > 0 {
            enc.encoder
                .copy_buffer_to_buffer(&b.radii.buf, 0, &b.staging.buf, radii_off, nn * 4);
        }
        self.submit(enc)?;
        let bytes = self.read_staging(staging_bytes)?;
        let u32s = |off: u64, count: usize| -> Vec<u32> {
            bytemuck::pod_collect_to_vec(&bytes[off as usize..off as usize + count * 4])
        };
        let f32s = |off: u64, count: usize| -> Vec<f32> {
            bytemuck::pod_collect_to_vec(&bytes[off as usize..off as usize + count * 4])
        };
        let radii = u32s(radii_off, n);
        let mut acc = vec![[0.0f32; 8]; npix];
        let (final_t, last, counters, observed) = if total32 > 0 {
            for (k, &p) in planes.iter().enumerate() {
                let plane = f32s(planes_off + k as u64 * npix as u64 * 4, npix);
                for (a, v) in acc.iter_mut().zip(plane) {
                    a[p] = v;
                }
            }
            (
                f32s(ft_off, npix),
                u32s(last_off, npix),
                u32s(cnt_off, 16),
                request.observed.then(|| u32s(obs_off, n)),
            )
        } else {
            (
                vec![1.0; npix],
                vec![0; npix],
                vec![0; 16],
                request.observed.then(|| vec![0; n]),
            )
        };
        let mut out = crate::pixel::assemble(cam, config, request, &acc, &final_t)?;
        out.radii = radii;
        out.observed = observed;
        out.stats = RenderStats {
            visible,
            intersections: total as usize,
            forward_pairs: counters[4] as u64 | (counters[5] as u64) << 32,
            backward_pairs: counters[6] as u64 | (counters[7] as u64) << 32,
            box_pairs: 0,
        };
        let geo = if request.plane_depth || request.expected_depth {
            acc.iter().map(|a| [a[3], a[4], a[5], a[6], a[7]]).collect()
        } else {
            Vec::new()
        };
        out.state = crate::ForwardState(crate::StateInner::Gpu(GpuState {
            rasterizer: self.id,
            generation: self.generation,
            n,
            width: cam.width,
            height: cam.height,
            request: *request,
            total: total32,
            final_t: final_t.clone(),
            geo,
        }));
        out.final_t = final_t;
        let max_last = last.iter().copied().max().unwrap_or(0);
        out.last_contributor = last;
        self.frame = Some(Frame {
            generation: self.generation,
            total: total32,
            max_last,
            tiles_in_c,
        });
        Ok(out)
    }

    /// Backward like [`crate::backward`] (same inputs as the render of `forward`, which must
    /// come from this rasterizer). Fastest right after that render; for an older render the
    /// device state is rebuilt first.
    pub fn backward(
        &mut self,
        gaussians: &Gaussians,
        camera: &Camera,
        config: &RasterConfig,
        forward: &RenderOutput,
        grads: &OutputGradients,
    ) -> Result<GaussianGradients> {
        let cam = crate::validate::check_inputs(gaussians, camera, config)?;
        let st = match &forward.state.0 {
            crate::StateInner::Gpu(st) => st,
            crate::StateInner::Cpu(_) => {
                return Err(RasterError::InvalidGradients(
                    "the forward render came from the CPU backend; use gs_raster::backward".into(),
                ));
            }
        };
        if st.rasterizer != self.id {
            return Err(RasterError::InvalidGradients(
                "the forward render came from another WgpuRasterizer".into(),
            ));
        }
        crate::validate::check_forward_matches((st.n, st.width, st.height), true, gaussians, &cam, "")?;
        crate::validate::check_all_grads(grads, &st.request, cam.width, cam.height)?;
        let frame = match self.frame {
            Some(f) if f.generation == st.generation => f,
            _ => {
                // An older render of this rasterizer: a later render overwrote its device
                // state. The forward is deterministic, so rebuild that state from the same
                // inputs (one extra forward) and check that it is the same render.
                self.render(gaussians, camera, &st.request, config)?;
                match self.frame {
                    Some(f) if f.total == st.total => f,
                    _ => {
                        return Err(RasterError::InvalidGradients(
                            "the Gaussians, camera or config differ from those of the forward render".into(),
                        ));
                    }
                }
            }
        };
        let n = gaussians.len();
        let mut out = GaussianGradients::zeros(n);
        let color = grads.color.is_some();
        let geo = grads.normal.is_some() || grads.distance.is_some() || grads.plane_depth.is_some();
        let depth = grads.expected_depth.is_some();
        if frame.total == 0 || !(color || geo || depth || grads.alpha.is_some()) {
            return Ok(out);
        }
        self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let res = self.backward_inner(gaussians, &cam, config, st, grads, frame, &mut out);
        let validation = pollster::block_on(self.device.pop_error_scope());
        let oom = pollster::block_on(self.device.pop_error_scope());
        if let Some(e) = validation.or(oom) {
            return Err(gpu_err(e));
        }
        res.map(|_| out)
    }

    #[allow(clippy::too_many_arguments)]
    fn backward_inner(
        &mut self,
        g: &Gaussians,
        cam: &CamParams,
        config: &RasterConfig,
        st: &GpuState,
        grads: &OutputGradients,
        frame: Frame,
        out: &mut GaussianGradients,
    ) -> Result<()> {
        let n = g.len();
        let nn = n as u64;
        let nc = coeffs_for_degree(g.sh_degree);
        let ncu = nc as u64;
        let (w, h) = (cam.width as usize, cam.height as usize);
        let npix = w * h;
        let flags = grads.color.is_some() as u32
            | ((grads.normal.is_some() || grads.distance.is_some() || grads.plane_depth.is_some())
                as u32)
                << 1
            | (grads.expected_depth.is_some() as u32) << 2;
        let cu = self.cam_uniform(cam, config, g, flags);
        self.queue
            .write_buffer(&self.cam_buf, 0, bytemuck::bytes_of(&cu));
        self.upload_gaussians(g);
        // Per-pixel channel gradients, folded on the host exactly as the CPU backend does.
        let mut pg = std::mem::take(&mut self.scratch_px);
        pg.clear();
        pg.reserve(npix * 9);
        for y in 0..h {
            for x in 0..w {
                let (gc, ga) = crate::pixel::pixel_grads(cam, config, grads, &st.final_t, &st.geo, x, y);
                pg.extend_from_slice(&gc);
                pg.push(ga);
            }
        }
        let gstride = 15 + 3 * ncu;
        let bands = self.bands(cam)?;
        let dev = self.device.clone();
        self.bufs.pixgrad.ensure(&dev, npix as u64 * 36);
        self.bufs.bstate.ensure(&dev, npix as u64 * 36);
        self.bufs.gacc.ensure(&dev, nn * 64 + 4);
        self.bufs.gout.ensure(&dev, nn * gstride * 4 + 4);
        self.bufs.staging.ensure(&dev, nn * gstride * 4 + 4);
        self.queue
            .write_buffer(&self.bufs.pixgrad.buf, 0, bytemuck::cast_slice(&pg));
        self.scratch_px = pg;
        let mut enc = self.encoder();
        let b = &self.bufs;
        enc.encoder.clear_buffer(&b.gacc.buf, 0, Some(nn * 64 + 4));
        let tv = if frame.tiles_in_c { &b.vals_c } else { &b.vals_b };
        let windows = frame.max_last.div_ceil(BWD_WINDOW);
        for &(r0, rows, p0, bp) in &bands {
            for wi in (0..windows).rev() {
                self.make_room(&mut enc, 1)?;
                self.dispatch(
                    &mut enc,
                    &self.kernels.raster_bwd,
                    &[
                        whole(&b.ranges),
                        whole(tv),
                        whole(&b.splat),
                        range(&b.final_t, p0 * 4, bp * 4),
                        range(&b.last, p0 * 4, bp * 4),
                        range(&b.pixgrad, p0 * 36, bp * 36),
                        whole(&b.gacc),
                        range(&b.bstate, p0 * 36, bp * 36),
                    ],
                    PassUniform {
                        n: bp as u32,
                        shift: wi * BWD_WINDOW,
                        nb: (wi + 1).saturating_mul(BWD_WINDOW),
                        base: r0,
                        ..Default::default()
                    },
                    (cam.tiles_x, rows),
                )?;
            }
        }
        let n32 = n as u32;
        let mut base = 0u32;
        while base < n32 {
            let m = (n32 - base).min(CHUNK) as u64;
            let bb = base as u64;
            self.make_room(&mut enc, 1)?;
            self.dispatch_1d(
                &mut enc,
                &self.kernels.project_bwd,
                &[
                    range(&b.params, bb * PARAM_STRIDE * 4, m * PARAM_STRIDE * 4),
                    range(&b.sh, bb * ncu * 12, m * ncu * 12),
                    range(&b.proj, bb * 20, m * 20),
                    range(&b.gacc, bb * 64, m * 64),
                    range(&b.gout, bb * gstride * 4, m * gstride * 4),
                ],
                PassUniform {
                    n: m as u32,
                    base,
                    ..Default::default()
                },
            )?;
            base += m as u32;
        }
        enc.encoder
            .copy_buffer_to_buffer(&b.gout.buf, 0, &b.staging.buf, 0, nn * gstride * 4);
        self.submit(enc)?;
        let bytes = self.read_staging(nn * gstride * 4)?;
        let v: Vec<f32> = bytemuck::pod_collect_to_vec(&bytes);
        let gs = gstride as usize;
        for i in 0..n {
            let r = &v[i * gs..(i + 1) * gs];
            out.means[i] = [r[0], r[1], r[2]];
            out.log_scales[i] = [r[3], r[4], r[5]];
            out.rotations[i] = [r[6], r[7], r[8], r[9]];
            out.opacity_logits[i] = r[10];
            out.mean2d[i] = [r[11], r[12]];
            out.mean2d_abs[i] = [r[13], r[14]];
            for k in 0..nc {
                out.sh[i][k] = [r[15 + 3 * k], r[16 + 3 * k], r[17 + 3 * k]];
            }
        }
        Ok(())
    }
}

impl Kernels {
    fn new(device: &wgpu::Device, native_atomics: bool) -> Self {
        const COMMON: &str = include_str!("common.wgsl");
        const PROJ_COMMON: &str = include_str!("proj_common.wgsl");
        let make = |src: String, entry: &str, storage: &[bool]| -> Kernel {
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(entry),
                source: wgpu::ShaderSource::Wgsl(src.into()),
            });
            let mut entries = vec![
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: true,
                        min_binding_size: None,
                    },
                    count: None,
                },
            ];
            for (k, &read_only) in storage.iter().enumerate() {
                entries.push(wgpu::BindGroupLayoutEntry {
                    binding: 2 + k as u32,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                });
            }
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(entry),
                entries: &entries,
            });
            let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(entry),
                bind_group_layouts: &[&layout],
                push_constant_ranges: &[],
            });
            let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&pl),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            });
            Kernel { pipeline, layout }
        };
        let src = |body: &str| format!("{COMMON}\n{body}");
        let proj_src = |body: &str| format!("{COMMON}\n{body}\n{PROJ_COMMON}");
        let gacc = if native_atomics {
            include_str!("gacc_native.wgsl")
        } else {
            include_str!("gacc_cas.wgsl")
        };
        let bwd = include_str!("raster_bwd.wgsl").replace("//GACC_DECL", gacc);
        const R: bool = true;
        const W: bool = false;
        Kernels {
            project: make(
                proj_src(include_str!("project.wgsl")),
                "project",
                &[R, R, W, W, W, W, W, W],
            ),
            project_bwd: make(
                proj_src(include_str!("project_bwd.wgsl")),
                "project_bwd",
                &[R, R, R, R, W],
            ),
            scan_reduce: make(src(include_str!("scan.wgsl")), "scan_reduce", &[W, W]),
            scan_apply: make(src(include_str!("scan.wgsl")), "scan_apply", &[W, W]),
            radix_count: make(src(include_str!("radix_count.wgsl")), "radix_count", &[R, W]),
            radix_scatter: make(
                src(include_str!("radix_scatter.wgsl")),
                "radix_scatter",
                &[R, R, R, W, W],
            ),
            isect_count: make(
                src(include_str!("isect_count.wgsl")),
                "isect_count",
                &[R, R, R, W, W],
            ),
            isect_emit: make(
                src(include_str!("isect_emit.wgsl")),
                "isect_emit",
                &[R, R, R, R, W, W],
            ),
            tile_ranges: make(src(include_str!("tile_ranges.wgsl")), "tile_ranges", &[R, W]),
            raster_fwd: make(
                src(include_str!("raster_fwd.wgsl")),
                "raster_fwd",
                &[R, R, R, W, W, W, W, W],
            ),
            raster_bwd: make(src(&bwd), "raster_bwd", &[R, R, R, R, R, R, W, W]),
        }
    }
}

