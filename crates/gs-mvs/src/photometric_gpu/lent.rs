//! υ/ω that L_p made on the device, lent to L_f of the same step (docs/architecture.md §GPU):
//! both weigh the same (reference pixel, source) pairs by the same visibility of the same
//! plane depths, so L_f reads L_p's records where they are instead of reading the depths back
//! and making υ/ω again on the host.

use gs_gpu::{DeviceImage, wgpu};

/// The visibility of a [`super::PhotometricGpu`] evaluation whose υ/ω ran on the device: each
/// (source, pixel)'s υω and flags, each (source, row)'s counts and ω sum, the surface it was
/// made from and the keys and depth versions of its views. Valid until that executor's next
/// evaluation (which makes or drops its own).
#[derive(Debug, Clone)]
pub struct DeviceVisibility {
    /// `VisTexel`s, source-major, `[H][W]` a source.
    pub(crate) texels: wgpu::Buffer,
    /// `VisRow`s, source-major, `H` a source.
    pub(crate) rows: wgpu::Buffer,
    /// The reference surface whose z it was made from.
    pub(crate) surface: wgpu::Buffer,
    /// The reference's key, then each source's.
    pub(crate) views: Vec<u64>,
    /// Each source's plane depth version.
    pub(crate) depth_versions: Vec<u64>,
    pub(crate) width: usize,
    pub(crate) height: usize,
}

impl DeviceVisibility {
    /// Whether it was made from `surface` for the views `views` (the reference's key, then each
    /// source's) with the sources' depths at `depth_versions`.
    pub fn is_of(&self, surface: &DeviceImage, views: &[u64], depth_versions: &[u64]) -> bool {
        self.surface == *surface.buffer()
            && self.views == views
            && self.depth_versions == depth_versions
            && (self.width, self.height) == (surface.width(), surface.height())
    }

    /// Its sources.
    pub fn sources(&self) -> usize {
        self.depth_versions.len()
    }
}
