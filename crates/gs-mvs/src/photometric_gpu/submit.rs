//! How a device L_p evaluation reaches the device: its inputs staged (uploads and buffer
//! sizes), the patch kernel and the reduction recorded, and the sums read back.

use super::reference::{Plane, RefView};
use super::{Entries, NccFrame, NccPair, NccResult, PhotometricGpu, gpu_error, reduce, reference, select};
use crate::error::Result;
use crate::geometry::{PairGeometry, padded, padded_rows};
use crate::photometric::{NccMode, PhotometricConfig, PhotometricSource};
use gs_gpu::{BufId, DeviceImage, PassUniform, PendingRead};

impl PhotometricGpu {
    /// Uploads an evaluation's inputs (the plane only when it is on the host; the entries only
    /// when the host selected them) and sizes its buffers.
    pub(super) fn stage(&mut self, inputs: &Inputs<'_>, plane: Plane<'_>, entries: &Entries<'_>, keep: bool) {
        self.pool.begin_frame();
        let (b, frame) = (&self.bufs, inputs.frame);
        let texels = match plane {
            Plane::Host { normal, distance } => reference::plane_texels(&normal, &distance),
            Plane::Device(_) => Vec::new(),
        };
        let mut uploads: Vec<(BufId, &[u8])> = vec![
            (b.pairs, bytemuck::cast_slice(inputs.pairs)),
            (b.surface, bytemuck::cast_slice(&texels)),
            (b.rays, bytemuck::cast_slice(inputs.rays)),
        ];
        if let Entries::Host { entries, weights, row_starts } = entries {
            uploads.extend([(b.entries, bytemuck::cast_slice(entries)), (b.weights, bytemuck::cast_slice(weights)), (b.row_starts, bytemuck::cast_slice(row_starts))]);
        }
        for (id, bytes) in uploads {
            self.pool.ensure(id, bytes.len() as u64);
            self.ctx.write_buffer(self.pool.buffer(id), 0, bytes);
        }
        let count = entries.count(frame.sources as usize) as u64;
        let layout = Readback::of(frame, keep);
        let outputs = [
            (b.entries, 4 * count),
            (b.weights, 4 * count),
            (b.row_starts, gs_gpu::bytes_of::<u32>((frame.sources * (frame.height + 1)) as usize)),
            (b.results, std::mem::size_of::<NccResult>() as u64 * count),
            (b.row_sums, gs_gpu::bytes_of::<reduce::NccRowSums>((frame.sources * frame.height) as usize)),
            (b.totals, layout.totals),
            (b.vis_rows, gs_gpu::bytes_of::<select::VisRow>(1)),
            (b.scales, gs_gpu::bytes_of::<f32>(frame.sources as usize)),
            (b.grads, gs_gpu::bytes_of::<reduce::PlaneGrad>(frame.pixels as usize)),
            (b.staging, layout.total()),
        ];
        for (id, bytes) in outputs {
            self.pool.ensure(id, bytes.max(4));
        }
        self.disp.write_frame(frame);
    }

    /// Records the patch kernel over each source's entries (`ranges`: its first entry and at
    /// most how many) and the reduction.
    pub(super) fn encode_patches(&self, enc: &mut gs_gpu::Encoder, frame: &NccFrame, plane: Plane<'_>, ranges: &[(u32, u32)]) -> Result<()> {
        let (b, p) = (&self.bufs, &self.pool);
        let [pairs, entries, mut surface, row_starts, rays, results] = [b.pairs, b.entries, b.surface, b.row_starts, b.rays, b.results].map(|id| p.whole(id));
        if let Plane::Device(image) = plane {
            surface = gs_gpu::Bind::whole(image.buffer());
        }
        let patch_binds = [pairs, entries, surface, row_starts, self.greys.bind(), rays, results];
        let sum_binds = [b.entries, b.results, b.weights, b.row_starts, b.row_sums, b.scales, b.grads].map(|id| p.whole(id));
        // One dispatch per source over its entries: `base` its first entry, `p1` its pair.
        for (k, &(base, n)) in ranges.iter().enumerate() {
            self.disp.make_room(enc, 1);
            let per_source = PassUniform { n, base, p1: k as u32, ..Default::default() };
            self.disp.dispatch_1d(enc, &self.kernel, &patch_binds, per_source).map_err(gpu_error)?;
        }
        let threads = [frame.sources * frame.height, frame.sources, frame.pixels];
        self.disp.make_room(enc, self.sums.len());
        for (kernel, n) in self.sums.iter().zip(threads) {
            self.disp.dispatch_1d(enc, kernel, &sum_binds, PassUniform { n, ..Default::default() }).map_err(gpu_error)?;
        }
        Ok(())
    }

