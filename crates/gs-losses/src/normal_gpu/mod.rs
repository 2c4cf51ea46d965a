//! L_nc and L_ns on the device (behind the `wgpu` feature), the twin of
//! [`crate::normal_losses`]: four WGSL passes (`normal.wgsl`) compute N̂, each pixel's values
//! and ∂/∂N̂, ∂/∂Ñ, then the chain through N̂ into the plane depth z; a fifth sums each row's
//! values in order (compensated f32) and a sixth adds the rows in order (double-f32 pairs),
//! and the host reads those totals alone, so one input gives one result on one device. Tolerances: `tests/normal_gpu.rs` (docs/method.md §L_nc, §L_ns; docs/architecture.md
//! §GPU).

use crate::device::{LossKernels, gpu_error};
use gs_gpu::{GeneratedStruct, bytes_of, declarations};
use crate::error::Result;
use crate::image_loss::EdgeGuide;
use crate::normal::{NORMALIZE_EPS, ray_x, ray_y};
use crate::error::LossError;
use crate::normal_loss::{NormalLossConfig, NormalLossOutput, NsGate, NsPairs, check_inputs, check_view};
use gs_core::{Image, Intrinsics};
use gs_gpu::{Arena, Bind, Binding, DeviceImage, GpuContext, PassUniform, PendingRead, SURFACE_CHANNELS, SurfaceTexel};
use std::borrow::Cow;

gs_gpu::wgsl_struct! {
    /// Constants of one evaluation (binding 0; WGSL `struct NormalFrame`).
    pub(crate) struct NormalFrame as "NormalFrame" {
        width: u32,
        height: u32,
        /// Pixels (width · height).
        n: u32,
        /// Whether the inputs' `alpha` holds A (else it is 1).
        has_alpha: u32,
        /// λ1 / n, the scale of ∂L_nc.
        s_nc: f32,
        /// λ2 / n, the scale of ∂L_ns.
        s_ns: f32,
        /// τ, the gate's threshold.
        tau: f32,
        /// τ², the hinge of L_ns.
        tau2: f32,
        /// 0: the gate passes above τ ([`NsGate::Above`]); 1: below.
        gate: u32,
        /// 1: only pairs off the image border count ([`NsPairs::Interior`]).
        interior: u32,
        /// The ε of the normalisation.
        eps: f32,
        /// Where the view's δ plane starts in `consts` (floats).
        delta_at: u32,
        /// Where the rays (x of each column, then y of each row) start in `consts`.
        rays_at: u32,
        pad0: u32,
        pad1: u32,
    }
}

gs_gpu::wgsl_struct! {
    /// One pixel's 3-vector (WGSL `struct PixelVec3`): N̂, ∂/∂N̂ or ∂/∂Ñ. 12 bytes, so an array
    /// of them is the host's 3-channel image.
    pub(crate) struct PixelVec3 as "PixelVec3" {
        v: [f32; 3],
    }
}

gs_gpu::wgsl_struct! {
    /// One pixel's loss terms (WGSL `struct PixelTerms`); after the pixels, one a row with the
    /// row's sums (`nc`, the right and down pairs' sum in `ns_right`, `pairs`), then the
    /// image's totals as two records (`normal_totals`: [`Totals`]). 16 bytes.
    pub(crate) struct PixelTerms as "PixelTerms" {
        /// δ·‖N̂ − Ñ‖₁.
        nc: f32,
        /// δ_k·ReLU(‖N̂_k − N̂_p‖₁ − τ²) of the right and the down pair where it is active.
        ns_right: f32,
        ns_down: f32,
        /// The number of active pairs (0, 1 or 2).
        pairs: f32,
    }
}

gs_gpu::wgsl_struct! {
    /// ∂/∂dx and ∂/∂dy of one pixel's normal (WGSL `struct DiffGrad`), the central
    /// differences of its neighbours' points. 24 bytes.
    pub(crate) struct DiffGrad as "DiffGrad" {
        dx: [f32; 3],
        dy: [f32; 3],
    }
}

/// The kernels' storage bindings, by name (slot order; one table for the four passes).
const BINDINGS: [Binding<'static>; 8] = [
    Binding::read("surface", "array<SurfaceTexel>"),
    Binding::read("consts", "array<f32>"),
    Binding::write("nhat", "array<PixelVec3>"),
    Binding::write("values", "array<PixelTerms>"),
    Binding::write("gnhat", "array<PixelVec3>"),
    Binding::write("gnt", "array<PixelVec3>"),
    Binding::write("gab", "array<DiffGrad>"),
    Binding::write("gz", "array<f32>"),
];

