//! L_p on the device (behind the `wgpu` feature), the twin of [`crate::photometric`]: one WGSL
//! kernel (`ncc.wgsl`) evaluates every selected (pixel, source) patch — its NCC cost and the
//! gradient with respect to the rendered plane (Ñ, D) — and three more (`reduce.wgsl`) sum
//! them in fixed orders into each (source, row)'s statistics and the gradient image; a last
//! (`totals.wgsl`) adds each source's rows, and those totals and the gradient alone come
//! back. For a reference whose plane is on the host, υ/ω and the seeded pixel
//! selection run on the host with the reference's own code, so the two executors choose the
//! same patches and differ only in the patch arithmetic and the f32 sums; for a reference whose
//! plane is on the device they run there too ([`select`]: the same rules and draw, υ/ω within
//! rounding). The tolerances are in `tests/photometric_gpu.rs`; one seed gives one result on one
//! device (docs/method.md §L_p, docs/architecture.md §GPU).
//!
//! The grey images (and the sources' plane depths) go into an arena (gs-gpu's [`Arena`]); keyed
//! by view ([`PhotometricGpu::loss_of_views`], [`ViewKeys`]) they stay there between calls and
//! are uploaded once (a depth once a version).

mod depths;
mod lent;
mod outcome;
mod reduce;
mod reference;
mod select;
mod submit;

pub use depths::{DeviceSource, SourceDepth, keep_depth_kernel_source};
pub use lent::DeviceVisibility;
pub use outcome::{PendingPhotometric, PhotometricOnDevice};
pub use reduce::reduce_kernel_source;
pub use reference::{SurfaceReference, surface_depth, upload_surface};
pub use select::{selection_kernel_source, visibility_kernel_source};
pub(crate) use select::{VisRow, VisTexel};
use outcome::{Done, Pending};
use submit::{Inputs, Readback, patch_inputs};

use crate::error::{MvsError, Result};
use crate::photometric::{
    PhotometricConfig, PhotometricOutput, PhotometricReference, PhotometricSource, SourceStats, patch_geometry,
    select_pixels,
};
use reference::RefView;
use crate::visibility::{Visibility, visibility_unchecked};
use crate::geometry::{MapView, PairGeometry};
use rayon::prelude::*;
use gs_gpu::{Arena, Binding, BufId, BufferPool, DeviceImage, Dispatcher, GpuContext, Kernel, ShrinkPolicy};
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
        /// Entries a source may hold when the device selects them (source k's from k · slot).
        slot: u32,
        /// 1 when the host drew the device's candidates (`masks`), 0 when all are evaluated.
        capped: u32,
        pad0: u32,
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
const BINDINGS: [Binding<'static>; 7] = [
    Binding::read("pairs", "array<NccPair>"),
    Binding::read("entries", "array<u32>"),
    Binding::read("surface", "array<SurfaceTexel>"),
    Binding::read("row_starts", "array<u32>"),
    Binding::read("greys", "array<f32>"),
    Binding::read("rays", "array<f32>"),
    Binding::write("results", "array<NccResult>"),
];

/// The kernel's whole WGSL source (generated declarations, then `ncc.wgsl`).
pub fn ncc_kernel_source() -> String {
    gs_gpu::kernel_source(&[&declarations(), include_str!("sampling.wgsl"), include_str!("ncc.wgsl")], &BINDINGS)
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
    /// Each source's totals (read back).
    totals: BufId,
    scales: BufId,
    grads: BufId,
    /// The readback of the sums (pooled: a mappable buffer per call is costly to create).
    staging: BufId,
    /// The device selection's: visibility records per pair, per (source, pixel) and per
    /// (source, row); each row's first candidate rank and the drawn candidates' bitmask (capped);
    /// the readback of the rows' counts (capped).
    vis_pairs: BufId,
    vis: BufId,
    vis_rows: BufId,
    cand_starts: BufId,
    masks: BufId,
    vis_staging: BufId,
}

/// The device executor of L_p: its context, buffers and kernels.
pub struct PhotometricGpu {
    ctx: GpuContext,
    pool: BufferPool,
    disp: Dispatcher,
    kernel: Kernel,
    /// The reduction's passes ([`reduce::PASSES`]).
    sums: Vec<Kernel>,
    /// Each source's totals of its rows (totals.wgsl).
    totals: Kernel,
    /// The device selection's passes.
    selection: select::SelectionKernels,
    bufs: Buffers,
    /// The grey images (and the sources' plane depths), kept per view between calls when the
    /// caller keys them ([`PhotometricGpu::loss_of_views`]).
    greys: Arena,
    /// Copies a reference's plane depth into the arena ([`ViewKeys::keep_reference_depth`]).
    keep: Kernel,
    /// The last evaluation's υ/ω, where they were made on the device for keyed views.
    made: Option<DeviceVisibility>,
}

