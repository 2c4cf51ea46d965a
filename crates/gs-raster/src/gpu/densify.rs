//! Density control on the resident model (docs/architecture.md §GPU): clone, split and prune
//! without the model leaving the device, the twin of gs-train's `densify_and_prune`.
//!
//! Masks and gs-gpu's scan and sort do the host's list work: each Gaussian's candidacy
//! (densify/classify.wgsl), the AbsGS limit (a scan), the budget's choice of the best scores
//! (a stable radix sort, ties by index), the born rows' parents (scans of the clone and split
//! flags), the prune, and a scatter of every surviving row into a second set of buffers, which
//! then become the model's. The born rows' positions are the host's: it reads back their
//! parents' records and samples each position with its own rule and random stream, so the
//! model is the one the host would make. The host reads back counts twice and the parents'
//! records (44 bytes a born row) once, and uploads 12 bytes a born row.

use super::kernels::{PARAM_MATH, ParamRecord, ShCoeff};
use super::resident::StatRecord;
use super::WgpuRasterizer;
use crate::{BornParent, DensifyCounts, DensifyRule, RasterError, Result};
use gs_core::sh::coeffs_for_degree;
use gs_core::Gaussians;
use gs_gpu::{Binding, BufId, BufferPool, Dispatcher, Encoder, GeneratedStruct, GpuContext, Kernel, PassUniform, bytes_of, grid};

gs_gpu::wgsl_struct! {
    /// The constants of one densification (binding 0 of densify/*.wgsl, WGSL `struct
    /// DensifyRule`): [`DensifyRule`] for a model of `n` Gaussians.
    pub(crate) struct DensifyUniform as "DensifyRule" {
        /// Gaussians before the step.
        n: u32,
        /// SH coefficients per Gaussian on the device.
        nc: u32,
        /// SH coefficients per Gaussian after a degree rise (densify/sh_widen.wgsl).
        nc_next: u32,
        /// How many candidates the budget lets grow.
        room: u32,
        max_abs_splits: u32,
        prune_big: u32,
        grad_threshold: f32,
        abs_grad_threshold: f32,
        small_limit: f32,
        max_screen_radius: f32,
        min_opacity: f32,
        max_world: f32,
        /// ln of the split divisor, taken off a split child's log-scales.
        shrink: f32,
        /// The opacity reset: opacities above this level take `reset_logit` (densify/reset.wgsl).
        reset_level: f32,
        reset_logit: f32,
    }
}

