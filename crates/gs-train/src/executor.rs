//! The reference executor of a [`StepPlan`]: render the view on the trainer's rasterizer
//! (CPU or wgpu), evaluate the plan's loss terms on the CPU through the [`LossTerm`] contract,
//! back-propagate through exposure and rasterizer, take the Adam step. This is the numerical
//! reference for any executor that runs the terms elsewhere (a GPU executor implements the same
//! plan and must match it).

use crate::caches::{downscaled_camera, photo};
use crate::error::{Result, TrainError};
use crate::params::{Param, adam_step, set_lr};
use crate::plan::StepPlan;
use crate::profile::{Clock, Part};
use crate::terms::{GradientBuffers, LossValues, SourceInputs, TermInputs};
use crate::trainer::Trainer;
use gs_core::Image;
use gs_raster::RenderRequest;

impl Trainer<'_> {
    /// Fills the per-view caches that `plan` needs (edge guide, grey images, feature maps).
    fn prepare_caches(&mut self, plan: &StepPlan) -> Result<()> {
        let (scene, views, cfg) = (self.scene, &self.train_views, &self.config);
        if plan.needs_guide() {
            self.caches.guide(plan.slot, photo(scene, views, plan.slot), cfg.losses.delta)?;
        }
        let with_reference = |s: &[usize]| std::iter::once(plan.slot).chain(s.to_vec()).collect::<Vec<usize>>();
        if plan.photometric.is_some() {
            for k in with_reference(&plan.sources) {
                self.caches.ensure_grey(k, photo(scene, views, k), cfg.ncc_scale)?;
            }
        }
        if plan.phase.features && !plan.sources.is_empty() {
            let level = cfg.feature_layer;
            for k in with_reference(&plan.sources) {
                self.caches.ensure_features(k, photo(scene, views, k), level)?;
            }
        }
        Ok(())
    }

    /// Renders the plane depth of training slot `slot` without gradients (a source view), at
    /// 1/`source_depth_downscale` of its size and upsampled back when that is above 1.
    fn source_plane_depth(&mut self, slot: usize) -> Result<Image> {
        let req = RenderRequest { color: false, alpha: false, plane_depth: true, ..RenderRequest::default() };
        let camera = &self.scene.views[self.train_views[slot]].camera;
        let s = self.config.source_depth_downscale;
        let rendered_at = downscaled_camera(camera, s)?;
        let out = self.rasterizer.render(&self.state.gaussians, &rendered_at, &req, &self.raster)?;
        let depth = out.plane_depth.expect("requested");
        if s > 1 {
            return crate::source_depths::upsample_depth(&depth, camera.width as usize, camera.height as usize);
        }
        Ok(depth)
    }

    /// Renders the plan's source depths that the memo cannot serve ([`crate::source_depths`]):
    /// with reuse on they go into the memo, else they are returned in source order.
    fn render_source_depths(&mut self, plan: &StepPlan) -> Result<Vec<Image>> {
        let (it, max_age) = (plan.iteration, self.config.source_depth_max_age);
        let mut rendered = Vec::new();
        for &s in &plan.sources {
            if self.state.source_depths.fresh(s, it, max_age).is_none() {
                let d = self.source_plane_depth(s)?;
                if max_age > 0 {
                    self.state.source_depths.store(s, it, d);
                } else {
                    rendered.push(d);
                }
            }
        }
        Ok(rendered)
    }

    /// Carries out `plan` (render, loss terms, backward, Adam; no density control) and returns
    /// the loss values. Accumulates the densification statistics when the plan says so.
    pub fn execute(&mut self, plan: &StepPlan) -> Result<LossValues> {
        let it = plan.iteration;
        let phase = crate::checkpoint::Elapsed::phase_of(&self.config, it);
        let mut clock = Clock::start();
        set_lr(&mut self.state.adam, Param::Means, plan.lr_means)?;
        self.prepare_caches(plan)?;
        let small = downscaled_camera(&self.scene.views[plan.view].camera, plan.scale)?;
        let camera = if plan.scale > 1 { &small } else { &self.scene.views[plan.view].camera };
        if plan.scale > 1 {
            self.caches.ensure_scaled(plan.slot, &self.scene.views[plan.view].image, plan.scale, camera)?;
        }
        self.profile.add(phase, Part::Caches, clock.lap());
        // The sources' depths before the reference's render: a device rasterizer keeps only its
        // last render's state, which the backward below reuses (rendering them after it would
        // cost the backward one more render to rebuild that state). Renders are pure, so the
        // order changes no value.
        let max_age = self.config.source_depth_max_age;
        let rendered_depths = self.render_source_depths(plan)?;
        self.profile.add(phase, Part::SourceDepths, clock.lap());
        let out = self.rasterizer.render(&self.state.gaussians, camera, &plan.render, &self.raster)?;
        let rendered = out.color.as_ref().expect("the plan always renders colour");
        // Exposure compensation: the loss sees exp(a)·c + b of this view.
        let corrected = match &self.state.exposure {
            Some(e) => Some(crate::exposure::apply(rendered, &e.params[plan.slot])?),
            None => None,
        };
        self.profile.add(phase, Part::Render, clock.lap());
        let memo = &self.state.source_depths;
        let depths: Vec<&Image> = match max_age {
            0 => rendered_depths.iter().collect(),
            _ => plan.sources.iter().map(|&s| memo.fresh(s, it, max_age).expect("stored above")).collect(),
        };
        let sources: Vec<SourceInputs> = plan
            .sources
            .iter()
            .zip(depths)
            .map(|(&s, d)| SourceInputs {
                camera: &self.scene.views[self.train_views[s]].camera,
                plane_depth: d,
                grey: self.caches.grey(s),
                features: self.caches.features(s),
            })
            .collect();
        let inputs = TermInputs {
            gaussians: &self.state.gaussians,
            camera,
            photo: self.caches.scaled(plan.slot, plan.scale).unwrap_or(&self.scene.views[plan.view].image),
            render: &out,
            color: corrected.as_ref().unwrap_or(rendered),
            guide: self.caches.guide_of(plan.slot),
            grey: self.caches.grey(plan.slot),
            features: self.caches.features(plan.slot),
            sources: &sources,
            devices: &self.devices,
        };
        let mut values = LossValues::default();
        let mut grads = GradientBuffers::default();
        for term in plan.terms(&self.config) {
            term.evaluate(&inputs, &plan.weights, &mut grads, &mut values)?;
            self.profile.add(phase, term.part(), clock.lap());
        }
        values.total = plan.weights.total(&values);
        if !values.total.is_finite() {
            return Err(TrainError::Diverged { iteration: it, problem: format!("the loss is not finite ({})", describe(&values)) });
        }
        drop(sources);
        let grad_color = grads.color.take().expect("L_I always runs");
        let grad_color = match &mut self.state.exposure {
            Some(e) => {
                let (gc, ge) = crate::exposure::backward(rendered, &e.params[plan.slot], &grad_color)?;
                e.step(plan.slot, &ge, it, self.config.iterations)?;
                gc
            }
            None => grad_color,
        };
        let mut g = self.rasterizer.backward(&self.state.gaussians, camera, &self.raster, &out, &grads.as_output(Some(&grad_color)))?;
        if let Some(go) = &grads.opacity_logits {
            g.opacity_logits.iter_mut().zip(go).for_each(|(a, b)| *a += b);
        }
        self.profile.add(phase, Part::Backward, clock.lap());
        if plan.refine.accumulate {
            self.state.stats.accumulate(&out.radii, &g, plan.scale as f32);
        }
        adam_step(&mut self.state.adam, &mut self.state.gaussians, &g, it)?;
        self.profile.add(phase, Part::Optimizer, clock.lap());
        // The reference's plane depth serves later iterations as this view's source depth.
        if max_age > 0
            && plan.scale == 1
            && let Some(depth) = out.plane_depth
        {
            self.state.source_depths.store(plan.slot, it, depth);
        }
        Ok(values)
    }
}

/// The loss values in words, for an error message.
fn describe(v: &LossValues) -> String {
    let mut s = format!("L1 {}, SSIM {}", v.l1, v.ssim);
    for (name, x) in v.optional_terms() {
        if let Some(x) = x {
            s.push_str(&format!(", {name} {x}"));
        }
    }
    s
}
