//! L_p on the device (behind the `wgpu` feature), the twin of [`crate::photometric`]: one WGSL
//! kernel (`ncc.wgsl`) evaluates every selected (pixel, source) patch — its NCC cost and the
//! gradient with respect to the rendered plane (Ñ, D) — while υ/ω, the seeded pixel selection
//! and the sums stay on the host and use the reference's own code. So the two executors differ
//! only in the patch arithmetic (f32 on both; the tolerances are in `tests/photometric_gpu.rs`),
//! and the host sums the device's per-patch results in a fixed order: one seed gives one result
//! on one device (docs/method.md §L_p, docs/architecture.md §GPU).

use crate::error::{MvsError, Result};
use crate::photometric::{
    NccMode, PhotometricConfig, PhotometricOutput, PhotometricReference, PhotometricSource, SourceStats, check_inputs,
    patch_geometry, photometric_loss, select_pixels,
};
use crate::visibility::{Visibility, visibility_unchecked};
use crate::geometry::PairGeometry;
use rayon::prelude::*;
use gs_gpu::{Binding, BufId, BufferPool, Dispatcher, GpuContext, Kernel, PassUniform, ShrinkPolicy};

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

const STATUS_MASKED: u32 = 1;
const STATUS_VALID: u32 = 2;

/// The kernel's storage bindings, by name (slot order).
const BINDINGS: [Binding<'static>; 7] = [
    Binding::read("pairs", "array<NccPair>"),
    Binding::read("entries", "array<vec2<u32>>"),
    Binding::read("normal", "array<PixelNormal>"),
    Binding::read("distance", "array<f32>"),
    Binding::read("greys", "array<f32>"),
    Binding::read("rays", "array<f32>"),
    Binding::write("results", "array<NccResult>"),
];

gs_gpu::wgsl_struct! {
    /// The rendered normal Ñ of one reference pixel (WGSL `struct PixelNormal`): the `[H][W][3]`
    /// normal image read as records, the same bytes. 12 bytes.
    pub(crate) struct PixelNormal as "PixelNormal" {
        n: [f32; 3],
    }
}

/// The kernel's whole WGSL source (generated declarations, then `ncc.wgsl`).
pub fn ncc_kernel_source() -> String {
    gs_gpu::kernel_source(&[&declarations(), include_str!("ncc.wgsl")], &BINDINGS)
}

/// The frame uniform and the storage records: one list for the kernel's declarations and the
/// layout test.
fn generated_structs() -> [gs_gpu::GeneratedStruct; 4] {
    use gs_gpu::GeneratedStruct as G;
    [G::of::<NccFrame>(), G::of::<NccPair>(), G::of::<NccResult>(), G::of::<PixelNormal>()]
}

fn declarations() -> String {
    gs_gpu::declarations(&generated_structs())
}

struct Buffers {
    pairs: BufId,
    entries: BufId,
    normal: BufId,
    distance: BufId,
    greys: BufId,
    rays: BufId,
    results: BufId,
    /// The readback of the results (pooled: a mappable buffer per call is costly to create).
    staging: BufId,
}

/// The device executor of L_p: its context, buffers and kernel.
pub struct PhotometricGpu {
    ctx: GpuContext,
    pool: BufferPool,
    disp: Dispatcher,
    kernel: Kernel,
    bufs: Buffers,
}

impl std::fmt::Debug for PhotometricGpu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "PhotometricGpu({})", self.ctx.description())
    }
}

fn gpu_error(e: gs_gpu::GpuError) -> MvsError {
    MvsError::Device(e.to_string())
}

