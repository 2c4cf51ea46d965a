//! L_nc and L_ns on the device (behind the `wgpu` feature), the twin of
//! [`crate::normal_losses`]: four WGSL passes (`normal.wgsl`) compute N̂, each pixel's values
//! and ∂/∂N̂, ∂/∂Ñ, then the chain through N̂ into the plane depth z. The host sums the
//! per-pixel values in the reference's fixed order, so one input gives one result on one
//! device. Tolerances: `tests/normal_gpu.rs` (docs/method.md §L_nc, §L_ns; docs/architecture.md
//! §GPU).

use crate::device::{LossKernels, gpu_error};
use crate::error::Result;
use crate::image_loss::EdgeGuide;
use crate::normal::{NORMALIZE_EPS, ray_x, ray_y};
use crate::normal_loss::{NormalLossConfig, NormalLossOutput, NsGate, NsPairs, check_inputs, consistency_sum, smoothing_sum};
use gs_core::{Image, Intrinsics};
use gs_gpu::{Binding, GpuContext, PassUniform, WgslStruct};

gs_gpu::wgsl_struct! {
    /// Constants of one evaluation (binding 0; WGSL `struct NormalFrame`).
    pub(crate) struct NormalFrame as "NormalFrame" {
        width: u32,
        height: u32,
        /// Pixels (width · height).
        n: u32,
        /// Whether `inputs` holds the alpha plane A after δ.
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

/// The kernels' storage bindings, by name (slot order; one table for the four passes).
const BINDINGS: [Binding<'static>; 8] = [
    Binding::read("inputs", "array<f32>"),
    Binding::read("rays", "array<f32>"),
    Binding::write("nhat", "array<f32>"),
    Binding::write("values", "array<f32>"),
    Binding::write("gnhat", "array<f32>"),
    Binding::write("gnt", "array<f32>"),
    Binding::write("gab", "array<f32>"),
    Binding::write("gz", "array<f32>"),
];

const PASSES: [&str; 4] = ["depth_normals", "normal_terms", "normal_chain", "depth_gradient"];

/// The kernels' whole WGSL source.
pub fn normal_kernel_source() -> String {
    gs_gpu::kernel_source(&[&NormalFrame::wgsl_decl(), include_str!("normal.wgsl")], &BINDINGS)
}

/// The device executor of L_nc and L_ns: its context (shared), buffers and four kernels.
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
        let frame = (NormalFrame::wgsl_decl(), std::mem::size_of::<NormalFrame>());
        Ok(Self { k: LossKernels::new(ctx, &frame.0, frame.1, include_str!("normal.wgsl"), &BINDINGS, &PASSES)? })
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
        check_inputs(plane_depth, rendered_normal, alpha, guide, intrinsics, cfg)?;
        let (w, h) = (plane_depth.width(), plane_depth.height());
        let n = w * h;
        let bytes = 4 * n as u64;
        if n == 0 || 6 * bytes > self.k.ctx.max_storage_binding() || n > u32::MAX as usize / 6 {
            return crate::normal_losses(plane_depth, rendered_normal, alpha, guide, intrinsics, cfg);
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
        // Each binding's size: planes of one value per pixel, and the rays; the readback: N̂, the
        // values, ∂/∂Ñ and ∂/∂z.
        const READ: u64 = 3 + 4 + 3 + 1;
        let k = &mut self.k;
        k.begin([6 * bytes, 4 * rays.len() as u64, 3 * bytes, 4 * bytes, 3 * bytes, 3 * bytes, 6 * bytes, bytes], READ * bytes);
        let [inputs, ray_buf, nhat, values, _, gnt, _, gz] = k.bufs;
        let q = k.ctx.queue();
        let planes: [&[f32]; 4] = [plane_depth.data(), rendered_normal.data(), guide.delta.data(), alpha.map_or(&[], |a| a.data())];
        let mut at = 0;
        for plane in planes {
            q.write_buffer(k.pool.buffer(inputs), at, bytemuck::cast_slice(plane));
            at += 4 * plane.len() as u64;
        }
        q.write_buffer(k.pool.buffer(ray_buf), 0, bytemuck::cast_slice(&rays));
        k.disp.write_frame(&frame);
        let p = &k.pool;
        let binds = k.bufs.map(|id| p.whole(id));
        let mut enc = k.disp.encoder();
        k.ctx.push_error_scopes();
        for kernel in &k.kernels {
            k.disp.dispatch_1d(&mut enc, kernel, &binds, PassUniform { n: n as u32, ..Default::default() }).map_err(gpu_error)?;
        }
        let staging = p.buffer(k.staging);
        let mut at = 0;
        for (id, planes) in [(nhat, 3), (values, 4), (gnt, 3), (gz, 1)] {
            enc.encoder.copy_buffer_to_buffer(p.buffer(id), 0, staging, at, planes * bytes);
            at += planes * bytes;
        }
        k.disp.submit(enc);
        k.ctx.pop_error_scopes().map_err(gpu_error)?;
        let (nhat, values, g_nt, g_z) = k
            .ctx
            .read_mapped(staging, READ * bytes, |m| {
                let all = bytemuck::cast_slice::<u8, f32>(m);
                let (nhat, rest) = all.split_at(3 * n);
                let (values, rest) = rest.split_at(4 * n);
                let (g_nt, g_z) = rest.split_at(3 * n);
                (nhat.to_vec(), values.to_vec(), g_nt.to_vec(), g_z.to_vec())
            })
            .map_err(gpu_error)?;
        let l_nc = consistency_sum(n, |p| values[4 * p] as f64) / n as f64;
        // The reference's L_ns sum: each row's active pairs in order (right, then down), in f64.
        let rows = (0..h)
            .map(|j| {
                let row = &values[4 * j * w..4 * (j + 1) * w];
                let s = row.chunks(4).flat_map(|v| [v[1] as f64, v[2] as f64]).fold(0.0, |s, v| s + v);
                (s, row.chunks(4).map(|v| v[3] as usize).sum())
            })
            .collect();
        let (ns_sum, active) = smoothing_sum(rows);
        let l_ns = ns_sum / n as f64;
        NormalLossOutput::assemble(cfg, (w, h), (l_nc, l_ns, active), nhat, g_z, g_nt)
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn frame_matches_its_wgsl_layout() {
        gs_gpu::check_layout::<super::NormalFrame>(&super::normal_kernel_source()).unwrap();
    }
}
