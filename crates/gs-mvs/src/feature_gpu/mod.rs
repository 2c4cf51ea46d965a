//! L_f on the device (behind the `wgpu` feature), the twin of
//! [`crate::feature_alignment::feature_loss`] for gs-features' VGG maps: one WGSL kernel
//! (`align.wgsl`) evaluates every (reference pixel, source) pair — the term υω·|1 − cos| and
//! its derivative with respect to the reference plane depth — and the reduction
//! (`reduce.wgsl`, [`reduce`]) sums each source's rows and adds its share of the gradient
//! image, sources in order, then (`totals.wgsl`) adds each source's rows, so that one record a
//! source and one value a pixel come back. [`FeatureGpu::loss`] takes υ/ω from the host's own code; [`FeatureGpu::start_on_device`]
//! reads those L_p made on the device for the same views in the same step, and the rendered
//! surface's plane depth, and keeps the gradient image there ([`on_device`]). One input gives
//! one result on one device (docs/method.md §L_f, docs/architecture.md §GPU).
//!
//! The feature maps live on the device between calls, in an arena of equal slots keyed by the
//! caller (a training view's slot), so a view's maps are uploaded once, not every iteration.
//! When the maps of one call do not fit one storage binding of the device, the host evaluates
//! the call (the reference).

use crate::error::{MvsError, Result};
use crate::feature_alignment::{
    AlignView, COS_EPS, FeatureOutput, FeatureSource, add_source_sums, check_inputs, feature_loss_with_weights,
};
use crate::geometry::PairGeometry;
use crate::visibility::{Visibility, visibility_unchecked};
use gs_features::FeatureMap;
use gs_gpu::{Arena, Binding, BufId, BufferPool, Dispatcher, GpuContext, Kernel, PassUniform, ShrinkPolicy, bytes_of};
use reduce::{AlignRowSums, AlignTotals};
use std::borrow::Cow;
use rayon::prelude::*;

pub mod on_device;
pub mod reduce;

gs_gpu::wgsl_struct! {
    /// Constants of one L_f evaluation (binding 0 of the kernel; WGSL `struct AlignFrame`): the
    /// reference's size, intrinsics and feature map (its arena offset, size and 1 / stride).
    pub(crate) struct AlignFrame as "AlignFrame" {
        width: u32,
        height: u32,
        channels: u32,
        ref_offset: u32,
        ref_w: u32,
        ref_h: u32,
        r_fx: f32,
        r_fy: f32,
        r_cx: f32,
        r_cy: f32,
        ref_inv_stride: f32,
        /// The cosine's norm floor ([`COS_EPS`]).
        eps: f32,
        /// Sources of the call (N).
        sources: u32,
        /// The weight of the gradient's apply pass (λ4; [`on_device`]).
        weight: f32,
    }
}

gs_gpu::wgsl_struct! {
    /// One reference/source pair (WGSL `struct AlignPair`): the rows of R_rs, t_rs, the
    /// source's intrinsics and its feature map in the arena.
    pub(crate) struct AlignPair as "AlignPair" {
        r0: [f32; 4],
        r1: [f32; 4],
        r2: [f32; 4],
        t: [f32; 4],
        s_fx: f32,
        s_fy: f32,
        s_cx: f32,
        s_cy: f32,
        map_offset: u32,
        map_w: u32,
        map_h: u32,
        inv_stride: f32,
    }
}

gs_gpu::wgsl_struct! {
    /// One pair's outcome (WGSL `struct AlignResult`): status 0 not in V (υω = 0), 1 in V
    /// without a term (behind the source camera, or not finite), 2 a term.
    pub(crate) struct AlignResult as "AlignResult" {
        /// υω·|1 − cos|.
        term: f32,
        cos: f32,
        /// υω·∂|1 − cos|/∂z_r.
        grad: f32,
        status: u32,
    }
}

