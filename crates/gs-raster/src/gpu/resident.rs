//! The model on the device: the parameter records and SH the kernels read, and, while a
//! training run keeps them resident, the Adam moments, the densification statistics and the
//! device twins of [`gs_core::Adam`] (adam.wgsl) and [`gs_core::DensifyStats::accumulate`]
//! (densify_stats.wgsl; docs/architecture.md §GPU).
//!
//! Without residency every render uploads the host's Gaussians, as before. A resident model
//! is uploaded once ([`WgpuRasterizer::make_resident`]); from then on renders bind it as it
//! is, and [`WgpuRasterizer::backward_and_step`] runs the backward, the view's statistics and
//! the Adam step on the device and reads back only a divergence flag (4 bytes). The host's
//! copy falls behind: [`WgpuRasterizer::read_resident`] brings the parameters (and, when
//! asked, the moments and statistics) back at the caller's cadence. Whoever changes the
//! host's Gaussians, moments or statistics ends the residency first
//! ([`WgpuRasterizer::release_resident`]); a resident render of Gaussians of another size or
//! SH degree is an error, never a silent mix.

use super::adam_kernels::{ADAM, AdamUniform, ExtraGrad, adam_specs, adam_structs};
use super::kernels::{ParamGrad, ParamRecord, ShCoeff};
use super::resident_rows::{Moment, check_stats, fill_param_moments, fill_sh_moments, groups_of, store_moments, store_parameters, store_stats};
use super::{GpuTimings, WgpuRasterizer, chunks, pod_vec, upload_with};
use crate::{DeviceStep, OutputGradients, RasterConfig, RasterError, RenderOutput, Result, StepExtras};
use gs_core::sh::coeffs_for_degree;
use gs_core::{Adam, Camera, DensifyStats, Gaussians, GroupStep, Param};
use gs_gpu::{BufId, BufferPool, Dispatcher, Encoder, GpuContext, Kernel, PassUniform, PendingRead, ShrinkPolicy, bytes_of};

pub(crate) use super::adam_kernels::StatRecord;
use rayon::prelude::*;
use std::time::Instant;

/// The size of a resident model: renders of other Gaussians are refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Residency {
    pub(super) n: usize,
    pub(super) sh_degree: u32,
}

/// A resident step started by [`WgpuRasterizer::start_step`] whose divergence flag has not
/// been read; dropped unread, the flag is given up.
#[derive(Debug)]
pub struct PendingStep {
    read: PendingRead,
    /// When the backward was submitted (its device time counts from here).
    submitted: Instant,
}

/// The model's buffers (their own pool: a resident model must never be reallocated by the
/// shrink policy of a render's frame), the Adam kernels and their dispatcher.
pub(super) struct Model {
    pub(super) pool: BufferPool,
    pub(super) params: BufId,
    pub(super) sh: BufId,
    pub(super) m_params: BufId,
    pub(super) v_params: BufId,
    pub(super) m_sh: BufId,
    pub(super) v_sh: BufId,
    extra: BufId,
    flags: BufId,
    /// The divergence flag's own readback buffer: a step's flag may be read after the next
    /// render, which uses the rasterizer's staging buffer.
    flag_staging: BufId,
    pub(super) stats: BufId,
    resident: Option<Residency>,
    disp: Dispatcher,
    adam_params: Kernel,
    adam_sh: Kernel,
    densify_stats: Kernel,
}

