//! L_I on the device (behind the `wgpu` feature), the twin of [`crate::image_loss()`]: L1, D-SSIM
//! and the edge term in one set of WGSL passes (`image.wgsl`) that writes ∂L_I/∂Ĩ and each
//! value's or pixel's terms, sums those along each image row in order (compensated f32) and
//! adds the rows in order (double-f32 pairs); the host reads the three totals alone, so one
//! input gives one result on one device. [`ImageLossGpu::ssim_backward`] is D-SSIM alone, the twin of
//! [`crate::ssim::ssim_backward`] over the whole image. Tolerances: `tests/image_gpu.rs`
//! (docs/method.md §L_I, docs/architecture.md §GPU).

use crate::device::{LossKernels, gpu_error};
use gs_gpu::{GeneratedStruct, bytes_of, declarations};
use crate::dims::Dims;
use crate::error::{LossError, Result};
use crate::gradient::GRAD_NORM_EPS;
use crate::image_loss::{EdgeGuide, ImageLossConfig, ImageLossOutput, check_inputs};
use crate::ssim::{SSIM_C1, SSIM_C2, gaussian_window_1d};
use gs_core::Image;
use gs_gpu::{Arena, ArenaKey, Binding, DeviceImage, GpuContext, PassUniform, PendingRead};
use std::borrow::Cow;

gs_gpu::wgsl_struct! {
    /// Constants of one evaluation (binding 0; WGSL `struct ImageFrame`).
    pub(crate) struct ImageFrame as "ImageFrame" {
        width: u32,
        height: u32,
        channels: u32,
        /// Values per image (width · height · channels).
        n: u32,
        /// Pixels (width · height).
        pixels: u32,
        /// SSIM's weight per value: its weight / n.
        wp: f32,
        /// L1's weight per value: (1 − β1) / n.
        w_l1: f32,
        /// The edge term's weight per pixel: β2 / pixels.
        w_edge: f32,
        c1: f32,
        c2: f32,
        /// 1 / channels.
        inv_c: f32,
        /// 1 when the edge passes ran (the edge term is on and the image has an interior).
        edge: u32,
        /// Workgroups of the range pass.
        groups: u32,
        /// The ε of ∇Ĩ's min–max normalisation.
        grad_eps: f32,
        /// 1 when the edge term's values were written (a guide was given; with or without an
        /// interior).
        edge_values: u32,
        /// Where a, b and the pixel plane ∇I start in the arena (`images`), in floats.
        a_at: u32,
        b_at: u32,
        guide_at: u32,
        pad1: u32,
        pad2: u32,
        /// The 11 window taps (the last lane of g2 unused).
        g0: [f32; 4],
        g1: [f32; 4],
        g2: [f32; 4],
    }
}

gs_gpu::wgsl_struct! {
    /// One pixel of the edge term (WGSL `struct EdgeTexel`): `edge_raw` writes the channel
    /// means of the central differences, `edge_terms` the backward's coefficients on them,
    /// which `loss_gradient` reads at the pixel's neighbours. 16 bytes.
    pub(crate) struct EdgeTexel as "EdgeTexel" {
        /// g_x, g_y (0 on the border).
        gx: f32,
        gy: f32,
        /// ∂(edge term)/∂g_x, ∂/∂g_y (0 on the border and off the larger axis).
        cx: f32,
        cy: f32,
    }
}

gs_gpu::wgsl_struct! {
    /// A min and max of max(g_x, g_y) over interior pixels (WGSL `struct EdgeRange`): record 0
    /// the whole interior's, record 1 + g range group g's share. 8 bytes.
    pub(crate) struct EdgeRange as "EdgeRange" {
        lo: f32,
        hi: f32,
    }
}

/// The kernels' storage bindings, by name (slot order; one table for every pass). The `f32`
/// arrays are planes of one value per image value or pixel (see `image.wgsl`).
const BINDINGS: [Binding<'static>; 8] = [
    Binding::read("images", "array<f32>"),
    Binding::write("moments", "array<f32>"),
    Binding::write("partials", "array<f32>"),
    Binding::write("blurred", "array<f32>"),
    Binding::write("values", "array<f32>"),
    Binding::write("grad", "array<f32>"),
    Binding::write("edge", "array<EdgeTexel>"),
    Binding::write("edge_ranges", "array<EdgeRange>"),
];

/// The frame uniform and the storage records: one list for the kernels' declarations and the
/// layout test.
fn generated_structs() -> [GeneratedStruct; 3] {
    [GeneratedStruct::of::<ImageFrame>(), GeneratedStruct::of::<EdgeTexel>(), GeneratedStruct::of::<EdgeRange>()]
}