    /// Records each source's totals (with its rows' visibility counts when `vis_back`), copies
    /// what the host reads (the totals, the gradient unless it is copied into `kept`) into the
    /// staging buffer, submits, and requests the readback (one round trip).
    pub(super) fn read_sums(&self, mut enc: gs_gpu::Encoder, frame: &NccFrame, kept: Option<&DeviceImage>, vis_back: bool) -> Result<(PendingRead, Readback)> {
        let (b, p) = (&self.bufs, &self.pool);
        let layout = Readback::of(frame, kept.is_some());
        let binds = [b.row_sums, b.vis_rows, b.totals].map(|id| p.whole(id));
        self.disp.make_room(&mut enc, 1);
        self.disp.dispatch_1d(&mut enc, &self.totals, &binds, PassUniform { n: frame.sources, p1: vis_back as u32, ..Default::default() }).map_err(gpu_error)?;
        let staging = p.buffer(b.staging);
        enc.encoder.copy_buffer_to_buffer(p.buffer(b.totals), 0, staging, 0, layout.totals);
        let grad_bytes = gs_gpu::bytes_of::<reduce::PlaneGrad>(frame.pixels as usize);
        match kept {
            Some(image) => enc.encoder.copy_buffer_to_buffer(p.buffer(b.grads), 0, image.buffer(), 0, grad_bytes),
            None => enc.encoder.copy_buffer_to_buffer(p.buffer(b.grads), 0, staging, layout.totals, grad_bytes),
        }
        self.disp.submit(enc);
        Ok((self.ctx.request_read(staging, layout.total()), layout))
    }
}

/// What an evaluation's readback holds, in order: each source's totals, and the gradient
/// image unless it stays on the device.
#[derive(Debug, Clone, Copy)]
pub(super) struct Readback {
    totals: u64,
    grads: u64,
}

impl Readback {
    pub(super) fn of(frame: &NccFrame, keep: bool) -> Self {
        Self {
            totals: gs_gpu::bytes_of::<reduce::NccTotals>(frame.sources as usize),
            grads: if keep { 0 } else { gs_gpu::bytes_of::<reduce::PlaneGrad>(frame.pixels as usize) },
        }
    }

    pub(super) fn total(&self) -> u64 {
        self.totals + self.grads
    }

    /// The readback's parts.
    pub(super) fn split(&self, m: &[u8]) -> (Vec<reduce::NccTotals>, Vec<reduce::PlaneGrad>) {
        let (totals, grads) = m.split_at(self.totals as usize);
        (bytemuck::pod_collect_to_vec(totals), bytemuck::pod_collect_to_vec(grads))
    }
}

/// The host-built inputs of one evaluation.
pub(super) struct Inputs<'a> {
    pub frame: &'a NccFrame,
    pub pairs: &'a [NccPair],
    pub rays: &'a [f32],
}

/// The frame, the reference's ray tables and the pair records of an evaluation whose grey
/// images lie at `offsets` in the arena (the reference's first), each source's geometry and
/// grey scale in `geometry`.
pub(super) fn patch_inputs(
    reference: &RefView<'_>,
    sources: &[PhotometricSource<'_, f32>],
    geometry: &[(&PairGeometry<f32>, usize)],
    offsets: &[u32],
    config: &PhotometricConfig,
) -> (NccFrame, Vec<f32>, Vec<NccPair>) {
    let (w, h) = (reference.camera.width as usize, reference.camera.height as usize);
    let mut frame = NccFrame {
        width: w as u32,
        height: h as u32,
        sources: sources.len() as u32,
        pixels: (w * h) as u32,
        grey_width: reference.grey.width as u32,
        side: config.patch_size as u32,
        ref_offset: offsets[0],
        ..Default::default()
    };
    frame.mode = match config.ncc {
        NccMode::Pgsr => 0,
        NccMode::Plain => 1,
    };
    let mut rays = Vec::new();
    if let Some((g, scale)) = geometry.first() {
        let (xs, ys) = g.ref_ray_tables(reference.grey.width, reference.grey.height);
        rays = [xs, ys].concat();
        frame.grey_scale = *scale as u32;
    }
    let pairs = geometry.iter().zip(sources).zip(&offsets[1..]).map(|((&(g, _), source), &offset)| pair_record(g, offset, source)).collect();
    (frame, rays, pairs)
}

/// The pair record of `g` with the source grey image at `offset` in `greys` (the arena).
fn pair_record(g: &PairGeometry<f32>, offset: u32, source: &PhotometricSource<'_, f32>) -> NccPair {
    let [a0, a1, a2] = padded_rows(&g.a);
    NccPair {
        a0,
        a1,
        a2,
        kt: padded(&g.kt),
        src_w: g.src_w,
        src_h: g.src_h,
        grey_offset: offset,
        grey_width: source.grey.width as u32,
        grey_height: source.grey.height as u32,
        ..Default::default()
    }
}