/// The keys under which [`PhotometricGpu::start_on_device`] keeps its per-view arrays on the
/// device between calls.
#[derive(Debug, Clone, Copy)]
pub struct ViewKeys<'a> {
    /// One per view, the reference's then each source's (e.g. its training slot): a view's grey
    /// image is held under its key, as [`PhotometricGpu::loss_of_views`] holds it.
    pub views: &'a [u64],
    /// One per source: the version of its plane depth under its view's key (e.g. the iteration
    /// that rendered it); another version is uploaded again, into the same slot.
    pub depth_versions: &'a [u64],
    /// The version under which the reference's plane depth (its surface's z) stays in the
    /// arena, under the reference's key, for later evaluations that take this view as a
    /// source ([`SourceDepth::Held`]); `None` keeps nothing.
    pub keep_reference_depth: Option<u64>,
}

/// How much device memory the arena of grey images holds (bytes), at most one storage binding.
const ARENA_BYTES: u64 = 512 << 20;

/// The arena part of a view's plane depth (its grey image is part 0).
const DEPTH_PART: u32 = 1;

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

/// The entries of an evaluation: the host's (uploaded with their υω and each source's row
/// starts), or selected on the device, `slot` a source.
enum Entries<'a> {
    Host { entries: &'a [Entry], weights: &'a [f32], row_starts: &'a [u32] },
    Device { slot: usize },
}

impl Entries<'_> {
    fn count(&self, sources: usize) -> usize {
        match self {
            Entries::Host { entries, .. } => entries.len(),
            Entries::Device { slot } => sources * slot,
        }
    }
}

