//! The wgpu backward: per-pixel channel gradients folded on the host (the CPU code), the
//! reverse blend `raster_bwd` per band and window (one `ScreenGrad` partial per intersection),
//! `grad_reduce` (each Gaussian's partials summed in a fixed order, so runs repeat bit for
//! bit), then `project_bwd` per chunk of Gaussians, and the readback of the parameter
//! gradients.

use super::kernels::{BlendState, ColourGrad, ParamGrad, ParamRecord, PixelGrad, ScreenGrad, ShCoeff, TileRect};
use gs_gpu::bytes_of;
use super::split::BWD_WINDOW;
use super::{CamUniform, ENTRY_WINDOW, Frame, GpuState, GpuTimings, WgpuRasterizer, chunks, pod_vec};
use crate::cpu::project::CamParams;
use crate::validate::{check_all_grads, check_forward_matches, check_inputs};
use crate::{
    GaussianGradients, OutputGradients, RasterConfig, RasterError, RenderOutput, Result, StateInner,
};
use gs_core::sh::coeffs_for_degree;
use gs_core::{Camera, Gaussians};
use gs_gpu::{Encoder, PassUniform};
use rayon::prelude::*;
use std::time::Instant;

/// The inputs of a backward once checked: the camera constants, the forward render's state
/// and the device frame that holds it.
pub(super) struct Checked<'f> {
    pub(super) cam: CamParams,
    pub(super) st: &'f GpuState,
    pub(super) frame: Frame,
}

impl WgpuRasterizer {
    /// Backward like [`crate::backward`] (same inputs as the render of `forward`, which must
    /// come from this rasterizer). Fastest right after that render; for an older render the
    /// device state is rebuilt first.
    pub fn backward(
        &mut self,
        gaussians: &Gaussians,
        camera: &Camera,
        config: &RasterConfig,
        forward: &RenderOutput,
        grads: &OutputGradients,
    ) -> Result<GaussianGradients> {
        let Some(checked) = self.checked_frame(gaussians, camera, config, forward, grads)? else {
            return Ok(GaussianGradients::zeros(gaussians.len()));
        };
        self.scoped(|r| r.backward_inner(gaussians, config, grads, &checked))
    }

