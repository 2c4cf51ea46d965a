//! L_p's sums on the device (`reduce.wgsl`): the per-row statistics, 1/|V| of each source and
//! the gradient image, from the patch results that stay on the device. The host reads one
//! record a (source, row) and one a pixel instead of one a patch (docs/architecture.md §GPU).

use super::{Entry, NccFrame, NccResult};
use crate::photometric::{PhotometricOutput, SourceStats};
use gs_gpu::{Binding, GeneratedStruct};

gs_gpu::wgsl_struct! {
    /// One (source, row)'s statistics (WGSL `struct NccRowSums`): the sums of υω·cost and of
    /// cost over its valid patches (compensated f32, in order), and its patches inside the
    /// source and valid. 16 bytes.
    pub(crate) struct NccRowSums as "NccRowSums" {
        weighted: f32,
        cost: f32,
        inside: u32,
        valid: u32,
    }
}

/// One reference pixel's ∂L_p/∂Ñ and ∂L_p/∂D: gs-gpu's record, which the rasterizer's
/// backward reads when the gradient image stays on the device.
pub(crate) use gs_gpu::PlaneGrad;

/// The reduction kernels' storage bindings, by name (slot order).
pub(super) const BINDINGS: [Binding<'static>; 7] = [
    Binding::read("entries", "array<u32>"),
    Binding::read("results", "array<NccResult>"),
    Binding::read("weights", "array<f32>"),
    Binding::read("row_starts", "array<u32>"),
    Binding::write("row_sums", "array<NccRowSums>"),
    Binding::write("scales", "array<f32>"),
    Binding::write("grads", "array<PlaneGrad>"),
];

/// The passes in order.
pub(super) const PASSES: [&str; 3] = ["ncc_rows", "ncc_scales", "ncc_gradient"];

/// The frame uniform and the records the reduction reads or writes.
pub(super) fn generated_structs() -> [GeneratedStruct; 4] {
    use gs_gpu::GeneratedStruct as G;
    [G::of::<NccFrame>(), G::of::<NccResult>(), G::of::<NccRowSums>(), G::of::<PlaneGrad>()]
}

/// The reduction's whole WGSL source.
pub fn reduce_kernel_source() -> String {
    gs_gpu::kernel_source(&[&gs_gpu::declarations(&generated_structs()), include_str!("reduce.wgsl")], &BINDINGS)
}

/// For each source's entries (`ranges` into `entries`, each row-major), the first entry of
/// each of the `h` rows of width `w` and one past the last: `h + 1` global indices a source.
pub(super) fn row_starts(entries: &[Entry], ranges: &[std::ops::Range<usize>], w: usize, h: usize) -> Vec<u32> {
    let mut starts = Vec::with_capacity(ranges.len() * (h + 1));
    for range in ranges {
        let mut i = range.start;
        for y in 0..=h {
            while i < range.end && (entries[i] as usize) < y * w {
                i += 1;
            }
            starts.push(i as u32);
        }
    }
    starts
}

/// One source's statistics from its rows' sums, the rows added in order in f64 as
/// [`crate::photometric_loss`] adds its rows: L_p,s = Σ υω·cost / |V|.
pub(super) fn source_stats(mut stats: SourceStats, rows: &[NccRowSums]) -> SourceStats {
    for r in rows {
        stats.n_inside_source += r.inside as usize;
        stats.n_valid += r.valid as usize;
        stats.weighted_cost_sum += r.weighted as f64;
        stats.cost_sum += r.cost as f64;
    }
    if stats.n_valid > 0 {
        stats.loss = stats.weighted_cost_sum / stats.n_valid as f64;
    }
    stats
}

/// Writes the gradient image's records into `out`'s planes.
pub(super) fn unpack_gradient(out: &mut PhotometricOutput<f32>, grads: &[PlaneGrad]) {
    for ((n, d), g) in out.grad_normal.chunks_exact_mut(3).zip(out.grad_distance.iter_mut()).zip(grads) {
        n.copy_from_slice(&g.n);
        *d = g.d;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_match_their_wgsl_layout() {
        let src = reduce_kernel_source();
        gs_gpu::check_layouts(&generated_structs(), &src).unwrap();
        gs_gpu::validate_kernel(&src).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!([gs_gpu::bytes_of::<NccRowSums>(1), gs_gpu::bytes_of::<PlaneGrad>(1)], [16, 16]);
    }

    #[test]
    fn row_starts_bound_each_sources_rows() {
        // A 3×2 image: source 0 picks pixels 1, 3, 5; source 1 picks pixel 4.
        let entries = [1, 3, 5, 4];
        let starts = row_starts(&entries, &[0..3, 3..4], 3, 2);
        assert_eq!(starts, vec![0, 1, 3, 3, 3, 4]);
    }
}