/// The frame uniform and the storage records: one list for the kernels' declarations and the
/// layout test.
fn generated_structs() -> [GeneratedStruct; 5] {
    [
        GeneratedStruct::of::<NormalFrame>(),
        GeneratedStruct::of::<SurfaceTexel>(),
        GeneratedStruct::of::<PixelVec3>(),
        GeneratedStruct::of::<PixelTerms>(),
        GeneratedStruct::of::<DiffGrad>(),
    ]
}

/// The passes in order: one thread per pixel, then (`row_sums`) one per row, then
/// (`normal_totals`) one.
const PASSES: [&str; 6] = ["depth_normals", "normal_terms", "normal_chain", "depth_gradient", "row_sums", "normal_totals"];

/// The image's totals that `normal_totals` writes after the rows' sums, each a double-f32 pair
/// (`gs_gpu::wide_value`) in two [`PixelTerms`] records: (L_nc's sum, L_ns's sum), then (the
/// active pairs, 0). What comes back.
struct Totals([PixelTerms; 2]);

impl Totals {
    const BYTES: u64 = 2 * std::mem::size_of::<PixelTerms>() as u64;

    fn of(bytes: &[u8]) -> Self {
        let r: &[PixelTerms] = bytemuck::cast_slice(bytes);
        Self([r[0], r[1]])
    }

    /// L_nc, L_ns and the number of active pairs of `n` pixels.
    fn terms(&self, n: usize) -> (f64, f64, usize) {
        let [a, b] = &self.0;
        let nc = gs_gpu::wide_value([a.nc, a.ns_right]);
        let ns = gs_gpu::wide_value([a.ns_down, a.pairs]);
        let pairs = gs_gpu::wide_value([b.nc, b.ns_right]);
        (nc / n as f64, ns / n as f64, pairs as usize)
    }
}

/// The kernels' whole WGSL source.
pub fn normal_kernel_source() -> String {
    gs_gpu::kernel_source(&[&declarations(&generated_structs()), include_str!("normal.wgsl")], &BINDINGS)
}

/// How much device memory the arena of δ planes and rays holds (bytes), at most one storage
/// binding.
const ARENA_BYTES: u64 = 256 << 20;

/// The device executor of L_nc and L_ns: its context (shared), buffers, five kernels and the
/// arena that keeps each view's δ plane on the device.
pub struct NormalGpu {
    k: LossKernels<8>,
    arena: Arena,
}

/// The rendered surface of an evaluation: images on the host, or a [`DeviceImage`] of
/// [`SurfaceTexel`]s kept on the device (whose alpha counts when `with_alpha`).
#[derive(Clone, Copy)]
enum Surface<'a> {
    Host { plane_depth: &'a Image, normal: &'a Image, alpha: Option<&'a Image> },
    Device { image: &'a DeviceImage, with_alpha: bool },
}

impl std::fmt::Debug for NormalGpu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "NormalGpu({})", self.k.ctx.description())
    }
}