/// The kernel's storage bindings, by name (slot order).
const BINDINGS: [Binding<'static>; 5] = [
    Binding::read("pairs", "array<AlignPair>"),
    Binding::read("weights", "array<f32>"),
    Binding::read("depth", "array<f32>"),
    Binding::read("maps", "array<f32>"),
    Binding::write("results", "array<AlignResult>"),
];

fn generated_structs() -> [gs_gpu::GeneratedStruct; 3] {
    use gs_gpu::GeneratedStruct as G;
    [G::of::<AlignFrame>(), G::of::<AlignPair>(), G::of::<AlignResult>()]
}

fn declarations() -> String {
    gs_gpu::declarations(&generated_structs())
}

/// How the host kernel reads its inputs: υω and z_r as f32 arrays.
const HOST_ACCESS: &str = "fn pair_weight(e: u32) -> f32 { return weights[e]; }\nfn ref_depth(p: u32) -> f32 { return depth[p]; }\n";

/// The host kernel's whole WGSL source (generated declarations, its accessors, then
/// `align.wgsl`).
pub fn align_kernel_source() -> String {
    gs_gpu::kernel_source(&[&declarations(), HOST_ACCESS, include_str!("align.wgsl")], &BINDINGS)
}

fn gpu_error(e: gs_gpu::GpuError) -> MvsError {
    MvsError::Device(e.to_string())
}

struct Buffers {
    pairs: BufId,
    weights: BufId,
    depth: BufId,
    /// One source's pair results at a time.
    results: BufId,
    row_sums: BufId,
    /// Each source's totals (read back).
    totals: BufId,
    scales: BufId,
    grads: BufId,
    staging: BufId,
}

/// How much device memory the feature arena holds by default (bytes), at most one storage binding.
const ARENA_BYTES: u64 = 1 << 30;

/// The device executor of L_f: its context, buffers, kernel and feature arena.
pub struct FeatureGpu {
    ctx: GpuContext,
    pool: BufferPool,
    disp: Dispatcher,
    kernel: Kernel,
    /// The reduction's passes ([`reduce::PASSES`]).
    sums: Vec<Kernel>,
    /// Each source's totals of its rows (totals.wgsl).
    totals: Kernel,
    /// The pair kernel on L_p's visibility and the surface, and the gradient's apply pass.
    device: on_device::Kernels,
    bufs: Buffers,
    arena: Arena,
}

impl std::fmt::Debug for FeatureGpu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "FeatureGpu({})", self.ctx.description())
    }
}

