//! L_p on the device (behind the `wgpu` feature), the twin of [`crate::photometric`]: one WGSL
//! kernel (`ncc.wgsl`) evaluates every selected (pixel, source) patch — its NCC cost and the
//! gradient with respect to the rendered plane (Ñ, D) — and three more (`reduce.wgsl`) sum
//! them in fixed orders into each (source, row)'s statistics and the gradient image, which
//! alone come back. υ/ω and the seeded pixel selection stay on the host and use the
//! reference's own code, so the two executors choose the same patches and differ only in the
//! patch arithmetic and the f32 sums (the tolerances are in `tests/photometric_gpu.rs`): one
//! seed gives one result on one device (docs/method.md §L_p, docs/architecture.md §GPU).
//!
//! The grey images go into an arena (gs-gpu's [`Arena`]); keyed by view
//! ([`PhotometricGpu::loss_of_views`]) they stay there between calls and are uploaded once.

mod reduce;
mod reference;

pub use reduce::reduce_kernel_source;
pub use reference::SurfaceReference;

use crate::error::{MvsError, Result};
use crate::photometric::{
    NccMode, PhotometricConfig, PhotometricOutput, PhotometricReference, PhotometricSource, SourceStats, patch_geometry,
    select_pixels,
};
use reference::{Plane, RefView};
use crate::visibility::{Visibility, visibility_unchecked};
use crate::geometry::PairGeometry;
use rayon::prelude::*;
use gs_gpu::{Arena, Binding, BufId, BufferPool, DeviceImage, Dispatcher, GpuContext, Kernel, PassUniform, PendingRead, ShrinkPolicy};
use std::borrow::Cow;

gs_gpu::wgsl_struct! {
    /// Constants of one L_p evaluation (binding 0 of the kernel; WGSL `struct NccFrame`).
    pub(crate) struct NccFrame as "NccFrame" {
        /// Reference camera width (pixel index → column, row).
        width: u32,
        /// Reference grey image width (row stride of `greys`; the y ray table starts here).
        grey_width: u32,
        /// Reference grey image scale s (1..=4).
        grey_scale: u32,
        /// Patch side (`patch` is a reserved word in WGSL).
        side: u32,
        /// 0 = [`NccMode::Pgsr`], 1 = [`NccMode::Plain`].
        mode: u32,
        /// Reference camera height (the reduction's rows).
        height: u32,
        /// Source views of this call.
        sources: u32,
        /// Reference pixels (width · height).
        pixels: u32,
        /// Where the reference grey image starts in `greys` (the arena), in floats.
        ref_offset: u32,
        pad0: u32,
        pad1: u32,
        pad2: u32,
    }
}

gs_gpu::wgsl_struct! {
    /// One reference/source pair (WGSL `struct NccPair`): the rows of K_s R_rs, K_s t_rs, the
    /// source size and where its grey image lies in `greys`.
    pub(crate) struct NccPair as "NccPair" {
        a0: [f32; 4],
        a1: [f32; 4],
        a2: [f32; 4],
        kt: [f32; 4],
        src_w: f32,
        src_h: f32,
        grey_offset: u32,
        grey_width: u32,
        grey_height: u32,
        pad0: u32,
        pad1: u32,
        pad2: u32,
    }
}

gs_gpu::wgsl_struct! {
    /// One patch's outcome (WGSL `struct NccResult`): status 0 outside, 1 masked, 2 counted.
    pub(crate) struct NccResult as "NccResult" {
        /// ∂cost/∂Ñ (xyz).
        grad_n: [f32; 4],
        status: u32,
        cost: f32,
        /// ∂cost/∂D.
        grad_d: f32,
        pad: u32,
    }
}

/// The kernel's storage bindings, by name (slot order).
const BINDINGS: [Binding<'static>; 6] = [
    Binding::read("pairs", "array<NccPair>"),
    Binding::read("entries", "array<u32>"),
    Binding::read("surface", "array<SurfaceTexel>"),
    Binding::read("greys", "array<f32>"),
    Binding::read("rays", "array<f32>"),
    Binding::write("results", "array<NccResult>"),
];

/// The kernel's whole WGSL source (generated declarations, then `ncc.wgsl`).
pub fn ncc_kernel_source() -> String {
    gs_gpu::kernel_source(&[&declarations(), include_str!("ncc.wgsl")], &BINDINGS)
}

