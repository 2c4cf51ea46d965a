//! Range checks of every setting; a message names the setting by its key (as `--set` takes it).

use super::{InitMode, TrainConfig};
use crate::error::{Result, TrainError};

impl TrainConfig {
    /// Checks every value against its documented range; the message names the option.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(TrainError::InvalidConfig(m));
        if self.iterations == 0 || self.iterations > 10_000_000 {
            return bad(format!("iterations = {} must be in 1..=10,000,000", self.iterations));
        }
        if !(self.warmup_end <= self.photometric_end && self.photometric_end <= self.features_end) {
            return bad(format!(
                "phase boundaries must be ordered: warmup_end {} ≤ photometric_end {} ≤ features_end {}",
                self.warmup_end, self.photometric_end, self.features_end
            ));
        }
        self.check_schedule_fits()?;
        if self.source_views == 0 || self.source_views > 16 {
            return bad(format!("source_views = {} must be in 1..=16", self.source_views));
        }
        if !(1..=4).contains(&self.ncc_scale) {
            return bad(format!("ncc_scale = {} must be in 1..=4", self.ncc_scale));
        }
        if self.patch_size % 2 == 0 || !(3..=9).contains(&self.patch_size) {
            return bad(format!("patch_size = {} must be odd in 3..=9", self.patch_size));
        }
        if self.max_pixels_per_source == 0 {
            return bad("max_pixels_per_source must be positive".into());
        }
        if !(self.sh_min_gain.is_finite() && self.sh_min_gain < 1.0) {
            return bad(format!("sh_min_gain = {} must be finite and below 1", self.sh_min_gain));
        }
        if self.sh_degree_max > 3 {
            return bad(format!("sh_degree_max = {} must be ≤ 3", self.sh_degree_max));
        }
        if self.max_gaussians == 0 || self.max_gaussians > gs_core::gaussians::MAX_GAUSSIANS {
            return bad(format!("max_gaussians = {} must be in 1..={}", self.max_gaussians, gs_core::gaussians::MAX_GAUSSIANS));
        }
        let w = &self.weights;
        for (name, v) in [
            ("beta1", w.beta1),
            ("beta2", w.beta2),
            ("lambda_nc", w.lambda_nc),
            ("lambda_ns", w.lambda_ns),
            ("lambda_p", w.lambda_p),
            ("lambda_f", w.lambda_f),
            ("tau", w.tau),
            ("lambda_o", w.lambda_o),
            ("lambda_s", w.lambda_s),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("{name} = {v} must be finite and ≥ 0"));
            }
        }
        if w.beta1 > 1.0 {
            return bad(format!("beta1 = {} must be ≤ 1", w.beta1));
        }
        let lr = &self.lr;
        for (name, v) in [
            ("lr.position_init", lr.position_init as f32),
            ("lr.position_final", lr.position_final as f32),
            ("lr.sh_dc", lr.sh_dc),
            ("lr.sh_rest", lr.sh_rest),
            ("lr.opacity", lr.opacity),
            ("lr.scaling", lr.scaling),
            ("lr.rotation", lr.rotation),
        ] {
            if !(v.is_finite() && v >= 0.0 && v < 10.0) {
                return bad(format!("{name} = {v} must be in [0, 10)"));
            }
        }
        if lr.position_init > 0.0 && !(lr.position_final > 0.0) {
            return bad("lr.position_final must be positive (log-linear decay)".into());
        }
        let d = &self.densify;
        if d.interval == 0 {
            return bad("densify.interval must be positive".into());
        }
        for (name, v) in [
            ("densify.grad_threshold", d.grad_threshold),
            ("densify.abs_grad_threshold", d.abs_grad_threshold),
            ("densify.percent_dense", d.percent_dense),
            ("densify.min_opacity", d.min_opacity),
            ("densify.max_screen_radius", d.max_screen_radius),
            ("densify.max_world_scale", d.max_world_scale),
            ("densify.gaussians_per_surface_pixel", d.gaussians_per_surface_pixel),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("{name} = {v} must be finite and ≥ 0"));
            }
        }
        if let Some(r) = &d.region {
            r.validate().map_err(TrainError::InvalidConfig)?;
        }
        let f = &d.floaters;
        if !(f.fraction.is_finite() && (0.0..=1.0).contains(&f.fraction)) {
            return bad(format!("densify.floaters.fraction = {} must be in [0, 1]", f.fraction));
        }
        if !(f.margin.is_finite() && (0.0..1.0).contains(&f.margin)) {
            return bad(format!("densify.floaters.margin = {} must be in [0, 1)", f.margin));
        }
        if !(f.min_alpha.is_finite() && f.min_alpha > 0.0 && f.min_alpha <= 1.0) {
            return bad(format!("densify.floaters.min_alpha = {} must be in (0, 1]", f.min_alpha));
        }
        if f.min_views == 0 {
            return bad("densify.floaters.min_views must be positive".into());
        }
        if !(f.path_clearance.is_finite() && (0.0..=1.0).contains(&f.path_clearance)) {
            return bad(format!("densify.floaters.path_clearance = {} must be in [0, 1] (a share of the camera spacing)", f.path_clearance));
        }
        if !(d.growth_window > 0.0 && d.growth_window <= 1.0) {
            return bad(format!("densify.growth_window = {} must be in (0, 1]", d.growth_window));
        }
        let c2f = &self.coarse_to_fine;
        if c2f.levels > 3 {
            return bad(format!("coarse_to_fine.levels = {} must be ≤ 3", c2f.levels));
        }
        if c2f.levels > 0 && c2f.until > self.warmup_end {
            return bad(format!(
                "coarse_to_fine.until = {} must not pass warmup_end = {} (the geometry terms run at full size)",
                c2f.until, self.warmup_end
            ));
        }
        if self.multiview_interval == 0 {
            return bad("multiview_interval must be positive".into());
        }
        if !(1..=8).contains(&self.source_depth_downscale) {
            return bad(format!("source_depth_downscale = {} must be in 1..=8", self.source_depth_downscale));
        }
        if !(self.smoothing_3d >= 0.0 && self.smoothing_3d <= crate::smoothing::MAX_K) {
            return bad(format!("smoothing_3d = {} must lie in [0, {}]", self.smoothing_3d, crate::smoothing::MAX_K));
        }
        // The renderer's settings (near plane, background, low-pass filter) by the renderer's rules.
        match self.raster_config().validate() {
            Err(gs_raster::RasterError::InvalidConfig(m)) => return bad(m),
            Err(e) => return bad(e.to_string()),
            Ok(()) => {}
        }
        if matches!(self.init, InitMode::Cube | InitMode::Sphere) && self.random_points == 0 {
            return bad("random_points must be positive for cube/sphere init".into());
        }
        Ok(())
    }

    /// Refuses phase boundaries beyond the last iteration (e.g. `--set iterations=20` on a
    /// schedule of thousands): the phases after them would never run, and the run would end
    /// in the colour warm-up without a word. A boundary equal to `iterations` is allowed (that
    /// phase runs to the end, or the next one is empty).
    fn check_schedule_fits(&self) -> Result<()> {
        let d = &self.densify;
        let boundaries = [
            ("warmup_end", self.warmup_end, "the colour warm-up"),
            ("photometric_end", self.photometric_end, "the L_p phase"),
            ("features_end", self.features_end, "the L_f phase"),
            ("densify.from", d.from, "densification"),
            ("densify.until", d.until, "densification"),
            ("densify.prune_big_after", d.prune_big_after, "large-Gaussian pruning"),
        ];
        let beyond: Vec<String> = boundaries
            .iter()
            .filter(|(_, v, _)| *v > self.iterations)
            .map(|(k, v, what)| format!("{k} = {v} ({what})"))
            .collect();
        if beyond.is_empty() {
            return Ok(());
        }
        Err(TrainError::InvalidConfig(format!(
            "iterations = {} ends before the schedule's boundaries {}, so the phases after them would never run; give --iterations {} to scale the whole schedule, or set those boundaries to at most {} too",
            self.iterations,
            beyond.join(", "),
            self.iterations,
            self.iterations
        )))
    }
}