impl PhotometricGpu {
    /// The executor on `ctx`'s device (shared, e.g. with the rasterizer's), its kernel compiled.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let ctx = ctx.clone();
        let kernel = Kernel::new(&ctx, "ncc_patch", &[&declarations(), include_str!("sampling.wgsl"), include_str!("ncc.wgsl")], &BINDINGS).map_err(gpu_error)?;
        let selection = select::SelectionKernels::new(&ctx)?;
        let sum_decls = gs_gpu::declarations(&reduce::generated_structs());
        let sums = reduce::PASSES
            .iter()
            .map(|entry| Kernel::new(&ctx, entry, &[&sum_decls, include_str!("reduce.wgsl")], &reduce::BINDINGS))
            .collect::<std::result::Result<Vec<_>, _>>()
            .map_err(gpu_error)?;
        let totals = Kernel::new(&ctx, "ncc_totals", &[&sum_decls, include_str!("totals.wgsl")], &reduce::TOTALS_BINDINGS).map_err(gpu_error)?;
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
            totals: pool.add_storage("ncc totals"),
            scales: pool.add_storage("ncc scales"),
            grads: pool.add_storage("ncc gradient"),
            staging: pool.add_staging("ncc readback"),
            vis_pairs: pool.add_storage("ncc visibility pairs"),
            vis: pool.add_storage("ncc visibility"),
            vis_rows: pool.add_storage("ncc visibility rows"),
            cand_starts: pool.add_storage("ncc candidate starts"),
            masks: pool.add_storage("ncc drawn candidates"),
            vis_staging: pool.add_staging("ncc candidate counts"),
        };
        let disp = Dispatcher::new(&ctx, std::mem::size_of::<NccFrame>() as u64);
        let greys = Arena::new(&ctx, "ncc greys", ARENA_BYTES);
        let keep = depths::keep_depth_kernel(&ctx)?;
        Ok(Self { ctx, pool, disp, kernel, sums, totals, selection, bufs, greys, keep, made: None })
    }

    /// The adapter, in words.
    pub fn adapter_description(&self) -> String {
        self.ctx.description()
    }

    /// The υ/ω of the last evaluation, where [`PhotometricGpu::start_on_device`] or
    /// [`PhotometricGpu::visibility_on_device`] made them on the device for views it was given
    /// keys of: what L_f of the same step reads ([`crate::FeatureGpu::start_on_device`]).
    pub fn visibility(&self) -> Option<&DeviceVisibility> {
        self.made.as_ref()
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
        if keys.is_some_and(|k| k.len() != sources.len() + 1) {
            return Err(MvsError::InvalidInput(format!("{} grey image keys for a reference and {} sources", keys.map_or(0, <[u64]>::len), sources.len())));
        }
        self.made = None;
        let view = RefView::of_host(reference);
        view.check(sources, config)?;
        self.start_on_host(view, sources, keys, config, false)
    }

    /// [`PhotometricGpu::start`] of a reference whose rendered plane is on the device (the
    /// rasterizer's surface image) and whose gradient image stays there (a `DeviceImage` of
    /// gs-gpu `PlaneGrad`s, for the rasterizer's backward there): neither crosses to the host,
    /// nor do υ/ω and the selected patches, which are made on the device from the surface's
    /// plane depth and the sources' (`keys` holds the sources' depths by version; a
    /// [`SourceDepth::Held`] one is there already). Only each source's totals come back,
    /// and, when a source may exceed the sampling cap, its candidate counts first (one more
    /// wait). With [`ViewKeys::keep_reference_depth`] the reference's depth stays in the arena.
    /// [`PhotometricGpu::finish_on_device`] reads it.
    pub fn start_on_device(
        &mut self,
        reference: &SurfaceReference<'_>,
        sources: &[DeviceSource<'_>],
        keys: Option<ViewKeys<'_>>,
        config: &PhotometricConfig,
    ) -> Result<PendingPhotometric> {
        let (view, on_host, held) = self.device_inputs(reference, sources, keys, config)?;
        let pending = match self.start_selecting(&view, &on_host, &held, keys, config)? {
            Some(pending) => pending,
            None => {
                // The host selects: every depth comes to the host first.
                let held = self.read_back_held(sources, keys)?;
                let on_host: Vec<PhotometricSource<'_, f32>> = sources.iter().zip(&held).map(|(s, d)| s.on_host(d.as_deref())).collect();
                let z = match reference.plane_depth {
                    Some(_) => None,
                    None => Some(view.surface_depth(&self.ctx)?),
                };
                let view = RefView { plane_depth: z.as_deref().map_or(view.plane_depth, |z| MapView { data: z, ..view.plane_depth }), ..view };
                self.start_on_host(view, &on_host, keys.map(|k| k.views), config, true)?
            }
        };
        // After the evaluation's submission, which reads the arena as it was.
        if let (Some(k), Some(version)) = (keys, keys.and_then(|k| k.keep_reference_depth)) {
            self.keep_depth(reference.surface, k.views[0], version)?;
        }
        Ok(pending)
    }

    /// υ/ω of `reference` (its plane on the device) against `sources` made on the device
    /// alone, as [`PhotometricGpu::start_on_device`] makes them, for L_f in a step without L_p
    /// ([`crate::FeatureGpu::start_on_device`]): the sources' depths go into the arena under
    /// `keys` as there (a held one is there already), and the visibility is lent until this
    /// executor's next evaluation. One submission, nothing read back. `None` where the device
    /// would not select ([`PhotometricGpu::start_on_device`]'s limits).
    pub fn visibility_on_device(
        &mut self,
        reference: &SurfaceReference<'_>,
        sources: &[DeviceSource<'_>],
        keys: ViewKeys<'_>,
        config: &PhotometricConfig,
    ) -> Result<Option<DeviceVisibility>> {
        let (view, on_host, held) = self.device_inputs(reference, sources, Some(keys), config)?;
        let Some(begun) = self.begin_visibility(&view, &on_host, &held, Some(keys), config)? else {
            return Ok(None);
        };
        self.disp.submit(begun.enc);
        self.ctx.pop_error_scopes().map_err(gpu_error)?;
        Ok(self.made.clone())
    }

    /// The checked inputs of an evaluation of a reference plane on the device: the reference,
    /// the sources as the host's code reads them, and which depths are held (no lent visibility
    /// survives it).
    fn device_inputs<'a>(
        &mut self,
        reference: &SurfaceReference<'a>,
        sources: &[DeviceSource<'a>],
        keys: Option<ViewKeys<'_>>,
        config: &PhotometricConfig,
    ) -> Result<(RefView<'a>, Vec<PhotometricSource<'a, f32>>, Vec<bool>)> {
        if let Some(k) = keys
            && (k.views.len() != sources.len() + 1 || k.depth_versions.len() != sources.len())
        {
            let (v, d) = (k.views.len(), k.depth_versions.len());
            return Err(MvsError::InvalidInput(format!("{v} view keys and {d} depth versions for a reference and {} sources", sources.len())));
        }
        self.made = None;
        self.check_held(sources, keys)?;
        let on_host: Vec<PhotometricSource<'a, f32>> = sources.iter().map(|s| s.on_host(None)).collect();
        let view = RefView::of_device(reference, &self.ctx)?;
        view.check(&on_host, config)?;
        Ok((view, on_host, sources.iter().map(DeviceSource::held).collect()))
    }

    /// An evaluation of `reference` (its inputs checked by the caller) whose υ/ω and selection
    /// run on the host, the gradient image kept on the device when `keep`.
    fn start_on_host(
        &mut self,
        reference: RefView<'_>,
        sources: &[PhotometricSource<'_, f32>],
        keys: Option<&[u64]>,
        config: &PhotometricConfig,
        keep: bool,
    ) -> Result<PendingPhotometric> {
        let host = |r| Ok(PendingPhotometric(Pending::Ready(r)));
        if !self.greys_fit(&reference, sources) {
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
        let geometry: Vec<_> = prepared.iter().map(|p| (&p.g, p.scale)).collect();
        let (frame, rays, pairs) = patch_inputs(&reference, sources, &geometry, &offsets, config);
        let picked = prepared.iter().map(|p| p.picked.len()).sum();
        let mut entries: Vec<Entry> = Vec::with_capacity(picked);
        let mut weights: Vec<f32> = Vec::with_capacity(picked);
        let mut ranges = Vec::with_capacity(sources.len());
        for p in &prepared {
            ranges.push((entries.len() as u32, p.picked.len() as u32));
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
        let done = Done { counted: Some(counted), config: config.clone(), width: w, height: h };
        if entries.is_empty() {
            return host(done.output(&vec![reduce::NccTotals::default(); sources.len()], &[]));
        }
        let ranges_of: Vec<std::ops::Range<usize>> = ranges.iter().map(|&(b, n)| b as usize..(b + n) as usize).collect();
        let row_starts = reduce::row_starts(&entries, &ranges_of, w, h);
        let kept = self.kept_gradient(keep, w, h)?;
        let inputs = Inputs { frame: &frame, pairs: &pairs, rays: &rays };
        self.stage(&inputs, reference.plane, &Entries::Host { entries: &entries, weights: &weights, row_starts: &row_starts }, kept.is_some());
        let mut enc = self.disp.encoder();
        self.ctx.push_error_scopes();
        self.encode_patches(&mut enc, &frame, reference.plane, &ranges)?;
        let (read, layout) = self.read_sums(enc, &frame, kept.as_ref(), false)?;
        self.ctx.pop_error_scopes().map_err(gpu_error)?;
        Ok(PendingPhotometric(Pending::Device { read, layout, done, kept }))
    }

    /// Whether the reference's and the sources' grey images fit one storage binding.
    fn greys_fit(&self, reference: &RefView<'_>, sources: &[PhotometricSource<'_, f32>]) -> bool {
        let grey_values = reference.grey.data.len() + sources.iter().map(|s| s.grey.data.len()).sum::<usize>();
        4 * grey_values as u64 <= self.ctx.max_storage_binding()
    }

    /// The device image the gradient is kept in, when `keep`.
    fn kept_gradient(&self, keep: bool, w: usize, h: usize) -> Result<Option<DeviceImage>> {
        match keep {
            true => Ok(Some(DeviceImage::new(&self.ctx, "L_p gradient", w, h, gs_gpu::PLANE_GRAD_CHANNELS).map_err(gpu_error)?)),
            false => Ok(None),
        }
    }

    /// The result of a started evaluation (waiting for the device if it has not answered).
    pub fn finish(&mut self, pending: PendingPhotometric) -> Result<PhotometricOutput<f32>> {
        let (read, layout, done) = match pending.0 {
            Pending::Ready(out) => return Ok(out),
            Pending::Device { kept: Some(_), .. } => return Err(MvsError::InvalidInput("an evaluation whose gradient stays on the device, finished for the host".into())),
            Pending::Device { read, layout, done, kept: None } => (read, layout, done),
        };
        let (totals, grads) = self.ctx.finish_read(read, |m| layout.split(m)).map_err(gpu_error)?;
        Ok(done.output(&totals, &grads))
    }

    /// The result of an evaluation started by [`PhotometricGpu::start_on_device`]: the values
    /// (one wait, unless an earlier wait brought them) with the gradient image on the device,
    /// or the whole output on the host where the evaluation was made there (grey images too
    /// large for the device, or no patch to evaluate).
    pub fn finish_on_device(&mut self, pending: PendingPhotometric) -> Result<PhotometricOnDevice> {
        let (read, layout, done, gradient) = match pending.0 {
            Pending::Ready(out) => return Ok(PhotometricOnDevice::Host(out)),
            Pending::Device { kept: None, .. } => return Err(MvsError::InvalidInput("an evaluation for the host, finished on the device".into())),
            Pending::Device { read, layout, done, kept: Some(gradient) } => (read, layout, done, gradient),
        };
        let (totals, _) = self.ctx.finish_read(read, |m| layout.split(m)).map_err(gpu_error)?;
        let (loss, per_source) = done.stats(&totals);
        Ok(PhotometricOnDevice::Device { loss, per_source, gradient })
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