/// The frame uniform and the storage records: one list for the kernel's declarations and the
/// layout test.
fn generated_structs() -> [gs_gpu::GeneratedStruct; 4] {
    use gs_gpu::GeneratedStruct as G;
    [G::of::<NccFrame>(), G::of::<NccPair>(), G::of::<NccResult>(), G::of::<gs_gpu::SurfaceTexel>()]
}

fn declarations() -> String {
    gs_gpu::declarations(&generated_structs())
}

struct Buffers {
    pairs: BufId,
    entries: BufId,
    /// The reference's rendered plane uploaded from the host (one `SurfaceTexel` a pixel).
    surface: BufId,
    rays: BufId,
    results: BufId,
    /// υω of each entry.
    weights: BufId,
    /// Each source's first entry of each row (and one past its last).
    row_starts: BufId,
    /// The reduction's outputs: per (source, row), per source, per pixel.
    row_sums: BufId,
    scales: BufId,
    grads: BufId,
    /// The readback of the sums (pooled: a mappable buffer per call is costly to create).
    staging: BufId,
}

/// The device executor of L_p: its context, buffers and kernels.
pub struct PhotometricGpu {
    ctx: GpuContext,
    pool: BufferPool,
    disp: Dispatcher,
    kernel: Kernel,
    /// The reduction's passes ([`reduce::PASSES`]).
    sums: Vec<Kernel>,
    bufs: Buffers,
    /// The grey images, kept per view between calls when the caller keys them
    /// ([`PhotometricGpu::loss_of_views`]).
    greys: Arena,
}

/// How much device memory the arena of grey images holds (bytes), at most one storage binding.
const ARENA_BYTES: u64 = 512 << 20;

impl std::fmt::Debug for PhotometricGpu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "PhotometricGpu({})", self.ctx.description())
    }
}

fn gpu_error(e: gs_gpu::GpuError) -> MvsError {
    MvsError::Device(e.to_string())
}

/// One selected patch: its reference pixel (the entries are grouped by source, and the patch
/// kernel runs once per source's range, so the source is not stored).
type Entry = u32;

/// One source's host work before the kernel: υ/ω, the pair geometry and grey scale, the
/// selection (0 not a candidate, 1 not sampled, 2 evaluated) and its evaluated entries.
struct Prepared {
    vis: Visibility<f32>,
    g: PairGeometry<f32>,
    scale: usize,
    selected: Vec<u8>,
    picked: Vec<Entry>,
}

