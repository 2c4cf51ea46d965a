//! Where a step's outputs go (docs/architecture.md §GPU): what its render brings to the host
//! and keeps on the device, and where the depth memo keeps the view's plane depth.

use super::{ReferenceExecutor, RunInputs};
use crate::error::Result;
use crate::plan::StepPlan;
use crate::source_depths::StoredDepth;
use crate::trainer::TrainState;
use gs_core::Image;
use gs_raster::RenderRequest;

impl ReferenceExecutor {
    /// The step's render request, and where its depths go: the colour stays on the device when
    /// L_I runs there and no exposure correction on the host reads it; the surface (z, Ñ,
    /// D, A) stays there for L_nc/L_ns and L_p when they run on the device, so Ñ, D and the
    /// alpha need not come back (docs/architecture.md §GPU). The memo's depths may stay on the
    /// device where L_p reads them there and L_f, if it runs, runs there too (on L_p's υ/ω):
    /// then this view's depth stays there too, kept by L_p under this iteration, and so do the
    /// sources rendered for the step ([`crate::source_depths`]); elsewhere the sources' depths
    /// come back first.
    pub(super) fn step_request(&mut self, run: &RunInputs<'_>, state: &mut TrainState, plan: &StepPlan) -> Result<(RenderRequest, DepthsPlaced)> {
        let color_on_device = self.devices.image_on_device() && (state.exposure.is_none() || self.devices.exposure_on_device());
        let r = &plan.render;
        let surface_on_device = self.devices.normal_on_device() && (r.normal || r.distance || r.plane_depth);
        let plane_stays = surface_on_device && (plan.photometric.is_none() || self.devices.photometric_on_device());
        let multiview = plan.photometric.is_some() || plan.weights.lambda_f > 0.0;
        let depths_stay = plane_stays && multiview && (plan.weights.lambda_f == 0.0 || self.devices.features_on_device());
        let memo_on_device = *self.memo_on_device.get_or_insert_with(|| crate::source_depths::memo_fits_on_device(run, &self.devices));
        let max_age = run.config.source_depth_max_age;
        let keep_depth = (depths_stay && memo_on_device && max_age > 0 && plan.scale == 1).then_some(plan.iteration);
        match depths_stay {
            true => crate::source_depths::drop_lost(&mut state.source_depths, &self.devices, &self.caches, &plan.sources),
            false => crate::source_depths::bring_back(&mut state.source_depths, &self.devices, &self.caches, Some(&plan.sources))?,
        }
        let request = RenderRequest {
            radii: !self.adam_on_device,
            alpha: r.alpha && !surface_on_device,
            normal: r.normal && !plane_stays,
            distance: r.distance && !plane_stays,
            color_on_device,
            surface_on_device,
            // The plane depth stays in the surface where the memo keeps it there, or where no
            // memo reads it and every term reads it there.
            plane_depth_on_device: keep_depth.is_some() || (depths_stay && max_age == 0),
            // A step on the device gathers its statistics there, from the counts there.
            observed_on_device: self.adam_on_device,
            ..plan.render
        };
        Ok((request, DepthsPlaced { keep_depth, sources_stay: depths_stay && memo_on_device }))
    }

    /// Records the reference's plane depth (rendered at full size) in the memo, where it serves
    /// later steps as this view's source depth: from the host, or kept on the device by L_p
    /// under `keep` (where it was not, it is forgotten and rendered again when needed).
    pub(super) fn store_reference_depth(&self, state: &mut TrainState, plan: &StepPlan, camera: &gs_core::Camera, host: Option<Image>, keep: Option<u64>) {
        let (w, h, it) = (camera.width as usize, camera.height as usize, plan.iteration);
        let kept = || self.caches.grey(plan.slot).is_some_and(|g| self.devices.holds_depth(plan.slot, g, w * h, it));
        match host {
            Some(depth) => state.source_depths.store(plan.slot, it, StoredDepth::Host(depth)),
            None if keep.is_some() && kept() => state.source_depths.store(plan.slot, it, StoredDepth::Device { width: w, height: h }),
            None if keep.is_some() => state.source_depths.forget(plan.slot),
            None => {}
        }
    }
}

/// Where a step's depths go ([`ReferenceExecutor::step_request`]).
pub(super) struct DepthsPlaced {
    /// The version under which L_p keeps the reference's depth on the device.
    pub(super) keep_depth: Option<u64>,
    /// Whether the sources rendered for the step keep their depths on the device.
    pub(super) sources_stay: bool,
}
