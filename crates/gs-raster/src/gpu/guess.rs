//! Renders of an image size rendered before, in one submission and one readback
//! (docs/architecture.md §GPU): the intersection buffers and the blend's window count are
//! guessed from the last render of that size plus a quarter, and the counters in the readback
//! say whether the guess held; when it did not, the caller renders again, counting first. The
//! guess changes no value: `pad_keys` sorts the unused entries after the intersections, and
//! the windows beyond the longest list blend nothing.

use super::readback::{Readback, counters_of};
use super::kernels::COUNTER_LONGEST_TILE_LIST;
use super::{Frame, GpuTimings, WgpuRasterizer};
use crate::cpu::project::CamParams;
use crate::{RasterConfig, RenderOutput, RenderRequest, Result};
use gs_core::{Camera, Gaussians};
use gs_gpu::PendingRead;
use std::time::Instant;

/// How much a guess adds to the last render's intersections and longest list (a quarter).
const GUESS_MARGIN: u64 = 4;

/// Image sizes whose last render a rasterizer remembers for its guesses.
const GUESSED_SIZES: usize = 8;

/// What the last render of one image size found: the guess of the next one of that size.
#[derive(Debug, Clone, Copy)]
pub(super) struct SizeGuess {
    width: u32,
    height: u32,
    intersections: u64,
    longest_list: u32,
}

impl WgpuRasterizer {
    /// The guess for a render of `cam`'s size: the intersections' capacity and the blend's
    /// window count, from the last render of that size plus a margin, within the request's
    /// cap and one storage binding; `None` for a size not rendered before.
    pub(super) fn guess_of(&self, cam: &CamParams, config: &RasterConfig, n: u64) -> Option<(u32, u32)> {
        let last = self.guesses.iter().find(|s| s.width == cam.width && s.height == cam.height)?;
        let grow = |v: u64| v + v / GUESS_MARGIN + 1024;
        let limit = (config.max_intersections as u64).min(u32::MAX as u64).min(self.ctx.max_storage_binding() / 4);
        let cap = grow(last.intersections).min(limit);
        let longest = grow(last.longest_list as u64).min(cap).min(n).max(1);
        Some((cap as u32, (longest as u32).div_ceil(self.split.forward_window())))
    }

    /// Remembers what a render of `cam`'s size found (the latest [`GUESSED_SIZES`] sizes).
    pub(super) fn remember(&mut self, cam: &CamParams, intersections: u64, longest_list: u32) {
        self.guesses.retain(|s| s.width != cam.width || s.height != cam.height);
        if self.guesses.len() == GUESSED_SIZES {
            self.guesses.remove(0);
        }
        self.guesses.push(SizeGuess { width: cam.width, height: cam.height, intersections, longest_list });
    }

    /// The render in one submission with the intersections' buffers and the blend's windows
    /// sized by `guess`; `None` when the counters that come back exceed it (nothing of it is
    /// kept, and the caller renders again, counting first).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn render_guessed(
        &mut self,
        g: &Gaussians,
        cam: &CamParams,
        config: &RasterConfig,
        request: &RenderRequest,
        bands: &[(u32, u32, u64, u64)],
        rb: &Readback,
        (cap, windows): (u32, u32),
    ) -> Result<Option<((RenderOutput, Instant), Frame)>> {
        self.submit_guessed(g, cam, request, bands, rb, (cap, windows))?;
        let (out, t2) = self.ctx.read_mapped(self.pool.buffer(rb.staging), rb.bytes, |bytes| {
            (self.guessed_output(g, cam, config, request, rb, bytes, (cap, windows)), Instant::now())
        })?;
        let Some(out) = out else {
            return Ok(None);
        };
        let (out, frame, longest) = out?;
        self.remember(cam, frame.total as u64, longest);
        Ok(Some(((out, t2), frame)))
    }

    /// The guessed render's one submission: projection and blend with the intersections'
    /// buffers and the blend's windows sized by `guess`, its outputs copied to `rb`'s staging
    /// buffer (the camera written before).
    fn submit_guessed(
        &mut self,
        g: &Gaussians,
        cam: &CamParams,
        request: &RenderRequest,
        bands: &[(u32, u32, u64, u64)],
        rb: &Readback,
        guess: (u32, u32),
    ) -> Result<()> {
        let npix = cam.width as u64 * cam.height as u64;
        self.reserve_projection(g, npix, (cam.tiles_x * cam.tiles_y) as u64);
        self.reserve_blend(guess.0 as u64, rb);
        let mut enc = self.encode_projection(g)?;
        self.blend(&mut enc, cam, request, bands, g.len() as u32, guess, rb)?;
        self.disp.submit(enc);
        Ok(())
    }

    /// The output of a guessed render from its staging bytes, its frame (`self.generation`
    /// names it) and its longest tile list; `None` when the counters exceed the guess
    /// `(cap, windows)`.
    #[allow(clippy::too_many_arguments)]
    fn guessed_output(
        &self,
        g: &Gaussians,
        cam: &CamParams,
        config: &RasterConfig,
        request: &RenderRequest,
        rb: &Readback,
        bytes: &[u8],
        (cap, windows): (u32, u32),
    ) -> Option<Result<(RenderOutput, Frame, u32)>> {
        let c = counters_of(bytes, rb);
        let total = c[2] as u64 | (c[3] as u64) << 32;
        let longest = c[COUNTER_LONGEST_TILE_LIST];
        if total > cap as u64 || longest > windows.saturating_mul(self.split.forward_window()) {
            return None;
        }
        let out = self.forward_output(g, cam, config, request, rb, bytes, c[0] as usize, total as u32);
        Some(out.map(|(out, max_last)| (out, Frame { generation: self.generation, total: total as u32, max_last }, longest)))
    }
}

