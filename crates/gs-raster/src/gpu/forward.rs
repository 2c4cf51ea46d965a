//! The wgpu forward: projection, depth sort and intersection counts, then emission, tile sort,
//! tile ranges, links and the blend; what comes back and how is `readback.rs`.
//!
//! The intersections size the buffers of the second half: a render of a new size counts them
//! first (two submissions and readbacks); one of a size rendered before guesses them
//! (`guess.rs`: one submission and readback, rendering again when the guess fell short).

use super::kernels::{ParamRecord, ShCoeff, Splat, TileRect};
use gs_gpu::bytes_of;
use super::readback::{Readback, longest_tile_list};
use super::{CamUniform, ENTRY_WINDOW, Frame, GpuTimings, WgpuRasterizer, chunks};
use crate::cpu::project::CamParams;
use crate::{RasterConfig, RasterError, RenderOutput, RenderRequest, Result};
use gs_core::sh::coeffs_for_degree;
use gs_core::{Camera, Gaussians};
use gs_gpu::{DeviceImage, Encoder, Kernel, PassUniform};
use std::time::Instant;

impl WgpuRasterizer {
    /// Renders like [`crate::render`] (same inputs, errors and outputs; `stats.box_pairs` is a
    /// CPU-only work estimate and stays 0 here).
    pub fn render(
        &mut self,
        gaussians: &Gaussians,
        camera: &Camera,
        request: &RenderRequest,
        config: &RasterConfig,
    ) -> Result<RenderOutput> {
        self.render_alone(gaussians, camera, request, config, true)
    }

    /// A render with its own waits, guessed when `guess` and the size was rendered before.
    pub(super) fn render_alone(
        &mut self,
        gaussians: &Gaussians,
        camera: &Camera,
        request: &RenderRequest,
        config: &RasterConfig,
        guess: bool,
    ) -> Result<RenderOutput> {
        request.validate()?;
        let cam = crate::validate::check_inputs(gaussians, camera, config)?;
        self.frame = None;
        self.generation += 1;
        let res = self.scoped(|r| r.render_inner(gaussians, &cam, request, config, guess));
        if res.is_err() {
            self.frame = None;
        }
        res
    }

    fn render_inner(
        &mut self,
        g: &Gaussians,
        cam: &CamParams,
        request: &RenderRequest,
        config: &RasterConfig,
        guess: bool,
    ) -> Result<RenderOutput> {
        let nn = g.len() as u64;
        let bands = self.frame_bands(g, cam)?;
        self.write_camera(g, cam, request, config);
        // No buffer holds anything needed any more: the pool may shrink now (the model's own
        // pool only when it is not resident).
        self.pool.begin_frame();
        let t0 = Instant::now();
        self.model.prepare(&self.ctx, g)?;
        let t1 = Instant::now();
        let rb = self.readback(request, cam, nn, self.bufs.staging)?;
        let guess = if guess { self.guess_of(cam, config, nn) } else { None };
        if let Some((cap, windows)) = guess
            && let Some((out, frame)) = self.render_guessed(g, cam, config, request, &bands, &rb, (cap, windows))?
        {
            return Ok(self.finish_render(out, frame, (t0, t1)));
        }
        self.render_counted(g, cam, request, config, &bands, &rb, (t0, t1))
    }

    /// The checks of a render's sizes against the device's limits; its bands of tile rows.
    pub(super) fn frame_bands(&self, g: &Gaussians, cam: &CamParams) -> Result<Vec<(u32, u32, u64, u64)>> {
        let n_tiles = (cam.tiles_x * cam.tiles_y) as u64;
        self.check_binding("the splat buffer", g.len() as u64 * bytes_of::<Splat>(1))?;
        let bands = self.bands(cam)?;
        self.check_binding("the tile ranges", n_tiles * 8)?;
        if cam.tiles_x > 65535 {
            return Err(RasterError::Gpu(format!(
                "{} tile columns exceed 65535 workgroups per dimension",
                cam.tiles_x
            )));
        }
        Ok(bands)
    }

    /// The render's camera and switches, for the next submission's kernels.
    pub(super) fn write_camera(&self, g: &Gaussians, cam: &CamParams, request: &RenderRequest, config: &RasterConfig) {
        let flags = request.color as u32
            | (request.geo() as u32) << 1
            | (request.expected_depth as u32) << 2
            | (request.observed as u32) << 3;
        self.disp
            .write_frame(&CamUniform::new(cam, config, g, flags, request.applied_cut()));
    }

