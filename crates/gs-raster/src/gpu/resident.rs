//! The model on the device: the parameter records and SH the kernels read, and, while a
//! training run keeps them resident, the Adam moments and the device twin of
//! [`gs_core::Adam`] (adam.wgsl; docs/architecture.md §GPU).
//!
//! Without residency every render uploads the host's Gaussians, as before. A resident model
//! is uploaded once ([`WgpuRasterizer::make_resident`]); from then on renders bind it as it
//! is, and [`WgpuRasterizer::backward_and_step`] runs the backward and the Adam step on the
//! device and reads back only a divergence flag (4 bytes) and, when asked, the screen-space
//! gradients of the densification statistics (16 bytes a Gaussian). The host's copy of the
//! parameters falls behind: [`WgpuRasterizer::read_resident`] brings the parameters (and,
//! when asked, the moments) back at the caller's cadence. Whoever changes the host's
//! Gaussians or moments ends the residency first ([`WgpuRasterizer::release_resident`]); a
//! resident render of Gaussians of another size or SH degree is an error, never a silent
//! mix.

use super::kernels::{ParamGrad, ParamRecord, ShCoeff};
use super::backward::pod_vec;
use super::{GpuTimings, WgpuRasterizer, chunks, upload_with};
use crate::{DeviceStep, OutputGradients, RasterConfig, RasterError, RenderOutput, Result, StepExtras};
use gs_core::sh::coeffs_for_degree;
use gs_core::optim::ParamGroup;
use gs_core::{Adam, Camera, Gaussians, GroupStep, Param};
use gs_gpu::{
    Binding, BufId, BufferPool, Dispatcher, Encoder, GeneratedStruct, GpuContext, Kernel,
    PassUniform, ShrinkPolicy, bytes_of,
};
use rayon::prelude::*;
use std::time::Instant;

gs_gpu::wgsl_struct! {
    /// The constants of one device Adam step (binding 0 of the Adam kernels; WGSL
    /// `struct AdamStep`): each group's bias-corrected factors ([`gs_core::GroupStep`]).
    pub(crate) struct AdamUniform as "AdamStep" {
        /// SH coefficients per Gaussian on the device (the active degree's).
        nc: u32,
        /// 1 when a loss term adds its own opacity-logit gradient (binding `extra_opacity`).
        extra_opacity: u32,
        beta1: f32,
        beta2: f32,
        eps: f32,
        step_means: f32,
        bc2_means: f32,
        step_sh_dc: f32,
        bc2_sh_dc: f32,
        step_sh_rest: f32,
        bc2_sh_rest: f32,
        step_opacity: f32,
        bc2_opacity: f32,
        step_log_scales: f32,
        bc2_log_scales: f32,
        step_rotations: f32,
        bc2_rotations: f32,
    }
}

gs_gpu::wgsl_struct! {
    /// One Gaussian's screen-space gradients as a device step reads them back (WGSL
    /// `struct ScreenStat`, written by `adam_params` from its `ParamGrad`): 16 of the
    /// record's 60 bytes, for the densification statistics.
    pub(crate) struct ScreenStat as "ScreenStat" {
        /// ∂L/∂ of the projected centre in NDC (x, y).
        mean2d: [f32; 2],
        /// Σ |∂L/∂x|, Σ |∂L/∂y| in NDC.
        mean2d_abs: [f32; 2],
    }
}

/// The size of a resident model: renders of other Gaussians are refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Residency {
    n: usize,
    sh_degree: u32,
}

/// The model's buffers (their own pool: a resident model must never be reallocated by the
/// shrink policy of a render's frame), the Adam kernels and their dispatcher.
pub(super) struct Model {
    pub(super) pool: BufferPool,
    pub(super) params: BufId,
    pub(super) sh: BufId,
    m_params: BufId,
    v_params: BufId,
    m_sh: BufId,
    v_sh: BufId,
    extra: BufId,
    flags: BufId,
    screen: BufId,
    resident: Option<Residency>,
    disp: Dispatcher,
    adam_params: Kernel,
    adam_sh: Kernel,
}

/// The structs of the Adam kernels (declarations and layout test).
fn adam_structs() -> [GeneratedStruct; 5] {
    [
        GeneratedStruct::of::<AdamUniform>(),
        GeneratedStruct::of::<ParamRecord>(),
        GeneratedStruct::of::<ShCoeff>(),
        GeneratedStruct::of::<ParamGrad>(),
        GeneratedStruct::of::<ScreenStat>(),
    ]
}