impl Model {
    pub(super) fn new(ctx: &GpuContext) -> gs_gpu::Result<Self> {
        let mut pool = BufferPool::new(ctx, ShrinkPolicy::default());
        let mut b = |l| pool.add_storage(l);
        let (params, sh, m_params, v_params) = (b("params"), b("sh"), b("m_params"), b("v_params"));
        let (m_sh, v_sh, extra, flags) = (b("m_sh"), b("v_sh"), b("extra_grads"), b("adam_flags"));
        let stats = b("densify_stats");
        let flag_staging = pool.add_staging("adam flag readback");
        let decls = gs_gpu::declarations(&adam_structs());
        let specs = adam_specs();
        // Each kernel by its entry point's name, so that the list's order cannot mix them up.
        let kernel = |name: &str| {
            let (entry, own, bindings) = specs.iter().find(|s| s.0 == name).expect("a kernel of adam_specs");
            Kernel::new(ctx, entry, &[&decls, ADAM, own], bindings)
        };
        Ok(Self {
            adam_params: kernel("adam_params")?,
            adam_sh: kernel("adam_sh")?,
            densify_stats: kernel("densify_stats")?,
            disp: Dispatcher::new(ctx, std::mem::size_of::<AdamUniform>() as u64),
            pool,
            params,
            sh,
            m_params,
            v_params,
            m_sh,
            v_sh,
            extra,
            flags,
            flag_staging,
            stats,
            resident: None,
        })
    }

    /// Makes the parameter buffers hold `g` for a render: uploaded when not resident (a new
    /// pool frame first), bound as they are when resident and of `g`'s size and degree.
    pub(super) fn prepare(&mut self, ctx: &GpuContext, g: &Gaussians) -> Result<()> {
        match self.resident {
            _ if self.holds(g) => Ok(()),
            Some(r) => Err(r.refuses(g, "the render was given", ": release the residency after changing the model")),
            None => {
                self.pool.begin_frame();
                self.upload(ctx, g);
                Ok(())
            }
        }
    }

    /// The size of the resident model, if one is resident.
    pub(super) fn residency(&self) -> Option<Residency> {
        self.resident
    }

    /// Makes `next` (params, m_params, v_params, sh, m_sh, v_sh, as densify/scatter*.wgsl
    /// filled them) the model's buffers, of `n` Gaussians, and the model's old buffers the
    /// next set (gpu/densify.rs).
    pub(super) fn swap_rows(&mut self, next: &mut [BufId; 6], n: usize) {
        let mine = [&mut self.params, &mut self.m_params, &mut self.v_params, &mut self.sh, &mut self.m_sh, &mut self.v_sh];
        for (a, b) in mine.into_iter().zip(next.iter_mut()) {
            std::mem::swap(a, b);
        }
        if let Some(r) = &mut self.resident {
            r.n = n;
        }
    }

    /// Makes `next` (sh, m_sh, v_sh at SH degree `degree`, as densify/sh_widen.wgsl filled
    /// them) the model's SH buffers, and the model's old ones the next set.
    pub(super) fn swap_sh(&mut self, next: &mut [BufId], degree: u32) {
        for (a, b) in [&mut self.sh, &mut self.m_sh, &mut self.v_sh].into_iter().zip(next.iter_mut()) {
            std::mem::swap(a, b);
        }
        if let Some(r) = &mut self.resident {
            r.sh_degree = degree;
        }
    }

    /// Whether the resident model is one of `g`'s size and SH degree.
    pub(super) fn holds(&self, g: &Gaussians) -> bool {
        self.resident == Some(Residency::of(g))
    }

    /// Uploads parameters and SH (packed, only the active degree's coefficients), written in
    /// parallel straight into the queue's staging memory.
    fn upload(&mut self, ctx: &GpuContext, g: &Gaussians) {
        let n = g.len();
        let nc = coeffs_for_degree(g.sh_degree);
        upload_with(ctx, &mut self.pool, self.params, n, |out: &mut [ParamRecord]| {
            out.par_iter_mut().enumerate().for_each(|(i, r)| *r = ParamRecord::of(g, i))
        });
        upload_with(ctx, &mut self.pool, self.sh, n * nc, |out: &mut [ShCoeff]| {
            if nc > 0 {
                out.par_chunks_mut(nc).zip(&g.sh).for_each(|(r, c)| {
                    r.iter_mut().zip(c).for_each(|(r, v)| r.rgb = *v);
                })
            }
        });
    }
}

impl Residency {
    fn of(g: &Gaussians) -> Self {
        Self { n: g.len(), sh_degree: g.sh_degree }
    }

