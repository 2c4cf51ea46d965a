//! The capture path's floater rule without the model crossing (docs/architecture.md §GPU):
//! each Gaussian's mean is tested against the path's capsules on the device, in f32, and the
//! rows the rule removes go by the retain's scatters (gpu/densify/retain.rs). Where f32 cannot
//! settle a mark (a mean within a band of a capsule's boundary), the row's index and mean come
//! back and the host tests it with its own f64 rule, gs-core's `Capsule::contains`: the rows
//! kept are the host's, bit for bit. Usually none is unsure, and two counts of 4 bytes come
//! back where the host read 44 bytes a Gaussian.

use super::Densify;
use crate::gpu::WgpuRasterizer;
use crate::{RasterError, Result, TrimOnDevice, UnsureRows};
use gs_core::sh::coeffs_for_degree;
use gs_core::{Capsule, Gaussians};
use gs_gpu::{Bind, PassUniform, bytes_of};

gs_gpu::wgsl_struct! {
    /// One capsule of free space (WGSL `struct CapsuleRecord`): gs-core's [`Capsule`] in f32,
    /// its axis given as the f64 difference b − a rounded once, so that a short capsule keeps
    /// its direction. 52 bytes.
    pub(crate) struct CapsuleRecord as "CapsuleRecord" {
        a: [f32; 3],
        ab: [f32; 3],
        fa: [f32; 3],
        fb: [f32; 3],
        radius: f32,
    }
}

gs_gpu::wgsl_struct! {
    /// A Gaussian whose mark f32 could not settle (WGSL `struct UnsurePoint`): its row and
    /// mean. 16 bytes.
    pub(crate) struct UnsurePoint as "UnsurePoint" {
        row: u32,
        mean: [f32; 3],
    }
}

impl CapsuleRecord {
    fn of(c: &Capsule) -> Self {
        let f = |v: gs_core::glam::DVec3| v.as_vec3().to_array();
        Self { a: f(c.a), ab: f(c.b - c.a), fa: f(c.fa), fb: f(c.fb), radius: c.radius as f32 }
    }
}

impl WgpuRasterizer {
    /// Marks each Gaussian of the resident model (of `g`'s size and degree; `g` itself is not
    /// read) inside or outside `capsules` on the device and keeps the marks there for
    /// [`WgpuRasterizer::retain_outside_resident`]. Returns the rows whose mark f32 could not
    /// settle, with their means, for the host to test with [`Capsule::contains`] (usually
    /// none: then 4 bytes come back). `None`, with nothing marked, where the model's buffers
    /// do not fit one storage binding each.
    pub fn mark_capsules_resident(&mut self, g: &Gaussians, capsules: &[Capsule]) -> Result<Option<UnsureRows>> {
        let Some(r) = self.model.residency().filter(|_| self.model.holds(g)) else {
            return Err(RasterError::Gpu("marking the capture path on the device needs the model resident".into()));
        };
        let (n, nc) = (r.n as u64, coeffs_for_degree(r.sh_degree) as u64);
        if !self.rows_fit(n, nc) {
            return Ok(None);
        }
        self.make_densify()?;
        let records: Vec<CapsuleRecord> = capsules.iter().map(CapsuleRecord::of).collect();
        let unsure = self.scoped(|s| s.mark_scoped(n, &records))?;
        self.densify.as_mut().expect("made above").marked = Some(r.n);
        Ok(Some(unsure))
    }