/// The step of one scalar (both kernels), then each kernel's own source.
const ADAM: &str = include_str!("adam.wgsl");

/// The Adam kernels: entry point, own source and storage bindings.
fn adam_specs() -> [(&'static str, &'static str, Vec<Binding<'static>>); 2] {
    use Binding as B;
    let (par, sh) = ("array<ParamRecord>", "array<ShCoeff>");
    [
        (
            "adam_params",
            include_str!("adam_params.wgsl"),
            vec![
                B::write("params", par),
                B::write("m_params", par),
                B::write("v_params", par),
                B::read("grads", "array<ParamGrad>"),
                B::read("extra_opacity", "array<f32>"),
                B::write("flags", "array<atomic<u32>>"),
                B::write("screen", "array<ScreenStat>"),
            ],
        ),
        (
            "adam_sh",
            include_str!("adam_sh.wgsl"),
            vec![B::write("sh", sh), B::write("m_sh", sh), B::write("v_sh", sh), B::read("grads_sh", sh)],
        ),
    ]
}

impl Model {
    pub(super) fn new(ctx: &GpuContext) -> gs_gpu::Result<Self> {
        let mut pool = BufferPool::new(ctx, ShrinkPolicy::default());
        let mut b = |l| pool.add_storage(l);
        let (params, sh, m_params, v_params) = (b("params"), b("sh"), b("m_params"), b("v_params"));
        let (m_sh, v_sh, extra, flags) = (b("m_sh"), b("v_sh"), b("extra_opacity"), b("adam_flags"));
        let screen = b("screen_stats");
        let decls = gs_gpu::declarations(&adam_structs());
        let [(e0, s0, b0), (e1, s1, b1)] = adam_specs();
        Ok(Self {
            adam_params: Kernel::new(ctx, e0, &[&decls, ADAM, s0], &b0)?,
            adam_sh: Kernel::new(ctx, e1, &[&decls, ADAM, s1], &b1)?,
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
            screen,
            resident: None,
        })
    }

    /// Makes the parameter buffers hold `g` for a render: uploaded when not resident (a new
    /// pool frame first), bound as they are when resident and of `g`'s size and degree.
    pub(super) fn prepare(&mut self, ctx: &GpuContext, g: &Gaussians) -> Result<()> {
        match self.resident {
            _ if self.holds(g) => Ok(()),
            Some(r) => Err(RasterError::Gpu(format!(
                "the resident model holds {} Gaussians of SH degree {}, the render was given {} of degree {}: release the residency after changing the model",
                r.n,
                r.sh_degree,
                g.len(),
                g.sh_degree
            ))),
            None => {
                self.pool.begin_frame();
                self.upload(ctx, g);
                Ok(())
            }
        }
    }

    /// Whether the resident model is one of `g`'s size and SH degree.
    fn holds(&self, g: &Gaussians) -> bool {
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
}

/// Picks one moment array (m or v) of a group.
type Moment = fn(&ParamGroup) -> &[f32];

/// The six groups of `adam` in [`Param::ALL`] order, each checked to hold `n` rows.
fn groups_of(adam: &Adam, n: usize) -> Result<[&ParamGroup; 6]> {
    let group = |p: Param| -> Result<&ParamGroup> {
        let g = adam.groups.iter().find(|g| g.name == p.name()).ok_or_else(|| RasterError::Gpu(format!("the optimiser has no group '{}'", p.name())))?;
        if g.row_width != p.row_width() || g.m.len() != n * p.row_width() {
            return Err(RasterError::Gpu(format!("the optimiser's group '{}' holds {} moments, not {} rows of {}", p.name(), g.m.len(), n, p.row_width())));
        }
        Ok(g)
    };
    let [means, dc, rest, opacity, scales, rot] = Param::ALL.map(group);
    Ok([means?, dc?, rest?, opacity?, scales?, rot?])
}

/// Fills `out` with one moment (m or v, `pick`) of the non-SH groups, a `ParamRecord` per
/// Gaussian.
fn fill_param_moments(out: &mut [ParamRecord], groups: &[&ParamGroup; 6], pick: Moment) {
    let [means, _, _, opacity, scales, rot] = groups.map(pick);
    out.par_iter_mut().enumerate().for_each(|(i, r)| {
        *r = ParamRecord {
            mean: means[3 * i..3 * i + 3].try_into().expect("3"),
            log_scale: scales[3 * i..3 * i + 3].try_into().expect("3"),
            rot_w: rot[4 * i],
            rot_x: rot[4 * i + 1],
            rot_y: rot[4 * i + 2],
            rot_z: rot[4 * i + 3],
            opacity_logit: opacity[i],
        }
    });
}

/// Fills `out` with one moment (m or v, `pick`) of the SH groups, `nc` `ShCoeff` per Gaussian:
/// coefficient 0 from SH DC, the others from SH rest.
fn fill_sh_moments(out: &mut [ShCoeff], groups: &[&ParamGroup; 6], nc: usize, pick: Moment) {
    let (dc, rest, w) = (pick(groups[1]), pick(groups[2]), Param::ShRest.row_width());
    out.par_chunks_mut(nc).enumerate().for_each(|(i, coeffs)| {
        for (k, c) in coeffs.iter_mut().enumerate() {
            let rgb = if k == 0 { &dc[3 * i..3 * i + 3] } else { &rest[w * i + 3 * (k - 1)..w * i + 3 * k] };
            c.rgb = rgb.try_into().expect("3");
        }
    });
}

/// Writes device moment records back into one moment array (m or v) of each of `adam`'s
/// groups; SH coefficients above the active degree keep their host values.
fn store_moments(adam: &mut Adam, params: &[ParamRecord], sh: &[ShCoeff], nc: usize, pick: fn(&mut ParamGroup) -> &mut [f32]) -> Result<()> {
    for p in Param::ALL {
        let g = adam.group_mut(p.name()).map_err(|e| RasterError::Gpu(e.to_string()))?;
        let rows = pick(g).par_chunks_mut(p.row_width()).enumerate();
        match p {
            Param::Means => rows.for_each(|(i, r)| r.copy_from_slice(&params[i].mean)),
            Param::LogScales => rows.for_each(|(i, r)| r.copy_from_slice(&params[i].log_scale)),
            Param::Rotations => rows.for_each(|(i, r)| r.copy_from_slice(&params[i].rotation())),
            Param::Opacity => rows.for_each(|(i, r)| r[0] = params[i].opacity_logit),
            Param::ShDc => rows.for_each(|(i, r)| r.copy_from_slice(&sh[i * nc].rgb)),
            Param::ShRest => rows.for_each(|(i, r)| {
                for k in 1..nc {
                    r[3 * (k - 1)..3 * k].copy_from_slice(&sh[i * nc + k].rgb);
                }
            }),
        }
    }
    Ok(())
}

impl WgpuRasterizer {
    /// Keeps `g` and the moments of `adam` (one group per [`Param`], by name) on the device
    /// from now on: renders bind them without an upload and
    /// [`backward_and_step`](Self::backward_and_step) steps them there.
    pub fn make_resident(&mut self, g: &Gaussians, adam: &Adam) -> Result<()> {
        crate::validate::check_gaussians(g)?;
        let (n, nc) = (g.len(), coeffs_for_degree(g.sh_degree));
        let groups = groups_of(adam, n)?;
        let m = &mut self.model;
        m.resident = None;
        m.prepare(&self.ctx, g)?;
        // Written in parallel straight into the queue's staging memory, like the parameters.
        let moments: [(BufId, BufId, Moment); 2] = [(m.m_params, m.m_sh, |g| &g.m), (m.v_params, m.v_sh, |g| &g.v)];
        for (par, sh, pick) in moments {
            upload_with(&self.ctx, &mut m.pool, par, n, |out: &mut [ParamRecord]| fill_param_moments(out, &groups, pick));
            upload_with(&self.ctx, &mut m.pool, sh, n * nc, |out: &mut [ShCoeff]| fill_sh_moments(out, &groups, nc, pick));
        }
        m.resident = Some(Residency::of(g));
        Ok(())
    }

    /// Whether a model is resident.
    pub fn is_resident(&self) -> bool {
        self.model.resident.is_some()
    }

    /// Ends the residency: the next render uploads its Gaussians again. The device's
    /// parameters and moments are dropped; read them first
    /// ([`read_resident`](Self::read_resident)) to keep them.
    pub fn release_resident(&mut self) {
        self.model.resident = None;
    }

    /// Copies the resident parameters and SH into `g` (of the resident size and degree) and,
    /// when given, the resident moments into `adam`, in one readback; the residency goes on.
    pub fn read_resident(&mut self, g: &mut Gaussians, adam: Option<&mut Adam>) -> Result<()> {
        let Some(r) = self.model.resident else {
            return Err(RasterError::Gpu("no model is resident".into()));
        };
        if !self.model.holds(g) {
            return Err(RasterError::Gpu(format!(
                "the resident model holds {} Gaussians of SH degree {}, not the {} of degree {} given to read it into",
                r.n,
                r.sh_degree,
                g.len(),
                g.sh_degree
            )));
        }
        let nc = coeffs_for_degree(r.sh_degree);
        let (pb, sb) = (bytes_of::<ParamRecord>(r.n), bytes_of::<ShCoeff>(r.n * nc));
        let m = &self.model;
        let mut order = vec![(m.params, pb), (m.sh, sb)];
        if adam.is_some() {
            order.extend([(m.m_params, pb), (m.v_params, pb), (m.m_sh, sb), (m.v_sh, sb)]);
        }
        let total: u64 = order.iter().map(|(_, b)| b).sum();
        self.pool.ensure(self.bufs.staging, total + 4);
        let staging = self.pool.buffer(self.bufs.staging);
        let mut enc = m.disp.encoder();
        let mut at = 0;
        for (id, bytes) in order {
            enc.encoder.copy_buffer_to_buffer(m.pool.buffer(id), 0, staging, at, bytes);
            at += bytes;
        }
        m.disp.submit(enc);
        self.ctx.read_mapped(staging, at, |bytes| {
            let (own, moments) = bytes.split_at((pb + sb) as usize);
            let (par, sh) = own.split_at(pb as usize);
            store_parameters(g, &pod_vec::<ParamRecord>(par), &pod_vec::<ShCoeff>(sh), nc);
            let Some(adam) = adam else { return Ok(()) };
            let (par, sh) = moments.split_at(2 * pb as usize);
            let (par, sh) = (pod_vec::<ParamRecord>(par), pod_vec::<ShCoeff>(sh));
            let ((mp, vp), (ms, vs)) = (par.split_at(r.n), sh.split_at(r.n * nc));
            store_moments(adam, mp, ms, nc, |g| &mut g.m)?;
            store_moments(adam, vp, vs, nc, |g| &mut g.v)
        })?
    }
}

impl AdamUniform {
    /// The uniform of one step: each group of `adam` counts the step ([`GroupStep`]).
    fn begin_step(adam: &mut Adam, nc: usize, extra_opacity: bool) -> Result<Self> {
        let cfg = adam.config;
        let mut step = |p: Param| -> Result<GroupStep> {
            Ok(adam.group_mut(p.name()).map_err(|e| RasterError::Gpu(e.to_string()))?.begin_step(&cfg))
        };
        let [means, dc, rest, opacity, scales, rot] = Param::ALL.map(&mut step);
        let (means, dc, rest, opacity, scales, rot) = (means?, dc?, rest?, opacity?, scales?, rot?);
        Ok(Self {
            nc: nc as u32,
            extra_opacity: extra_opacity as u32,
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
    /// followed by [`gs_core::Adam::step_strided`] on each group. The new parameters and the
    /// moments stay on the device (`g`, the host's copy, falls behind until
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
        if !self.model.holds(g) {
            return Err(RasterError::Gpu("a device step needs the model resident (make_resident) with these Gaussians".into()));
        }
        if let Some(x) = extras.extra_opacity
            && x.len() != g.len()
        {
            return Err(RasterError::InvalidGradients(format!("{} extra opacity gradients for {} Gaussians", x.len(), g.len())));
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
            let uniform = AdamUniform::begin_step(adam, nc, extras.extra_opacity.is_some())?;
            let (step, t2) = r.step_on_device(g.len(), &uniform, extras)?;
            r.timings.backward = GpuTimings { upload: t1 - t0, device: t2 - t1, unpack: t2.elapsed() };
            Ok(step)
        });
        // The device's parameters moved: the last render's state is no longer theirs.
        self.frame = None;
        out
    }

    /// An encoder that zeroes the gradient buffers of `n` Gaussians with `nc` SH coefficients.
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

    /// Runs the Adam kernels of `n` Gaussians on the gradients in `gout` / `gout_sh` and reads
    /// back the divergence flag and, when asked, the screen gradients; also returns when the
    /// readback arrived.
    fn step_on_device(&mut self, n: usize, uniform: &AdamUniform, extras: StepExtras<'_>) -> Result<(DeviceStep, Instant)> {
        let nc = uniform.nc as usize;
        let m = &mut self.model;
        match extras.extra_opacity {
            Some(x) => upload_with(&self.ctx, &mut m.pool, m.extra, n, |out: &mut [f32]| out.copy_from_slice(x)),
            None => m.pool.ensure(m.extra, 4),
        }
        m.pool.ensure(m.flags, 4);
        m.pool.ensure(m.screen, bytes_of::<ScreenStat>(n.max(1)));
        m.disp.write_frame(uniform);
        let gb = if extras.screen { bytes_of::<ScreenStat>(n) } else { 0 };
        self.pool.ensure(self.bufs.staging, 4 + gb);
        let (m, p, b) = (&self.model, &self.pool, &self.bufs);
        let mut enc = m.disp.encoder();
        enc.encoder.clear_buffer(m.pool.buffer(m.flags), 0, Some(4));
        let (rec, shr, grad) = (bytes_of::<ParamRecord>(1), nc as u64 * bytes_of::<ShCoeff>(1), bytes_of::<ParamGrad>(1));
        let stat = bytes_of::<ScreenStat>(1);
        for (bb, c) in chunks(n as u32) {
            m.disp.make_room(&mut enc, 2);
            let pass = PassUniform { n: c as u32, base: bb as u32, ..Default::default() };
            let extra = match extras.extra_opacity {
                Some(_) => m.pool.range(m.extra, bb * 4, c * 4),
                None => m.pool.whole(m.extra),
            };
            let binds = [
                m.pool.range(m.params, bb * rec, c * rec),
                m.pool.range(m.m_params, bb * rec, c * rec),
                m.pool.range(m.v_params, bb * rec, c * rec),
                p.range(b.gout, bb * grad, c * grad),
                extra,
                m.pool.whole(m.flags),
                m.pool.range(m.screen, bb * stat, c * stat),
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
        let staging = p.buffer(b.staging);
        enc.encoder.copy_buffer_to_buffer(m.pool.buffer(m.flags), 0, staging, 0, 4);
        if extras.screen {
            enc.encoder.copy_buffer_to_buffer(m.pool.buffer(m.screen), 0, staging, 4, gb);
        }
        m.disp.submit(enc);
        self.ctx.read_mapped(staging, 4 + gb, |bytes| {
            let arrived = Instant::now();
            let (flags, screen) = bytes.split_at(4);
            let stats = pod_vec::<ScreenStat>(screen);
            let step = DeviceStep {
                means_finite: u32::from_le_bytes(flags.try_into().expect("4 bytes")) == 0,
                mean2d: stats.par_iter().map(|r| r.mean2d).collect(),
                mean2d_abs: stats.par_iter().map(|r| r.mean2d_abs).collect(),
            };
            (step, arrived)
        })
        .map_err(RasterError::from)
    }
}

/// The host's copy of the parameters from the device's records (SH above the active degree
/// untouched).
fn store_parameters(g: &mut Gaussians, params: &[ParamRecord], sh: &[ShCoeff], nc: usize) {
    let rec = |i: usize| &params[i];
    g.means.par_iter_mut().enumerate().for_each(|(i, v)| *v = rec(i).mean);
    g.log_scales.par_iter_mut().enumerate().for_each(|(i, v)| *v = rec(i).log_scale);
    g.rotations.par_iter_mut().enumerate().for_each(|(i, v)| *v = rec(i).rotation());
    g.opacity_logits.par_iter_mut().enumerate().for_each(|(i, v)| *v = rec(i).opacity_logit);
    g.sh.par_iter_mut().zip(sh.par_chunks(nc)).for_each(|(c, s)| c.iter_mut().zip(s).for_each(|(c, s)| *c = s.rgb));
}

#[cfg(test)]
mod tests {
    use super::*;
    use gs_gpu::{check_layout, kernel_source};

    /// Both Adam kernels' full sources parse and validate, and their generated structs have
    /// the Rust offsets and sizes (naga's layouter against `offset_of!` / `size_of`).
    #[test]
    fn the_adam_kernels_parse_with_the_hosts_layouts() {
        let decls = gs_gpu::declarations(&adam_structs());
        for (entry, own, bindings) in adam_specs() {
            let src = kernel_source(&[&decls, ADAM, own], &bindings);
            check_layout::<PassUniform>(&src).unwrap_or_else(|e| panic!("{entry}: {e}"));
            gs_gpu::check_layouts(&adam_structs(), &src).unwrap_or_else(|e| panic!("{entry}: {e}"));
            gs_gpu::validate_kernel(&src).unwrap_or_else(|e| panic!("{entry}: {e}"));
        }
        assert_eq!(std::mem::size_of::<AdamUniform>(), 4 * 17);
    }
}