/// Entry point, own source and storage bindings of each kernel.
fn specs() -> Vec<(&'static str, &'static str, Vec<Binding<'static>>)> {
    use Binding as B;
    let (par, sh, u) = ("array<ParamRecord>", "array<ShCoeff>", "array<u32>");
    vec![
        (
            "densify_classify",
            include_str!("densify/classify.wgsl"),
            vec![B::read("params", par), B::read("stats", "array<StatRecord>"), B::write("classes", u), B::write("abs_flags", u), B::write("keys", u)],
        ),
        (
            "densify_candidates",
            include_str!("densify/candidates.wgsl"),
            vec![
                B::read("classes", u),
                B::read("abs_flags", u),
                B::read("chosen", u),
                B::write("keys", u),
                B::write("vals", u),
                B::write("clone_flags", u),
                B::write("split_flags", u),
            ],
        ),
        ("densify_choose", include_str!("densify/choose.wgsl"), vec![B::read("sorted", u), B::write("chosen", u)]),
        (
            "densify_parents",
            include_str!("densify/parents.wgsl"),
            vec![B::read("params", par), B::read("clone_ranks", u), B::read("split_ranks", u), B::write("parents", u), B::write("born", par)],
        ),
        (
            "densify_born",
            include_str!("densify/born.wgsl"),
            vec![B::read("means", "array<f32>"), B::read("clone_ranks", u), B::read("split_ranks", u), B::write("born", par), B::write("keep", u)],
        ),
        (
            "densify_keep",
            include_str!("densify/keep.wgsl"),
            vec![B::read("params", par), B::read("stats", "array<StatRecord>"), B::read("split_ranks", u), B::write("keep", u)],
        ),
        (
            "densify_scatter",
            include_str!("densify/scatter.wgsl"),
            vec![
                B::read("params", par),
                B::read("m_params", par),
                B::read("v_params", par),
                B::read("born", par),
                B::read("dest", u),
                B::write("next_params", par),
                B::write("next_m", par),
                B::write("next_v", par),
            ],
        ),
        (
            "densify_scatter_sh",
            include_str!("densify/scatter_sh.wgsl"),
            vec![
                B::read("sh", sh),
                B::read("m_sh", sh),
                B::read("v_sh", sh),
                B::read("parents", u),
                B::read("dest", u),
                B::write("next_sh", sh),
                B::write("next_m_sh", sh),
                B::write("next_v_sh", sh),
            ],
        ),
        (
            "densify_scatter_stats",
            include_str!("densify/scatter_stats.wgsl"),
            vec![B::read("stats", "array<StatRecord>"), B::read("dest", u), B::write("next_stats", "array<StatRecord>")],
        ),
        (
            "sh_widen",
            include_str!("densify/sh_widen.wgsl"),
            vec![B::read("sh", sh), B::read("m_sh", sh), B::read("v_sh", sh), B::write("next_sh", sh), B::write("next_m_sh", sh), B::write("next_v_sh", sh)],
        ),
        ("densify_count_views", include_str!("densify/views.wgsl"), vec![B::read("observed", u), B::write("views", u), B::write("dest", u)]),
        ("densify_observed_keep", include_str!("densify/views.wgsl"), vec![B::read("observed", u), B::write("views", u), B::write("dest", u)]),
        ("densify_mark_capsules", include_str!("densify/region.wgsl"), region_bindings()),
        ("densify_unsure_list", include_str!("densify/region.wgsl"), region_bindings()),
        ("densify_settle_marks", include_str!("densify/region.wgsl"), region_bindings()),
        ("densify_outside_keep", include_str!("densify/region.wgsl"), region_bindings()),
        (
            "densify_reset",
            include_str!("densify/reset.wgsl"),
            vec![B::write("params", par), B::write("m_params", par), B::write("v_params", par)],
        ),
    ]
}

/// The storage bindings of densify/region.wgsl (every entry point declares them all).
fn region_bindings() -> Vec<Binding<'static>> {
    use Binding as B;
    let u = "array<u32>";
    vec![
        B::read("params", "array<ParamRecord>"),
        B::read("capsules", "array<CapsuleRecord>"),
        B::write("marks", u),
        B::write("ranks", u),
        B::write("unsure", "array<UnsurePoint>"),
        B::read("settled", u),
        B::write("dest", u),
    ]
}

/// The structs the kernels declare.
fn structs() -> [GeneratedStruct; 6] {
    use GeneratedStruct as G;
    [G::of::<DensifyUniform>(), G::of::<ParamRecord>(), G::of::<ShCoeff>(), G::of::<StatRecord>(), G::of::<CapsuleRecord>(), G::of::<UnsurePoint>()]
}

const COMMON: &str = include_str!("densify/common.wgsl");

mod region;
mod retain;
mod views;

use region::{CapsuleRecord, UnsurePoint};
mod widen;

