//! D-SSIM on the device (behind the `wgpu` feature), the twin of [`crate::ssim::ssim_backward`]
//! over the whole image: four WGSL passes (`ssim.wgsl`) compute the SSIM map and ∂SSIM/∂a, and
//! the host sums the map by rows in the reference's fixed order, so one input gives one result
//! on one device. [`SsimGpu::image_loss`] is [`crate::image_loss`] with this SSIM (L1 and the
//! edge term are cheap and stay on the host). Tolerances: `tests/ssim_gpu.rs`
//! (docs/method.md §L_I, docs/architecture.md §GPU).

use crate::dims::{Dims, ordered_sum};
use crate::error::{LossError, Result};
use crate::image_loss::{EdgeGuide, ImageLossConfig, ImageLossOutput, image_loss_with};
use crate::ssim::{SSIM_C1, SSIM_C2, gaussian_window_1d};
use gs_core::Image;
use gs_gpu::{Binding, BufId, BufferPool, Dispatcher, GpuContext, Kernel, PassUniform, ShrinkPolicy, WgslStruct};

gs_gpu::wgsl_struct! {
    /// Constants of one SSIM evaluation (binding 0; WGSL `struct SsimFrame`).
    pub(crate) struct SsimFrame as "SsimFrame" {
        width: u32,
        height: u32,
        channels: u32,
        /// Values per image (width · height · channels).
        n: u32,
        /// The weight per value: `weight` / n.
        wp: f32,
        c1: f32,
        c2: f32,
        pad: u32,
        /// The 11 window taps (the last lane of g2 unused).
        g0: [f32; 4],
        g1: [f32; 4],
        g2: [f32; 4],
    }
}

/// The kernels' storage bindings, by name (slot order; one table for the four passes).
const BINDINGS: [Binding<'static>; 6] = [
    Binding::read("images", "array<f32>"),
    Binding::write("moments", "array<f32>"),
    Binding::write("partials", "array<f32>"),
    Binding::write("blurred", "array<f32>"),
    Binding::write("smap", "array<f32>"),
    Binding::write("grad", "array<f32>"),
];

const PASSES: [&str; 4] = ["blur_rows", "ssim_values", "blur_partials", "ssim_gradient"];

/// The kernels' whole WGSL source.
pub fn ssim_kernel_source() -> String {
    gs_gpu::kernel_source(&[&SsimFrame::wgsl_decl(), include_str!("ssim.wgsl")], &BINDINGS)
}

/// The device executor of D-SSIM: its context (shared), buffers and four kernels.
pub struct SsimGpu {
    ctx: GpuContext,
    pool: BufferPool,
    disp: Dispatcher,
    kernels: Vec<Kernel>,
    bufs: [BufId; 6],
    /// The readback of the SSIM map and the gradient (pooled: a mappable buffer per call is
    /// costly to create).
    staging: BufId,
}

impl std::fmt::Debug for SsimGpu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "SsimGpu({})", self.ctx.description())
    }
}

fn gpu_error(e: gs_gpu::GpuError) -> LossError {
    LossError::Device(e.to_string())
}

