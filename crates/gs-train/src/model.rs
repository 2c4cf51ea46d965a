//! The trained-model type shared by training, meshing, rendering and evaluation: Gaussians
//! over a scene, with the split, the rasterizer settings and the scene extent r they were
//! trained with. A [`crate::Trainer`] lends one of its current state ([`crate::Trainer::model`]);
//! a reopened run folder builds one from `config.json` and `point_cloud.ply`.

use crate::error::{Result, TrainError};
use gs_core::{Gaussians, Scene};
use gs_raster::{RasterConfig, Rasterizer, RenderOutput, RenderRequest};

/// A trained (or training) model, borrowed from whoever owns the scene and the Gaussians.
#[derive(Clone, Copy)]
pub struct TrainedModel<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Training view indices (into `scene.views`).
    pub train: &'a [usize],
    /// Held-out view indices.
    pub test: &'a [usize],
    /// Rasterizer settings of the run (near plane, background).
    pub raster: &'a RasterConfig,
    /// Scene extent r of the training cameras (the unit of the training thresholds).
    pub extent: f64,
    /// The Gaussians.
    pub gaussians: &'a Gaussians,
}

impl TrainedModel<'_> {
    /// Renders `request` of scene view `view` with `rasterizer`.
    pub fn render(&self, rasterizer: &mut Rasterizer, view: usize, request: &RenderRequest) -> Result<RenderOutput> {
        let v = self.scene.views.get(view).ok_or_else(|| TrainError::InvalidScene(format!("view index {view} out of range")))?;
        Ok(rasterizer.render(self.gaussians, &v.camera, request, self.raster)?)
    }
}