impl NormalGpu {
    /// The executor on `ctx`'s device (shared, e.g. with the rasterizer's), its kernels compiled.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let decls = declarations(&generated_structs());
        let frame = std::mem::size_of::<NormalFrame>();
        let k = LossKernels::new(ctx, &decls, frame, include_str!("normal.wgsl"), &BINDINGS, &PASSES)?;
        Ok(Self { k, arena: Arena::new(ctx, "normal-loss arena", ARENA_BYTES) })
    }

    /// [`crate::normal_losses`] on the device: the same inputs, checks and output. Views larger
    /// than one storage binding of this device are computed by the reference.
    pub fn normal_losses(
        &mut self,
        plane_depth: &Image,
        rendered_normal: &Image,
        alpha: Option<&Image>,
        guide: &EdgeGuide,
        intrinsics: &Intrinsics,
        cfg: &NormalLossConfig,
    ) -> Result<NormalLossOutput> {
        let pending = self.start(plane_depth, rendered_normal, alpha, guide, intrinsics, None, cfg)?;
        self.finish(pending)
    }

    /// Submits [`NormalGpu::normal_losses`] and returns at once; [`NormalGpu::finish`] reads
    /// the result. The guide's δ stays on the device under `view` between calls (uploaded on
    /// first use and when evicted; `None`: every call). Readbacks of several executors on one
    /// device started before the first finish cost the host one wait. Finish an evaluation
    /// before starting the next on this executor.
    #[allow(clippy::too_many_arguments)]
    pub fn start(
        &mut self,
        plane_depth: &Image,
        rendered_normal: &Image,
        alpha: Option<&Image>,
        guide: &EdgeGuide,
        intrinsics: &Intrinsics,
        view: Option<u64>,
        cfg: &NormalLossConfig,
    ) -> Result<PendingNormalLosses> {
        check_inputs(plane_depth, rendered_normal, alpha, guide, intrinsics, cfg)?;
        let surface = Surface::Host { plane_depth, normal: rendered_normal, alpha };
        match self.submit(surface, guide, intrinsics, view, cfg)? {
            Some(submitted) => Ok(PendingNormalLosses(Pending::Device(submitted))),
            None => Ok(PendingNormalLosses(Pending::Host(crate::normal_losses(plane_depth, rendered_normal, alpha, guide, intrinsics, cfg)?))),
        }
    }

    /// [`NormalGpu::start`] of a rendered surface kept on this device (a render's
    /// [`SurfaceTexel`]s, which never came to the host; A counts when `with_alpha`): N̂ and the
    /// gradients stay on the device ([`NormalGpu::finish_on_device`]); only the totals (32 bytes) come
    /// back. A view too large for the device's bindings is refused.
    #[allow(clippy::too_many_arguments)]
    pub fn start_on_device(
        &mut self,
        surface: &DeviceImage,
        with_alpha: bool,
        guide: &EdgeGuide,
        intrinsics: &Intrinsics,
        view: Option<u64>,
        cfg: &NormalLossConfig,
    ) -> Result<PendingDeviceNormalLosses> {
        if !surface.is_on(&self.k.ctx) {
            return Err(LossError::Device("the rendered surface lives on another device".into()));
        }
        if surface.channels() != SURFACE_CHANNELS {
            return Err(LossError::Channels(format!("a rendered surface has {} channels, needs {SURFACE_CHANNELS}", surface.channels())));
        }
        check_view((surface.width(), surface.height()), guide, intrinsics, cfg)?;
        match self.submit(Surface::Device { image: surface, with_alpha }, guide, intrinsics, view, cfg)? {
            Some(submitted) => Ok(PendingDeviceNormalLosses(submitted)),
            None => Err(LossError::Device(format!("a view of {}×{} does not fit this device's bindings", surface.width(), surface.height()))),
        }
    }

    /// One evaluation submitted (its readback requested: the totals, and N̂ and the
    /// gradients unless the surface is on the device, where they stay); `None` when the view
    /// does not fit the device's bindings or the arena.
    fn submit(&mut self, surface: Surface<'_>, guide: &EdgeGuide, intrinsics: &Intrinsics, view: Option<u64>, cfg: &NormalLossConfig) -> Result<Option<Submitted>> {
        let (w, h) = (guide.delta.width(), guide.delta.height());
        let n = w * h;
        // The largest records are ∂/∂(dx, dy), 24 bytes a pixel.
        let largest = bytes_of::<SurfaceTexel>(1).max(bytes_of::<DiffGrad>(1));
        if n == 0 || n > u32::MAX as usize || n as u64 * largest > self.k.ctx.max_storage_binding() {
            return Ok(None);
        }
        let rays: Vec<f32> = (0..w).map(|i| ray_x(intrinsics, i) as f32).chain((0..h).map(|j| ray_y(intrinsics, j) as f32)).collect();
        let items = [(view.map(|v| (v, 0)), n), (None, rays.len())];
        let arrays = [guide.delta.data(), &rays];
        let Some(at) = self.arena.place(&self.k.ctx, &items, |i| Cow::Borrowed(arrays[i])) else {
            return Ok(None);
        };
        let with_alpha = match surface {
            Surface::Host { alpha, .. } => alpha.is_some(),
            Surface::Device { with_alpha, .. } => with_alpha,
        };
        let frame = NormalFrame {
            width: w as u32,
            height: h as u32,
            n: n as u32,
            has_alpha: with_alpha as u32,
            s_nc: (cfg.lambda_nc as f64 / n as f64) as f32,
            s_ns: (cfg.lambda_ns as f64 / n as f64) as f32,
            tau: cfg.tau,
            tau2: (cfg.tau as f64 * cfg.tau as f64) as f32,
            gate: (cfg.gate == NsGate::Below) as u32,
            interior: (cfg.pairs == NsPairs::Interior) as u32,
            eps: NORMALIZE_EPS as f32,
            delta_at: at[0],
            rays_at: at[1],
            pad0: 0,
            pad1: 0,
        };
        let kept = match surface {
            Surface::Device { .. } => Some(KeptOnDevice::new(&self.k.ctx, (w, h))?),
            Surface::Host { .. } => None,
        };
        // The readback: the totals, then (unless kept on the device) N̂, ∂/∂Ñ and ∂/∂z.
        let (vec3, terms, plane) = (bytes_of::<PixelVec3>(n), bytes_of::<PixelTerms>(n), bytes_of::<f32>(n));
        let (rows, sums) = (bytes_of::<PixelTerms>(h), Totals::BYTES);
        let read = if kept.is_some() { sums } else { sums + 2 * vec3 + plane };
        let k = &mut self.k;
        k.begin([bytes_of::<SurfaceTexel>(n), 4, vec3, terms + rows + sums, vec3, vec3, bytes_of::<DiffGrad>(n), plane], read);
        let [surface_buf, _, nhat, values, _, gnt, _, gz] = k.bufs;
        if let Surface::Host { plane_depth, normal, alpha } = surface {
            k.ctx.write_buffer(k.pool.buffer(surface_buf), 0, bytemuck::cast_slice(&surface_texels(plane_depth, normal, alpha)));
        }
        k.disp.write_frame(&frame);
        let p = &k.pool;
        let mut binds = k.bufs.map(|id| p.whole(id));
        binds[1] = self.arena.bind();
        if let Surface::Device { image, .. } = surface {
            binds[0] = Bind::whole(image.buffer());
        }
        let mut enc = k.disp.encoder();
        k.ctx.push_error_scopes();
        for (kernel, name) in k.kernels.iter().zip(PASSES) {
            let threads = match name {
                "row_sums" => h,
                "normal_totals" => 1,
                _ => n,
            };
            k.disp.dispatch_1d(&mut enc, kernel, &binds, PassUniform { n: threads as u32, ..Default::default() }).map_err(gpu_error)?;
        }
        let staging = p.buffer(k.staging);
        enc.encoder.copy_buffer_to_buffer(p.buffer(values), terms + rows, staging, 0, sums);
        match &kept {
            Some(kept) => {
                for (id, image) in [(nhat, &kept.depth_normal), (gnt, &kept.grad_normal), (gz, &kept.grad_plane_depth)] {
                    enc.encoder.copy_buffer_to_buffer(p.buffer(id), 0, image.buffer(), 0, image.bytes());
                }
            }
            None => {
                let mut at = sums;
                for (id, size) in [(nhat, vec3), (gnt, vec3), (gz, plane)] {
                    enc.encoder.copy_buffer_to_buffer(p.buffer(id), 0, staging, at, size);
                    at += size;
                }
            }
        }
        k.disp.submit(enc);
        k.ctx.pop_error_scopes().map_err(gpu_error)?;
        let read = k.ctx.request_read(staging, read);
        Ok(Some(Submitted { read, cfg: *cfg, size: (w, h), sizes: (vec3, sums), kept }))
    }

    /// The result of a started evaluation (waiting for the device if it has not answered).
    pub fn finish(&mut self, pending: PendingNormalLosses) -> Result<NormalLossOutput> {
        let Submitted { read, cfg, size: (w, h), sizes: (vec3, sums), .. } = match pending.0 {
            Pending::Host(out) => return Ok(out),
            Pending::Device(s) => s,
        };
        let (nhat, totals, g_nt, g_z) = self
            .k
            .ctx
            .finish_read(read, |m| {
                let (totals, rest) = m.split_at(sums as usize);
                let (nhat, rest) = rest.split_at(vec3 as usize);
                let (g_nt, g_z) = rest.split_at(vec3 as usize);
                // N̂ and ∂/∂Ñ: the records' components are the 3-channel images' values.
                let f = |b: &[u8]| bytemuck::cast_slice::<u8, f32>(b).to_vec();
                (f(nhat), Totals::of(totals), f(g_nt), f(g_z))
            })
            .map_err(gpu_error)?;
        NormalLossOutput::assemble(&cfg, (w, h), totals.terms(w * h), nhat, g_z, g_nt)
    }

    /// The result of an evaluation started on the device: the values (one wait, unless an
    /// earlier wait brought them), N̂ and the gradients on the device.
    pub fn finish_on_device(&mut self, pending: PendingDeviceNormalLosses) -> Result<NormalLossOutput<DeviceImage>> {
        let Submitted { read, cfg, size: (w, h), kept, .. } = pending.0;
        let kept = kept.ok_or_else(|| LossError::Device("an evaluation on the device without its images".into()))?;
        let totals = self.k.ctx.finish_read(read, Totals::of).map_err(gpu_error)?;
        let (l_nc, l_ns, active) = totals.terms(w * h);
        Ok(NormalLossOutput {
            l_nc,
            l_ns,
            ns_active_pairs: active,
            total: cfg.lambda_nc as f64 * l_nc + cfg.lambda_ns as f64 * l_ns,
            depth_normal: kept.depth_normal,
            grad_plane_depth: kept.grad_plane_depth,
            grad_normal: kept.grad_normal,
        })
    }
}

