//! The records and kernel table of the device Adam step and the densification statistics
//! (adam.wgsl, adam_params.wgsl, adam_sh.wgsl, densify_stats.wgsl), which gpu/resident.rs runs
//! on the resident model (docs/architecture.md §GPU).

use super::kernels::{ParamGrad, ParamRecord, ShCoeff};
use gs_gpu::{Binding, GeneratedStruct};

gs_gpu::wgsl_struct! {
    /// The constants of one device Adam step (binding 0 of the Adam kernels; WGSL
    /// `struct AdamStep`): each group's bias-corrected factors ([`gs_core::GroupStep`]).
    pub(crate) struct AdamUniform as "AdamStep" {
        /// SH coefficients per Gaussian on the device (the active degree's).
        nc: u32,
        /// 1 when loss terms add their own parameter gradients (binding `extra`).
        extra: u32,
        /// 1 when the step accumulates the densification statistics (densify_stats.wgsl).
        accumulate: u32,
        /// 1 when each view counts the pixels the Gaussian is in front of (binding `observed`).
        pixel_weighted: u32,
        /// How many training-size pixels one rendered pixel spans (the radii count that often).
        radius_scale: f32,
        beta1: f32,
        beta2: f32,
        eps: f32,
        step_means: f32,
        bc2_means: f32,
        step_sh_dc: f32,
        bc2_sh_dc: f32,
        step_sh_rest: f32,
        bc2_sh_rest: f32,
        step_opacity: f32,
        bc2_opacity: f32,
        step_log_scales: f32,
        bc2_log_scales: f32,
        step_rotations: f32,
        bc2_rotations: f32,
    }
}

gs_gpu::wgsl_struct! {
    /// The parameter-space loss terms' own gradients of one Gaussian (WGSL `struct
    /// ExtraGrad`; [`crate::StepExtras`]), added to the backward's by adam_params.wgsl. 16 bytes.
    pub(crate) struct ExtraGrad as "ExtraGrad" {
        /// ∂L/∂ opacity logit (L_o).
        opacity_logit: f32,
        /// ∂L/∂ log-scale (L_s).
        log_scale: [f32; 3],
    }
}

gs_gpu::wgsl_struct! {
    /// One Gaussian's densification statistics on the device (WGSL `struct StatRecord`):
    /// a row of [`gs_core::DensifyStats`], accumulated by densify_stats.wgsl as
    /// [`gs_core::DensifyStats::accumulate`] does on the host.
    pub(crate) struct StatRecord as "StatRecord" {
        /// Σ over views of ‖∂L/∂μ₂ᴅ‖.
        grad_sum: f32,
        /// Σ over views of the AbsGS norm.
        abs_grad_sum: f32,
        /// Views (or, pixel-weighted, pixels) that saw the Gaussian.
        visible_count: u32,
        /// Largest screen radius seen, pixels.
        max_radius: f32,
    }
}

/// The structs of the Adam kernels (declarations and layout test).
pub(super) fn adam_structs() -> [GeneratedStruct; 6] {
    [
        GeneratedStruct::of::<AdamUniform>(),
        GeneratedStruct::of::<ExtraGrad>(),
        GeneratedStruct::of::<ParamRecord>(),
        GeneratedStruct::of::<ShCoeff>(),
        GeneratedStruct::of::<ParamGrad>(),
        GeneratedStruct::of::<StatRecord>(),
    ]
}

/// The step of one scalar (both kernels), then each kernel's own source.
pub(super) const ADAM: &str = include_str!("adam.wgsl");

/// The Adam kernels and the statistics kernel: entry point, own source and storage bindings.
pub(super) fn adam_specs() -> [(&'static str, &'static str, Vec<Binding<'static>>); 3] {
    use Binding as B;
    let (par, sh) = ("array<ParamRecord>", "array<ShCoeff>");
    [
        (
            "adam_params",
            include_str!("adam_params.wgsl"),
            vec![
                B::write("params", par),
                B::write("m_params", par),
                B::write("v_params", par),
                B::read("grads", "array<ParamGrad>"),
                B::read("extra", "array<ExtraGrad>"),
                B::write("flags", "array<atomic<u32>>"),
            ],
        ),
        (
            "adam_sh",
            include_str!("adam_sh.wgsl"),
            vec![B::write("sh", sh), B::write("m_sh", sh), B::write("v_sh", sh), B::read("grads_sh", sh)],
        ),
        (
            "densify_stats",
            include_str!("densify_stats.wgsl"),
            vec![
                B::read("grads", "array<ParamGrad>"),
                B::read("radii", "array<u32>"),
                B::read("observed", "array<u32>"),
                B::write("stats", "array<StatRecord>"),
            ],
        ),
    ]
}


#[cfg(test)]
mod tests {
    use super::*;
    use gs_gpu::{PassUniform, check_layout, kernel_source};

    /// The Adam and statistics kernels' full sources parse and validate, and their generated structs have
    /// the Rust offsets and sizes (naga's layouter against `offset_of!` / `size_of`).
    #[test]
    fn the_adam_kernels_parse_with_the_hosts_layouts() {
        let decls = gs_gpu::declarations(&adam_structs());
        for (entry, own, bindings) in adam_specs() {
            let src = kernel_source(&[&decls, ADAM, own], &bindings);
            check_layout::<PassUniform>(&src).unwrap_or_else(|e| panic!("{entry}: {e}"));
            gs_gpu::check_layouts(&adam_structs(), &src).unwrap_or_else(|e| panic!("{entry}: {e}"));
            gs_gpu::validate_kernel(&src).unwrap_or_else(|e| panic!("{entry}: {e}"));
        }
        assert_eq!(std::mem::size_of::<AdamUniform>(), 4 * 20);
    }
}
