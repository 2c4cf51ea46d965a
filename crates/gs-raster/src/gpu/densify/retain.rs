//! Removing Gaussians from the resident model by a mask (the multi-view trim, the floater
//! rule; docs/architecture.md §GPU): the twin of gs-train's `retain_rows` with the statistics'
//! `retain`. The mask goes up (4 bytes a Gaussian), a scan gives each survivor its place, and
//! the scatters of density control move the survivors' records, SH, moments and statistics
//! into the next buffer set, which becomes the model's. Nothing is read back.

use super::{Densify, DensifyUniform};
use crate::gpu::WgpuRasterizer;
use crate::gpu::kernels::ParamRecord;
use crate::gpu::resident::StatRecord;
use crate::{RasterError, Result, TrimOnDevice};
use gs_core::Gaussians;
use gs_core::sh::coeffs_for_degree;
use gs_gpu::{PassUniform, bytes_of};

impl WgpuRasterizer {
    /// Keeps the rows of the resident model (of `g`'s size and degree; `g` itself is not read)
    /// where `keep` is true, in order, with their parameters, moments and densification
    /// statistics. Returns the Gaussians left, or `None`, with the model unchanged, where the
    /// model's buffers do not fit one storage binding each (the host then removes them). A
    /// mask of another length, or one that keeps nothing, is an error: the caller keeps at
    /// least one Gaussian, as the host's rule does.
    pub fn retain_resident(&mut self, g: &Gaussians, keep: &[bool]) -> Result<Option<usize>> {
        let r = self.resident_to_change(g, "removing Gaussians")?;
        if keep.len() != r.n {
            return Err(RasterError::InvalidGaussians(format!("a keep mask of {} rows for a model of {} Gaussians", keep.len(), r.n)));
        }
        let kept = keep.iter().filter(|k| **k).count();
        if kept == 0 && r.n > 0 {
            return Err(RasterError::InvalidGaussians("a keep mask that keeps no Gaussian".into()));
        }
        if kept == r.n {
            return Ok(Some(kept));
        }
        let nc = coeffs_for_degree(r.sh_degree) as u64;
        if !self.rows_fit(r.n as u64, nc) {
            return Ok(None);
        }
        self.make_densify()?;
        self.scoped(|s| s.retain_scoped(keep, kept, nc))?;
        Ok(Some(kept))
    }

    /// The retain of `keep` (keeping `kept` rows) on the made kernels.
    fn retain_scoped(&mut self, keep: &[bool], kept: usize, nc: u64) -> Result<()> {
        let n = keep.len() as u64;
        let d = self.densify.as_mut().expect("made above");
        // The mask and a last zero, scanned in place into each survivor's row.
        crate::gpu::upload_with(&self.ctx, &mut self.pool, d.dest, keep.len() + 1, |out: &mut [u32]| {
            out.iter_mut().zip(keep.iter().chain([&false])).for_each(|(o, k)| *o = *k as u32)
        });
        self.reserve_retain(n, nc);
        let d = self.densify.as_ref().expect("made above");
        let mut enc = d.disp.encoder();
        self.sort.prefix_scan().encode(&d.disp, &mut enc, &self.pool, self.pool.whole(d.dest), n as u32 + 1)?;
        self.encode_scatter_kept(&mut enc, n, nc)?;
        self.densify.as_ref().expect("made above").disp.submit(enc);
        self.swap_in_kept(kept);
        Ok(())
    }

    /// Makes the keep mask of `n` rows (of `nc` SH coefficients) in `dest` with `make_mask`
    /// (kernels that write 1 for each survivor and a last zero), scans it into each survivor's
    /// row and returns the survivors' number (the scan's total, read back: 4 bytes).
    pub(super) fn scan_mask(&mut self, n: u64, nc: u64, make_mask: impl FnOnce(&Self, &mut gs_gpu::Encoder) -> Result<()>) -> Result<usize> {
        let d = self.densify.as_ref().expect("made by the caller");
        self.pool.ensure(d.dest, 4 * (n + 1));
        self.pool.ensure(self.bufs.staging, 16);
        self.reserve_retain(n, nc);
        let d = self.densify.as_ref().expect("made by the caller");
        let mut enc = d.disp.encoder();
        make_mask(self, &mut enc)?;
        let p = &self.pool;
        self.sort.prefix_scan().encode(&d.disp, &mut enc, p, p.whole(d.dest), n as u32 + 1)?;
        let staging = p.buffer(self.bufs.staging);
        enc.encoder.copy_buffer_to_buffer(p.buffer(d.dest), 4 * n, staging, 0, 4);
        d.disp.submit(enc);
        Ok(self.ctx.read_mapped(staging, 4, bytemuck::pod_read_unaligned::<u32>)? as usize)
    }

