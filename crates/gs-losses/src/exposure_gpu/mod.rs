//! Exposure compensation on the device (behind the `wgpu` feature), the twin of
//! [`crate::exposure`]: a view's rendered colour kept on the device is corrected there
//! (c' = exp(a)·c + b) for L_I on the device, and the backward chains L_I's gradient there
//! (∂L/∂c = exp(a)·∂L/∂c') and sums each image row's share of ∂L/∂(a, b) in compensated f32,
//! then the rows in order as double-f32 pairs, so that six totals come back (`exposure.wgsl`).
//! The gains exp(a) are the host's. Tolerances: `tests/exposure_gpu.rs` (docs/architecture.md
//! §GPU).

use crate::device::{LossKernels, gpu_error};
use crate::error::{LossError, Result};
use crate::exposure::{ExposureParams, exposure_gains};
use gs_gpu::{Bind, Binding, DeviceImage, GeneratedStruct, GpuContext, PassUniform, bytes_of, declarations};

gs_gpu::wgsl_struct! {
    /// Constants of one view's correction (binding 0; WGSL `struct ExposureFrame`).
    pub(crate) struct ExposureFrame as "ExposureFrame" {
        /// exp(a) per channel (the last lane unused).
        gain: [f32; 4],
        /// b per channel (the last lane unused).
        bias: [f32; 4],
        width: u32,
        height: u32,
        pad0: u32,
        pad1: u32,
    }
}

gs_gpu::wgsl_struct! {
    /// One image row's share of ∂L/∂(a, b) (WGSL `struct ExposureRow`): Σ ∂L/∂c'·exp(a)·c and
    /// Σ ∂L/∂c' per channel; after the rows, the image's totals as two records, the pairs'
    /// high parts, then their low parts (`exposure_totals`). 32 bytes.
    pub(crate) struct ExposureRow as "ExposureRow" {
        scaled: [f32; 4],
        plain: [f32; 4],
    }
}

/// The storage bindings, by name (slot order).
const BINDINGS: [Binding<'static>; 4] = [
    Binding::read("colour", "array<f32>"),
    Binding::read("grad", "array<f32>"),
    Binding::write("out", "array<f32>"),
    Binding::write("rows", "array<ExposureRow>"),
];

/// The passes, in `BINDINGS`' kernel order.
const PASSES: [&str; 4] = ["exposure_apply", "exposure_chain", "exposure_rows", "exposure_totals"];

/// The passes' indices in [`PASSES`]: the correction and the chained gradient (a thread a
/// value), the row sums (a thread a row), their totals (one thread).
const APPLY: usize = 0;
const CHAIN: usize = 1;
const ROWS: usize = 2;
const TOTALS: usize = 3;

fn generated_structs() -> [GeneratedStruct; 2] {
    [GeneratedStruct::of::<ExposureFrame>(), GeneratedStruct::of::<ExposureRow>()]
}

/// The kernels' whole WGSL source.
pub fn exposure_kernel_source() -> String {
    gs_gpu::kernel_source(&[&declarations(&generated_structs()), include_str!("exposure.wgsl")], &BINDINGS)
}

/// The device executor of the exposure correction.
pub struct ExposureGpu {
    k: LossKernels<4>,
}

impl std::fmt::Debug for ExposureGpu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "ExposureGpu({})", self.k.ctx.description())
    }
}

