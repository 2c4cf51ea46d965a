//! L_f on the device (behind the `wgpu` feature), the twin of
//! [`crate::feature_alignment::feature_loss`] for gs-features' VGG maps: one WGSL kernel
//! (`align.wgsl`) evaluates every (reference pixel, source) pair — the term υω·|1 − cos| and
//! its derivative with respect to the reference plane depth — while υ/ω and the sums stay on
//! the host and use the reference's own code, summed in its order: one input gives one result
//! on one device (docs/method.md §L_f, docs/architecture.md §GPU).
//!
//! The feature maps live on the device between calls, in an arena of equal slots keyed by the
//! caller (a training view's slot), so a view's maps are uploaded once, not every iteration.
//! When the maps of one call do not fit one storage binding of the device, the host evaluates
//! the call (the reference).

use crate::error::{MvsError, Result};
use crate::feature_alignment::{
    AlignView, COS_EPS, FeatureOutput, FeatureSource, add_source, check_inputs, feature_loss_with_weights,
};
use crate::geometry::PairGeometry;
use crate::visibility::{Visibility, visibility_unchecked};
use gs_features::FeatureMap;
use gs_gpu::{Arena, Binding, BufId, BufferPool, Dispatcher, GpuContext, Kernel, PassUniform, ShrinkPolicy};
use std::borrow::Cow;
use rayon::prelude::*;

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

const STATUS_NOT_IN_V: u32 = 0;
const STATUS_TERM: u32 = 2;

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

/// The kernel's whole WGSL source (generated declarations, then `align.wgsl`).
pub fn align_kernel_source() -> String {
    gs_gpu::kernel_source(&[&declarations(), include_str!("align.wgsl")], &BINDINGS)
}

fn gpu_error(e: gs_gpu::GpuError) -> MvsError {
    MvsError::Device(e.to_string())
}

