//! Renders of an image size rendered before, in one submission and one readback
//! (docs/architecture.md §GPU): the intersection buffers and the blend's window count are
//! guessed from the last render of that size plus a quarter, and the counters in the readback
//! say whether the guess held; when it did not, the caller renders again, counting first. The
//! guess changes no value: `pad_keys` sorts the unused entries after the intersections, and
//! the windows beyond the longest list blend nothing.

use super::forward::{Readback, counters_of};
use super::kernels::COUNTER_LONGEST_TILE_LIST;
use super::{FWD_WINDOW, Frame, WgpuRasterizer};
use crate::cpu::project::CamParams;
use crate::{RasterConfig, RenderOutput, RenderRequest, Result};
use gs_core::Gaussians;
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
        Some((cap as u32, (longest as u32).div_ceil(FWD_WINDOW)))
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
        let npix = cam.width as u64 * cam.height as u64;
        let n_tiles = (cam.tiles_x * cam.tiles_y) as u64;
        self.reserve_projection(g, npix, n_tiles);
        self.reserve_blend(cap as u64, rb);
        let mut enc = self.encode_projection(g)?;
        self.blend(&mut enc, cam, request, bands, g.len() as u32, (cap, windows), rb)?;
        self.disp.submit(enc);
        let (out, t2) = self.ctx.read_mapped(self.pool.buffer(self.bufs.staging), rb.bytes, |bytes| {
            let t2 = Instant::now();
            let c = counters_of(bytes, rb);
            let total = c[2] as u64 | (c[3] as u64) << 32;
            let longest = c[COUNTER_LONGEST_TILE_LIST];
            if total > cap as u64 || longest > windows.saturating_mul(FWD_WINDOW) {
                return (None, t2);
            }
            let out = self.forward_output(g, cam, config, request, rb, bytes, c[0] as usize, total as u32);
            (Some(out.map(|(out, max_last)| (out, max_last, total, longest))), t2)
        })?;
        let Some(out) = out else {
            return Ok(None);
        };
        let (out, max_last, total, longest) = out?;
        self.remember(cam, total, longest);
        Ok(Some(((out, t2), Frame { generation: self.generation, total: total as u32, max_last })))
    }
}