    /// The render counting its intersections first (two submissions and readbacks): a size
    /// not rendered before, or one whose guess fell short. The camera is written.
    #[allow(clippy::too_many_arguments)]
    fn render_counted(
        &mut self,
        g: &Gaussians,
        cam: &CamParams,
        request: &RenderRequest,
        config: &RasterConfig,
        bands: &[(u32, u32, u64, u64)],
        rb: &Readback,
        (t0, t1): (Instant, Instant),
    ) -> Result<RenderOutput> {
        let npix = cam.width as u64 * cam.height as u64;
        let n_tiles = (cam.tiles_x * cam.tiles_y) as u64;
        let (visible, total) = self.project_and_count(g, npix, n_tiles)?;
        if total > config.max_intersections as u64 || total > u32::MAX as u64 {
            return Err(RasterError::TooManyIntersections {
                count: total,
                cap: config.max_intersections,
            });
        }
        self.check_binding("the tile intersections", total * 4)?;
        // No tile list is longer than the visible Gaussians or the intersections.
        let windows = (total as u32).min(visible as u32).max(1).div_ceil(self.split.forward_window());
        self.reserve_blend(total, rb);
        let mut enc = self.disp.encoder();
        self.blend(&mut enc, cam, request, bands, g.len() as u32, (total as u32, windows), rb)?;
        self.disp.submit(enc);
        let out = self.ctx.read_mapped(self.pool.buffer(rb.staging), rb.bytes, |bytes| {
            let t2 = Instant::now();
            let out = self.forward_output(g, cam, config, request, rb, bytes, visible, total as u32);
            (out.map(|(out, max_last)| (out, max_last, longest_tile_list(bytes, rb, total))), t2)
        })?;
        let (out, t2) = out;
        let (out, max_last, longest) = out?;
        let frame = Frame { generation: self.generation, total: total as u32, max_last };
        self.remember(cam, total, longest);
        Ok(self.finish_render((out, t2), frame, (t0, t1)))
    }

    /// The render's timings and frame; returns its output.
    fn finish_render(&mut self, (out, t2): (RenderOutput, Instant), frame: Frame, (t0, t1): (Instant, Instant)) -> RenderOutput {
        self.timings.render = GpuTimings { upload: t1 - t0, device: t2 - t1, unpack: t2.elapsed() };
        self.frame = Some(frame);
        out
    }

    /// Phase 1 alone (a render of a size not rendered before, or whose guess fell short):
    /// submitted with its counters' readback; returns the visible Gaussians and the exact
    /// total of intersections.
    fn project_and_count(&mut self, g: &Gaussians, npix: u64, n_tiles: u64) -> Result<(usize, u64)> {
        self.reserve_projection(g, npix, n_tiles);
        let mut enc = self.encode_projection(g)?;
        let (p, b) = (&self.pool, &self.bufs);
        enc.encoder.copy_buffer_to_buffer(p.buffer(b.counters), 0, p.buffer(b.staging), 0, 32);
        self.disp.submit(enc);
        let head: Vec<u32> = bytemuck::pod_collect_to_vec(&self.ctx.read_buffer(p.buffer(b.staging), 32)?);
        Ok((head[0] as usize, head[2] as u64 | (head[3] as u64) << 32))
    }

    /// The buffers of phase 1 and the per-pixel outputs, before anything is encoded (a buffer
    /// that grows loses its contents).
    pub(super) fn reserve_projection(&mut self, g: &Gaussians, npix: u64, n_tiles: u64) {
        let nn = g.len() as u64;
        let (p, b) = (&mut self.pool, &self.bufs);
        let (splat, rect) = (bytes_of::<Splat>(1), bytes_of::<TileRect>(1));
        p.ensure(b.splat, (nn + 1) * splat);
        p.ensure(b.proj, (nn + 1) * rect);
        p.ensure(b.radii, nn * 4 + 4);
        for k in [b.keys_a, b.vals_a, b.keys_b, b.vals_b, b.counts, b.observed] {
            p.ensure(k, nn * 4 + 4);
        }
        self.sort.reserve(p, nn);
        self.sort.prefix_scan().reserve(p, nn + 1);
        p.ensure(b.ranges, n_tiles * 8);
        p.ensure(b.acc, npix * 32);
        p.ensure(b.depth_plane, npix * 4);
        p.ensure(b.final_t, npix * 4);
        p.ensure(b.last, npix * 4);
        p.ensure(b.counters, 64);
        p.ensure(b.staging, 64);
    }