    /// The error for Gaussians `g` of another size or degree than the resident model, their
    /// count and degree framed by `before` and `after`.
    pub(super) fn refuses(self, g: &Gaussians, before: &str, after: &str) -> RasterError {
        RasterError::Gpu(format!(
            "the resident model holds {} Gaussians of SH degree {}, {before} {} of degree {}{after}",
            self.n,
            self.sh_degree,
            g.len(),
            g.sh_degree
        ))
    }
}

impl WgpuRasterizer {
    /// Keeps `g`, the moments of `adam` (one group per [`Param`], by name) and the
    /// densification statistics `stats` on the device from now on: renders bind them without
    /// an upload and [`backward_and_step`](Self::backward_and_step) steps them there.
    pub fn make_resident(&mut self, g: &Gaussians, adam: &Adam, stats: &DensifyStats) -> Result<()> {
        crate::validate::check_gaussians(g)?;
        let (n, nc) = (g.len(), coeffs_for_degree(g.sh_degree));
        let groups = groups_of(adam, n)?;
        check_stats(stats, n)?;
        let m = &mut self.model;
        m.resident = None;
        m.prepare(&self.ctx, g)?;
        // Written in parallel straight into the queue's staging memory, like the parameters.
        let moments: [(BufId, BufId, Moment); 2] = [(m.m_params, m.m_sh, |g| &g.m), (m.v_params, m.v_sh, |g| &g.v)];
        for (par, sh, pick) in moments {
            upload_with(&self.ctx, &mut m.pool, par, n, |out: &mut [ParamRecord]| fill_param_moments(out, &groups, pick));
            upload_with(&self.ctx, &mut m.pool, sh, n * nc, |out: &mut [ShCoeff]| fill_sh_moments(out, &groups, nc, pick));
        }
        upload_with(&self.ctx, &mut m.pool, m.stats, n, |out: &mut [StatRecord]| {
            out.par_iter_mut().enumerate().for_each(|(i, r)| *r = StatRecord::of(stats, i))
        });
        m.resident = Some(Residency::of(g));
        Ok(())
    }

    /// Whether a model is resident.
    pub fn is_resident(&self) -> bool {
        self.model.resident.is_some()
    }

    /// Ends the residency: the next render uploads its Gaussians again. The device's
    /// parameters, moments and statistics are dropped; read them first
    /// ([`read_resident`](Self::read_resident)) to keep them.
    pub fn release_resident(&mut self) {
        self.model.resident = None;
    }

    /// Copies the resident parameters and SH into `g` (of the resident size and degree) and,
    /// when given, the resident moments and densification statistics into `optimiser`, in
    /// one readback; the residency goes on.
    pub fn read_resident(&mut self, g: &mut Gaussians, optimiser: Option<(&mut Adam, &mut DensifyStats)>) -> Result<()> {
        self.read_resident_parts(g, true, optimiser)
    }

    /// The resident parameter records alone into `g` (means, log-scales, rotations and
    /// opacity logits; its SH coefficients stay as they are): 44 bytes a Gaussian.
    pub fn read_resident_records(&mut self, g: &mut Gaussians) -> Result<()> {
        self.read_resident_parts(g, false, None)
    }