impl FeatureGpu {
    /// The executor on `ctx`'s device (shared, e.g. with the rasterizer's), its kernel
    /// compiled, keeping up to 1 GiB of feature maps on the device.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        Self::with_arena_bytes(ctx, ARENA_BYTES)
    }

    /// [`FeatureGpu::new`] keeping up to `arena_bytes` of feature maps on the device (at least
    /// the maps of one call; a call whose maps do not fit is evaluated on the host).
    pub fn with_arena_bytes(ctx: &GpuContext, arena_bytes: u64) -> Result<Self> {
        let ctx = ctx.clone();
        let kernel = Kernel::new(&ctx, "align_pair", &[&declarations(), HOST_ACCESS, include_str!("align.wgsl")], &BINDINGS).map_err(gpu_error)?;
        let device = on_device::Kernels::new(&ctx)?;
        let sum_decls = gs_gpu::declarations(&reduce::generated_structs());
        let sums = reduce::PASSES
            .iter()
            .map(|entry| Kernel::new(&ctx, entry, &[&sum_decls, include_str!("reduce.wgsl")], &reduce::BINDINGS))
            .collect::<gs_gpu::Result<Vec<_>>>()
            .map_err(gpu_error)?;
        let totals = Kernel::new(&ctx, "align_totals", &[&sum_decls, include_str!("totals.wgsl")], &reduce::TOTALS_BINDINGS).map_err(gpu_error)?;
        let mut pool = BufferPool::new(&ctx, ShrinkPolicy::default());
        let bufs = Buffers {
            pairs: pool.add_storage("align pairs"),
            weights: pool.add_storage("align weights"),
            depth: pool.add_storage("align depth"),
            results: pool.add_storage("align results"),
            row_sums: pool.add_storage("align row sums"),
            totals: pool.add_storage("align totals"),
            scales: pool.add_storage("align scales"),
            grads: pool.add_storage("align gradient"),
            staging: pool.add_staging("align readback"),
        };
        let disp = Dispatcher::new(&ctx, std::mem::size_of::<AlignFrame>() as u64);
        let arena = Arena::new(&ctx, "feature arena", arena_bytes);
        Ok(Self { ctx, pool, disp, kernel, sums, totals, device, bufs, arena })
    }

    /// The adapter, in words.
    pub fn adapter_description(&self) -> String {
        self.ctx.description()
    }

    /// [`crate::feature_alignment::feature_loss`] with the pairs evaluated on the device: the
    /// same υ/ω, statistics and gradient layout.
    pub fn loss(&mut self, reference: &AlignView<'_>, sources: &[AlignView<'_>]) -> Result<FeatureOutput<f32>> {
        let host_ref = reference.as_reference();
        let host_sources: Vec<FeatureSource<'_, f32>> = sources.iter().map(AlignView::as_source).collect();
        check_inputs(&host_ref, &host_sources)?;
        let geometry: Vec<PairGeometry<f32>> = sources.iter().map(|s| PairGeometry::new(reference.camera, s.camera)).collect();
        let weights: Vec<Visibility<f32>> = sources
            .par_iter()
            .zip(&geometry)
            .map(|(s, g)| visibility_unchecked(g, &reference.plane_depth, &s.plane_depth))
            .collect();
        let (w, h) = (reference.camera.width as usize, reference.camera.height as usize);
        // One source's results and all the weights each in one storage binding, or the host.
        let max = self.ctx.max_storage_binding();
        if sources.is_empty() || bytes_of::<AlignResult>(w * h) > max || bytes_of::<f32>(sources.len() * w * h) > max {
            return feature_loss_with_weights(&host_ref, &host_sources, &weights);
        }
        let maps: Vec<(u64, &FeatureMap)> = std::iter::once(reference).chain(sources).map(|v| (v.key, v.features)).collect();
        let Some(offsets) = self.place_maps(&maps) else {
            return feature_loss_with_weights(&host_ref, &host_sources, &weights);
        };
        let frame = align_frame(reference.camera, reference.features, offsets[0], sources.len());
        let pairs: Vec<AlignPair> = sources.iter().zip(&geometry).zip(&offsets[1..]).map(|((s, g), &o)| pair_record(g, s.features, o)).collect();
        let mut flat = Vec::with_capacity(sources.len() * w * h);
        for vis in &weights {
            flat.extend((0..w * h).map(|p| vis.weight(p)));
        }
        let (totals, grad) = self.evaluate(&frame, &pairs, &flat, reference.plane_depth.data)?;
        let mut out = FeatureOutput { loss: 0.0, per_source: Vec::with_capacity(sources.len()), grad_plane_depth: grad, width: w, height: h };
        for (vis, t) in weights.iter().zip(&totals) {
            add_source_sums((&mut out.loss, &mut out.per_source), vis.stats(), [t.sums()], sources.len());
        }
        Ok(out)
    }

    /// Uploads the pairs, weights and depth; for each source in order, runs the pair kernel
    /// and the reduction's passes (its rows, its scale, its share of the gradient), then each
    /// source's totals, all in one submission; reads back the totals and the gradient image.
    fn evaluate(&mut self, frame: &AlignFrame, pairs: &[AlignPair], weights: &[f32], depth: &[f32]) -> Result<(Vec<AlignTotals>, Vec<f32>)> {
        let total_bytes = self.begin(frame, pairs);
        let (b, npix) = (&self.bufs, (frame.width * frame.height) as u64);
        for (id, bytes) in [(b.weights, bytemuck::cast_slice(weights)), (b.depth, bytemuck::cast_slice(depth))] {
            self.pool.ensure(id, bytes.len() as u64);
            self.ctx.write_buffer(self.pool.buffer(id), 0, bytes);
        }
        let grad_bytes = bytes_of::<f32>(npix as usize);
        self.pool.ensure(b.grads, grad_bytes);
        self.pool.ensure(b.staging, total_bytes + grad_bytes);
        let p = &self.pool;
        let mut enc = self.disp.encoder();
        enc.encoder.clear_buffer(p.buffer(b.grads), 0, Some(grad_bytes));
        self.ctx.push_error_scopes();
        let binds = [p.whole(b.pairs), p.whole(b.weights), p.whole(b.depth), self.arena.bind(), p.whole(b.results)];
        let recorded = self.encode_sources(&mut enc, frame, &self.kernel, &binds, p.whole(b.grads)).and_then(|_| self.encode_totals(&mut enc, frame, None));
        let staging = p.buffer(b.staging);
        enc.encoder.copy_buffer_to_buffer(p.buffer(b.totals), 0, staging, 0, total_bytes);
        enc.encoder.copy_buffer_to_buffer(p.buffer(b.grads), 0, staging, total_bytes, grad_bytes);
        self.disp.submit(enc);
        self.ctx.pop_error_scopes().map_err(gpu_error)?;
        recorded.map_err(gpu_error)?;
        self.ctx
            .read_mapped(staging, total_bytes + grad_bytes, |r| {
                let (totals, grad) = r.split_at(total_bytes as usize);
                (bytemuck::pod_collect_to_vec(totals), bytemuck::pod_collect_to_vec(grad))
            })
            .map_err(gpu_error)
    }

    /// Starts an evaluation of `frame`: its pairs uploaded, its frame written, and the pair
    /// results, row sums, totals and scales sized; returns the totals' bytes.
    fn begin(&mut self, frame: &AlignFrame, pairs: &[AlignPair]) -> u64 {
        let b = &self.bufs;
        self.pool.begin_frame();
        self.pool.ensure(b.pairs, bytes_of::<AlignPair>(pairs.len()));
        self.ctx.write_buffer(self.pool.buffer(b.pairs), 0, bytemuck::cast_slice(pairs));
        let total_bytes = bytes_of::<AlignTotals>(frame.sources as usize);
        self.pool.ensure(b.results, bytes_of::<AlignResult>((frame.width * frame.height) as usize));
        self.pool.ensure(b.row_sums, bytes_of::<AlignRowSums>((frame.sources * frame.height) as usize));
        self.pool.ensure(b.totals, total_bytes);
        self.pool.ensure(b.scales, bytes_of::<f32>(frame.sources as usize));
        self.disp.write_frame(frame);
        total_bytes
    }

    /// The arena offsets of `maps` (each under its key), uploading those it does not hold;
    /// `None` when they do not fit it together.
    fn place_maps(&mut self, maps: &[(u64, &FeatureMap)]) -> Option<Vec<u32>> {
        let items: Vec<_> = maps.iter().map(|(key, m)| (Some((*key, 0)), m.width() * m.height() * m.channels())).collect();
        self.arena.place(&self.ctx, &items, |i| Cow::Owned(maps[i].1.to_f32_vec()))
    }

    /// Records each source's totals of its rows (and, given the visibility's rows `vis_rows`,
    /// of their counts).
    fn encode_totals(&self, enc: &mut gs_gpu::Encoder, frame: &AlignFrame, vis_rows: Option<gs_gpu::Bind<'_>>) -> gs_gpu::Result<()> {
        let (p, b) = (&self.pool, &self.bufs);
        // Without visibility rows the kernel reads none; the row sums stand in for the binding.
        let binds = [p.whole(b.row_sums), vis_rows.unwrap_or(p.whole(b.row_sums)), p.whole(b.totals)];
        self.disp.make_room(enc, 1);
        self.disp.dispatch_1d(enc, &self.totals, &binds, PassUniform { n: frame.sources, p1: vis_rows.is_some() as u32, ..Default::default() })
    }

    /// Records, for each source in order, the pair kernel `kernel` on `binds` (its pair results
    /// into the pool's `results`) and the reduction's passes, which add the source's share of
    /// the gradient into `grads`.
    fn encode_sources(&self, enc: &mut gs_gpu::Encoder, frame: &AlignFrame, kernel: &Kernel, binds: &[gs_gpu::Bind<'_>], grads: gs_gpu::Bind<'_>) -> gs_gpu::Result<()> {
        let (p, b, npix) = (&self.pool, &self.bufs, frame.width * frame.height);
        let sum_binds = [p.whole(b.results), p.whole(b.row_sums), p.whole(b.scales), grads];
        for k in 0..frame.sources {
            self.disp.make_room(enc, 4);
            self.disp.dispatch_1d(enc, kernel, binds, PassUniform { n: npix, base: k * npix, ..Default::default() })?;
            for (pass, n) in self.sums.iter().zip([frame.height, 1, npix]) {
                self.disp.dispatch_1d(enc, pass, &sum_binds, PassUniform { n, p1: k, ..Default::default() })?;
            }
        }
        Ok(())
    }
}