/// The kernels, their dispatcher and buffers: scratch in the rasterizer's pool, the next
/// model set in the model's own pool (swapped with the model's after a step).
pub(super) struct Densify {
    disp: Dispatcher,
    kernels: Vec<(&'static str, Kernel)>,
    classes: BufId,
    abs_flags: BufId,
    chosen: BufId,
    clone_ranks: BufId,
    split_ranks: BufId,
    parents: BufId,
    means: BufId,
    born: BufId,
    dest: BufId,
    /// params, m_params, v_params, sh, m_sh, v_sh of the next model.
    next: [BufId; 6],
    /// The next model's statistics (a retain keeps them, gpu/densify/retain.rs).
    next_stats: BufId,
    /// Each Gaussian's count of training views that observed it (gpu/densify/views.rs).
    views: BufId,
    /// The model size the view counts are of, until the model changes.
    counted: Option<usize>,
    /// The capture path's capsules, each Gaussian's mark against them (in the model's pool,
    /// like `views`), the scan of the unsure marks, the unsure rows' list and the host's list
    /// of those inside (gpu/densify/region.rs).
    capsules: BufId,
    marks: BufId,
    ranks: BufId,
    unsure: BufId,
    settled: BufId,
    /// The model size the marks are of, until the model changes.
    marked: Option<usize>,
}

impl Densify {
    pub(super) fn new(ctx: &GpuContext, pool: &mut BufferPool, model_pool: &mut BufferPool) -> Result<Self> {
        let decls = gs_gpu::declarations(&structs());
        let kernels = specs()
            .into_iter()
            .map(|(entry, own, bindings)| Ok((entry, Kernel::new(ctx, entry, &[&decls, COMMON, PARAM_MATH, own], &bindings)?)))
            .collect::<Result<Vec<_>>>()?;
        let mut b = |l| pool.add_storage(l);
        let (classes, abs_flags, chosen, clone_ranks) = (b("densify_classes"), b("densify_abs"), b("densify_chosen"), b("densify_clone_ranks"));
        let (split_ranks, parents, means, born, dest) = (b("densify_split_ranks"), b("densify_parents"), b("densify_means"), b("densify_born"), b("densify_dest"));
        let next = ["next_params", "next_m_params", "next_v_params", "next_sh", "next_m_sh", "next_v_sh"].map(|l| model_pool.add_storage(l));
        let next_stats = model_pool.add_storage("next_stats");
        // In the model's pool, which keeps its buffers while the model is resident: the counts
        // outlive the renders between which they are made.
        let views = model_pool.add_storage("densify_views");
        let marks = model_pool.add_storage("densify_marks");
        let (capsules, ranks, unsure, settled) = (b("densify_capsules"), b("densify_unsure_ranks"), b("densify_unsure"), b("densify_settled"));
        let disp = Dispatcher::new(ctx, std::mem::size_of::<DensifyUniform>() as u64);
        Ok(Self {
            disp,
            kernels,
            classes,
            abs_flags,
            chosen,
            clone_ranks,
            split_ranks,
            parents,
            means,
            born,
            dest,
            next,
            next_stats,
            views,
            counted: None,
            capsules,
            marks,
            ranks,
            unsure,
            settled,
            marked: None,
        })
    }

    /// Records the copy of the clone and split totals (the scans' last elements, of `n`
    /// Gaussians) to the start of `staging`.
    fn copy_totals(&self, enc: &mut Encoder, pool: &BufferPool, n: u64, staging: &gs_gpu::wgpu::Buffer) {
        enc.encoder.copy_buffer_to_buffer(pool.buffer(self.clone_ranks), n * 4, staging, 0, 4);
        enc.encoder.copy_buffer_to_buffer(pool.buffer(self.split_ranks), n * 4, staging, 4, 4);
    }

    /// Grows the next model set (in the model's `pool`) to hold `rows` Gaussians of `nc` SH
    /// coefficients each: records and moments, SH and their moments.
    fn reserve_next(&self, pool: &mut BufferPool, rows: u64, nc: u64) {
        for (k, id) in self.next.iter().enumerate() {
            let row = if k < 3 { bytes_of::<ParamRecord>(1) } else { nc.max(1) * bytes_of::<ShCoeff>(1) };
            pool.ensure(*id, rows.max(1) * row);
        }
    }