/// How a pass is dispatched.
#[derive(Clone, Copy)]
enum Grid {
    /// One thread per value.
    Values,
    /// One thread per pixel, with the edge term.
    EdgePixels,
    /// [`RANGE_GROUPS`] workgroups at most, with the edge term on an image with an interior.
    RangeGroups,
    /// One workgroup, as `RangeGroups`.
    RangeTotal,
    /// One thread per image row.
    Rows,
    /// One thread.
    Total,
}

/// The passes in order, with their grids.
const PASSES: [(&str, Grid); 10] = [
    ("blur_rows", Grid::Values),
    ("ssim_values", Grid::Values),
    ("blur_partials", Grid::Values),
    ("edge_raw", Grid::EdgePixels),
    ("edge_range_groups", Grid::RangeGroups),
    ("edge_range", Grid::RangeTotal),
    ("edge_terms", Grid::EdgePixels),
    ("loss_gradient", Grid::Values),
    ("row_sums", Grid::Rows),
    ("image_totals", Grid::Total),
];

/// Sums a row that `row_sums` writes after the value planes: SSIM, |a − b|, |∇Ĩ − ∇I|.
const ROW_SUMS: usize = 3;

/// The image's totals of the three sums that `image_totals` writes after the rows' sums, each
/// a double-f32 pair (`gs_gpu::wide_value`): what comes back.
const TOTALS: usize = 2 * ROW_SUMS;

/// Most workgroups of the range pass (each strides over the image).
const RANGE_GROUPS: usize = 256;

/// The kernels' whole WGSL source.
pub fn image_kernel_source() -> String {
    gs_gpu::kernel_source(&[&declarations(&generated_structs()), include_str!("image.wgsl")], &BINDINGS)
}

/// How much device memory the arena of photos and edge guides holds (bytes), at most one
/// storage binding.
const ARENA_BYTES: u64 = 512 << 20;

/// The rendered image Ĩ of an evaluation: on the host, or kept on the device (copied into
/// the arena there, its gradient kept there too).
#[derive(Clone, Copy)]
enum Rendered<'a> {
    Host(&'a [f32]),
    Device(&'a DeviceImage),
}

/// What [`ImageLossGpu::submit`] compares the rendered image with: b, the guide's ∇I, and the key
/// under which both stay on the device between calls (none: uploaded every call).
struct Targets<'a> {
    b: &'a [f32],
    guide: Option<&'a [f32]>,
    key: Option<u64>,
}

/// The device executor of L_I: its context (shared), buffers, kernels and the arena that keeps
/// each view's photo and edge guide on the device ([`ImageLossGpu::image_loss_of_view`]).
pub struct ImageLossGpu {
    k: LossKernels<8>,
    arena: Arena,
}

impl std::fmt::Debug for ImageLossGpu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "ImageLossGpu({})", self.k.ctx.description())
    }
}

/// An evaluation submitted to the device (its readback requested), not read yet.
struct Submitted {
    read: PendingRead,
    dims: Dims,
    /// Whether the edge term's values were written.
    edge: bool,
    /// The gradient kept on the device (a rendered image given there), else read back.
    grad: Option<DeviceImage>,
}

/// An L_I evaluation started by [`ImageLossGpu::start`]: on the device, or already made on the
/// host (images too large for the device's bindings).
pub struct PendingImageLoss(Pending<Image>);

/// An L_I evaluation of a rendered image kept on the device, started by
/// [`ImageLossGpu::start_on_device`]; its gradient stays there.
pub struct PendingDeviceImageLoss(Pending<DeviceImage>);

enum Pending<G> {
    Device(Submitted, ImageLossConfig),
    Host(ImageLossOutput<G>),
}

/// What one evaluation read back: the three terms' means and ∂/∂a (empty when it stayed on
/// the device).
struct Terms {
    ssim: f64,
    l1: f64,
    edge: Option<f64>,
    grad: Vec<f32>,
}