impl PhotometricGpu {
    /// The executor on `ctx`'s device (shared, e.g. with the rasterizer's), its kernel compiled.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let ctx = ctx.clone();
        let kernel = Kernel::new(&ctx, "ncc_patch", &[&declarations(), include_str!("ncc.wgsl")], &BINDINGS).map_err(gpu_error)?;
        let sum_decls = gs_gpu::declarations(&reduce::generated_structs());
        let sums = reduce::PASSES
            .iter()
            .map(|entry| Kernel::new(&ctx, entry, &[&sum_decls, include_str!("reduce.wgsl")], &reduce::BINDINGS))
            .collect::<std::result::Result<Vec<_>, _>>()
            .map_err(gpu_error)?;
        let mut pool = BufferPool::new(&ctx, ShrinkPolicy::default());
        let bufs = Buffers {
            pairs: pool.add_storage("ncc pairs"),
            entries: pool.add_storage("ncc entries"),
            surface: pool.add_storage("ncc surface"),
            rays: pool.add_storage("ncc rays"),
            results: pool.add_storage("ncc results"),
            weights: pool.add_storage("ncc weights"),
            row_starts: pool.add_storage("ncc row starts"),
            row_sums: pool.add_storage("ncc row sums"),
            scales: pool.add_storage("ncc scales"),
            grads: pool.add_storage("ncc gradient"),
            staging: pool.add_staging("ncc readback"),
        };
        let disp = Dispatcher::new(&ctx, std::mem::size_of::<NccFrame>() as u64);
        let greys = Arena::new(&ctx, "ncc greys", ARENA_BYTES);
        Ok(Self { ctx, pool, disp, kernel, sums, bufs, greys })
    }

    /// The adapter, in words.
    pub fn adapter_description(&self) -> String {
        self.ctx.description()
    }

    /// [`photometric_loss`] with the patches evaluated on the device: the same selection, υ/ω,
    /// statistics and gradient layout. Grey images too large for one storage binding of this
    /// device are evaluated on the host (the reference).
    pub fn loss(
        &mut self,
        reference: &PhotometricReference<'_, f32>,
        sources: &[PhotometricSource<'_, f32>],
        config: &PhotometricConfig,
    ) -> Result<PhotometricOutput<f32>> {
        let pending = self.start(reference, sources, None, config)?;
        self.finish(pending)
    }

    /// [`PhotometricGpu::loss`] with the grey images kept on the device between calls under
    /// `keys` (the reference's, then each source's), uploaded only on first use and when
    /// evicted: the caller names one grey image by one key (e.g. a training view's slot).
    pub fn loss_of_views(
        &mut self,
        reference: &PhotometricReference<'_, f32>,
        sources: &[PhotometricSource<'_, f32>],
        keys: &[u64],
        config: &PhotometricConfig,
    ) -> Result<PhotometricOutput<f32>> {
        let pending = self.start(reference, sources, Some(keys), config)?;
        self.finish(pending)
    }

    /// Submits [`PhotometricGpu::loss_of_views`] (`keys` `None`: nothing kept) and returns
    /// once the device has the work; [`PhotometricGpu::finish`] reads the result. Readbacks of
    /// several executors on one device started before the first finish cost the host one
    /// wait. Finish an evaluation before starting the next on this executor.
    pub fn start(
        &mut self,
        reference: &PhotometricReference<'_, f32>,
        sources: &[PhotometricSource<'_, f32>],
        keys: Option<&[u64]>,
        config: &PhotometricConfig,
    ) -> Result<PendingPhotometric> {
        self.start_keeping(RefView::of_host(reference), sources, keys, config, false)
    }

    /// [`PhotometricGpu::start`] of a reference whose rendered plane is on the device (the
    /// rasterizer's surface image) and whose gradient image stays there (a `DeviceImage` of
    /// gs-gpu `PlaneGrad`s, for the rasterizer's backward there): neither crosses to the host,
    /// only each (source, row)'s sums come back. [`PhotometricGpu::finish_on_device`] reads it.
    pub fn start_on_device(
        &mut self,
        reference: &SurfaceReference<'_>,
        sources: &[PhotometricSource<'_, f32>],
        keys: Option<&[u64]>,
        config: &PhotometricConfig,
    ) -> Result<PendingPhotometric> {
        let view = RefView::of_device(reference, &self.ctx)?;
        self.start_keeping(view, sources, keys, config, true)
    }

    /// An evaluation of `reference` started, the gradient image kept on the device when `keep`.
    fn start_keeping(
        &mut self,
        reference: RefView<'_>,
        sources: &[PhotometricSource<'_, f32>],
        keys: Option<&[u64]>,
        config: &PhotometricConfig,
        keep: bool,
    ) -> Result<PendingPhotometric> {
        if keys.is_some_and(|k| k.len() != sources.len() + 1) {
            return Err(MvsError::InvalidInput(format!("{} grey image keys for a reference and {} sources", keys.map_or(0, <[u64]>::len), sources.len())));
        }
        let host = |r| Ok(PendingPhotometric(Pending::Ready(r)));
        reference.check(sources, config)?;
        let grey_values = reference.grey.data.len() + sources.iter().map(|s| s.grey.data.len()).sum::<usize>();
        if 4 * grey_values as u64 > self.ctx.max_storage_binding() {
            return host(reference.host_loss(&self.ctx, sources, config)?);
        }
        let (w, h) = (reference.camera.width as usize, reference.camera.height as usize);
        // υ/ω, the pair geometry and the seeded selection of each source, sources in parallel
        // (each is the reference's own computation; the results keep the source order).
        let prepared = sources
            .par_iter()
            .enumerate()
            .map(|(k, source)| {
                let vis = visibility_unchecked(&PairGeometry::new(reference.camera, source.camera), &reference.plane_depth, &source.plane_depth);
                let (g, scale) = patch_geometry((reference.camera, &reference.grey), source)?;
                let selected = select_pixels(&vis, config, k, w, h);
                let picked: Vec<Entry> = selected.iter().enumerate().filter(|(_, s)| **s == 2).map(|(p, _)| p as Entry).collect();
                Ok(Prepared { vis, g, scale, selected, picked })
            })
            .collect::<Result<Vec<Prepared>>>()?;
        // The grey images in the arena (reference first), then the pairs and the selected
        // entries with their υω, source by source (row-major within each).
        let greys: Vec<&[f32]> = std::iter::once(reference.grey.data).chain(sources.iter().map(|s| s.grey.data)).collect();
        let items: Vec<_> = greys.iter().enumerate().map(|(i, g)| (keys.map(|k| (k[i], 0)), g.len())).collect();
        let Some(offsets) = self.greys.place(&self.ctx, &items, |i| Cow::Borrowed(greys[i])) else {
            return host(reference.host_loss(&self.ctx, sources, config)?);
        };
        let mut frame = NccFrame {
            width: w as u32,
            height: h as u32,
            sources: sources.len() as u32,
            pixels: (w * h) as u32,
            grey_width: reference.grey.width as u32,
            side: config.patch_size as u32,
            ref_offset: offsets[0],
            ..Default::default()
        };
        frame.mode = match config.ncc {
            NccMode::Pgsr => 0,
            NccMode::Plain => 1,
        };
        let mut rays = Vec::new();
        if let Some(first) = prepared.first() {
            let (xs, ys) = first.g.ref_ray_tables(reference.grey.width, reference.grey.height);
            rays = [xs, ys].concat();
            frame.grey_scale = first.scale as u32;
        }
        let mut pairs = Vec::with_capacity(sources.len());
        let picked = prepared.iter().map(|p| p.picked.len()).sum();
        let mut entries: Vec<Entry> = Vec::with_capacity(picked);
        let mut weights: Vec<f32> = Vec::with_capacity(picked);
        let mut ranges = Vec::with_capacity(sources.len());
        for ((p, source), &offset) in prepared.iter().zip(sources).zip(&offsets[1..]) {
            pairs.push(pair_record(&p.g, offset, source));
            ranges.push(entries.len()..entries.len() + p.picked.len());
            entries.extend_from_slice(&p.picked);
            weights.extend(p.picked.iter().map(|&e| p.vis.weight(e as usize)));
        }
        if std::mem::size_of::<NccResult>() as u64 * entries.len() as u64 > self.ctx.max_storage_binding() {
            return host(reference.host_loss(&self.ctx, sources, config)?);
        }
        // What the host counted of each source; the device adds the patches' sums.
        let counted: Vec<SourceStats> = prepared
            .iter()
            .map(|p| SourceStats {
                visibility: p.vis.stats(),
                n_candidates: p.selected.iter().filter(|&&s| s != 0).count(),
                n_sampled: p.picked.len(),
                ..Default::default()
            })
            .collect();
        let done = Done { counted, width: w, height: h };
        if entries.is_empty() {
            return host(done.output(&vec![reduce::NccRowSums::default(); sources.len() * h], &[]));
        }
        let inputs = Inputs { frame: &frame, pairs: &pairs, entries: &entries, weights: &weights, rays: &rays };
        let kept = match keep {
            true => Some(DeviceImage::new(&self.ctx, "L_p gradient", w, h, gs_gpu::PLANE_GRAD_CHANNELS).map_err(gpu_error)?),
            false => None,
        };
        let (read, row_bytes) = self.submit(&inputs, reference.plane, &ranges, &reduce::row_starts(&entries, &ranges, w, h), kept.as_ref())?;
        Ok(PendingPhotometric(Pending::Device { read, row_bytes, done, kept }))
    }

    /// The result of a started evaluation (waiting for the device if it has not answered).
    pub fn finish(&mut self, pending: PendingPhotometric) -> Result<PhotometricOutput<f32>> {
        let (read, row_bytes, done) = match pending.0 {
            Pending::Ready(out) => return Ok(out),
            Pending::Device { kept: Some(_), .. } => return Err(MvsError::InvalidInput("an evaluation whose gradient stays on the device, finished for the host".into())),
            Pending::Device { read, row_bytes, done, kept: None } => (read, row_bytes, done),
        };
        let (rows, grads): (Vec<reduce::NccRowSums>, Vec<reduce::PlaneGrad>) = self
            .ctx
            .finish_read(read, |m| {
                let (rows, grads) = m.split_at(row_bytes as usize);
                (bytemuck::pod_collect_to_vec(rows), bytemuck::pod_collect_to_vec(grads))
            })
            .map_err(gpu_error)?;
        Ok(done.output(&rows, &grads))
    }

    /// The result of an evaluation started by [`PhotometricGpu::start_on_device`]: the values
    /// (one wait, unless an earlier wait brought them) with the gradient image on the device,
    /// or the whole output on the host where the evaluation was made there (grey images too
    /// large for the device, or no patch to evaluate).
    pub fn finish_on_device(&mut self, pending: PendingPhotometric) -> Result<PhotometricOnDevice> {
        let (read, done, gradient) = match pending.0 {
            Pending::Ready(out) => return Ok(PhotometricOnDevice::Host(out)),
            Pending::Device { kept: None, .. } => return Err(MvsError::InvalidInput("an evaluation for the host, finished on the device".into())),
            Pending::Device { read, done, kept: Some(gradient), .. } => (read, done, gradient),
        };
        let rows: Vec<reduce::NccRowSums> = self.ctx.finish_read(read, bytemuck::pod_collect_to_vec).map_err(gpu_error)?;
        let (loss, per_source) = done.stats(&rows);
        Ok(PhotometricOnDevice::Device { loss, per_source, gradient })
    }

    /// Uploads the inputs, runs the patch kernel over every entry and the reduction, and
    /// requests the readback of each (source, row)'s sums and the gradient image (one round
    /// trip; the gradient copied into `kept` instead when given); returns it with the bytes of
    /// the sums.
    fn submit(
        &mut self,
        inputs: &Inputs<'_>,
        plane: Plane<'_>,
        ranges: &[std::ops::Range<usize>],
        row_starts: &[u32],
        kept: Option<&DeviceImage>,
    ) -> Result<(PendingRead, u64)> {
        let (b, frame) = (&self.bufs, inputs.frame);
        let result_bytes = std::mem::size_of::<NccResult>() as u64;
        let row_bytes = gs_gpu::bytes_of::<reduce::NccRowSums>((frame.sources * frame.height) as usize);
        let grad_bytes = gs_gpu::bytes_of::<reduce::PlaneGrad>(frame.pixels as usize);
        let grad_back = if kept.is_some() { 0 } else { grad_bytes };
        self.pool.begin_frame();
        // The reference's plane goes up only when it is on the host.
        let texels = match plane {
            Plane::Host { normal, distance } => reference::plane_texels(&normal, &distance),
            Plane::Device(_) => Vec::new(),
        };
        let uploads: [(BufId, &[u8]); 6] = [
            (b.pairs, bytemuck::cast_slice(inputs.pairs)),
            (b.entries, bytemuck::cast_slice(inputs.entries)),
            (b.surface, bytemuck::cast_slice(&texels)),
            (b.rays, bytemuck::cast_slice(inputs.rays)),
            (b.weights, bytemuck::cast_slice(inputs.weights)),
            (b.row_starts, bytemuck::cast_slice(row_starts)),
        ];
        for (id, bytes) in uploads {
            self.pool.ensure(id, bytes.len() as u64);
            self.ctx.write_buffer(self.pool.buffer(id), 0, bytes);
        }
        let outputs = [
            (b.results, result_bytes * inputs.entries.len() as u64),
            (b.row_sums, row_bytes),
            (b.scales, gs_gpu::bytes_of::<f32>(frame.sources as usize)),
            (b.grads, grad_bytes),
            (b.staging, row_bytes + grad_back),
        ];
        for (id, bytes) in outputs {
            self.pool.ensure(id, bytes);
        }
        self.disp.write_frame(frame);
        let p = &self.pool;
        let [pairs, entries, mut surface, rays, results] = [b.pairs, b.entries, b.surface, b.rays, b.results].map(|id| p.whole(id));
        if let Plane::Device(image) = plane {
            surface = gs_gpu::Bind::whole(image.buffer());
        }
        let patch_binds = [pairs, entries, surface, self.greys.bind(), rays, results];
        let sum_binds = [b.entries, b.results, b.weights, b.row_starts, b.row_sums, b.scales, b.grads].map(|id| p.whole(id));
        let mut enc = self.disp.encoder();
        self.ctx.push_error_scopes();
        let threads = [frame.sources * frame.height, frame.sources, frame.pixels];
        let pass = |n: u32| PassUniform { n, ..Default::default() };
        // One dispatch per source over its entries: `base` its first entry, `p1` its pair.
        for (k, range) in ranges.iter().enumerate() {
            self.disp.make_room(&mut enc, 1);
            let per_source = PassUniform { n: range.len() as u32, base: range.start as u32, p1: k as u32, ..Default::default() };
            self.disp.dispatch_1d(&mut enc, &self.kernel, &patch_binds, per_source).map_err(gpu_error)?;
        }
        self.disp.make_room(&mut enc, self.sums.len());
        for (kernel, n) in self.sums.iter().zip(threads) {
            self.disp.dispatch_1d(&mut enc, kernel, &sum_binds, pass(n)).map_err(gpu_error)?;
        }
        let staging = p.buffer(b.staging);
        enc.encoder.copy_buffer_to_buffer(p.buffer(b.row_sums), 0, staging, 0, row_bytes);
        match kept {
            Some(image) => enc.encoder.copy_buffer_to_buffer(p.buffer(b.grads), 0, image.buffer(), 0, grad_bytes),
            None => enc.encoder.copy_buffer_to_buffer(p.buffer(b.grads), 0, staging, row_bytes, grad_bytes),
        }
        self.disp.submit(enc);
        self.ctx.pop_error_scopes().map_err(gpu_error)?;
        Ok((self.ctx.request_read(staging, row_bytes + grad_back), row_bytes))
    }
}

/// L_p started by [`PhotometricGpu::start`]: on the device, or already made (on the host, or
/// without a patch to evaluate).
pub struct PendingPhotometric(Pending);

/// What [`PhotometricGpu::finish_on_device`] gives: L_p made on the host (its gradient there),
/// or its values with the gradient image on the device.
pub enum PhotometricOnDevice {
    /// Made on the host (grey images too large for the device, or no patch to evaluate).
    Host(PhotometricOutput<f32>),
    /// Made on the device.
    Device {
        /// L_p, summed over sources.
        loss: f64,
        /// Each source's statistics.
        per_source: Vec<SourceStats>,
        /// ∂L_p/∂(Ñ, D) of each reference pixel: `[H][W]` gs-gpu `PlaneGrad`s (4 channels).
        gradient: DeviceImage,
    },
}

enum Pending {
    /// `kept`: the gradient image, when it stays on the device.
    Device { read: PendingRead, row_bytes: u64, done: Done, kept: Option<DeviceImage> },
    Ready(PhotometricOutput<f32>),
}

/// What the output needs besides the device's sums: the host's counts per source and the size.
struct Done {
    counted: Vec<SourceStats>,
    width: usize,
    height: usize,
}

impl Done {
    /// The output from each (source, row)'s sums and the gradient image.
    fn output(self, rows: &[reduce::NccRowSums], grads: &[reduce::PlaneGrad]) -> PhotometricOutput<f32> {
        let (w, h) = (self.width, self.height);
        let (loss, per_source) = self.stats(rows);
        let mut out = PhotometricOutput { loss, per_source, grad_normal: vec![0.0; w * h * 3], grad_distance: vec![0.0; w * h], width: w, height: h };
        reduce::unpack_gradient(&mut out, grads);
        out
    }

    /// L_p and each source's statistics from each (source, row)'s sums.
    fn stats(self, rows: &[reduce::NccRowSums]) -> (f64, Vec<SourceStats>) {
        let per_source: Vec<SourceStats> = self.counted.into_iter().zip(rows.chunks_exact(self.height.max(1))).map(|(counted, rows)| reduce::source_stats(counted, rows)).collect();
        (per_source.iter().fold(0.0, |sum, s| sum + s.loss), per_source)
    }
}

/// The host-built inputs of one evaluation.
struct Inputs<'a> {
    frame: &'a NccFrame,
    pairs: &'a [NccPair],
    entries: &'a [Entry],
    weights: &'a [f32],
    rays: &'a [f32],
}

/// The pair record of `g` with the source grey image at `offset` in `greys` (the arena).
fn pair_record(g: &PairGeometry<f32>, offset: u32, source: &PhotometricSource<'_, f32>) -> NccPair {
    let row = |r: usize| [g.a[3 * r], g.a[3 * r + 1], g.a[3 * r + 2], 0.0];
    NccPair {
        a0: row(0),
        a1: row(1),
        a2: row(2),
        kt: [g.kt[0], g.kt[1], g.kt[2], 0.0],
        src_w: g.src_w,
        src_h: g.src_h,
        grey_offset: offset,
        grey_width: source.grey.width as u32,
        grey_height: source.grey.height as u32,
        ..Default::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_match_their_wgsl_layout() {
        let src = ncc_kernel_source();
        gs_gpu::check_layouts(&generated_structs(), &src).unwrap();
        gs_gpu::validate_kernel(&src).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(gs_gpu::bytes_of::<gs_gpu::SurfaceTexel>(1), 24);
    }
}
