//! L_nc and L_ns on the device (behind the `wgpu` feature), the twin of
//! [`crate::normal_losses`]: four WGSL passes (`normal.wgsl`) compute N̂, each pixel's values
//! and ∂/∂N̂, ∂/∂Ñ, then the chain through N̂ into the plane depth z; a fifth sums each row's
//! values in order (compensated f32), and the host reads those sums alone and adds the rows in
//! order in f64, so one input gives one result on one device. Tolerances: `tests/normal_gpu.rs` (docs/method.md §L_nc, §L_ns; docs/architecture.md
//! §GPU).

use crate::device::{LossKernels, gpu_error};
use gs_gpu::{GeneratedStruct, bytes_of, declarations};
use crate::error::Result;
use crate::image_loss::EdgeGuide;
use crate::normal::{NORMALIZE_EPS, ray_x, ray_y};
use crate::normal_loss::{NormalLossConfig, NormalLossOutput, NsGate, NsPairs, check_inputs, smoothing_sum};
use gs_core::{Image, Intrinsics};
use gs_gpu::{Binding, GpuContext, PassUniform, PendingRead};

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
        pad: u32,
    }
}

gs_gpu::wgsl_struct! {
    /// One pixel's inputs (WGSL `struct PixelInput`), interleaved on the host from the
    /// planar images. 24 bytes.
    pub(crate) struct PixelInput as "PixelInput" {
        /// The plane depth z.
        z: f32,
        /// The rendered normal Ñ.
        normal: [f32; 3],
        /// The edge weight δ.
        delta: f32,
        /// A (0 and unread without alpha).
        alpha: f32,
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
    /// row's sums (`nc`, the right and down pairs' sum in `ns_right`, `pairs`). 16 bytes.
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
    Binding::read("inputs", "array<PixelInput>"),
    Binding::read("rays", "array<f32>"),
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
        GeneratedStruct::of::<PixelInput>(),
        GeneratedStruct::of::<PixelVec3>(),
        GeneratedStruct::of::<PixelTerms>(),
        GeneratedStruct::of::<DiffGrad>(),
    ]
}

/// The passes in order: one thread per pixel, then (`row_sums`) one per row.
const PASSES: [&str; 5] = ["depth_normals", "normal_terms", "normal_chain", "depth_gradient", "row_sums"];

/// The kernels' whole WGSL source.
pub fn normal_kernel_source() -> String {
    gs_gpu::kernel_source(&[&declarations(&generated_structs()), include_str!("normal.wgsl")], &BINDINGS)
}