    fn kernel(&self, entry: &str) -> &Kernel {
        &self.kernels.iter().find(|(e, _)| *e == entry).expect("a kernel of specs()").1
    }
}

/// What the first pass found: candidates before the budget.
struct Candidates {
    clones: u32,
    splits: u32,
}

impl WgpuRasterizer {
    /// Clone, split and prune the resident model (of `g`'s size and degree; `g` itself is not
    /// read) by `rule`. `sample` gives each born row's position from its parent, called in row
    /// order (clones in index order, then two children per split parent), as the host's rule
    /// calls its own: the host's random stream stays the one source of positions. The
    /// statistics start again at zero. Returns the counts, or `None`, with the model
    /// unchanged, where the step would leave no Gaussian (the host keeps the most opaque one)
    /// or the model's buffers do not fit one storage binding each.
    pub fn densify_resident(&mut self, g: &Gaussians, rule: &DensifyRule, sample: &mut dyn FnMut(&BornParent) -> [f32; 3]) -> Result<Option<DensifyCounts>> {
        let r = self.resident_to_change(g, "density control")?;
        let nc = coeffs_for_degree(r.sh_degree) as u64;
        // The rows at most doubled (every Gaussian split): every set must fit one binding.
        if !self.rows_fit(3 * r.n as u64, nc) {
            return Ok(None);
        }
        self.make_densify()?;
        self.scoped(|s| s.densify_scoped(rule, sample, r.n as u32, nc as u32))
    }

    /// The resident model's size, checked to be `g`'s: the model that `what` will change on
    /// the device (the last render's state is then no longer the model's).
    fn resident_to_change(&mut self, g: &Gaussians, what: &str) -> Result<super::resident::Residency> {
        let Some(r) = self.model.residency() else {
            return Err(RasterError::Gpu(format!("{what} on the device needs a resident model")));
        };
        if !self.model.holds(g) {
            return Err(r.refuses(g, &format!("{what} was given"), ""));
        }
        self.frame = None;
        if let Some(d) = self.densify.as_mut() {
            // The trim's view counts and the path's marks are of the model before the change.
            (d.counted, d.marked) = (None, None);
        }
        Ok(r)
    }

    /// Whether a model set of `rows` Gaussians of `nc` SH coefficients fits one storage
    /// binding a buffer (records and moments; SH and their moments; the statistics, smaller
    /// than a record, then fit too).
    fn rows_fit(&self, rows: u64, nc: u64) -> bool {
        const { assert!(std::mem::size_of::<StatRecord>() <= std::mem::size_of::<ParamRecord>()) };
        let max = self.ctx.max_storage_binding();
        rows * nc.max(1) * bytes_of::<ShCoeff>(1) <= max && rows * bytes_of::<ParamRecord>(1) <= max
    }

    /// Compiles the density-control kernels and adds their buffers, the first time.
    fn make_densify(&mut self) -> Result<()> {
        if self.densify.is_none() {
            self.densify = Some(Densify::new(&self.ctx, &mut self.pool, &mut self.model.pool)?);
        }
        Ok(())
    }

    /// The opacity reset on the resident model (of `g`'s size and degree): every opacity
    /// above `level` takes the logit `logit`, and the opacity moments start again at zero, the
    /// twin of gs-train's `reset_opacity`.
    pub fn reset_opacity_resident(&mut self, g: &Gaussians, level: f32, logit: f32) -> Result<()> {
        let r = self.resident_to_change(g, "the opacity reset")?;
        self.check_binding("the opacity reset", bytes_of::<ParamRecord>(r.n))?;
        self.make_densify()?;
        self.scoped(|s| {
            let (d, m) = (s.densify.as_ref().expect("made above"), &s.model);
            d.disp.write_frame(&DensifyUniform { n: r.n as u32, reset_level: level, reset_logit: logit, ..Default::default() });
            let mut enc = d.disp.encoder();
            let binds = [m.pool.whole(m.params), m.pool.whole(m.m_params), m.pool.whole(m.v_params)];
            d.disp.dispatch_1d(&mut enc, d.kernel("densify_reset"), &binds, PassUniform { n: r.n as u32, ..Default::default() })?;
            d.disp.submit(enc);
            Ok(())
        })
    }

