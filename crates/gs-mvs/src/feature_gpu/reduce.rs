//! L_f's sums on the device (`reduce.wgsl`): each source's row statistics, its scale
//! 1 / (|V|·N) and its share of the gradient image, from the pair results that stay on the
//! device. The host reads one record a (source, row) and one value a pixel instead of one
//! record a (source, pixel) (docs/architecture.md §GPU).

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

impl AlignRowSums {
    /// The row as the host's `add_source` takes it: pairs in V, the two sums.
    pub(super) fn row(&self) -> (usize, f64, f64) {
        (self.valid as usize, self.weighted as f64, self.cos as f64)
    }
}

/// The reduction kernels' storage bindings, by name (slot order).
pub(super) const BINDINGS: [Binding<'static>; 4] = [
    Binding::read("results", "array<AlignResult>"),
    Binding::write("row_sums", "array<AlignRowSums>"),
    Binding::write("scales", "array<f32>"),
    Binding::write("grads", "array<f32>"),
];

/// The passes, in the order each source runs them.
pub(super) const PASSES: [&str; 3] = ["align_rows", "align_scale", "align_gradient"];

/// The frame uniform and the records the reduction reads or writes.
pub(super) fn generated_structs() -> [GeneratedStruct; 3] {
    use gs_gpu::GeneratedStruct as G;
    [G::of::<AlignFrame>(), G::of::<AlignResult>(), G::of::<AlignRowSums>()]
}

/// The reduction's whole WGSL source.
pub fn reduce_kernel_source() -> String {
    gs_gpu::kernel_source(&[&gs_gpu::declarations(&generated_structs()), include_str!("reduce.wgsl")], &BINDINGS)
}