    fn read_resident_parts(&mut self, g: &mut Gaussians, with_sh: bool, optimiser: Option<(&mut Adam, &mut DensifyStats)>) -> Result<()> {
        debug_assert!(with_sh || optimiser.is_none(), "the moments come with the SH");
        let Some(r) = self.model.resident else {
            return Err(RasterError::Gpu("no model is resident".into()));
        };
        if !self.model.holds(g) {
            return Err(r.refuses(g, "not the", " given to read it into"));
        }
        let nc = coeffs_for_degree(r.sh_degree);
        let (pb, sb) = (bytes_of::<ParamRecord>(r.n), bytes_of::<ShCoeff>(if with_sh { r.n * nc } else { 0 }));
        let m = &self.model;
        let stb = bytes_of::<StatRecord>(r.n);
        let mut order = vec![(m.params, pb), (m.sh, sb)];
        if let Some((_, stats)) = &optimiser {
            check_stats(stats, r.n)?;
            order.extend([(m.stats, stb), (m.m_params, pb), (m.v_params, pb), (m.m_sh, sb), (m.v_sh, sb)]);
        }
        let total: u64 = order.iter().map(|(_, b)| b).sum();
        self.pool.ensure(self.bufs.staging, total + 4);
        let staging = self.pool.buffer(self.bufs.staging);
        let mut enc = m.disp.encoder();
        let mut at = 0;
        for (id, bytes) in order.into_iter().filter(|(_, bytes)| *bytes > 0) {
            enc.encoder.copy_buffer_to_buffer(m.pool.buffer(id), 0, staging, at, bytes);
            at += bytes;
        }
        m.disp.submit(enc);
        self.ctx.read_mapped(staging, at, |bytes| {
            let (own, moments) = bytes.split_at((pb + sb) as usize);
            let (par, sh) = own.split_at(pb as usize);
            store_parameters(g, &pod_vec::<ParamRecord>(par), &pod_vec::<ShCoeff>(sh), nc);
            let Some((adam, stats)) = optimiser else { return Ok(()) };
            let (st, moments) = moments.split_at(stb as usize);
            store_stats(stats, &pod_vec::<StatRecord>(st));
            let (par, sh) = moments.split_at(2 * pb as usize);
            let (par, sh) = (pod_vec::<ParamRecord>(par), pod_vec::<ShCoeff>(sh));
            let ((mp, vp), (ms, vs)) = (par.split_at(r.n), sh.split_at(r.n * nc));
            store_moments(adam, mp, ms, nc, |g| &mut g.m)?;
            store_moments(adam, vp, vs, nc, |g| &mut g.v)
        })?
    }
}

impl AdamUniform {
    /// The uniform of one step: each group of `adam` counts the step ([`GroupStep`]); the
    /// statistics accumulate as `extras` say, pixel-weighted when the render counted pixels.
    fn begin_step(adam: &mut Adam, nc: usize, extras: &StepExtras<'_>, pixel_weighted: bool) -> Result<Self> {
        let cfg = adam.config;
        let mut step = |p: Param| -> Result<GroupStep> {
            Ok(adam.group_mut(p.name()).map_err(|e| RasterError::Gpu(e.to_string()))?.begin_step(&cfg))
        };
        let [means, dc, rest, opacity, scales, rot] = Param::ALL.map(&mut step);
        let (means, dc, rest, opacity, scales, rot) = (means?, dc?, rest?, opacity?, scales?, rot?);
        Ok(Self {
            nc: nc as u32,
            extra: extras.any_extra() as u32,
            accumulate: extras.accumulate.is_some() as u32,
            pixel_weighted: pixel_weighted as u32,
            radius_scale: extras.accumulate.unwrap_or(1.0),
            beta1: cfg.beta1,
            beta2: cfg.beta2,
            eps: cfg.eps,
            step_means: means.step_size,
            bc2_means: means.bc2_sqrt,
            step_sh_dc: dc.step_size,
            bc2_sh_dc: dc.bc2_sqrt,
            step_sh_rest: rest.step_size,
            bc2_sh_rest: rest.bc2_sqrt,
            step_opacity: opacity.step_size,
            bc2_opacity: opacity.bc2_sqrt,
            step_log_scales: scales.step_size,
            bc2_log_scales: scales.bc2_sqrt,
            step_rotations: rot.step_size,
            bc2_rotations: rot.bc2_sqrt,
        })
    }
}

