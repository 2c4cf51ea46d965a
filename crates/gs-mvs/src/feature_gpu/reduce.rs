//! L_f's sums on the device (`reduce.wgsl`): each source's row statistics, its scale
//! 1 / (|V|·N) and its share of the gradient image, from the pair results that stay on the
//! device, and (`totals.wgsl`) each source's totals of its rows. The host reads one record a
//! source and one value a pixel instead of one record a (source, pixel) (docs/architecture.md
//! §GPU).

use super::{AlignFrame, AlignResult};
use gs_gpu::{Binding, GeneratedStruct};

gs_gpu::wgsl_struct! {
    /// One (source, row)'s statistics (WGSL `struct AlignRowSums`): the sums of υω·|1 − cos|
    /// and of cos over its terms (compensated f32, in order) and its pairs in V. 16 bytes.
    pub(crate) struct AlignRowSums as "AlignRowSums" {
        weighted: f32,
        cos: f32,
        valid: u32,
        pad: u32,
    }
}

gs_gpu::wgsl_struct! {
    /// One source's totals (WGSL `struct AlignTotals`, totals.wgsl): its rows' sums of
    /// υω·|1 − cos|, of cos and (where its υ/ω were made on the device) of ω over υ, each
    /// added in row order as a double-f32 pair (hi, lo; `gs_gpu::wide_value`), its pairs in V
    /// and its visibility counts. 40 bytes.
    pub(crate) struct AlignTotals as "AlignTotals" {
        weighted: [f32; 2],
        cos: [f32; 2],
        omega_sum: [f32; 2],
        valid: u32,
        upsilon: u32,
        omega_positive: u32,
        pad0: u32,
    }
}

impl AlignTotals {
    /// The source's sums as the host's `add_source_sums` takes a row: pairs in V, the two sums.
    pub(super) fn sums(&self) -> (usize, f64, f64) {
        (self.valid as usize, gs_gpu::wide_value(self.weighted), gs_gpu::wide_value(self.cos))
    }

    /// The visibility statistics of the source's rows, where the device made its υ/ω.
    pub(super) fn visibility(&self) -> crate::visibility::VisibilityStats {
        crate::visibility::VisibilityStats::of_counts(self.upsilon as usize, self.omega_positive as usize, gs_gpu::wide_value(self.omega_sum))
    }
}

/// The totals kernel's storage bindings, by name (slot order).
pub(super) const TOTALS_BINDINGS: [Binding<'static>; 3] =
    [Binding::read("row_sums", "array<AlignRowSums>"), Binding::read("vis_rows", "array<VisRow>"), Binding::write("totals", "array<AlignTotals>")];

/// The reduction kernels' storage bindings, by name (slot order).
pub(super) const BINDINGS: [Binding<'static>; 4] = [
    Binding::read("results", "array<AlignResult>"),
    Binding::write("row_sums", "array<AlignRowSums>"),
    Binding::write("scales", "array<f32>"),
    Binding::write("grads", "array<f32>"),
];

/// The passes, in the order each source runs them.
pub(super) const PASSES: [&str; 3] = ["align_rows", "align_scale", "align_gradient"];

/// The frame uniform and the records the reduction and the totals read or write.
pub(super) fn generated_structs() -> [GeneratedStruct; 5] {
    use gs_gpu::GeneratedStruct as G;
    [G::of::<AlignFrame>(), G::of::<AlignResult>(), G::of::<AlignRowSums>(), G::of::<crate::photometric_gpu::VisRow>(), G::of::<AlignTotals>()]
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