    /// After [`Self::scan_mask`] found `kept` survivors of `n` rows: where none survives,
    /// nothing changes (`NoneKept`: the caller keeps the most opaque one, as the host's rule
    /// does); else the survivors move into the next buffer set, which becomes the model's.
    pub(super) fn keep_scanned(&mut self, n: u64, nc: u64, kept: usize) -> Result<TrimOnDevice> {
        if kept == 0 && n > 0 {
            return Ok(TrimOnDevice::NoneKept);
        }
        if kept < n as usize {
            let d: &Densify = self.densify.as_ref().expect("made by the caller");
            let mut enc = d.disp.encoder();
            self.encode_scatter_kept(&mut enc, n, nc)?;
            self.densify.as_ref().expect("made by the caller").disp.submit(enc);
            self.swap_in_kept(kept);
        }
        Ok(TrimOnDevice::Kept(kept))
    }

    /// Sizes the buffers a retain of `n` rows of `nc` SH coefficients binds besides `dest`
    /// (which the caller fills with the keep mask and a last zero), and writes its frame.
    pub(super) fn reserve_retain(&mut self, n: u64, nc: u64) {
        let d = self.densify.as_mut().expect("made by the caller");
        let p = &mut self.pool;
        self.sort.prefix_scan().reserve(p, n + 1);
        // The born rows and parents are not read (no row is born), but are bound.
        p.ensure(d.born, bytes_of::<ParamRecord>(1));
        p.ensure(d.parents, 4);
        d.reserve_next(&mut self.model.pool, n, nc);
        self.model.pool.ensure(d.next_stats, bytes_of::<StatRecord>(n as usize).max(bytes_of::<StatRecord>(1)));
        d.disp.write_frame(&DensifyUniform { n: n as u32, nc: nc as u32, ..Default::default() });
    }

    /// Records the scatters of every row whose scanned `dest` says it stays (of `n` rows):
    /// record, SH, moments and statistics into the next buffer set.
    pub(super) fn encode_scatter_kept(&self, enc: &mut gs_gpu::Encoder, n: u64, nc: u64) -> Result<()> {
        let (p, m, d) = (&self.pool, &self.model, self.densify.as_ref().expect("made by the caller"));
        d.disp.make_room(enc, 3);
        let pass = PassUniform { n: n as u32, ..Default::default() };
        let mp = |id| m.pool.whole(id);
        let binds = [mp(m.params), mp(m.m_params), mp(m.v_params), p.whole(d.born), p.whole(d.dest), mp(d.next[0]), mp(d.next[1]), mp(d.next[2])];
        d.disp.dispatch_1d(enc, d.kernel("densify_scatter"), &binds, pass)?;
        if nc > 0 {
            let binds = [mp(m.sh), mp(m.m_sh), mp(m.v_sh), p.whole(d.parents), p.whole(d.dest), mp(d.next[3]), mp(d.next[4]), mp(d.next[5])];
            d.disp.dispatch_1d(enc, d.kernel("densify_scatter_sh"), &binds, pass)?;
        }
        d.disp.dispatch_1d(enc, d.kernel("densify_scatter_stats"), &[mp(m.stats), p.whole(d.dest), mp(d.next_stats)], pass)?;
        Ok(())
    }

    /// The next buffer set, holding `kept` rows, becomes the model's.
    pub(super) fn swap_in_kept(&mut self, kept: usize) {
        let d: &mut Densify = self.densify.as_mut().expect("made by the caller");
        self.model.swap_rows(&mut d.next, kept);
        std::mem::swap(&mut self.model.stats, &mut d.next_stats);
    }
}