impl ImageLossGpu {
    /// The executor on `ctx`'s device (shared, e.g. with the rasterizer's), its kernels compiled.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let decls = declarations(&generated_structs());
        let frame = std::mem::size_of::<ImageFrame>();
        let k = LossKernels::new(ctx, &decls, frame, include_str!("image.wgsl"), &BINDINGS, &PASSES.map(|p| p.0))?;
        Ok(Self { k, arena: Arena::new(ctx, "photo arena", ARENA_BYTES) })
    }

    /// Whether images of `dims` fit this device's storage bindings (else the reference runs):
    /// the largest, `moments`, holds five planes of values.
    fn fits(&self, dims: Dims) -> bool {
        let n = dims.len();
        n > 0 && n <= u32::MAX as usize / 5 && bytes_of::<f32>(5 * n) <= self.k.ctx.max_storage_binding()
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
        if !self.fits(dims) {
            return crate::ssim::ssim_backward(a, b, dims, crate::SsimRegion::Full, weight, grad_a);
        }
        let Some(submitted) = self.submit(Rendered::Host(a), Targets { b, guide: None, key: None }, dims, weight, 0.0, 0.0)? else {
            return crate::ssim::ssim_backward(a, b, dims, crate::SsimRegion::Full, weight, grad_a);
        };
        let t = self.collect(submitted)?;
        for (g, d) in grad_a.iter_mut().zip(&t.grad) {
            *g += d;
        }
        Ok(t.ssim)
    }

    /// [`crate::image_loss()`] on the device: the same inputs, checks and output.
    pub fn image_loss(&mut self, rendered: &Image, gt: &Image, guide: Option<&EdgeGuide>, cfg: &ImageLossConfig) -> Result<ImageLossOutput> {
        let pending = self.start(rendered, gt, guide, None, cfg)?;
        self.finish(pending)
    }

    /// [`ImageLossGpu::image_loss`] of a view whose photo `gt` and `guide` stay on the device
    /// under `view` between calls, uploaded only on first use and when evicted: the caller
    /// names one photo and guide by one `view` (e.g. a training view at one resolution).
    pub fn image_loss_of_view(&mut self, rendered: &Image, gt: &Image, guide: Option<&EdgeGuide>, view: u64, cfg: &ImageLossConfig) -> Result<ImageLossOutput> {
        let pending = self.start(rendered, gt, guide, Some(view), cfg)?;
        self.finish(pending)
    }

    /// Submits [`ImageLossGpu::image_loss_of_view`] (`view` `None`: nothing kept) and returns
    /// at once; [`ImageLossGpu::finish`] reads the result. Readbacks of several executors on
    /// one device started before the first finish cost the host one wait. Finish an
    /// evaluation before starting the next on this executor.
    pub fn start(&mut self, rendered: &Image, gt: &Image, guide: Option<&EdgeGuide>, view: Option<u64>, cfg: &ImageLossConfig) -> Result<PendingImageLoss> {
        let guide = check_inputs(Dims::of(rendered), gt, guide, cfg)?;
        Ok(PendingImageLoss(match self.submit_checked(Rendered::Host(rendered.data()), gt, guide, view, cfg)? {
            Some(s) => Pending::Device(s, *cfg),
            None => Pending::Host(crate::image_loss(rendered, gt, guide, cfg)?),
        }))
    }

    /// [`ImageLossGpu::start`] of a rendered image kept on this device (a render's colour that
    /// never came to the host): it is copied into the arena there, and the gradient stays there
    /// ([`ImageLossGpu::finish_on_device`]); only the totals (24 bytes) come back. Images too large for
    /// the device's bindings are read back and evaluated on the host, their gradient uploaded.
    pub fn start_on_device(&mut self, rendered: &DeviceImage, gt: &Image, guide: Option<&EdgeGuide>, view: Option<u64>, cfg: &ImageLossConfig) -> Result<PendingDeviceImageLoss> {
        if !rendered.is_on(&self.k.ctx) {
            return Err(LossError::Device("the rendered image lives on another device".into()));
        }
        let dims = Dims::new(rendered.width(), rendered.height(), rendered.channels());
        let guide = check_inputs(dims, gt, guide, cfg)?;
        Ok(PendingDeviceImageLoss(match self.submit_checked(Rendered::Device(rendered), gt, guide, view, cfg)? {
            Some(s) => Pending::Device(s, *cfg),
            None => {
                let host = Image::from_vec(dims.width, dims.height, dims.channels, rendered.read(&self.k.ctx).map_err(gpu_error)?)?;
                let out = crate::image_loss(&host, gt, guide, cfg)?;
                let ctx = &self.k.ctx;
                Pending::Host(out.map_grad(|g| DeviceImage::upload(ctx, "image loss gradient", (dims.width, dims.height, dims.channels), g.data()).map_err(gpu_error))?)
            }
        }))
    }

    /// An evaluation of checked inputs submitted to the device; `None` when the images do not
    /// fit it (the caller evaluates on the host).
    fn submit_checked(&mut self, rendered: Rendered<'_>, gt: &Image, guide: Option<&EdgeGuide>, view: Option<u64>, cfg: &ImageLossConfig) -> Result<Option<Submitted>> {
        let dims = Dims::of(gt);
        if !self.fits(dims) {
            return Ok(None);
        }
        let b1 = cfg.beta1 as f64;
        let targets = Targets { b: gt.data(), guide: guide.map(|g| g.gradient.data()), key: view };
        self.submit(rendered, targets, dims, -b1, 1.0 - b1, cfg.beta2 as f64)
    }

    /// The result of a started evaluation (waiting for the device if it has not answered).
    pub fn finish(&mut self, pending: PendingImageLoss) -> Result<ImageLossOutput> {
        match pending.0 {
            Pending::Host(out) => Ok(out),
            Pending::Device(s, cfg) => {
                let dims = s.dims;
                let t = self.collect(s)?;
                ImageLossOutput::assemble(&cfg, t.l1, t.ssim, t.edge, Image::from_vec(dims.width, dims.height, dims.channels, t.grad)?)
            }
        }
    }

    /// The result of an evaluation started on the device: the values (one wait, unless an
    /// earlier wait brought them) and the gradient, which stays on the device.
    pub fn finish_on_device(&mut self, pending: PendingDeviceImageLoss) -> Result<ImageLossOutput<DeviceImage>> {
        match pending.0 {
            Pending::Host(out) => Ok(out),
            Pending::Device(mut s, cfg) => {
                let grad = s.grad.take().ok_or_else(|| LossError::Device("an evaluation on the device without its gradient image".into()))?;
                let t = self.collect(s)?;
                ImageLossOutput::assemble(&cfg, t.l1, t.ssim, t.edge, grad)
            }
        }
    }

    /// One evaluation of `a` against `targets` submitted: SSIM at `w_ssim`, L1 at `w_l1` and,
    /// when the guide's ∇I is given, the edge term at `w_edge`; [`ImageLossGpu::collect`]
    /// reads their means and the summed gradient. `None` when the arena cannot hold the three
    /// images at once.
    fn submit(&mut self, a: Rendered<'_>, targets: Targets<'_>, dims: Dims, w_ssim: f64, w_l1: f64, w_edge: f64) -> Result<Option<Submitted>> {
        let (n, pixels) = (dims.len(), dims.pixels());
        let gt_gradient = targets.guide;
        let part = |p: u32| targets.key.map(|k| -> ArenaKey { (k, p) });
        let mut items = vec![(None, n), (part(0), n)];
        // Item 0, the rendered image: a device image is copied into its slot below.
        let mut arrays = vec![match a {
            Rendered::Host(values) => Some(values),
            Rendered::Device(_) => None,
        }];
        arrays.push(Some(targets.b));
        if let Some(gg) = gt_gradient {
            items.push((part(1), pixels));
            arrays.push(Some(gg));
        }
        let Some(at) = self.arena.place_with(&self.k.ctx, &items, |i| arrays[i].map(Cow::Borrowed)) else {
            return Ok(None);
        };
        let grad_image = match a {
            Rendered::Device(_) => Some(DeviceImage::new(&self.k.ctx, "image loss gradient", dims.width, dims.height, dims.channels).map_err(gpu_error)?),
            Rendered::Host(_) => None,
        };
        let interior = dims.width >= 3 && dims.height >= 3;
        let groups = pixels.div_ceil(256).clamp(1, RANGE_GROUPS);
        let g = gaussian_window_1d().map(|v| v as f32);
        let frame = ImageFrame {
            width: dims.width as u32,
            height: dims.height as u32,
            channels: dims.channels as u32,
            n: n as u32,
            pixels: pixels as u32,
            wp: (w_ssim / n as f64) as f32,
            w_l1: (w_l1 / n as f64) as f32,
            w_edge: (w_edge / pixels as f64) as f32,
            c1: SSIM_C1 as f32,
            c2: SSIM_C2 as f32,
            inv_c: (1.0 / dims.channels as f64) as f32,
            edge: (gt_gradient.is_some() && interior) as u32,
            groups: groups as u32,
            grad_eps: GRAD_NORM_EPS as f32,
            edge_values: gt_gradient.is_some() as u32,
            a_at: at[0],
            b_at: at[1],
            guide_at: at.get(2).copied().unwrap_or(0),
            pad1: 0,
            pad2: 0,
            g0: [g[0], g[1], g[2], g[3]],
            g1: [g[4], g[5], g[6], g[7]],
            g2: [g[8], g[9], g[10], 0.0],
        };
        let bytes = bytes_of::<f32>(n);
        let pixel_bytes = bytes_of::<f32>(pixels);
        // `values`: SSIM and |a − b| per value, |∇Ĩ − ∇I| per pixel, the row sums, then their
        // totals, which alone come back with the gradient.
        let sums_at = 2 * bytes + pixel_bytes + bytes_of::<f32>(ROW_SUMS * dims.height);
        let read = bytes_of::<f32>(TOTALS);
        // The gradient comes back after the sums unless it stays on the device.
        let grad_back = if grad_image.is_some() { 0 } else { bytes };
        let k = &mut self.k;
        let edge = [bytes_of::<EdgeTexel>(pixels), bytes_of::<EdgeRange>(1 + groups)];
        k.begin([4, 5 * bytes, 3 * bytes, 3 * bytes, sums_at + read, bytes, edge[0], edge[1]], read + grad_back);
        let [_, _, _, _, values, grad, _, _] = k.bufs;
        k.disp.write_frame(&frame);
        let p = &k.pool;
        let mut binds = k.bufs.map(|id| p.whole(id));
        binds[0] = self.arena.bind();
        let mut enc = k.disp.encoder();
        k.ctx.push_error_scopes();
        if let Rendered::Device(image) = a {
            enc.encoder.copy_buffer_to_buffer(image.buffer(), 0, self.arena.buffer(), 4 * at[0] as u64, bytes);
        }
        let per_value = PassUniform { n: n as u32, ..Default::default() };
        let per_pixel = PassUniform { n: pixels as u32, ..Default::default() };
        let per_row = PassUniform { n: dims.height as u32, ..Default::default() };
        for (kernel, (_, grid)) in k.kernels.iter().zip(PASSES) {
            match grid {
                Grid::Values => k.disp.dispatch_1d(&mut enc, kernel, &binds, per_value),
                Grid::EdgePixels if gt_gradient.is_some() => k.disp.dispatch_1d(&mut enc, kernel, &binds, per_pixel),
                Grid::RangeGroups if frame.edge == 1 => k.disp.dispatch(&mut enc, kernel, &binds, per_pixel, (groups as u32, 1)),
                Grid::RangeTotal if frame.edge == 1 => k.disp.dispatch(&mut enc, kernel, &binds, per_pixel, (1, 1)),
                Grid::Rows => k.disp.dispatch_1d(&mut enc, kernel, &binds, per_row),
                Grid::Total => k.disp.dispatch_1d(&mut enc, kernel, &binds, PassUniform { n: 1, ..Default::default() }),
                _ => Ok(()),
            }
            .map_err(gpu_error)?;
        }
        let staging = p.buffer(k.staging);
        enc.encoder.copy_buffer_to_buffer(p.buffer(values), sums_at, staging, 0, read);
        match &grad_image {
            Some(image) => enc.encoder.copy_buffer_to_buffer(p.buffer(grad), 0, image.buffer(), 0, bytes),
            None => enc.encoder.copy_buffer_to_buffer(p.buffer(grad), 0, staging, read, bytes),
        }
        k.disp.submit(enc);
        k.ctx.pop_error_scopes().map_err(gpu_error)?;
        let read = k.ctx.request_read(staging, read + grad_back);
        Ok(Some(Submitted { read, dims, edge: gt_gradient.is_some(), grad: grad_image }))
    }

    /// The means and gradient of a submitted evaluation.
    fn collect(&mut self, s: Submitted) -> Result<Terms> {
        let (n, pixels) = (s.dims.len(), s.dims.pixels());
        self.k
            .ctx
            .finish_read(s.read, |m| {
                let all = bytemuck::cast_slice::<u8, f32>(m);
                // The gradient follows the totals when it came back (else `grad` is empty).
                let (totals, grad) = all.split_at(TOTALS);
                let rows = |k: usize| gs_gpu::wide_value([totals[2 * k], totals[2 * k + 1]]);
                Terms {
                    ssim: rows(0) / n as f64,
                    l1: rows(1) / n as f64,
                    edge: s.edge.then(|| rows(2) / pixels as f64),
                    grad: grad.to_vec(),
                }
            })
            .map_err(gpu_error)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The whole source (what the device compiles) parses and validates, and each generated struct has the
    /// Rust offsets and sizes (naga's layouter against `offset_of!` / `size_of`).
    #[test]
    fn host_and_wgsl_struct_layouts_agree() {
        let src = image_kernel_source();
        gs_gpu::check_layout::<PassUniform>(&src).unwrap();
        gs_gpu::check_layouts(&generated_structs(), &src).unwrap();
        gs_gpu::validate_kernel(&src).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!([bytes_of::<EdgeTexel>(1), bytes_of::<EdgeRange>(1)], [16, 8]);
    }
}