    /// Removes the rows of the resident model (of `g`'s size and degree) that
    /// [`WgpuRasterizer::mark_capsules_resident`] marked inside, and those of its unsure rows
    /// listed in `inside`; the others stay, with their parameters, moments and statistics.
    /// `TrimOnDevice::NoneKept`, with nothing changed, where none would stay; `None` where the
    /// model's buffers do not fit one storage binding each; an error where the marks are not
    /// of this model or a listed row is not one of its rows.
    pub fn retain_outside_resident(&mut self, g: &Gaussians, inside: &[usize]) -> Result<Option<TrimOnDevice>> {
        let marked = self.densify.as_mut().and_then(|d| d.marked.take());
        let r = self.resident_to_change(g, "the capture path's floater rule")?;
        if marked != Some(r.n) {
            return Err(RasterError::Gpu("the capture path's marks are not of the resident model (mark them first)".into()));
        }
        if let Some(row) = inside.iter().find(|&&i| i >= r.n) {
            return Err(RasterError::InvalidGaussians(format!("row {row} listed inside the capture path, of a model of {} Gaussians", r.n)));
        }
        let (n, nc) = (r.n as u64, coeffs_for_degree(r.sh_degree) as u64);
        if !self.rows_fit(n, nc) {
            return Ok(None);
        }
        let settled = self.densify.as_ref().expect("marked above").settled;
        crate::gpu::upload_with(&self.ctx, &mut self.pool, settled, inside.len(), |out: &mut [u32]| {
            out.iter_mut().zip(inside).for_each(|(o, &i)| *o = i as u32)
        });
        self.scoped(|s| {
            let kept = s.scan_mask(n, nc, |s, enc| {
                let d = s.densify.as_ref().expect("made by the caller");
                let binds = s.region_binds();
                if !inside.is_empty() {
                    d.disp.dispatch_1d(enc, d.kernel("densify_settle_marks"), &binds, PassUniform { n: inside.len() as u32, ..Default::default() })?;
                }
                Ok(d.disp.dispatch_1d(enc, d.kernel("densify_outside_keep"), &binds, PassUniform { n: n as u32, ..Default::default() })?)
            })?;
            s.keep_scanned(n, nc, kept)
        })
        .map(Some)
    }

    /// Marks `n` Gaussians against `records`, scans the unsure ones and reads back how many
    /// there are, then (only where there are some) their rows and means.
    fn mark_scoped(&mut self, n: u64, records: &[CapsuleRecord]) -> Result<UnsureRows> {
        let d: &Densify = self.densify.as_ref().expect("made by the caller");
        let (capsules, marks, ranks, unsure, settled, dest) = (d.capsules, d.marks, d.ranks, d.unsure, d.settled, d.dest);
        crate::gpu::upload_with(&self.ctx, &mut self.pool, capsules, records.len(), |out: &mut [CapsuleRecord]| out.copy_from_slice(records));
        self.model.pool.ensure(marks, 4 * n.max(1));
        for (id, bytes) in [(ranks, 4 * (n + 1)), (unsure, bytes_of::<UnsurePoint>(1)), (settled, 4), (dest, 4), (self.bufs.staging, 16)] {
            self.pool.ensure(id, bytes);
        }
        self.sort.prefix_scan().reserve(&mut self.pool, n + 1);
        let d = self.densify.as_ref().expect("made by the caller");
        let (p, binds) = (&self.pool, self.region_binds());
        let mut enc = d.disp.encoder();
        let pass = PassUniform { n: n as u32, p1: records.len() as u32, ..Default::default() };
        d.disp.dispatch_1d(&mut enc, d.kernel("densify_mark_capsules"), &binds, pass)?;
        self.sort.prefix_scan().encode(&d.disp, &mut enc, p, p.whole(ranks), n as u32 + 1)?;
        let staging = p.buffer(self.bufs.staging);
        enc.encoder.copy_buffer_to_buffer(p.buffer(ranks), 4 * n, staging, 0, 4);
        d.disp.submit(enc);
        let total = self.ctx.read_mapped(staging, 4, bytemuck::pod_read_unaligned::<u32>)? as usize;
        if total == 0 {
            return Ok(Vec::new());
        }
        let bytes = bytes_of::<UnsurePoint>(total);
        self.pool.ensure(unsure, bytes);
        self.pool.ensure(self.bufs.staging, bytes);
        let d = self.densify.as_ref().expect("made by the caller");
        let (p, binds) = (&self.pool, self.region_binds());
        let mut enc = d.disp.encoder();
        d.disp.dispatch_1d(&mut enc, d.kernel("densify_unsure_list"), &binds, PassUniform { n: n as u32, ..Default::default() })?;
        let staging = p.buffer(self.bufs.staging);
        enc.encoder.copy_buffer_to_buffer(p.buffer(unsure), 0, staging, 0, bytes);
        d.disp.submit(enc);
        let points: Vec<UnsurePoint> = self.ctx.read_mapped(staging, bytes, bytemuck::pod_collect_to_vec)?;
        Ok(points.into_iter().map(|u| (u.row as usize, u.mean)).collect())
    }

    /// The bindings of densify/region.wgsl, in its order.
    fn region_binds(&self) -> [Bind<'_>; 7] {
        let (p, m, d) = (&self.pool, &self.model, self.densify.as_ref().expect("made by the caller"));
        [m.pool.whole(m.params), p.whole(d.capsules), m.pool.whole(d.marks), p.whole(d.ranks), p.whole(d.unsure), p.whole(d.settled), p.whole(d.dest)]
    }
}