    /// Phase 1 encoded: projection (chunked), depth sort, per-Gaussian tile counts and their
    /// scan; the visible Gaussians and the total of intersections land in `counters`.
    pub(super) fn encode_projection(&self, g: &Gaussians) -> Result<Encoder> {
        let n32 = g.len() as u32;
        let nn = n32 as u64;
        let nc = coeffs_for_degree(g.sh_degree) as u64;
        let b = &self.bufs;
        let (splat, rect) = (bytes_of::<Splat>(1), bytes_of::<TileRect>(1));
        let (param, sh) = (bytes_of::<ParamRecord>(1), bytes_of::<ShCoeff>(1));
        let (d, p, k, model) = (&self.disp, &self.pool, &self.kernels, &self.model);
        let mut enc = d.encoder();
        enc.encoder.clear_buffer(p.buffer(b.counters), 0, Some(64));
        // Every render's pixel counts start at zero, so that the buffer holds this render's
        // (zeros without intersections) for a step that reads it.
        enc.encoder.clear_buffer(p.buffer(b.observed), 0, Some(nn * 4 + 4));
        for (bb, m) in chunks(n32) {
            let pass = PassUniform {
                n: m as u32,
                base: bb as u32,
                ..Default::default()
            };
            let binds = [
                model.pool.range(model.params, bb * param, m * param),
                model.pool.range(model.sh, bb * nc * sh, m * nc * sh),
                p.range(b.splat, bb * splat, m * splat),
                p.range(b.proj, bb * rect, m * rect),
                p.whole(b.keys_a),
                p.whole(b.vals_a),
                p.whole(b.counters),
                p.range(b.radii, bb * 4, m * 4),
            ];
            d.dispatch_1d(&mut enc, &k.project, &binds, pass)?;
        }
        let (a, bpair) = (
            (p.whole(b.keys_a), p.whole(b.vals_a)),
            (p.whole(b.keys_b), p.whole(b.vals_b)),
        );
        let in_b = self.sort.encode(d, &mut enc, p, [a, bpair], n32, 32)?;
        debug_assert!(!in_b);
        let binds = [
            p.whole(b.keys_a),
            p.whole(b.vals_a),
            p.whole(b.proj),
            p.whole(b.counts),
            p.whole(b.counters),
        ];
        let pass = PassUniform {
            n: n32,
            ..Default::default()
        };
        d.dispatch_1d(&mut enc, &k.isect_count, &binds, pass)?;
        enc.encoder
            .clear_buffer(p.buffer(b.counts), nn * 4, Some(4));
        let counts = p.range(b.counts, 0, nn * 4 + 4);
        self.sort
            .prefix_scan()
            .encode(d, &mut enc, p, counts, n32 + 1)?;
        Ok(enc)
    }

    /// The buffers of phase 2 for `entries` intersections (the exact total, or a guess) and
    /// the staging buffer of `rb`, before anything is encoded.
    pub(super) fn reserve_blend(&mut self, entries: u64, rb: &Readback) {
        let (p, b) = (&mut self.pool, &self.bufs);
        for k in [b.keys_b, b.vals_b, b.keys_c, b.vals_c, b.isect_gid, b.gids, b.isect_pos] {
            p.ensure(k, entries * 4 + 4);
        }
        self.sort.reserve(p, entries);
        p.ensure(rb.staging, rb.bytes);
    }

