//! The CPU backend (the numerical reference): projection, binning, the tiled forward and
//! backward in rayon, and the naive per-pixel reference.

mod backward;
mod forward;
pub(crate) mod project;
pub(crate) mod raster;

pub use backward::backward;
pub use forward::{render, render_naive};

use crate::RenderRequest;
use project::{Features, Splat};

/// The CPU backend's forward state.
#[derive(Debug, Clone)]
pub(crate) struct CpuState {
    pub(crate) n_gaussians: usize,
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) request: RenderRequest,
    /// Visible splats and features in depth order (`order[k]` is the Gaussian of entry k).
    pub(crate) splats: Vec<Splat>,
    pub(crate) features: Vec<Features>,
    pub(crate) order: Vec<u32>,
    pub(crate) bins: raster::Bins,
    pub(crate) final_t: Vec<f32>,
    pub(crate) last: Vec<u32>,
    /// Per pixel Ñ (3), D, Σ w t_z (empty when not blended).
    pub(crate) geo: Vec<[f32; 5]>,
}

impl std::fmt::Debug for raster::Bins {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "Bins({} tiles, {} intersections)",
            self.offsets.len().saturating_sub(1),
            self.ids.len()
        )
    }
}
