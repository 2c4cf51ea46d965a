//! L_p's sums on the device (`reduce.wgsl`): the per-row statistics, 1/|V| of each source and
//! the gradient image, from the patch results that stay on the device, and (`totals.wgsl`)
//! each source's totals of its rows. The host reads one record a source and one a pixel
//! instead of one a patch (docs/architecture.md §GPU).

use super::select::VisRow;
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

gs_gpu::wgsl_struct! {
    /// One source's totals (WGSL `struct NccTotals`, totals.wgsl): its rows' sums of υω·cost,
    /// of cost and (where the device selected the patches) of ω over υ, each added in row order
    /// as a double-f32 pair (hi, lo; `gs_gpu::wide_value`), and its rows' patch and visibility
    /// counts. 48 bytes (WGSL `vec2<f32>` pairs, 8-byte aligned).
    pub(crate) struct NccTotals as "NccTotals" {
        weighted: [f32; 2],
        cost: [f32; 2],
        omega_sum: [f32; 2],
        inside: u32,
        valid: u32,
        upsilon: u32,
        omega_positive: u32,
        candidates: u32,
        pad0: u32,
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

/// The totals kernel's storage bindings, by name (slot order).
pub(super) const TOTALS_BINDINGS: [Binding<'static>; 3] =
    [Binding::read("row_sums", "array<NccRowSums>"), Binding::read("vis_rows", "array<VisRow>"), Binding::write("totals", "array<NccTotals>")];

/// The frame uniform and the records the reduction and the totals read or write.
pub(super) fn generated_structs() -> [GeneratedStruct; 6] {
    use gs_gpu::GeneratedStruct as G;
    [G::of::<NccFrame>(), G::of::<NccResult>(), G::of::<NccRowSums>(), G::of::<PlaneGrad>(), G::of::<VisRow>(), G::of::<NccTotals>()]
}

/// The reduction's whole WGSL source.
pub fn reduce_kernel_source() -> String {
    gs_gpu::kernel_source(&[&gs_gpu::declarations(&generated_structs()), include_str!("reduce.wgsl")], &BINDINGS)
}

/// The totals kernel's whole WGSL source.
#[cfg(test)]
pub(super) fn totals_kernel_source() -> String {
    gs_gpu::kernel_source(&[&gs_gpu::declarations(&generated_structs()), include_str!("totals.wgsl")], &TOTALS_BINDINGS)
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

/// One source's statistics from its totals: what the host counted of it (`counted`), else
/// the visibility and candidate counts of the device's selection (at most `cap` sampled), and
/// L_p,s = Σ υω·cost / |V|.
pub(super) fn source_stats(counted: Option<SourceStats>, t: &NccTotals, cap: Option<usize>) -> SourceStats {
    let mut stats = counted.unwrap_or_else(|| {
        let visibility = crate::visibility::VisibilityStats::of_counts(t.upsilon as usize, t.omega_positive as usize, gs_gpu::wide_value(t.omega_sum));
        super::select::selection_stats(visibility, t.candidates as usize, cap)
    });
    stats.n_inside_source = t.inside as usize;
    stats.n_valid = t.valid as usize;
    stats.weighted_cost_sum = gs_gpu::wide_value(t.weighted);
    stats.cost_sum = gs_gpu::wide_value(t.cost);
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
        assert_eq!([gs_gpu::bytes_of::<NccRowSums>(1), gs_gpu::bytes_of::<PlaneGrad>(1), gs_gpu::bytes_of::<NccTotals>(1)], [16, 16, 48]);
        let src = totals_kernel_source();
        gs_gpu::check_layouts(&generated_structs(), &src).unwrap();
        gs_gpu::validate_kernel(&src).unwrap_or_else(|e| panic!("{e}"));
    }

    #[test]
    fn row_starts_bound_each_sources_rows() {
        // A 3×2 image: source 0 picks pixels 1, 3, 5; source 1 picks pixel 4.
        let entries = [1, 3, 5, 4];
        let starts = row_starts(&entries, &[0..3, 3..4], 3, 2);
        assert_eq!(starts, vec![0, 1, 3, 3, 3, 4]);
    }
}