    /// The backward's checks, and the device state of `forward` (rebuilt when a later render
    /// overwrote it); `None` when nothing flows back (no intersections or no gradients).
    pub(super) fn checked_frame<'f>(
        &mut self,
        gaussians: &Gaussians,
        camera: &Camera,
        config: &RasterConfig,
        forward: &'f RenderOutput,
        grads: &OutputGradients,
    ) -> Result<Option<Checked<'f>>> {
        let cam = check_inputs(gaussians, camera, config)?;
        let st = match &forward.state.0 {
            StateInner::Gpu(st) => st,
            StateInner::Cpu(_) => {
                return Err(RasterError::InvalidGradients(
                    "the forward render came from the CPU backend; use gs_raster::backward".into(),
                ));
            }
        };
        if st.rasterizer != self.id {
            return Err(RasterError::InvalidGradients(
                "the forward render came from another WgpuRasterizer".into(),
            ));
        }
        check_forward_matches((st.n, st.width, st.height), true, gaussians, &cam, "")?;
        check_all_grads(grads, &st.request, cam.width, cam.height)?;
        let frame = match self.frame {
            Some(f) if f.generation == st.generation => f,
            _ => {
                // An older render of this rasterizer: a later render overwrote its device
                // state. The forward is deterministic, so rebuild that state from the same
                // inputs (one extra forward) and check that it is the same render.
                self.render(gaussians, camera, &st.request, config)?;
                match self.frame {
                    Some(f) if f.total == st.total => f,
                    _ => {
                        return Err(RasterError::InvalidGradients(
                            "the Gaussians, camera or config differ from those of the forward render".into(),
                        ));
                    }
                }
            }
        };
        let color = grads.color.is_some() || grads.device_color.is_some();
        let geo = grads.normal.is_some() || grads.distance.is_some() || grads.plane_depth.is_some() || grads.device_geometry.is_some() || grads.device_plane.is_some();
        let depth = grads.expected_depth.is_some();
        if frame.total == 0 || !(color || geo || depth || grads.alpha.is_some()) {
            return Ok(None);
        }
        Ok(Some(Checked { cam, st, frame }))
    }

    fn backward_inner(
        &mut self,
        g: &Gaussians,
        config: &RasterConfig,
        grads: &OutputGradients,
        checked: &Checked<'_>,
    ) -> Result<GaussianGradients> {
        let nn = g.len() as u64;
        // The readback: every Gaussian's `ParamGrad`, then its SH gradients.
        let grad_bytes = nn * bytes_of::<ParamGrad>(1);
        let sh_bytes = nn * coeffs_for_degree(g.sh_degree) as u64 * bytes_of::<ShCoeff>(1);
        let t0 = Instant::now();
        let mut enc = self.record_backward(g, config, grads, checked)?;
        let t1 = Instant::now();
        self.pool.ensure(self.bufs.staging, grad_bytes + sh_bytes + 4);
        let (p, b) = (&self.pool, &self.bufs);
        let staging = p.buffer(b.staging);
        enc.encoder.copy_buffer_to_buffer(p.buffer(b.gout), 0, staging, 0, grad_bytes);
        enc.encoder.copy_buffer_to_buffer(p.buffer(b.gout_sh), 0, staging, grad_bytes, sh_bytes);
        self.disp.submit(enc);
        let (out, t2) = self.ctx.read_mapped(staging, grad_bytes + sh_bytes, |bytes| {
            let t2 = Instant::now();
            let (gb, sb) = bytes.split_at(grad_bytes as usize);
            let out = unpack_gradients(&pod_vec(gb), &pod_vec(sb), g);
            (out, t2)
        })?;
        self.timings.backward = GpuTimings { upload: t1 - t0, device: t2 - t1, unpack: t2.elapsed() };
        Ok(out)
    }

    /// Records the backward of `frame` up to every Gaussian's `ParamGrad` and SH gradients
    /// in `gout` / `gout_sh` (the per-pixel gradients uploaded first); returns the encoder.
    pub(super) fn record_backward(
        &mut self,
        g: &Gaussians,
        config: &RasterConfig,
        grads: &OutputGradients,
        checked: &Checked<'_>,
    ) -> Result<Encoder> {
        let (cam, st, frame) = (&checked.cam, checked.st, checked.frame);
        let nn = g.len() as u64;
        let npix = cam.width as u64 * cam.height as u64;
        let (device_colour, device_geometry, device_plane) = (grads.device_color, grads.device_geometry, grads.device_plane);
        let elsewhere = |im: &gs_gpu::DeviceImage| !im.is_on(&self.ctx);
        if device_colour.is_some_and(elsewhere)
            || device_geometry.is_some_and(|g| elsewhere(g.normal) || elsewhere(g.plane_depth))
            || device_plane.is_some_and(|g| elsewhere(g.gradient))
        {
            return Err(RasterError::InvalidGradients("a device gradient lives on another device".into()));
        }
        let flags = (grads.color.is_some() || device_colour.is_some()) as u32
            | ((grads.normal.is_some() || grads.distance.is_some() || grads.plane_depth.is_some() || device_geometry.is_some() || device_plane.is_some())
                as u32)
                << 1
            | (grads.expected_depth.is_some() as u32) << 2;
        self.disp
            .write_frame(&CamUniform::new(cam, config, g, flags, 0.0));
        // The parameters on the device are those of this frame's render (its generation was
        // checked, or it was just rebuilt): no second upload.
        let bands = self.bands(cam)?;
        let rec = std::mem::size_of::<ScreenGrad>() as u64;
        let partial_bytes = frame.total as u64 * rec;
        self.check_binding("the per-intersection gradients", partial_bytes)?;
        let sh_bytes = nn * coeffs_for_degree(g.sh_degree) as u64 * bytes_of::<ShCoeff>(1);
        let (p, b) = (&mut self.pool, &self.bufs);
        p.ensure(b.bstate, npix * bytes_of::<BlendState>(1));
        p.ensure(b.partials, partial_bytes);
        p.ensure(b.gacc, nn * rec + 4);
        p.ensure(b.gout, nn * bytes_of::<ParamGrad>(1) + bytes_of::<ParamGrad>(1));
        p.ensure(b.gout_sh, sh_bytes + bytes_of::<ShCoeff>(1));
        // A render that brought back its plane depth alone left Ñ and D on the device.
        let geo = match (grads.plane_depth.is_some() || grads.expected_depth.is_some()) && st.geo.is_empty() {
            true => self.read_geo(cam, &bands)?,
            false => Vec::new(),
        };
        let colour_only = flags & !1 == 0;
        let rec = match colour_only {
            true => bytes_of::<ColourGrad>(1),
            false => bytes_of::<PixelGrad>(1),
        };
        // Where every gradient is on the device the host has nothing to fold: the records
        // start at zero there; otherwise the host folds its own (the device's left out).
        let on_host = [grads.color, grads.alpha, grads.normal, grads.distance, grads.plane_depth, grads.expected_depth];
        let nothing_on_host = on_host.iter().all(Option::is_none);
        if nothing_on_host {
            self.pool.ensure(self.bufs.pixgrad, npix * rec);
        } else {
            self.upload_pixel_grads(cam, config, st, if geo.is_empty() { &st.geo } else { &geo }, grads, colour_only);
        }
        let mut enc = self.disp.encoder();
        let (p, b) = (&self.pool, &self.bufs);
        if nothing_on_host {
            enc.encoder.clear_buffer(p.buffer(b.pixgrad), 0, Some(npix * rec));
        }
        if let Some(image) = device_colour {
            self.add_device_colour(&mut enc, &bands, image, colour_only)?;
        }
        // L_p's before L_nc's: the host added them in that order into one buffer (the plane
        // depth's fold last), so a run with both on the device keeps its bits.
        if let Some(plane) = device_plane {
            self.add_device_plane(&mut enc, &bands, plane)?;
        }
        if let Some(geometry) = device_geometry {
            self.add_device_geometry(&mut enc, &bands, geometry)?;
        }
        // Intersections beyond their tile's last contributor get no partial: zeros.
        enc.encoder
            .clear_buffer(p.buffer(b.partials), 0, Some(partial_bytes));
        self.blend_backward(&mut enc, cam, &bands, frame, colour_only)?;
        self.reduce_partials(&mut enc, cam, g.len() as u32)?;
        self.project_backward(&mut enc, g)?;
        Ok(enc)
    }

    /// Per pixel Ñ (3), D and Σ w t_z of the current frame, read from the device's
    /// accumulators (one round trip).
    fn read_geo(&mut self, cam: &CamParams, bands: &[(u32, u32, u64, u64)]) -> Result<Vec<[f32; 5]>> {
        let npix = cam.width as u64 * cam.height as u64;
        self.pool.ensure(self.bufs.staging, 5 * npix * 4);
        let mut enc = self.disp.encoder();
        self.copy_planes(&mut enc, &[3, 4, 5, 6, 7], bands, npix, (self.bufs.staging, 0));
        self.disp.submit(enc);
        let staging = self.pool.buffer(self.bufs.staging);
        let n = npix as usize;
        let geo = self.ctx.read_mapped(staging, 5 * npix * 4, |bytes| {
            let v: std::borrow::Cow<[f32]> = pod_vec(bytes);
            (0..n).into_par_iter().map(|i| std::array::from_fn(|k| v[k * n + i])).collect()
        })?;
        Ok(geo)
    }

    /// Per-pixel channel gradients, folded on the host exactly as the CPU backend does (rows
    /// in parallel), written to `pixgrad`: one `PixelGrad` a pixel, or, `colour_only` (no
    /// gradient of the geometry channels, whose five values are then zeros), one `ColourGrad`.
    /// `geo` is the frame's Ñ, D and Σ w t_z per pixel where plane or expected depth gradients
    /// need them.
    fn upload_pixel_grads(
        &mut self,
        cam: &CamParams,
        config: &RasterConfig,
        st: &GpuState,
        geo: &[[f32; 5]],
        grads: &OutputGradients,
        colour_only: bool,
    ) {
        /// Uploads one record a pixel, made by `record` from the pixel's folded gradients (rows
        /// in parallel).
        fn upload<T: bytemuck::Pod + Send>(
            r: &mut WgpuRasterizer,
            (w, h): (usize, usize),
            fold: &(impl Fn(usize, usize) -> ([f32; 8], f32) + Sync),
            record: impl Fn([f32; 8], f32) -> T + Sync,
        ) {
            super::upload_with(&r.ctx, &mut r.pool, r.bufs.pixgrad, w * h, |pg: &mut [T]| {
                pg.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
                    for (x, px) in row.iter_mut().enumerate() {
                        let (channels, final_t) = fold(x, y);
                        *px = record(channels, final_t);
                    }
                })
            });
        }
        let size = (cam.width as usize, cam.height as usize);
        let fold = |x, y| crate::pixel::pixel_grads(cam, config, grads, &st.final_t, geo, x, y);
        match colour_only {
            true => upload(self, size, &fold, |c, final_t| ColourGrad { channels: [c[0], c[1], c[2]], final_t }),
            false => upload(self, size, &fold, |channels, final_t| PixelGrad { channels, final_t }),
        }
    }

    /// `colour_grad_add` per band of tile rows: the device colour gradient `image` added into
    /// the pixels' records (`ColourGrad`s when `colour_only`, else `PixelGrad`s).
    fn add_device_colour(&self, enc: &mut Encoder, bands: &[(u32, u32, u64, u64)], image: &gs_gpu::DeviceImage, colour_only: bool) -> Result<()> {
        let (p, b, k) = (&self.pool, &self.bufs, &self.kernels);
        let (kernel, rec) = match colour_only {
            true => (&k.colour_grad_add_colour, bytes_of::<ColourGrad>(1)),
            false => (&k.colour_grad_add, bytes_of::<PixelGrad>(1)),
        };
        self.per_band(enc, bands, kernel, PassUniform::default(), |p0, bp| [image.pixels(p0, bp), p.range(b.pixgrad, p0 * rec, bp * rec)])
    }

    /// `geometry_grad_add` per band of tile rows: the device gradients of Ñ and of the plane
    /// depth (folded into Ñ and D with the band's accumulators) added into the pixels'
    /// `PixelGrad`s.
    fn add_device_geometry(&self, enc: &mut Encoder, bands: &[(u32, u32, u64, u64)], g: crate::DeviceGeometryGrads<'_>) -> Result<()> {
        let (p, b, rec) = (&self.pool, &self.bufs, bytes_of::<PixelGrad>(1));
        self.per_band(enc, bands, &self.kernels.geometry_grad_add, PassUniform::default(), |p0, bp| {
            [p.range(b.acc, p0 * 32, bp * 32), g.normal.pixels(p0, bp), g.plane_depth.pixels(p0, bp), p.range(b.pixgrad, p0 * rec, bp * rec)]
        })
    }

    /// `plane_grad_add` per band of tile rows: a loss's device gradient of Ñ and D, times its
    /// weight, added into the pixels' `PixelGrad`s.
    fn add_device_plane(&self, enc: &mut Encoder, bands: &[(u32, u32, u64, u64)], g: crate::DevicePlaneGrads<'_>) -> Result<()> {
        let (p, b, rec) = (&self.pool, &self.bufs, bytes_of::<PixelGrad>(1));
        let pass = PassUniform { p1: g.weight.to_bits(), ..Default::default() };
        self.per_band(enc, bands, &self.kernels.plane_grad_add, pass, |p0, bp| [g.gradient.pixels(p0, bp), p.range(b.pixgrad, p0 * rec, bp * rec)])
    }

    /// `raster_bwd` per band of tile rows and window of tile-list positions (last first).
    fn blend_backward(
        &self,
        enc: &mut Encoder,
        cam: &CamParams,
        bands: &[(u32, u32, u64, u64)],
        frame: Frame,
        colour_only: bool,
    ) -> Result<()> {
        let (d, p, b, k) = (&self.disp, &self.pool, &self.bufs, &self.kernels);
        let windows = frame.max_last.div_ceil(BWD_WINDOW);
        let (kernel, rec) = match colour_only {
            true => (&k.raster_bwd_colour, bytes_of::<ColourGrad>(1)),
            false => (&k.raster_bwd, bytes_of::<PixelGrad>(1)),
        };
        for &(r0, rows, p0, bp) in bands {
            for wi in (0..windows).rev() {
                d.make_room(enc, 1);
                let binds = [
                    p.whole(b.ranges),
                    p.whole(b.gids),
                    p.whole(b.splat),
                    p.range(b.final_t, p0 * 4, bp * 4),
                    p.range(b.last, p0 * 4, bp * 4),
                    p.range(b.pixgrad, p0 * rec, bp * rec),
                    p.whole(b.partials),
                    p.range(b.bstate, p0 * bytes_of::<BlendState>(1), bp * bytes_of::<BlendState>(1)),
                ];
                let pass = PassUniform {
                    n: bp as u32,
                    shift: wi * BWD_WINDOW,
                    nb: (wi + 1).saturating_mul(BWD_WINDOW),
                    base: r0,
                    ..Default::default()
                };
                d.dispatch(enc, kernel, &binds, pass, (cam.tiles_x, rows))?;
            }
        }
        Ok(())
    }

    /// `grad_reduce`: per depth-sorted Gaussian, its partials in emission order, in windows of
    /// emission entries (no Gaussian has more intersections than there are tiles).
    fn reduce_partials(&self, enc: &mut Encoder, cam: &CamParams, n: u32) -> Result<()> {
        let (d, p, b, k) = (&self.disp, &self.pool, &self.bufs, &self.kernels);
        let n_tiles = cam.tiles_x * cam.tiles_y;
        for wi in 0..n_tiles.div_ceil(ENTRY_WINDOW) {
            d.make_room(enc, 1);
            let binds = [
                p.whole(b.vals_a),
                p.whole(b.counts),
                p.whole(b.isect_pos),
                p.whole(b.partials),
                p.whole(b.gacc),
            ];
            let pass = PassUniform {
                n,
                shift: wi * ENTRY_WINDOW,
                nb: (wi + 1).saturating_mul(ENTRY_WINDOW),
                ..Default::default()
            };
            d.dispatch_1d(enc, &k.grad_reduce, &binds, pass)?;
        }
        Ok(())
    }

    /// `project_bwd` per chunk of Gaussians (a `ParamGrad` and the SH gradients of each).
    fn project_backward(&self, enc: &mut Encoder, g: &Gaussians) -> Result<()> {
        let (d, p, b, k, m) = (&self.disp, &self.pool, &self.bufs, &self.kernels, &self.model);
        let sh = coeffs_for_degree(g.sh_degree) as u64 * bytes_of::<ShCoeff>(1);
        let (param, rect) = (bytes_of::<ParamRecord>(1), bytes_of::<TileRect>(1));
        let (screen, grad) = (bytes_of::<ScreenGrad>(1), bytes_of::<ParamGrad>(1));
        for (bb, c) in chunks(g.len() as u32) {
            d.make_room(enc, 1);
            let binds = [
                m.pool.range(m.params, bb * param, c * param),
                m.pool.range(m.sh, bb * sh, c * sh),
                p.range(b.proj, bb * rect, c * rect),
                p.range(b.gacc, bb * screen, c * screen),
                p.range(b.gout, bb * grad, c * grad),
                p.range(b.gout_sh, bb * sh, c * sh),
            ];
            let pass = PassUniform {
                n: c as u32,
                base: bb as u32,
                ..Default::default()
            };
            d.dispatch_1d(enc, &k.project_bwd, &binds, pass)?;
        }
        Ok(())
    }
}

/// The gradients of `g` from one `ParamGrad` per Gaussian and its `nc` SH gradient records
/// (SH only up to the active degree, zero above), built in parallel.
fn unpack_gradients(v: &[ParamGrad], sh: &[ShCoeff], g: &Gaussians) -> GaussianGradients {
    let nc = coeffs_for_degree(g.sh_degree);
    let recs = || v.par_iter().take(g.len());
    GaussianGradients {
        means: recs().map(|r| r.param.mean).collect(),
        log_scales: recs().map(|r| r.param.log_scale).collect(),
        rotations: recs().map(|r| r.param.rotation()).collect(),
        opacity_logits: recs().map(|r| r.param.opacity_logit).collect(),
        mean2d: recs().map(|r| [r.mean2d_x, r.mean2d_y]).collect(),
        mean2d_abs: recs().map(|r| [r.mean2d_abs_x, r.mean2d_abs_y]).collect(),
        sh: (0..g.len())
            .into_par_iter()
            .map(|i| {
                let mut c = [[0.0f32; 3]; 16];
                c.iter_mut().zip(&sh[i * nc..(i + 1) * nc]).for_each(|(ck, s)| *ck = s.rgb);
                c
            })
            .collect(),
    }
}