impl ExposureGpu {
    /// The executor on `ctx`'s device (shared, e.g. with the rasterizer's).
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let decls = declarations(&generated_structs());
        let k = LossKernels::new(ctx, &decls, std::mem::size_of::<ExposureFrame>(), include_str!("exposure.wgsl"), &BINDINGS, &PASSES)?;
        Ok(Self { k })
    }

    /// c' = exp(a)·c + b of `color` (an RGB image on this device), into a new image there.
    pub fn apply(&mut self, color: &DeviceImage, e: &ExposureParams) -> Result<DeviceImage> {
        self.check(color, "the colour to correct")?;
        let out = DeviceImage::new(&self.k.ctx, "exposure-corrected colour", color.width(), color.height(), 3).map_err(gpu_error)?;
        self.k.begin([4, 4, 4, 4], 4);
        self.run(color, e, &[(APPLY, color, &out)], None)?;
        Ok(out)
    }

    /// Backward of [`ExposureGpu::apply`] at `color` (the uncorrected colour) from `grad_out`
    /// (∂L/∂c', RGB on this device): ∂L/∂c into a new image there, and ∂L/∂(a, b), whose row
    /// sums come back (one wait).
    pub fn backward(&mut self, color: &DeviceImage, e: &ExposureParams, grad_out: &DeviceImage) -> Result<(DeviceImage, ExposureParams)> {
        self.check(color, "the corrected colour")?;
        self.check(grad_out, "the exposure's output gradient")?;
        if (grad_out.width(), grad_out.height()) != (color.width(), color.height()) {
            return Err(LossError::ShapeMismatch(format!(
                "the exposure's output gradient is {}x{}, its colour {}x{}",
                grad_out.width(),
                grad_out.height(),
                color.width(),
                color.height()
            )));
        }
        let chained = DeviceImage::new(&self.k.ctx, "exposure colour gradient", color.width(), color.height(), 3).map_err(gpu_error)?;
        let h = color.height();
        let (row_bytes, total_bytes) = (bytes_of::<ExposureRow>(h), bytes_of::<ExposureRow>(2));
        self.k.begin([4, 4, 4, row_bytes + total_bytes], total_bytes);
        let passes = [(CHAIN, grad_out, &chained), (ROWS, grad_out, &chained), (TOTALS, grad_out, &chained)];
        let totals = self.run(color, e, &passes, Some((row_bytes, total_bytes)))?.unwrap_or_default();
        let [hi, lo] = [totals[0], totals[1]];
        let ge: [f64; 6] = std::array::from_fn(|k| match k {
            0..3 => gs_gpu::wide_value([hi.scaled[k], lo.scaled[k]]),
            _ => gs_gpu::wide_value([hi.plain[k - 3], lo.plain[k - 3]]),
        });
        Ok((chained, ge.map(|v| v as f32)))
    }

    /// Records `passes` (each: its index in [`PASSES`], the image bound as `grad` and the one
    /// bound as `out`) on `color`'s correction by `e`, submits, and reads back the records of
    /// `rows` that `read` gives (their offset and bytes).
    fn run(&mut self, color: &DeviceImage, e: &ExposureParams, passes: &[(usize, &DeviceImage, &DeviceImage)], read: Option<(u64, u64)>) -> Result<Option<Vec<ExposureRow>>> {
        let g = exposure_gains(e);
        let frame = ExposureFrame {
            gain: [g[0], g[1], g[2], 0.0],
            bias: [e[3], e[4], e[5], 0.0],
            width: color.width() as u32,
            height: color.height() as u32,
            ..Default::default()
        };
        let k = &self.k;
        k.disp.write_frame(&frame);
        let mut enc = k.disp.encoder();
        k.ctx.push_error_scopes();
        let recorded = (|| {
            for &(pass, grad, out) in passes {
                let binds = [Bind::whole(color.buffer()), Bind::whole(grad.buffer()), Bind::whole(out.buffer()), k.pool.whole(k.bufs[3])];
                let n = match pass {
                    ROWS => color.height(),
                    TOTALS => 1,
                    _ => color.len(),
                } as u32;
                k.disp.dispatch_1d(&mut enc, &k.kernels[pass], &binds, PassUniform { n, ..Default::default() })?;
            }
            Ok::<_, gs_gpu::GpuError>(())
        })();
        let staging = k.pool.buffer(k.staging);
        if let Some((at, bytes)) = read {
            enc.encoder.copy_buffer_to_buffer(k.pool.buffer(k.bufs[3]), at, staging, 0, bytes);
        }
        k.disp.submit(enc);
        k.ctx.pop_error_scopes().map_err(gpu_error)?;
        recorded.map_err(gpu_error)?;
        match read {
            Some((_, bytes)) => Ok(Some(k.ctx.read_mapped(staging, bytes, bytemuck::pod_collect_to_vec).map_err(gpu_error)?)),
            None => Ok(None),
        }
    }

    /// Checks that `image` is an RGB image on this executor's device.
    fn check(&self, image: &DeviceImage, what: &str) -> Result<()> {
        if !image.is_on(&self.k.ctx) {
            return Err(LossError::InvalidParameter(format!("{what} lives on another device")));
        }
        match image.channels() {
            3 => Ok(()),
            c => Err(LossError::Channels(format!("{what} has {c} channels, not 3"))),
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn records_match_their_wgsl_layout() {
        let src = super::exposure_kernel_source();
        gs_gpu::check_layouts(&super::generated_structs(), &src).unwrap();
        gs_gpu::validate_kernel(&src).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(gs_gpu::bytes_of::<super::ExposureRow>(1), 32);
    }
}