impl WgpuRasterizer {
    /// The backward of `forward` (a render of the resident model, of `g`'s size and degree) and
    /// one Adam step of every group of `adam` on the device, the twin of [`crate::backward`]
    /// followed by [`gs_core::Adam::step_strided`] on each group (and, when `extras` ask,
    /// [`DensifyStats::accumulate`] of the view before it). The new parameters, the moments
    /// and the statistics stay on the device (`g`, the host's copy, falls behind until
    /// [`read_resident`](Self::read_resident)); `adam`'s groups count the step. A render
    /// without intersections or gradients steps with zero gradients, as the host does.
    // The backward's five inputs, the optimiser and the step's extras.
    #[allow(clippy::too_many_arguments)]
    pub fn backward_and_step(
        &mut self,
        g: &Gaussians,
        camera: &Camera,
        config: &RasterConfig,
        forward: &RenderOutput,
        grads: &OutputGradients,
        adam: &mut Adam,
        extras: StepExtras<'_>,
    ) -> Result<DeviceStep> {
        let pending = self.start_step(g, camera, config, forward, grads, adam, extras)?;
        self.finish_step(pending)
    }

    /// [`backward_and_step`](Self::backward_and_step) submitted, with the read of its
    /// divergence flag requested and not waited for: read by
    /// [`finish_step`](Self::finish_step), after later work (a render) whose wait brings it at
    /// no cost. Finish a step before starting the next.
    #[allow(clippy::too_many_arguments)]
    pub fn start_step(
        &mut self,
        g: &Gaussians,
        camera: &Camera,
        config: &RasterConfig,
        forward: &RenderOutput,
        grads: &OutputGradients,
        adam: &mut Adam,
        extras: StepExtras<'_>,
    ) -> Result<PendingStep> {
        if !self.model.holds(g) {
            return Err(RasterError::Gpu("a device step needs the model resident (make_resident) with these Gaussians".into()));
        }
        for (what, len) in [("opacity", extras.extra_opacity.map(<[f32]>::len)), ("log-scale", extras.extra_log_scales.map(<[[f32; 3]]>::len))] {
            if let Some(len) = len
                && len != g.len()
            {
                return Err(RasterError::InvalidGradients(format!("{len} extra {what} gradients for {} Gaussians", g.len())));
            }
        }
        let checked = self.checked_frame(g, camera, config, forward, grads)?;
        let t0 = Instant::now();
        let out = self.scoped(|r| {
            let nc = coeffs_for_degree(g.sh_degree);
            let enc = match checked {
                Some(checked) => r.record_backward(g, config, grads, &checked)?,
                None => r.zero_gradients(g.len(), nc),
            };
            let t1 = Instant::now();
            r.disp.submit(enc);
            let uniform = AdamUniform::begin_step(adam, nc, &extras, forward.observed.is_some())?;
            let read = r.step_on_device(g.len(), &uniform, extras)?;
            r.timings.backward = GpuTimings { upload: t1 - t0, ..GpuTimings::default() };
            Ok(PendingStep { read, submitted: t1 })
        });
        // The device's parameters moved: the last render's state is no longer theirs.
        self.frame = None;
        out
    }

    /// The outcome of a started step (waiting for the device if it has not answered). The
    /// backward's device time counts until its flag arrived.
    pub fn finish_step(&mut self, pending: PendingStep) -> Result<DeviceStep> {
        let PendingStep { read, submitted } = pending;
        let step = self.ctx.finish_read(read, |flags| DeviceStep { means_finite: u32::from_le_bytes(flags.try_into().expect("4 bytes")) == 0 })?;
        let t2 = Instant::now();
        self.timings.backward.device = t2 - submitted;
        Ok(step)
    }

    /// An encoder that zeroes the gradient buffers of `n` Gaussians with `nc` SH coefficients.
    /// The statistics read the render's radii and pixel counts where it left them: the frame
    /// was checked (and rebuilt if a later render overwrote it) first.
    fn zero_gradients(&mut self, n: usize, nc: usize) -> Encoder {
        let (pb, sb) = (bytes_of::<ParamGrad>(n), bytes_of::<ShCoeff>(n * nc));
        let (p, b) = (&mut self.pool, &self.bufs);
        p.ensure(b.gout, pb + bytes_of::<ParamGrad>(1));
        p.ensure(b.gout_sh, sb + bytes_of::<ShCoeff>(1));
        let mut enc = self.disp.encoder();
        enc.encoder.clear_buffer(self.pool.buffer(b.gout), 0, Some(pb));
        enc.encoder.clear_buffer(self.pool.buffer(b.gout_sh), 0, Some(sb));
        enc
    }