/// The device executor of L_nc and L_ns: its context (shared), buffers and five kernels.
pub struct NormalGpu {
    k: LossKernels<8>,
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
        Ok(Self { k: LossKernels::new(ctx, &decls, frame, include_str!("normal.wgsl"), &BINDINGS, &PASSES)? })
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
        let pending = self.start(plane_depth, rendered_normal, alpha, guide, intrinsics, cfg)?;
        self.finish(pending)
    }

    /// Submits [`NormalGpu::normal_losses`] and returns at once; [`NormalGpu::finish`] reads
    /// the result. Readbacks of several executors on one device started before the first
    /// finish cost the host one wait. Finish an evaluation before starting the next on this
    /// executor.
    pub fn start(
        &mut self,
        plane_depth: &Image,
        rendered_normal: &Image,
        alpha: Option<&Image>,
        guide: &EdgeGuide,
        intrinsics: &Intrinsics,
        cfg: &NormalLossConfig,
    ) -> Result<PendingNormalLosses> {
        check_inputs(plane_depth, rendered_normal, alpha, guide, intrinsics, cfg)?;
        let (w, h) = (plane_depth.width(), plane_depth.height());
        let n = w * h;
        // The largest records are the inputs and ∂/∂(dx, dy), 24 bytes a pixel.
        let largest = bytes_of::<PixelInput>(1).max(bytes_of::<DiffGrad>(1));
        if n == 0 || n > u32::MAX as usize || n as u64 * largest > self.k.ctx.max_storage_binding() {
            return Ok(PendingNormalLosses(Pending::Host(crate::normal_losses(plane_depth, rendered_normal, alpha, guide, intrinsics, cfg)?)));
        }
        let frame = NormalFrame {
            width: w as u32,
            height: h as u32,
            n: n as u32,
            has_alpha: alpha.is_some() as u32,
            s_nc: (cfg.lambda_nc as f64 / n as f64) as f32,
            s_ns: (cfg.lambda_ns as f64 / n as f64) as f32,
            tau: cfg.tau,
            tau2: (cfg.tau as f64 * cfg.tau as f64) as f32,
            gate: (cfg.gate == NsGate::Below) as u32,
            interior: (cfg.pairs == NsPairs::Interior) as u32,
            eps: NORMALIZE_EPS as f32,
            pad: 0,
        };
        let rays: Vec<f32> = (0..w).map(|i| ray_x(intrinsics, i) as f32).chain((0..h).map(|j| ray_y(intrinsics, j) as f32)).collect();
        let inputs = pixel_inputs(plane_depth, rendered_normal, &guide.delta, alpha);
        // The readback: N̂, the rows' sums, ∂/∂Ñ and ∂/∂z.
        let (vec3, terms, plane) = (bytes_of::<PixelVec3>(n), bytes_of::<PixelTerms>(n), bytes_of::<f32>(n));
        let sums = bytes_of::<PixelTerms>(h);
        let read = [vec3, sums, vec3, plane];
        let k = &mut self.k;
        k.begin([bytes_of::<PixelInput>(n), bytes_of::<f32>(rays.len()), vec3, terms + sums, vec3, vec3, bytes_of::<DiffGrad>(n), plane], read.iter().sum());
        let [input_buf, ray_buf, nhat, values, _, gnt, _, gz] = k.bufs;
        k.ctx.write_buffer(k.pool.buffer(input_buf), 0, bytemuck::cast_slice(&inputs));
        k.ctx.write_buffer(k.pool.buffer(ray_buf), 0, bytemuck::cast_slice(&rays));
        k.disp.write_frame(&frame);
        let p = &k.pool;
        let binds = k.bufs.map(|id| p.whole(id));
        let mut enc = k.disp.encoder();
        k.ctx.push_error_scopes();
        for (kernel, name) in k.kernels.iter().zip(PASSES) {
            let threads = if name == "row_sums" { h } else { n };
            k.disp.dispatch_1d(&mut enc, kernel, &binds, PassUniform { n: threads as u32, ..Default::default() }).map_err(gpu_error)?;
        }
        let staging = p.buffer(k.staging);
        let mut at = 0;
        for ((id, from), size) in [(nhat, 0), (values, terms), (gnt, 0), (gz, 0)].into_iter().zip(read) {
            enc.encoder.copy_buffer_to_buffer(p.buffer(id), from, staging, at, size);
            at += size;
        }
        k.disp.submit(enc);
        k.ctx.pop_error_scopes().map_err(gpu_error)?;
        let read = k.ctx.request_read(staging, at);
        Ok(PendingNormalLosses(Pending::Device { read, cfg: *cfg, size: (w, h), sizes: (vec3, sums) }))
    }

    /// The result of a started evaluation (waiting for the device if it has not answered).
    pub fn finish(&mut self, pending: PendingNormalLosses) -> Result<NormalLossOutput> {
        let (read, cfg, (w, h), (vec3, sums)) = match pending.0 {
            Pending::Host(out) => return Ok(out),
            Pending::Device { read, cfg, size, sizes } => (read, cfg, size, sizes),
        };
        let (nhat, rows, g_nt, g_z) = self
            .k
            .ctx
            .finish_read(read, |m| {
                let (nhat, rest) = m.split_at(vec3 as usize);
                let (rows, rest) = rest.split_at(sums as usize);
                let (g_nt, g_z) = rest.split_at(vec3 as usize);
                // N̂ and ∂/∂Ñ: the records' components are the 3-channel images' values.
                let f = |b: &[u8]| bytemuck::cast_slice::<u8, f32>(b).to_vec();
                (f(nhat), bytemuck::cast_slice::<u8, PixelTerms>(rows).to_vec(), f(g_nt), f(g_z))
            })
            .map_err(gpu_error)?;
        NormalLossOutput::assemble(&cfg, (w, h), term_sums(&rows, w * h), nhat, g_z, g_nt)
    }
}

/// L_nc and L_ns started by [`NormalGpu::start`]: on the device, or already made on the host
/// (a view too large for the device's bindings).
pub struct PendingNormalLosses(Pending);

enum Pending {
    Device {
        read: PendingRead,
        cfg: NormalLossConfig,
        /// The view's width and height.
        size: (usize, usize),
        /// Bytes of N̂ (and of ∂/∂Ñ) and of the rows' sums in the readback.
        sizes: (u64, u64),
    },
    Host(NormalLossOutput),
}

/// The per-pixel input records from the planar images: z, Ñ, δ and A (0 without alpha).
fn pixel_inputs(z: &Image, normal: &Image, delta: &Image, alpha: Option<&Image>) -> Vec<PixelInput> {
    let normals: &[[f32; 3]] = bytemuck::cast_slice(normal.data());
    let alpha = |p: usize| alpha.map_or(0.0, |a| a.data()[p]);
    let zd = z.data().iter().zip(delta.data());
    zd.zip(normals).enumerate().map(|(p, ((&z, &delta), &normal))| PixelInput { z, normal, delta, alpha: alpha(p) }).collect()
}

/// L_nc, L_ns and the number of active pairs of `n` pixels from the rows' sums (`row_sums`),
/// the rows added in order in f64 as the reference adds its rows.
fn term_sums(rows: &[PixelTerms], n: usize) -> (f64, f64, usize) {
    let l_nc = rows.iter().map(|r| r.nc as f64).sum::<f64>() / n as f64;
    let (ns_sum, active) = smoothing_sum(rows.iter().map(|r| (r.ns_right as f64, r.pairs as usize)).collect());
    (l_nc, ns_sum / n as f64, active)
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
        let sizes = [bytes_of::<PixelInput>(1), bytes_of::<PixelVec3>(1), bytes_of::<PixelTerms>(1), bytes_of::<DiffGrad>(1)];
        assert_eq!(sizes, [24, 12, 16, 24]);
    }
}