/// One selected patch: reference pixel and pair index.
type Entry = [u32; 2];

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
        let mut pool = BufferPool::new(&ctx, ShrinkPolicy::default());
        let bufs = Buffers {
            pairs: pool.add_storage("ncc pairs"),
            entries: pool.add_storage("ncc entries"),
            normal: pool.add_storage("ncc normal"),
            distance: pool.add_storage("ncc distance"),
            greys: pool.add_storage("ncc greys"),
            rays: pool.add_storage("ncc rays"),
            results: pool.add_storage("ncc results"),
            staging: pool.add_staging("ncc readback"),
        };
        let disp = Dispatcher::new(&ctx, std::mem::size_of::<NccFrame>() as u64);
        Ok(Self { ctx, pool, disp, kernel, bufs })
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
        check_inputs(reference, sources, config)?;
        let grey_values = reference.grey.data.len() + sources.iter().map(|s| s.grey.data.len()).sum::<usize>();
        if 4 * grey_values as u64 > self.ctx.max_storage_binding() {
            return photometric_loss(reference, sources, config);
        }
        let (w, h) = (reference.camera.width as usize, reference.camera.height as usize);
        // υ/ω, the pair geometry and the seeded selection of each source, sources in parallel
        // (each is the reference's own computation; the results keep the source order).
        let prepared = sources
            .par_iter()
            .enumerate()
            .map(|(k, source)| {
                let vis = visibility_unchecked(&PairGeometry::new(reference.camera, source.camera), &reference.plane_depth, &source.plane_depth);
                let (g, scale) = patch_geometry(reference, source)?;
                let selected = select_pixels(&vis, config, k, w, h);
                let picked: Vec<Entry> = selected.iter().enumerate().filter(|(_, s)| **s == 2).map(|(p, _)| [p as u32, k as u32]).collect();
                Ok(Prepared { vis, g, scale, selected, picked })
            })
            .collect::<Result<Vec<Prepared>>>()?;
        // Pairs, greys and the selected entries, source by source (row-major within each).
        let mut frame = NccFrame { width: w as u32, grey_width: reference.grey.width as u32, side: config.patch_size as u32, ..Default::default() };
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
        let mut greys: Vec<f32> = reference.grey.data.to_vec();
        let mut entries: Vec<Entry> = Vec::with_capacity(prepared.iter().map(|p| p.picked.len()).sum());
        let mut ranges = Vec::with_capacity(sources.len());
        for (p, source) in prepared.iter().zip(sources) {
            pairs.push(pair_record(&p.g, greys.len(), source));
            greys.extend_from_slice(source.grey.data);
            ranges.push(entries.len()..entries.len() + p.picked.len());
            entries.extend_from_slice(&p.picked);
        }
        let results = self.evaluate(&frame, &pairs, &entries, reference, &greys, &rays)?;
        let mut out = PhotometricOutput {
            loss: 0.0,
            per_source: Vec::with_capacity(sources.len()),
            grad_normal: vec![0.0; w * h * 3],
            grad_distance: vec![0.0; w * h],
            width: w,
            height: h,
        };
        for (p, range) in prepared.iter().zip(ranges) {
            let stats = add_source(&mut out, &entries[range.clone()], &results[range], &p.vis, &p.selected, w);
            out.per_source.push(stats);
        }
        Ok(out)
    }

    /// Uploads the inputs, runs the kernel over `entries` (in chunks that fit one storage
    /// binding) and reads the results back.
    fn evaluate(
        &mut self,
        frame: &NccFrame,
        pairs: &[NccPair],
        entries: &[Entry],
        reference: &PhotometricReference<'_, f32>,
        greys: &[f32],
        rays: &[f32],
    ) -> Result<Vec<NccResult>> {
        if entries.is_empty() {
            return Ok(Vec::new());
        }
        let b = &self.bufs;
        let result_bytes = std::mem::size_of::<NccResult>() as u64;
        let chunk = (self.ctx.max_storage_binding() / result_bytes).min(1 << 22) as usize;
        self.pool.begin_frame();
        let uploads: [(BufId, &[u8]); 6] = [
            (b.pairs, bytemuck::cast_slice(pairs)),
            (b.entries, bytemuck::cast_slice(entries)),
            (b.normal, bytemuck::cast_slice(reference.normal.data)),
            (b.distance, bytemuck::cast_slice(reference.distance.data)),
            (b.greys, bytemuck::cast_slice(greys)),
            (b.rays, bytemuck::cast_slice(rays)),
        ];
        for (id, bytes) in uploads {
            self.pool.ensure(id, bytes.len() as u64);
            self.ctx.write_buffer(self.pool.buffer(id), 0, bytes);
        }
        self.pool.ensure(b.results, result_bytes * chunk.min(entries.len()) as u64);
        self.pool.ensure(b.staging, result_bytes * chunk.min(entries.len()) as u64);
        self.disp.write_frame(frame);
        let mut results = Vec::with_capacity(entries.len());
        for base in (0..entries.len()).step_by(chunk) {
            let n = chunk.min(entries.len() - base);
            let p = &self.pool;
            let binds = [b.pairs, b.entries, b.normal, b.distance, b.greys, b.rays, b.results].map(|id| p.whole(id));
            let mut enc = self.disp.encoder();
            let pass = PassUniform { n: n as u32, base: base as u32, ..Default::default() };
            self.ctx.push_error_scopes();
            self.disp.dispatch_1d(&mut enc, &self.kernel, &binds, pass).map_err(gpu_error)?;
            let bytes = result_bytes * n as u64;
            enc.encoder.copy_buffer_to_buffer(p.buffer(b.results), 0, p.buffer(b.staging), 0, bytes);
            self.disp.submit(enc);
            self.ctx.pop_error_scopes().map_err(gpu_error)?;
            self.ctx
                .read_mapped(p.buffer(b.staging), bytes, |m| results.extend_from_slice(bytemuck::cast_slice::<u8, NccResult>(m)))
                .map_err(gpu_error)?;
        }
        Ok(results)
    }
}

