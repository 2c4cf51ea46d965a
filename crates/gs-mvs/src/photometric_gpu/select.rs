//! L_p's visibility υ/ω and pixel selection on the device (`visibility.wgsl`, `select.wgsl`),
//! the twins of [`crate::visibility`] and `photometric::select_pixels`, for a reference whose
//! plane is on the device ([`super::PhotometricGpu::start_on_device`]): the reference's plane
//! depth is the surface's z, each source's plane depth goes into the arena once a version, and
//! the selected entries and their υω are written on the device, so neither the depths' υω nor
//! the entries cross. When no source can exceed the sampling cap every candidate is evaluated and
//! the whole evaluation is one submission; otherwise the host reads each (source, row)'s
//! candidate count (one more wait) and draws the patches with the seed, exactly as the host's
//! selection draws them (docs/architecture.md §GPU).

use super::outcome::{Done, Pending, PendingPhotometric};
use super::reference::{Plane, RefView};
use super::{DEPTH_PART, DeviceVisibility, Entries, Inputs, NccFrame, NccResult, PhotometricGpu, ViewKeys, gpu_error, patch_inputs};
use crate::error::Result;
use crate::geometry::{PairGeometry, padded, padded_rows};
use crate::photometric::{PhotometricConfig, PhotometricSource, SourceStats, drawn_candidates, patch_geometry};
use crate::visibility::VisibilityStats;
use gs_gpu::{Binding, GeneratedStruct, GpuContext, Kernel, PassUniform, bytes_of};
use std::borrow::Cow;

gs_gpu::wgsl_struct! {
    /// One reference/source pair's visibility constants (WGSL `struct VisPair`): the rows of
    /// R_rs, t_rs, both cameras' (fx, fy, cx, cy), the source size, where its plane depth lies
    /// in the arena and where its bitmask of drawn candidates starts.
    pub(crate) struct VisPair as "VisPair" {
        r0: [f32; 4],
        r1: [f32; 4],
        r2: [f32; 4],
        t: [f32; 4],
        ref_k: [f32; 4],
        src_k: [f32; 4],
        src_w: f32,
        src_h: f32,
        depth_offset: u32,
        depth_width: u32,
        depth_height: u32,
        mask_offset: u32,
        pad0: u32,
        pad1: u32,
    }
}

gs_gpu::wgsl_struct! {
    /// One (source, reference pixel)'s υω and flags (WGSL `struct VisTexel`: 1 υ, 2 ω > 0,
    /// 4 candidate).
    pub(crate) struct VisTexel as "VisTexel" {
        weight: f32,
        flags: u32,
    }
}

gs_gpu::wgsl_struct! {
    /// One (source, row)'s visibility counts and its sum of ω over υ (WGSL `struct VisRow`).
    pub(crate) struct VisRow as "VisRow" {
        upsilon: u32,
        omega_positive: u32,
        candidates: u32,
        omega_sum: f32,
    }
}

/// The visibility kernels' storage bindings, by name (slot order).
const VIS_BINDINGS: [Binding<'static>; 5] = [
    Binding::read("vis_pairs", "array<VisPair>"),
    Binding::read("surface", "array<SurfaceTexel>"),
    Binding::read("greys", "array<f32>"),
    Binding::write("vis", "array<VisTexel>"),
    Binding::write("vis_rows", "array<VisRow>"),
];

/// The selection kernels' storage bindings, by name (slot order).
const SELECT_BINDINGS: [Binding<'static>; 8] = [
    Binding::read("vis_pairs", "array<VisPair>"),
    Binding::read("vis", "array<VisTexel>"),
    Binding::read("vis_rows", "array<VisRow>"),
    Binding::write("row_starts", "array<u32>"),
    Binding::read("cand_starts", "array<u32>"),
    Binding::read("masks", "array<u32>"),
    Binding::write("entries", "array<u32>"),
    Binding::write("weights", "array<f32>"),
];

fn vis_structs() -> [GeneratedStruct; 5] {
    use gs_gpu::GeneratedStruct as G;
    [G::of::<NccFrame>(), G::of::<VisPair>(), G::of::<gs_gpu::SurfaceTexel>(), G::of::<VisTexel>(), G::of::<VisRow>()]
}

fn select_structs() -> [GeneratedStruct; 4] {
    use gs_gpu::GeneratedStruct as G;
    [G::of::<NccFrame>(), G::of::<VisPair>(), G::of::<VisTexel>(), G::of::<VisRow>()]
}

fn vis_parts() -> [String; 3] {
    [gs_gpu::declarations(&vis_structs()), include_str!("sampling.wgsl").into(), include_str!("visibility.wgsl").into()]
}