/// A render of `render_views` submitted with its readback requested and not waited for.
struct InFlight {
    index: usize,
    cam: CamParams,
    rb: Readback,
    guess: (u32, u32),
    generation: u64,
    read: PendingRead,
}

impl WgpuRasterizer {
    /// Renders `views` in order like [`render`](Self::render) each (the same outputs, bit for
    /// bit), with one wait for all those of a size rendered before: each is submitted right
    /// after the last, into its own staging buffer, and all are read back together. A size not
    /// rendered before counts first and waits, as a render does; a guess that fell short is
    /// rendered again afterwards. The last view's device state is the one kept for a backward
    /// (when a guess of an earlier view fell short, the backward rebuilds it).
    pub fn render_views(&mut self, g: &Gaussians, views: &[(&Camera, RenderRequest)], config: &RasterConfig) -> Result<Vec<RenderOutput>> {
        let mut cams = Vec::with_capacity(views.len());
        for (camera, request) in views {
            request.validate()?;
            cams.push(crate::validate::check_inputs(g, camera, config)?);
        }
        // The sizes not rendered before, except the last view's, render first; the rest
        // are guessed (the last again at the end when it is a new size).
        let last = views.len().saturating_sub(1);
        let new_size = |r: &Self, i: usize| r.guess_of(&cams[i], config, g.len() as u64).is_none();
        let mut outs: Vec<Option<RenderOutput>> = (0..views.len()).map(|_| None).collect();
        for i in 0..last {
            if new_size(self, i) {
                outs[i] = Some(self.render(g, views[i].0, &views[i].1, config)?);
            }
        }
        let guessed: Vec<usize> = (0..views.len()).filter(|&i| outs[i].is_none() && !new_size(self, i)).collect();
        self.frame = None;
        let res = self.scoped(|r| r.render_guessed_together(g, &cams, views, config, &guessed, &mut outs));
        if res.is_err() {
            self.frame = None;
        }
        res?;
        // Whatever is left: the last view when its size is new (counted, as a render of a new
        // size is), and the guesses that fell short (counted at once, not guessed again).
        for i in 0..views.len() {
            if outs[i].is_none() {
                let guess = !guessed.contains(&i);
                outs[i] = Some(self.render_alone(g, views[i].0, &views[i].1, config, guess)?);
            }
        }
        Ok(outs.into_iter().map(|o| o.expect("every view rendered")).collect())
    }

    /// The guessed renders of `views` at `indices`, submitted one after another and read with
    /// one wait; fills `outs` where the guess held (the last one's frame kept when it is the
    /// last submitted).
    fn render_guessed_together(
        &mut self,
        g: &Gaussians,
        cams: &[CamParams],
        views: &[(&Camera, RenderRequest)],
        config: &RasterConfig,
        indices: &[usize],
        outs: &mut [Option<RenderOutput>],
    ) -> Result<()> {
        if indices.is_empty() {
            return Ok(());
        }
        let (nn, t0) = (g.len() as u64, Instant::now());
        self.pool.begin_frame();
        self.model.prepare(&self.ctx, g)?;
        let t1 = Instant::now();
        while self.batch_staging.len() < indices.len() {
            let id = self.pool.add_staging("batch staging");
            self.batch_staging.push(id);
        }
        let mut flying = Vec::with_capacity(indices.len());
        for (k, &index) in indices.iter().enumerate() {
            let (cam, request) = (cams[index], &views[index].1);
            let bands = self.frame_bands(g, &cam)?;
            let guess = self.guess_of(&cam, config, nn).expect("a size rendered before");
            let rb = self.readback(request, &cam, nn, self.batch_staging[k])?;
            self.write_camera(g, &cam, request, config);
            self.submit_guessed(g, &cam, request, &bands, &rb, guess)?;
            self.generation += 1;
            let read = self.ctx.request_read(self.pool.buffer(rb.staging), rb.bytes);
            flying.push(InFlight { index, cam, rb, guess, generation: self.generation, read });
        }
        let newest = self.generation;
        for f in flying {
            let InFlight { index, cam, rb, guess: (cap, windows), generation, read } = f;
            let request = &views[index].1;
            // The output names the render it came from (a backward of an older one rebuilds it).
            self.generation = generation;
            let parsed = self.ctx.finish_read(read, |bytes| self.guessed_output(g, &cam, config, request, &rb, bytes, (cap, windows)))?;
            if let Some(parsed) = parsed {
                let (out, frame, longest) = parsed?;
                self.remember(&cam, frame.total as u64, longest);
                if generation == newest {
                    self.frame = Some(frame);
                }
                outs[index] = Some(out);
            }
        }
        self.generation = newest;
        let t2 = Instant::now();
        self.timings.render = GpuTimings { upload: t1 - t0, device: t2 - t1, unpack: t2.elapsed() };
        Ok(())
    }
}