/// The pair record of `g` with the source grey image at `offset` in `greys`.
fn pair_record(g: &PairGeometry<f32>, offset: usize, source: &PhotometricSource<'_, f32>) -> NccPair {
    let row = |r: usize| [g.a[3 * r], g.a[3 * r + 1], g.a[3 * r + 2], 0.0];
    NccPair {
        a0: row(0),
        a1: row(1),
        a2: row(2),
        kt: [g.kt[0], g.kt[1], g.kt[2], 0.0],
        src_w: g.src_w,
        src_h: g.src_h,
        grey_offset: offset as u32,
        grey_width: source.grey.width as u32,
        grey_height: source.grey.height as u32,
        ..Default::default()
    }
}

/// Adds one source's patch results to `out` as [`photometric_loss`] does: statistics summed by
/// row and then over rows, L_p,s = Σ υω·cost / |V|, the υω-weighted gradients scaled by 1/|V|.
fn add_source(
    out: &mut PhotometricOutput<f32>,
    entries: &[Entry],
    results: &[NccResult],
    vis: &Visibility<f32>,
    selected: &[u8],
    w: usize,
) -> SourceStats {
    let mut stats = SourceStats {
        visibility: vis.stats(),
        n_candidates: selected.iter().filter(|&&s| s != 0).count(),
        n_sampled: entries.len(),
        ..Default::default()
    };
    let mut row: Option<usize> = None;
    let (mut weighted, mut cost) = (0.0f64, 0.0f64);
    let flush = |weighted: &mut f64, cost: &mut f64, stats: &mut SourceStats| {
        stats.weighted_cost_sum += std::mem::take(weighted);
        stats.cost_sum += std::mem::take(cost);
    };
    for (e, r) in entries.iter().zip(results) {
        let p = e[0] as usize;
        if row != Some(p / w) {
            flush(&mut weighted, &mut cost, &mut stats);
            row = Some(p / w);
        }
        if r.status >= STATUS_MASKED {
            stats.n_inside_source += 1;
        }
        if r.status == STATUS_VALID {
            stats.n_valid += 1;
            let wt = vis.weight(p);
            weighted += (wt * r.cost) as f64;
            cost += r.cost as f64;
        }
    }
    flush(&mut weighted, &mut cost, &mut stats);
    if stats.n_valid > 0 {
        stats.loss = stats.weighted_cost_sum / stats.n_valid as f64;
        out.loss += stats.loss;
        let scale = (1.0 / stats.n_valid as f64) as f32;
        for (e, r) in entries.iter().zip(results).filter(|(_, r)| r.status == STATUS_VALID) {
            let p = e[0] as usize;
            let wt = vis.weight(p);
            for c in 0..3 {
                out.grad_normal[3 * p + c] += wt * r.grad_n[c] * scale;
            }
            out.grad_distance[p] += wt * r.grad_d * scale;
        }
    }
    stats
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_match_their_wgsl_layout() {
        let src = ncc_kernel_source();
        gs_gpu::check_layouts(&generated_structs(), &src).unwrap();
        gs_gpu::validate_kernel(&src).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(gs_gpu::bytes_of::<PixelNormal>(1), 12);
    }
}