    fn densify_scoped(&mut self, rule: &DensifyRule, sample: &mut dyn FnMut(&BornParent) -> [f32; 3], n: u32, nc: u32) -> Result<Option<DensifyCounts>> {
        let room = rule.room.min(u32::MAX as usize) as u32;
        let uniform = DensifyUniform {
            n,
            nc,
            room,
            max_abs_splits: rule.max_abs_splits.min(u32::MAX as usize) as u32,
            prune_big: rule.prune_big as u32,
            grad_threshold: rule.grad_threshold,
            abs_grad_threshold: rule.abs_grad_threshold,
            small_limit: rule.small_limit,
            max_screen_radius: rule.max_screen_radius,
            min_opacity: rule.min_opacity,
            max_world: rule.max_world,
            shrink: rule.split_divisor.ln(),
            ..Default::default()
        };
        let found = self.find_candidates(&uniform)?;
        let over = found.clones as u64 + found.splits as u64 > room as u64;
        if over {
            self.choose_best(n)?;
        }
        // Born rows at most: every candidate, or under the budget `room` of them, as many
        // splits as may be among them.
        let born_max = match over {
            false => found.clones + 2 * found.splits,
            true => room + found.splits.min(room),
        };
        let parents = self.born_parents(&uniform, born_max)?;
        let means: Vec<f32> = parents.iter().flat_map(sample).collect();
        let counts = self.grow_and_prune(&uniform, born_max, &means)?;
        let (clones, splits, kept) = (counts[0] as usize, counts[1] as usize, counts[2] as usize);
        if kept == 0 {
            return Ok(None);
        }
        self.swap_in(kept);
        let born = clones + 2 * splits;
        Ok(Some(DensifyCounts { candidates: (found.clones + found.splits) as usize, cloned: clones, split: splits, removed: n as usize + born - kept, len: kept }))
    }

    /// Classifies every Gaussian, applies the AbsGS limit and counts the candidates; leaves
    /// the sort keys (scores) and values (indices) in `keys_a` / `vals_a`.
    fn find_candidates(&mut self, uniform: &DensifyUniform) -> Result<Candidates> {
        let n = uniform.n as u64;
        let d = self.densify.as_ref().expect("made above");
        let (p, m) = (&mut self.pool, &self.model);
        for id in [d.classes, d.abs_flags, d.chosen] {
            p.ensure(id, 4 * n.max(1));
        }
        for id in [d.clone_ranks, d.split_ranks] {
            p.ensure(id, 4 * (n + 1));
        }
        for id in [self.bufs.keys_a, self.bufs.vals_a, self.bufs.keys_b, self.bufs.vals_b] {
            p.ensure(id, 4 * n.max(1));
        }
        self.sort.reserve(p, n + 1);
        self.sort.prefix_scan().reserve(p, n + 1);
        p.ensure(self.bufs.staging, 16);
        d.disp.write_frame(uniform);
        let (p, b) = (&self.pool, &self.bufs);
        let mut enc = d.disp.encoder();
        let pass = PassUniform { n: uniform.n, ..Default::default() };
        let binds = [m.pool.whole(m.params), m.pool.whole(m.stats), p.whole(d.classes), p.whole(d.abs_flags), p.whole(b.keys_a)];
        d.disp.dispatch_1d(&mut enc, d.kernel("densify_classify"), &binds, pass)?;
        self.sort.prefix_scan().encode(&d.disp, &mut enc, p, p.whole(d.abs_flags), uniform.n)?;
        self.flags(&mut enc, uniform.n, 0)?;
        let staging = p.buffer(b.staging);
        d.copy_totals(&mut enc, p, n, staging);
        d.disp.submit(enc);
        let [clones, splits] = self.read_counts::<2>()?;
        Ok(Candidates { clones, splits })
    }

    /// Records the candidates kernel (`mode` 1: only the chosen) and the scans of its flags.
    fn flags(&self, enc: &mut Encoder, n: u32, mode: u32) -> Result<()> {
        let (d, p, b) = (self.densify.as_ref().expect("made"), &self.pool, &self.bufs);
        let pass = PassUniform { n, mode, ..Default::default() };
        let binds = [p.whole(d.classes), p.whole(d.abs_flags), p.whole(d.chosen), p.whole(b.keys_a), p.whole(b.vals_a), p.whole(d.clone_ranks), p.whole(d.split_ranks)];
        d.disp.make_room(enc, 64);
        d.disp.dispatch(enc, d.kernel("densify_candidates"), &binds, pass, grid((n + 1).div_ceil(256)))?;
        self.sort.prefix_scan().encode(&d.disp, enc, p, p.whole(d.clone_ranks), n + 1)?;
        Ok(self.sort.prefix_scan().encode(&d.disp, enc, p, p.whole(d.split_ranks), n + 1)?)
    }