/// The visibility kernels' whole WGSL source.
pub fn visibility_kernel_source() -> String {
    let parts = vis_parts();
    gs_gpu::kernel_source(&parts.each_ref().map(String::as_str), &VIS_BINDINGS)
}

/// The selection kernels' whole WGSL source.
pub fn selection_kernel_source() -> String {
    gs_gpu::kernel_source(&[&gs_gpu::declarations(&select_structs()), include_str!("select.wgsl")], &SELECT_BINDINGS)
}

/// The four passes, compiled once per executor.
pub(super) struct SelectionKernels {
    pub pixels: Kernel,
    pub rows: Kernel,
    pub starts: Kernel,
    pub select: Kernel,
}

impl SelectionKernels {
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let parts = vis_parts();
        let vis = parts.each_ref().map(String::as_str);
        let select_decls = gs_gpu::declarations(&select_structs());
        let select = [select_decls.as_str(), include_str!("select.wgsl")];
        let make = |entry, sources: &[&str], bindings: &[Binding<'_>]| Kernel::new(ctx, entry, sources, bindings).map_err(gpu_error);
        Ok(Self {
            pixels: make("visibility_pixels", &vis, &VIS_BINDINGS)?,
            rows: make("visibility_rows", &vis, &VIS_BINDINGS)?,
            starts: make("select_starts", &select, &SELECT_BINDINGS)?,
            select: make("select_rows", &select, &SELECT_BINDINGS)?,
        })
    }
}