/// N̂ and the gradients of an evaluation whose surface is on the device, kept there.
struct KeptOnDevice {
    depth_normal: DeviceImage,
    grad_normal: DeviceImage,
    grad_plane_depth: DeviceImage,
}

impl KeptOnDevice {
    fn new(ctx: &GpuContext, (w, h): (usize, usize)) -> Result<Self> {
        let image = |label, c| DeviceImage::new(ctx, label, w, h, c).map_err(gpu_error);
        Ok(Self { depth_normal: image("depth normal", 3)?, grad_normal: image("normal-loss gradient of the normal", 3)?, grad_plane_depth: image("normal-loss gradient of the plane depth", 1)? })
    }
}

/// L_nc and L_ns started by [`NormalGpu::start`]: on the device, or already made on the host
/// (a view too large for the device's bindings).
pub struct PendingNormalLosses(Pending);

/// L_nc and L_ns of a surface on the device, started by [`NormalGpu::start_on_device`].
pub struct PendingDeviceNormalLosses(Submitted);

enum Pending {
    Device(Submitted),
    Host(NormalLossOutput),
}

/// An evaluation submitted to the device (its readback requested), not read yet.
struct Submitted {
    read: PendingRead,
    cfg: NormalLossConfig,
    /// The view's width and height.
    size: (usize, usize),
    /// Bytes of N̂ (and of ∂/∂Ñ) and of the totals in the readback.
    sizes: (u64, u64),
    /// N̂ and the gradients, when they stay on the device.
    kept: Option<KeptOnDevice>,
}