    /// The budget's choice: sorts the candidates by score and keeps the best `room`.
    fn choose_best(&mut self, n: u32) -> Result<()> {
        let (d, p, b) = (self.densify.as_ref().expect("made"), &self.pool, &self.bufs);
        let mut enc = d.disp.encoder();
        let pairs = [(p.whole(b.keys_a), p.whole(b.vals_a)), (p.whole(b.keys_b), p.whole(b.vals_b))];
        let in_b = self.sort.encode(&d.disp, &mut enc, p, pairs, n, 32)?;
        let sorted = if in_b { p.whole(b.vals_b) } else { p.whole(b.vals_a) };
        d.disp.make_room(&mut enc, 2);
        let pass = PassUniform { n, ..Default::default() };
        d.disp.dispatch_1d(&mut enc, d.kernel("densify_choose"), &[sorted, p.whole(d.chosen)], pass)?;
        self.flags(&mut enc, n, 1)?;
        d.disp.submit(enc);
        Ok(())
    }

    /// The born rows' parents, in row order: their records, read back for the host's sampler.
    fn born_parents(&mut self, uniform: &DensifyUniform, born_max: u32) -> Result<Vec<BornParent>> {
        let n = uniform.n as u64;
        let d = self.densify.as_ref().expect("made");
        let p = &mut self.pool;
        let record = bytes_of::<ParamRecord>(1);
        p.ensure(d.parents, 4 * (born_max as u64).max(1));
        p.ensure(d.born, record * (born_max as u64).max(1));
        // The counts and records now; grow_and_prune's three counts later.
        p.ensure(self.bufs.staging, (8 + record * born_max as u64).max(12));
        let (p, b, m) = (&self.pool, &self.bufs, &self.model);
        let mut enc = d.disp.encoder();
        let pass = PassUniform { n: uniform.n, ..Default::default() };
        let binds = [m.pool.whole(m.params), p.whole(d.clone_ranks), p.whole(d.split_ranks), p.whole(d.parents), p.whole(d.born)];
        d.disp.dispatch_1d(&mut enc, d.kernel("densify_parents"), &binds, pass)?;
        let staging = p.buffer(b.staging);
        d.copy_totals(&mut enc, p, n, staging);
        if born_max > 0 {
            enc.encoder.copy_buffer_to_buffer(p.buffer(d.born), 0, staging, 8, record * born_max as u64);
        }
        d.disp.submit(enc);
        let bytes = 8 + record * born_max as u64;
        self.ctx.read_mapped(staging, bytes, |bytes| {
            let counts: Vec<u32> = bytemuck::pod_collect_to_vec(&bytes[..8]);
            let born = (counts[0] as usize + 2 * counts[1] as usize).min(born_max as usize);
            let records: Vec<ParamRecord> = bytemuck::pod_collect_to_vec(&bytes[8..]);
            records[..born].iter().map(|r| BornParent { mean: r.mean, log_scale: r.log_scale, rotation: [r.rot_w, r.rot_x, r.rot_y, r.rot_z] }).collect()
        })
        .map_err(Into::into)
    }