impl PhotometricGpu {
    /// An evaluation of `reference` (its plane on the device) whose υ/ω and selection run on
    /// the device; `None` where that does not apply (a plane on the host, no source, an image
    /// smaller than a patch, arrays larger than one binding or the arena): the caller selects
    /// on the host.
    pub(super) fn start_selecting(
        &mut self,
        reference: &RefView<'_>,
        sources: &[PhotometricSource<'_, f32>],
        held: &[bool],
        keys: Option<ViewKeys<'_>>,
        config: &PhotometricConfig,
    ) -> Result<Option<PendingPhotometric>> {
        let Some(Begun { mut enc, frame, slot, capped, words }) = self.begin_visibility(reference, sources, held, keys, config)? else {
            return Ok(None);
        };
        let (w, h, n) = (reference.camera.width as usize, reference.camera.height as usize, sources.len());
        let kept = self.kept_gradient(true, w, h)?;
        let (b, threads) = (&self.bufs, |t: usize| PassUniform { n: t as u32, ..Default::default() });
        let mut counted = None;
        if capped {
            counted = Some(self.draw_from_counts(enc, (n, h), (slot, words), config)?);
            enc = self.disp.encoder();
            self.ctx.push_error_scopes();
        }
        {
            let p = &self.pool;
            let binds = [b.vis_pairs, b.vis, b.vis_rows, b.row_starts, b.cand_starts, b.masks, b.entries, b.weights].map(|id| p.whole(id));
            self.disp.make_room(&mut enc, 2);
            if !capped {
                self.disp.dispatch_1d(&mut enc, &self.selection.starts, &binds, threads(n)).map_err(gpu_error)?;
            }
            self.disp.dispatch_1d(&mut enc, &self.selection.select, &binds, threads(n * h)).map_err(gpu_error)?;
        }
        let ranges: Vec<(u32, u32)> = (0..n).map(|k| ((k * slot) as u32, slot as u32)).collect();
        self.encode_patches(&mut enc, &frame, reference.plane, &ranges)?;
        let (read, layout) = self.read_sums(enc, &frame, kept.as_ref(), !capped)?;
        self.ctx.pop_error_scopes().map_err(gpu_error)?;
        let done = Done { counted, config: config.clone(), width: w, height: h };
        Ok(Some(PendingPhotometric(Pending::Device { read, layout, done, kept })))
    }

    /// The first part of an evaluation whose υ/ω run on the device: the views placed in the
    /// arena, the inputs staged, and the visibility passes recorded (not submitted, inside an
    /// error scope the caller pops) with the visibility lent as `made` where `keys` name the
    /// views; `None` where that does not apply (see [`PhotometricGpu::start_selecting`]).
    pub(super) fn begin_visibility(
        &mut self,
        reference: &RefView<'_>,
        sources: &[PhotometricSource<'_, f32>],
        held: &[bool],
        keys: Option<ViewKeys<'_>>,
        config: &PhotometricConfig,
    ) -> Result<Option<Begun>> {
        let Plane::Device(surface) = reference.plane else {
            return Ok(None);
        };
        let (w, h, n) = (reference.camera.width as usize, reference.camera.height as usize, sources.len());
        let half = config.patch_size / 2;
        let inner = if w > 2 * half && h > 2 * half { (w - 2 * half) * (h - 2 * half) } else { 0 };
        // Each source's entries: every candidate, or at most the cap's number.
        let slot = config.max_pixels_per_source.map_or(inner, |cap| cap.min(inner));
        let capped = slot < inner;
        let max = self.ctx.max_storage_binding();
        if n == 0 || slot == 0 || !self.greys_fit(reference, sources) || bytes_of::<NccResult>(n * slot) > max || bytes_of::<VisTexel>(n * w * h) > max {
            return Ok(None);
        }
        let geometry = sources.iter().map(|s| patch_geometry((reference.camera, &reference.grey), s)).collect::<Result<Vec<_>>>()?;
        let Some(offsets) = self.place_views(reference, sources, held, keys)? else {
            return Ok(None);
        };
        let by_ref: Vec<_> = geometry.iter().map(|(g, s)| (g, *s)).collect();
        let (mut frame, rays, pairs) = patch_inputs(reference, sources, &by_ref, &offsets[..=n], config);
        (frame.slot, frame.capped) = (slot as u32, capped as u32);
        let words = inner.div_ceil(32);
        let vis_pairs: Vec<VisPair> = sources
            .iter()
            .zip(&offsets[n + 1..])
            .enumerate()
            .map(|(k, (s, &at))| {
                // At the cameras' sizes (the patch geometry is at the grey images').
                let g = PairGeometry::new(reference.camera, s.camera);
                vis_pair(&g, at, (s.plane_depth.width, s.plane_depth.height), (k * words) as u32)
            })
            .collect();
        self.stage(&Inputs { frame: &frame, pairs: &pairs, rays: &rays }, reference.plane, &Entries::Device { slot }, true);
        let b = &self.bufs;
        self.pool.ensure(b.vis_pairs, bytes_of::<VisPair>(n));
        self.ctx.write_buffer(self.pool.buffer(b.vis_pairs), 0, bytemuck::cast_slice(&vis_pairs));
        let row_bytes = bytes_of::<VisRow>(n * h);
        let sizes = [(b.vis, bytes_of::<VisTexel>(n * w * h)), (b.vis_rows, row_bytes), (b.cand_starts, 4 * (n * h) as u64), (b.masks, 4 * (n * words) as u64), (b.vis_staging, row_bytes)];
        for (id, bytes) in sizes {
            self.pool.ensure(id, bytes.max(4));
        }
        let threads = |t: usize| PassUniform { n: t as u32, ..Default::default() };
        let mut enc = self.disp.encoder();
        self.ctx.push_error_scopes();
        {
            let p = &self.pool;
            let binds = [p.whole(b.vis_pairs), gs_gpu::Bind::whole(surface.buffer()), self.greys.bind(), p.whole(b.vis), p.whole(b.vis_rows)];
            self.disp.make_room(&mut enc, 2);
            self.disp.dispatch_1d(&mut enc, &self.selection.pixels, &binds, threads(n * w * h)).map_err(gpu_error)?;
            self.disp.dispatch_1d(&mut enc, &self.selection.rows, &binds, threads(n * h)).map_err(gpu_error)?;
        }
        self.made = keys.map(|k| DeviceVisibility {
            texels: self.pool.buffer(b.vis).clone(),
            rows: self.pool.buffer(b.vis_rows).clone(),
            surface: surface.buffer().clone(),
            views: k.views.to_vec(),
            depth_versions: k.depth_versions.to_vec(),
            width: w,
            height: h,
        });
        Ok(Some(Begun { enc, frame, slot, capped, words }))
    }

    /// The grey images (the reference's first) and then the sources' plane depths in the
    /// arena, each under its view's key (a depth by its version): their offsets, or `None`
    /// when they do not fit. The depths the arena holds alone (`held`) are placed first, so
    /// that no upload of this call evicts them; an error if one is gone all the same.
    fn place_views(&mut self, reference: &RefView<'_>, sources: &[PhotometricSource<'_, f32>], held: &[bool], keys: Option<ViewKeys<'_>>) -> Result<Option<Vec<u32>>> {
        let n = sources.len();
        let greys = std::iter::once(reference.grey.data).chain(sources.iter().map(|s| s.grey.data));
        let arrays: Vec<&[f32]> = greys.chain(sources.iter().map(|s| s.plane_depth.data)).collect();
        let key = |i: usize| keys.map(|k| if i <= n { (k.views[i], 0) } else { (k.views[i - n], DEPTH_PART) });
        let is_held = |i: usize| i > n && held.get(i - n - 1).copied().unwrap_or(false);
        let mut order: Vec<usize> = (0..arrays.len()).filter(|&i| is_held(i)).collect();
        order.extend((0..arrays.len()).filter(|&i| !is_held(i)));
        // A depth's length is its size's: a held one has no values on the host.
        let floats = |i: usize| if i > n { sources[i - n - 1].plane_depth.width * sources[i - n - 1].plane_depth.height } else { arrays[i].len() };
        let items: Vec<_> = order.iter().map(|&i| (key(i), floats(i))).collect();
        let versions: Vec<u64> = order.iter().map(|&i| keys.filter(|_| i > n).map_or(0, |k| k.depth_versions[i - n - 1])).collect();
        let lost = std::cell::Cell::new(None);
        let placed = self.greys.place_versions(&self.ctx, &items, &versions, |j| {
            if is_held(order[j]) {
                lost.set(Some(order[j] - n - 1));
            }
            Cow::Borrowed(arrays[order[j]])
        });
        if let Some(k) = lost.get() {
            // Its slot holds no depth now: never let it pass for one.
            if let Some(keys) = keys {
                self.greys.forget((keys.views[k + 1], DEPTH_PART));
            }
            return Err(crate::error::MvsError::InvalidInput(format!("source {k}'s plane depth was evicted from the device")));
        }
        Ok(placed.map(|at| {
            let mut offsets = vec![0; at.len()];
            order.iter().zip(at).for_each(|(&i, o)| offsets[i] = o);
            offsets
        }))
    }

    /// A capped selection's host share (`n` sources of `h` rows): submits the visibility passes
    /// in `enc` with the rows' candidate counts copied out, waits for them, draws as the host's own selection draws
    /// and uploads each row's first entry and candidate rank and the drawn bitmask; returns
    /// what it counted of each source.
    fn draw_from_counts(&self, mut enc: gs_gpu::Encoder, (n, h): (usize, usize), (slot, words): (usize, usize), config: &PhotometricConfig) -> Result<Vec<SourceStats>> {
        let b = &self.bufs;
        let row_bytes = bytes_of::<VisRow>(n * h);
        let staging = self.pool.buffer(b.vis_staging);
        enc.encoder.copy_buffer_to_buffer(self.pool.buffer(b.vis_rows), 0, staging, 0, row_bytes);
        self.disp.submit(enc);
        let read = self.ctx.request_read(staging, row_bytes);
        self.ctx.pop_error_scopes().map_err(gpu_error)?;
        let rows: Vec<VisRow> = self.ctx.finish_read(read, bytemuck::pod_collect_to_vec).map_err(gpu_error)?;
        let drawn = draw(&rows, h, (slot, words), config);
        for (id, values) in [(b.row_starts, &drawn.row_starts), (b.cand_starts, &drawn.cand_starts), (b.masks, &drawn.masks)] {
            self.ctx.write_buffer(self.pool.buffer(id), 0, bytemuck::cast_slice(values));
        }
        Ok(rows.chunks_exact(h).map(|r| counted(r, config)).collect())
    }
}

/// What [`PhotometricGpu::begin_visibility`] leaves for the selection: the encoder holding the
/// visibility passes, the frame, each source's entry slot, whether the cap applies, and the
/// bitmask words a source.
pub(super) struct Begun {
    pub enc: gs_gpu::Encoder,
    frame: NccFrame,
    slot: usize,
    capped: bool,
    words: usize,
}

/// The visibility record of pair `g` with the source's plane depth (`width × height`) at
/// `depth_offset` in the arena and its bitmask at word `mask_offset`.
pub(super) fn vis_pair(g: &PairGeometry<f32>, depth_offset: u32, (width, height): (usize, usize), mask_offset: u32) -> VisPair {
    let [r0, r1, r2] = padded_rows(&g.rot);
    VisPair {
        r0,
        r1,
        r2,
        t: padded(&g.t),
        ref_k: [g.r_fx, g.r_fy, g.r_cx, g.r_cy],
        src_k: [g.s_fx, g.s_fy, g.s_cx, g.s_cy],
        src_w: g.src_w,
        src_h: g.src_h,
        depth_offset,
        depth_width: width as u32,
        depth_height: height as u32,
        mask_offset,
        ..Default::default()
    }
}

/// What the host counts of a source from its rows (the patches' sums come later): the
/// visibility statistics (the rows' ω sums added in order in f64), its candidates and how many
/// the cap lets through.
pub(super) fn counted(rows: &[VisRow], config: &PhotometricConfig) -> SourceStats {
    let candidates: usize = rows.iter().map(|r| r.candidates as usize).sum();
    selection_stats(visibility_stats(rows), candidates, config.max_pixels_per_source)
}

/// A source's counts before its patches are evaluated: its visibility statistics and
/// candidates, of which at most `cap` are sampled.
pub(super) fn selection_stats(visibility: VisibilityStats, candidates: usize, cap: Option<usize>) -> SourceStats {
    SourceStats { visibility, n_candidates: candidates, n_sampled: cap.map_or(candidates, |c| candidates.min(c)), ..Default::default() }
}

/// A source's visibility statistics from its rows' counts (the ω sums added in row order in
/// f64), as [`crate::Visibility::stats`] counts them on the host.
pub(super) fn visibility_stats(rows: &[VisRow]) -> VisibilityStats {
    let (mut upsilon, mut positive, mut omega) = (0, 0, 0.0f64);
    for r in rows {
        upsilon += r.upsilon as usize;
        positive += r.omega_positive as usize;
        omega += r.omega_sum as f64;
    }
    VisibilityStats::of_counts(upsilon, positive, omega)
}

/// The host's share of a capped selection, from each source's rows (`rows`: source-major, `h`
/// a source): each row's first entry (source k's from `k · slot`), each row's first candidate
/// rank, and a bitmask of the drawn ranks (`words` a source).
pub(super) struct Drawn {
    pub row_starts: Vec<u32>,
    pub cand_starts: Vec<u32>,
    pub masks: Vec<u32>,
}

pub(super) fn draw(rows: &[VisRow], h: usize, (slot, words): (usize, usize), config: &PhotometricConfig) -> Drawn {
    let sources = rows.len() / h.max(1);
    let mut d = Drawn { row_starts: Vec::with_capacity(sources * (h + 1)), cand_starts: Vec::with_capacity(rows.len()), masks: vec![0; sources * words] };
    for (k, rows) in rows.chunks_exact(h.max(1)).enumerate() {
        let mut first = 0u32;
        for r in rows {
            d.cand_starts.push(first);
            first += r.candidates;
        }
        let cand = &d.cand_starts[k * h..];
        let mask = &mut d.masks[k * words..(k + 1) * words];
        let mut taken: Vec<u32> = rows.iter().map(|r| r.candidates).collect();
        match drawn_candidates(first as usize, config, k) {
            Some(drawn) => {
                taken.fill(0);
                for c in drawn {
                    mask[c / 32] |= 1 << (c % 32);
                    // The row holding rank c: the last whose first rank is ≤ c.
                    taken[cand.partition_point(|&s| s as usize <= c) - 1] += 1;
                }
            }
            None => (0..first as usize).for_each(|c| mask[c / 32] |= 1 << (c % 32)),
        }
        let mut at = (k * slot) as u32;
        for t in taken {
            d.row_starts.push(at);
            at += t;
        }
        d.row_starts.push(at);
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_match_their_wgsl_layout() {
        for (structs, src) in [(&vis_structs()[..], visibility_kernel_source()), (&select_structs()[..], selection_kernel_source())] {
            gs_gpu::check_layouts(structs, &src).unwrap();
            gs_gpu::validate_kernel(&src).unwrap_or_else(|e| panic!("{e}"));
        }
        assert_eq!([gs_gpu::bytes_of::<VisPair>(1), gs_gpu::bytes_of::<VisTexel>(1), gs_gpu::bytes_of::<VisRow>(1)], [128, 8, 16]);
    }

    #[test]
    fn a_capped_draw_is_the_hosts_draw() {
        // Two sources of three rows: 5 and 2 candidates; a cap of 3 draws source 0 only.
        let row = |candidates| VisRow { candidates, ..Default::default() };
        let rows = [row(2), row(0), row(3), row(1), row(1), row(0)];
        let config = PhotometricConfig { max_pixels_per_source: Some(3), seed: 7, ..Default::default() };
        let d = draw(&rows, 3, (3, 1), &config);
        assert_eq!(d.cand_starts, vec![0, 2, 2, 0, 1, 2]);
        let drawn = drawn_candidates(5, &config, 0).unwrap();
        let want: u32 = drawn.iter().map(|c| 1u32 << c).sum();
        assert_eq!(d.masks, vec![want, 0b11]);
        let in_first = drawn.iter().filter(|&&c| c < 2).count() as u32;
        assert_eq!(d.row_starts, vec![0, in_first, in_first, 3, 3, 4, 5, 5]);
        assert_eq!(counted(&rows[..3], &config).n_sampled, 3);
        assert_eq!(counted(&rows[3..], &config).n_sampled, 2);
    }
}