/// The per-pixel surface records from the planar images: z, Ñ and A (0 without alpha; D, which
/// the normal terms do not read, 0).
fn surface_texels(z: &Image, normal: &Image, alpha: Option<&Image>) -> Vec<SurfaceTexel> {
    let normals: &[[f32; 3]] = bytemuck::cast_slice(normal.data());
    let alpha = |p: usize| alpha.map_or(0.0, |a| a.data()[p]);
    z.data().iter().zip(normals).enumerate().map(|(p, (&z, &normal))| SurfaceTexel { z, normal, distance: 0.0, alpha: alpha(p) }).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The whole source (what the device compiles) parses and validates, and each generated struct has the
    /// Rust offsets and sizes (naga's layouter against `offset_of!` / `size_of`).
    #[test]
    fn host_and_wgsl_struct_layouts_agree() {
        let src = normal_kernel_source();
        gs_gpu::check_layout::<PassUniform>(&src).unwrap();
        gs_gpu::check_layouts(&generated_structs(), &src).unwrap();
        gs_gpu::validate_kernel(&src).unwrap_or_else(|e| panic!("{e}"));
        let sizes = [bytes_of::<SurfaceTexel>(1), bytes_of::<PixelVec3>(1), bytes_of::<PixelTerms>(1), bytes_of::<DiffGrad>(1)];
        assert_eq!(sizes, [24, 12, 16, 24]);
    }
}