impl SsimGpu {
    /// The executor on `ctx`'s device (shared, e.g. with the rasterizer's), its kernels compiled.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let ctx = ctx.clone();
        let decl = SsimFrame::wgsl_decl();
        let kernels = PASSES
            .iter()
            .map(|entry| Kernel::new(&ctx, entry, &[&decl, include_str!("ssim.wgsl")], &BINDINGS).map_err(gpu_error))
            .collect::<Result<Vec<_>>>()?;
        let mut pool = BufferPool::new(&ctx, ShrinkPolicy::default());
        let bufs = ["ssim images", "ssim moments", "ssim partials", "ssim blurred", "ssim map", "ssim grad"].map(|l| pool.add_storage(l));
        let staging = pool.add_staging("ssim readback");
        let disp = Dispatcher::new(&ctx, std::mem::size_of::<SsimFrame>() as u64);
        Ok(Self { ctx, pool, disp, kernels, bufs, staging })
    }

    /// [`crate::ssim::ssim_backward`] over the whole image ([`crate::SsimRegion::Full`]):
    /// returns the mean SSIM and adds `weight · ∂SSIM/∂a` to `grad_a`.
    pub fn ssim_backward(&mut self, a: &[f32], b: &[f32], dims: Dims, weight: f64, grad_a: &mut [f32]) -> Result<f64> {
        let n = dims.len();
        if a.len() != n || b.len() != n || grad_a.len() != n {
            return Err(LossError::ShapeMismatch(format!(
                "SSIM of {}×{}×{} needs {n} values per buffer, got {}, {} and {}",
                dims.width,
                dims.height,
                dims.channels,
                a.len(),
                b.len(),
                grad_a.len()
            )));
        }
        if n == 0 {
            return Err(LossError::InvalidParameter("SSIM of an empty image".into()));
        }
        let bytes = 4 * n as u64;
        if 5 * bytes > self.ctx.max_storage_binding() || n > u32::MAX as usize / 5 {
            // Larger than one storage binding of this device: the reference computes it.
            return crate::ssim::ssim_backward(a, b, dims, crate::SsimRegion::Full, weight, grad_a);
        }
        let g = gaussian_window_1d().map(|v| v as f32);
        let frame = SsimFrame {
            width: dims.width as u32,
            height: dims.height as u32,
            channels: dims.channels as u32,
            n: n as u32,
            wp: (weight / n as f64) as f32,
            c1: SSIM_C1 as f32,
            c2: SSIM_C2 as f32,
            pad: 0,
            g0: [g[0], g[1], g[2], g[3]],
            g1: [g[4], g[5], g[6], g[7]],
            g2: [g[8], g[9], g[10], 0.0],
        };
        let [images, moments, partials, blurred, smap, grad] = self.bufs;
        self.pool.begin_frame();
        for (id, planes) in [(images, 2), (moments, 5), (partials, 3), (blurred, 3), (smap, 1), (grad, 1)] {
            self.pool.ensure(id, planes * bytes);
        }
        self.pool.ensure(self.staging, 2 * bytes);
        let q = self.ctx.queue();
        q.write_buffer(self.pool.buffer(images), 0, bytemuck::cast_slice(a));
        q.write_buffer(self.pool.buffer(images), bytes, bytemuck::cast_slice(b));
        self.disp.write_frame(&frame);
        let p = &self.pool;
        let binds = self.bufs.map(|id| p.whole(id));
        let mut enc = self.disp.encoder();
        self.ctx.push_error_scopes();
        for k in &self.kernels {
            self.disp.dispatch_1d(&mut enc, k, &binds, PassUniform { n: n as u32, ..Default::default() }).map_err(gpu_error)?;
        }
        let staging = p.buffer(self.staging);
        enc.encoder.copy_buffer_to_buffer(p.buffer(smap), 0, staging, 0, bytes);
        enc.encoder.copy_buffer_to_buffer(p.buffer(grad), 0, staging, bytes, bytes);
        self.disp.submit(enc);
        self.ctx.pop_error_scopes().map_err(gpu_error)?;
        let row = dims.width * dims.channels;
        let sum = self
            .ctx
            .read_mapped(staging, 2 * bytes, |m| {
                let (values, dssim): (&[f32], &[f32]) = bytemuck::cast_slice::<u8, f32>(m).split_at(n);
                for (g, d) in grad_a.iter_mut().zip(dssim) {
                    *g += d;
                }
                // The reference's sum: by rows in f64, the rows in order.
                ordered_sum(dims.height, |y| values[y * row..(y + 1) * row].iter().map(|&v| v as f64).sum())
            })
            .map_err(gpu_error)?;
        Ok(sum / n as f64)
    }

    /// [`crate::image_loss`] with D-SSIM evaluated on the device.
    pub fn image_loss(&mut self, rendered: &Image, gt: &Image, guide: Option<&EdgeGuide>, cfg: &ImageLossConfig) -> Result<ImageLossOutput> {
        image_loss_with(rendered, gt, guide, cfg, &mut |a, b, dims, weight, grad| self.ssim_backward(a, b, dims, weight, grad))
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn frame_matches_its_wgsl_layout() {
        gs_gpu::check_layout::<super::SsimFrame>(&super::ssim_kernel_source()).unwrap();
    }
}