struct Buffers {
    pairs: BufId,
    weights: BufId,
    depth: BufId,
    results: BufId,
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
        let kernel = Kernel::new(&ctx, "align_pair", &[&declarations(), include_str!("align.wgsl")], &BINDINGS).map_err(gpu_error)?;
        let mut pool = BufferPool::new(&ctx, ShrinkPolicy::default());
        let bufs = Buffers {
            pairs: pool.add_storage("align pairs"),
            weights: pool.add_storage("align weights"),
            depth: pool.add_storage("align depth"),
            results: pool.add_storage("align results"),
            staging: pool.add_staging("align readback"),
        };
        let disp = Dispatcher::new(&ctx, std::mem::size_of::<AlignFrame>() as u64);
        let arena = Arena::new(&ctx, "feature arena", arena_bytes);
        Ok(Self { ctx, pool, disp, kernel, bufs, arena })
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
        let maps: Vec<(u64, &FeatureMap)> = std::iter::once(reference).chain(sources).map(|v| (v.key, v.features)).collect();
        let items: Vec<_> = maps.iter().map(|(key, m)| (Some((*key, 0)), m.width() * m.height() * m.channels())).collect();
        let Some(offsets) = self.arena.place(&self.ctx, &items, |i| Cow::Owned(maps[i].1.to_f32_vec())) else {
            return feature_loss_with_weights(&host_ref, &host_sources, &weights);
        };
        let (w, h) = (reference.camera.width as usize, reference.camera.height as usize);
        let c = reference.features.channels();
        let cam = &reference.camera.intrinsics;
        let frame = AlignFrame {
            width: w as u32,
            height: h as u32,
            channels: c as u32,
            ref_offset: offsets[0],
            ref_w: reference.features.width() as u32,
            ref_h: reference.features.height() as u32,
            r_fx: cam.fx as f32,
            r_fy: cam.fy as f32,
            r_cx: cam.cx as f32,
            r_cy: cam.cy as f32,
            ref_inv_stride: 1.0 / reference.features.stride(),
            eps: COS_EPS as f32,
        };
        let pairs: Vec<AlignPair> = sources.iter().zip(&geometry).zip(&offsets[1..]).map(|((s, g), &o)| pair_record(g, s, o)).collect();
        let mut flat = Vec::with_capacity(sources.len() * w * h);
        for vis in &weights {
            flat.extend((0..w * h).map(|p| vis.weight(p)));
        }
        let results = self.evaluate(&frame, &pairs, &flat, reference.plane_depth.data)?;
        let mut out = FeatureOutput { loss: 0.0, per_source: Vec::with_capacity(sources.len()), grad_plane_depth: vec![0.0; w * h], width: w, height: h };
        for (k, vis) in weights.iter().enumerate() {
            add_results(&mut out, &results[k * w * h..(k + 1) * w * h], vis, w, sources.len());
        }
        Ok(out)
    }

    /// Uploads the pairs, weights and depth, runs the kernel over every (source, pixel) pair
    /// in chunks that fit one storage binding, and reads the results back.
    fn evaluate(&mut self, frame: &AlignFrame, pairs: &[AlignPair], weights: &[f32], depth: &[f32]) -> Result<Vec<AlignResult>> {
        if weights.is_empty() {
            return Ok(Vec::new());
        }
        let b = &self.bufs;
        let result_bytes = std::mem::size_of::<AlignResult>() as u64;
        let chunk = (self.ctx.max_storage_binding() / result_bytes).min(1 << 22) as usize;
        self.pool.begin_frame();
        let uploads: [(BufId, &[u8]); 3] =
            [(b.pairs, bytemuck::cast_slice(pairs)), (b.weights, bytemuck::cast_slice(weights)), (b.depth, bytemuck::cast_slice(depth))];
        for (id, bytes) in uploads {
            self.pool.ensure(id, bytes.len() as u64);
            self.ctx.write_buffer(self.pool.buffer(id), 0, bytes);
        }
        let n = weights.len();
        self.pool.ensure(b.results, result_bytes * chunk.min(n) as u64);
        self.pool.ensure(b.staging, result_bytes * chunk.min(n) as u64);
        self.disp.write_frame(frame);
        let mut results = Vec::with_capacity(n);
        for base in (0..n).step_by(chunk) {
            let m = chunk.min(n - base);
            let p = &self.pool;
            let binds = [p.whole(b.pairs), p.whole(b.weights), p.whole(b.depth), self.arena.bind(), p.whole(b.results)];
            let mut enc = self.disp.encoder();
            let pass = PassUniform { n: m as u32, base: base as u32, ..Default::default() };
            self.ctx.push_error_scopes();
            self.disp.dispatch_1d(&mut enc, &self.kernel, &binds, pass).map_err(gpu_error)?;
            let bytes = result_bytes * m as u64;
            enc.encoder.copy_buffer_to_buffer(p.buffer(b.results), 0, p.buffer(b.staging), 0, bytes);
            self.disp.submit(enc);
            self.ctx.pop_error_scopes().map_err(gpu_error)?;
            self.ctx
                .read_mapped(p.buffer(b.staging), bytes, |r| results.extend_from_slice(bytemuck::cast_slice::<u8, AlignResult>(r)))
                .map_err(gpu_error)?;
        }
        Ok(results)
    }
}

/// The pair record of `source` with the pair geometry `g`, its map at `offset` in the arena.
fn pair_record(g: &PairGeometry<f32>, source: &AlignView<'_>, offset: u32) -> AlignPair {
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
        map_w: source.features.width() as u32,
        map_h: source.features.height() as u32,
        inv_stride: 1.0 / source.features.stride(),
    }
}

/// Adds one source's pair results to `out` as the host reference does
/// ([`crate::feature_alignment`]'s `add_source`, on the same row sums and gradient).
fn add_results(out: &mut FeatureOutput<f32>, results: &[AlignResult], vis: &Visibility<f32>, w: usize, n_src: usize) {
    let rows = results.chunks(w).map(|row| {
        let (mut valid, mut wsum, mut csum) = (0usize, 0.0f64, 0.0f64);
        for r in row.iter().filter(|r| r.status != STATUS_NOT_IN_V) {
            valid += 1;
            if r.status == STATUS_TERM {
                wsum += r.term as f64;
                csum += r.cos as f64;
            }
        }
        (valid, wsum, csum)
    });
    let grad: Vec<f32> = results.par_iter().map(|r| if r.status == STATUS_TERM { r.grad } else { 0.0 }).collect();
    add_source(out, vis, rows, &grad, n_src);
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
    }
}