    /// Phase 2 encoded: emit the (tile, emission index) pairs into `entries` slots (padding
    /// after the intersections when `entries` is a guess), sort them by tile, find the tile
    /// ranges and links, blend in `windows` windows, and copy the outputs to the staging buffer.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn blend(
        &self,
        enc: &mut Encoder,
        cam: &CamParams,
        request: &RenderRequest,
        bands: &[(u32, u32, u64, u64)],
        n: u32,
        (entries, windows): (u32, u32),
        rb: &Readback,
    ) -> Result<()> {
        if entries > 0 {
            self.emit_and_sort(enc, cam, n, entries)?;
            self.blend_windows(enc, cam, bands, windows)?;
            if rb.plane_depth.is_some() {
                self.plane_depth_bands(enc, bands)?;
            }
            self.copy_outputs(enc, cam, request, bands, n, rb);
        }
        for (image, kernel) in [(&rb.colour, &self.kernels.colour_out), (&rb.surface, &self.kernels.surface_out)] {
            if let Some(image) = image {
                self.device_image_bands(enc, bands, (kernel, image), entries == 0)?;
            }
        }
        let (p, b) = (&self.pool, &self.bufs);
        let nn = n as u64;
        if let Some(at) = rb.radii.filter(|_| nn > 0) {
            enc.encoder.copy_buffer_to_buffer(p.buffer(b.radii), 0, p.buffer(rb.staging), at, nn * 4);
        }
        Ok(())
    }

    /// Emission windows, the stable tile sort, the tile ranges and the links (Gaussian ids in
    /// tile-list order, list positions by emission index).
    fn emit_and_sort(
        &self,
        enc: &mut Encoder,
        cam: &CamParams,
        n32: u32,
        entries: u32,
    ) -> Result<()> {
        let (d, p, b, k) = (&self.disp, &self.pool, &self.bufs, &self.kernels);
        let n_tiles = (cam.tiles_x * cam.tiles_y) as u64;
        // No rectangle has more entries than there are tiles.
        for wi in 0..(n_tiles as u32).div_ceil(ENTRY_WINDOW) {
            let binds = [
                p.whole(b.keys_a),
                p.whole(b.vals_a),
                p.whole(b.proj),
                p.whole(b.counts),
                p.whole(b.keys_b),
                p.whole(b.vals_b),
                p.whole(b.isect_gid),
            ];
            let pass = PassUniform {
                n: n32,
                shift: wi * ENTRY_WINDOW,
                nb: (wi + 1).saturating_mul(ENTRY_WINDOW),
                ..Default::default()
            };
            d.dispatch_1d(enc, &k.isect_emit, &binds, pass)?;
        }
        let all = PassUniform {
            n: entries,
            ..Default::default()
        };
        d.dispatch_1d(enc, &k.pad_keys, &[p.whole(b.keys_b), p.whole(b.ranges), p.whole(b.counters)], all)?;
        let bits = (32 - (n_tiles.max(2) as u32 - 1).leading_zeros()).max(1);
        let bpair = (p.whole(b.keys_b), p.whole(b.vals_b));
        let cpair = (p.whole(b.keys_c), p.whole(b.vals_c));
        let tiles_in_c = self.sort.encode(d, enc, p, [bpair, cpair], entries, bits)?;
        enc.encoder
            .clear_buffer(p.buffer(b.ranges), 0, Some(n_tiles * 8));
        let (tk, tv) = if tiles_in_c { (b.keys_c, b.vals_c) } else { (b.keys_b, b.vals_b) };
        d.dispatch_1d(enc, &k.tile_ranges, &[p.whole(tk), p.whole(b.ranges), p.whole(b.counters)], all)?;
        let links = [p.whole(tv), p.whole(b.isect_gid), p.whole(b.gids), p.whole(b.isect_pos), p.whole(b.counters)];
        d.dispatch_1d(enc, &k.isect_link, &links, all)?;
        Ok(())
    }

    /// The forward blend, per band of tile rows and `windows` windows of tile-list positions.
    fn blend_windows(
        &self,
        enc: &mut Encoder,
        cam: &CamParams,
        bands: &[(u32, u32, u64, u64)],
        windows: u32,
    ) -> Result<()> {
        let (d, p, b, k) = (&self.disp, &self.pool, &self.bufs, &self.kernels);
        let window = self.split.forward_window();
        for &(r0, rows, p0, bp) in bands {
            for wi in 0..windows {
                d.make_room(enc, 1);
                let binds = [
                    p.whole(b.ranges),
                    p.whole(b.gids),
                    p.whole(b.splat),
                    p.range(b.acc, p0 * 32, bp * 32),
                    p.range(b.final_t, p0 * 4, bp * 4),
                    p.range(b.last, p0 * 4, bp * 4),
                    p.whole(b.observed),
                    p.whole(b.counters),
                ];
                let pass = PassUniform {
                    n: bp as u32,
                    shift: wi * window,
                    nb: (wi + 1).saturating_mul(window),
                    base: r0,
                    mode: (wi == 0) as u32 | ((wi + 1 == windows) as u32) << 1,
                    ..Default::default()
                };
                d.dispatch(enc, &k.raster_fwd, &binds, pass, (cam.tiles_x, rows))?;
            }
        }
        Ok(())
    }

    /// `plane_depth_plane` per band of tile rows: the plane depth of each pixel from the
    /// band's accumulators into `depth_plane`.
    fn plane_depth_bands(&self, enc: &mut Encoder, bands: &[(u32, u32, u64, u64)]) -> Result<()> {
        let (p, b) = (&self.pool, &self.bufs);
        self.per_band(enc, bands, &self.kernels.plane_depth, PassUniform::default(), |p0, bp| {
            [p.range(b.acc, p0 * 32, bp * 32), p.range(b.depth_plane, p0 * 4, bp * 4)]
        })
    }

    /// `colour_out` or `surface_out` (`kernel`) per band of tile rows: each pixel's colour
    /// (accumulated colour plus T_final · background) or surface (z, Ñ, D, A) into `image`;
    /// when nothing was blended (`empty`) the background, or zeros.
    fn device_image_bands(&self, enc: &mut Encoder, bands: &[(u32, u32, u64, u64)], (kernel, image): (&Kernel, &DeviceImage), empty: bool) -> Result<()> {
        let (p, b) = (&self.pool, &self.bufs);
        let pass = PassUniform { mode: empty as u32, ..Default::default() };
        self.per_band(enc, bands, kernel, pass, |p0, bp| [p.range(b.acc, p0 * 32, bp * 32), p.range(b.final_t, p0 * 4, bp * 4), image.pixels(p0, bp)])
    }
}