    /// The born rows at the host's `means`, the prune and the scatter into the next buffers;
    /// reads back the clones, splits and surviving rows.
    fn grow_and_prune(&mut self, uniform: &DensifyUniform, born_max: u32, means: &[f32]) -> Result<[u32; 3]> {
        let (n, nc) = (uniform.n as u64, uniform.nc as u64);
        let rows = n + born_max as u64;
        let d = self.densify.as_ref().expect("made");
        let p = &mut self.pool;
        p.ensure(d.dest, 4 * (rows + 1));
        self.sort.prefix_scan().reserve(p, rows + 1);
        super::upload_with(&self.ctx, p, d.means, means.len().max(1), |out: &mut [f32]| out[..means.len()].copy_from_slice(means));
        d.reserve_next(&mut self.model.pool, rows, nc);
        let (p, b, m) = (&self.pool, &self.bufs, &self.model);
        let mut enc = d.disp.encoder();
        let whole = |id| p.whole(id);
        let pass = PassUniform { n: uniform.n, ..Default::default() };
        let binds = [whole(d.means), whole(d.clone_ranks), whole(d.split_ranks), whole(d.born), whole(d.dest)];
        let born_pass = PassUniform { n: born_max, ..Default::default() };
        d.disp.dispatch(&mut enc, d.kernel("densify_born"), &binds, born_pass, grid((born_max + 1).div_ceil(256)))?;
        let binds = [m.pool.whole(m.params), m.pool.whole(m.stats), whole(d.split_ranks), whole(d.dest)];
        d.disp.dispatch_1d(&mut enc, d.kernel("densify_keep"), &binds, pass)?;
        self.sort.prefix_scan().encode(&d.disp, &mut enc, p, whole(d.dest), rows as u32 + 1)?;
        d.disp.make_room(&mut enc, 2);
        let all = PassUniform { n: rows as u32, ..Default::default() };
        let mp = |id| m.pool.whole(id);
        let binds = [mp(m.params), mp(m.m_params), mp(m.v_params), whole(d.born), whole(d.dest), mp(d.next[0]), mp(d.next[1]), mp(d.next[2])];
        d.disp.dispatch_1d(&mut enc, d.kernel("densify_scatter"), &binds, all)?;
        if nc > 0 {
            let binds = [mp(m.sh), mp(m.m_sh), mp(m.v_sh), whole(d.parents), whole(d.dest), mp(d.next[3]), mp(d.next[4]), mp(d.next[5])];
            d.disp.dispatch_1d(&mut enc, d.kernel("densify_scatter_sh"), &binds, all)?;
        }
        let staging = p.buffer(b.staging);
        d.copy_totals(&mut enc, p, n, staging);
        enc.encoder.copy_buffer_to_buffer(p.buffer(d.dest), rows * 4, staging, 8, 4);
        d.disp.submit(enc);
        self.read_counts::<3>()
    }

    /// `K` u32 counts from the start of the staging buffer.
    fn read_counts<const K: usize>(&self) -> Result<[u32; K]> {
        let staging = self.pool.buffer(self.bufs.staging);
        let words = self.ctx.read_mapped(staging, 4 * K as u64, bytemuck::pod_collect_to_vec::<u8, u32>)?;
        Ok(std::array::from_fn(|k| words[k]))
    }

    /// Makes the next buffers the model's, `kept` Gaussians with statistics at zero.
    fn swap_in(&mut self, kept: usize) {
        let d = self.densify.as_mut().expect("made");
        self.model.swap_rows(&mut d.next, kept);
        let m = &mut self.model;
        m.pool.ensure(m.stats, bytes_of::<StatRecord>(kept));
        let mut enc = d.disp.encoder();
        enc.encoder.clear_buffer(m.pool.buffer(m.stats), 0, Some(bytes_of::<StatRecord>(kept)));
        d.disp.submit(enc);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gs_gpu::{check_layout, kernel_source};

    /// Every densify kernel parses and validates, with the host's layouts.
    #[test]
    fn the_densify_kernels_parse_with_the_hosts_layouts() {
        let decls = gs_gpu::declarations(&structs());
        for (entry, own, bindings) in specs() {
            assert!(bindings.len() <= 8, "{entry}: more storage bindings than WebGPU's default limit");
            let src = kernel_source(&[&decls, COMMON, PARAM_MATH, own], &bindings);
            check_layout::<PassUniform>(&src).unwrap_or_else(|e| panic!("{entry}: {e}"));
            gs_gpu::check_layouts(&structs(), &src).unwrap_or_else(|e| panic!("{entry}: {e}"));
            gs_gpu::validate_kernel(&src).unwrap_or_else(|e| panic!("{entry}: {e}"));
        }
    }
}