    /// Runs the statistics kernel (when the uniform says so, on the last render's radii and
    /// pixel counts) and the Adam kernels of `n` Gaussians on the gradients in `gout` /
    /// `gout_sh`, and requests the readback of the divergence flag.
    fn step_on_device(&mut self, n: usize, uniform: &AdamUniform, extras: StepExtras<'_>) -> Result<PendingRead> {
        let nc = uniform.nc as usize;
        let m = &mut self.model;
        match extras.any_extra() {
            true => upload_with(&self.ctx, &mut m.pool, m.extra, n, |out: &mut [ExtraGrad]| {
                for (i, e) in out.iter_mut().enumerate() {
                    e.opacity_logit = extras.extra_opacity.map_or(0.0, |x| x[i]);
                    e.log_scale = extras.extra_log_scales.map_or([0.0; 3], |x| x[i]);
                }
            }),
            false => m.pool.ensure(m.extra, bytes_of::<ExtraGrad>(1)),
        }
        m.pool.ensure(m.flags, 4);
        m.disp.write_frame(uniform);
        m.pool.ensure(m.flag_staging, 4);
        // The statistics read the radii and pixel counts the checked render (or
        // `zero_gradients`) left in their buffers, which hold `n` of each.
        let (m, p, b) = (&self.model, &self.pool, &self.bufs);
        let mut enc = m.disp.encoder();
        enc.encoder.clear_buffer(m.pool.buffer(m.flags), 0, Some(4));
        let (rec, shr, grad) = (bytes_of::<ParamRecord>(1), nc as u64 * bytes_of::<ShCoeff>(1), bytes_of::<ParamGrad>(1));
        let stat = bytes_of::<StatRecord>(1);
        for (bb, c) in chunks(n as u32) {
            m.disp.make_room(&mut enc, 3);
            let pass = PassUniform { n: c as u32, base: bb as u32, ..Default::default() };
            if uniform.accumulate != 0 {
                let binds = [
                    p.range(b.gout, bb * grad, c * grad),
                    p.range(b.radii, bb * 4, c * 4),
                    p.range(b.observed, bb * 4, c * 4),
                    m.pool.range(m.stats, bb * stat, c * stat),
                ];
                m.disp.dispatch_1d(&mut enc, &m.densify_stats, &binds, pass)?;
            }
            let xr = bytes_of::<ExtraGrad>(1);
            let extra = match extras.any_extra() {
                true => m.pool.range(m.extra, bb * xr, c * xr),
                false => m.pool.whole(m.extra),
            };
            let binds = [
                m.pool.range(m.params, bb * rec, c * rec),
                m.pool.range(m.m_params, bb * rec, c * rec),
                m.pool.range(m.v_params, bb * rec, c * rec),
                p.range(b.gout, bb * grad, c * grad),
                extra,
                m.pool.whole(m.flags),
            ];
            m.disp.dispatch_1d(&mut enc, &m.adam_params, &binds, pass)?;
            let binds = [
                m.pool.range(m.sh, bb * shr, c * shr),
                m.pool.range(m.m_sh, bb * shr, c * shr),
                m.pool.range(m.v_sh, bb * shr, c * shr),
                p.range(b.gout_sh, bb * shr, c * shr),
            ];
            m.disp.dispatch_1d(&mut enc, &m.adam_sh, &binds, pass)?;
        }
        let staging = m.pool.buffer(m.flag_staging);
        enc.encoder.copy_buffer_to_buffer(m.pool.buffer(m.flags), 0, staging, 0, 4);
        m.disp.submit(enc);
        Ok(self.ctx.request_read(staging, 4))
    }
}