/// The frame of an evaluation of `sources` sources against the reference `camera` whose
/// `features` lie at `ref_offset` in the arena.
fn align_frame(camera: &gs_core::Camera, features: &FeatureMap, ref_offset: u32, sources: usize) -> AlignFrame {
    let cam = &camera.intrinsics;
    AlignFrame {
        width: camera.width,
        height: camera.height,
        channels: features.channels() as u32,
        ref_offset,
        ref_w: features.width() as u32,
        ref_h: features.height() as u32,
        r_fx: cam.fx as f32,
        r_fy: cam.fy as f32,
        r_cx: cam.cx as f32,
        r_cy: cam.cy as f32,
        ref_inv_stride: 1.0 / features.stride(),
        eps: COS_EPS as f32,
        sources: sources as u32,
        weight: 0.0,
    }
}

/// The pair record of `source` with the pair geometry `g`, its map at `offset` in the arena.
fn pair_record(g: &PairGeometry<f32>, features: &FeatureMap, offset: u32) -> AlignPair {
    let [r0, r1, r2] = crate::geometry::padded_rows(&g.rot);
    AlignPair {
        r0,
        r1,
        r2,
        t: crate::geometry::padded(&g.t),
        s_fx: g.s_fx,
        s_fy: g.s_fy,
        s_cx: g.s_cx,
        s_cy: g.s_cy,
        map_offset: offset,
        map_w: features.width() as u32,
        map_h: features.height() as u32,
        inv_stride: 1.0 / features.stride(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_match_their_wgsl_layout() {
        let src = align_kernel_source();
        gs_gpu::check_layouts(&generated_structs(), &src).unwrap();
        gs_gpu::validate_kernel(&src).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(gs_gpu::bytes_of::<AlignResult>(1), 16);
        for sums in [reduce::reduce_kernel_source(), reduce::totals_kernel_source()] {
            gs_gpu::check_layouts(&reduce::generated_structs(), &sums).unwrap();
            gs_gpu::validate_kernel(&sums).unwrap_or_else(|e| panic!("{e}"));
        }
        assert_eq!([gs_gpu::bytes_of::<AlignRowSums>(1), gs_gpu::bytes_of::<AlignTotals>(1)], [16, 40]);
        for src in [on_device::device_kernel_source(), on_device::apply_kernel_source()] {
            gs_gpu::validate_kernel(&src).unwrap_or_else(|e| panic!("{e}"));
        }
        gs_gpu::check_layouts(&[gs_gpu::GeneratedStruct::of::<AlignFrame>()], &on_device::device_kernel_source()).unwrap();
    }
}
