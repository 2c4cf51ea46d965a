//! What a device L_p evaluation gives back: pending on the device or made on the host, and how
//! its statistics and gradient come together from the device's sums.

use super::reduce::{self, NccTotals, PlaneGrad};
use super::Readback;
use crate::photometric::{PhotometricConfig, PhotometricOutput, SourceStats};
use gs_gpu::{DeviceImage, PendingRead};

/// L_p started by [`super::PhotometricGpu::start`]: on the device, or already made (on the
/// host, or without a patch to evaluate).
pub struct PendingPhotometric(pub(super) Pending);

/// What [`super::PhotometricGpu::finish_on_device`] gives: L_p made on the host (its gradient
/// there), or its values with the gradient image on the device.
pub enum PhotometricOnDevice {
    /// Made on the host (grey images too large for the device, or no patch to evaluate).
    Host(PhotometricOutput<f32>),
    /// Made on the device.
    Device {
        /// L_p, summed over sources.
        loss: f64,
        /// Each source's statistics.
        per_source: Vec<SourceStats>,
        /// ∂L_p/∂(Ñ, D) of each reference pixel: `[H][W]` gs-gpu `PlaneGrad`s (4 channels).
        gradient: DeviceImage,
    },
}

pub(super) enum Pending {
    /// `kept`: the gradient image, when it stays on the device.
    Device { read: PendingRead, layout: Readback, done: Done, kept: Option<DeviceImage> },
    Ready(PhotometricOutput<f32>),
}

/// What the output needs besides the device's totals: what the host counted of each source
/// (`None` when the device selected the patches: then from the totals' visibility counts,
/// with `config`'s cap) and the size.
pub(super) struct Done {
    pub counted: Option<Vec<SourceStats>>,
    pub config: PhotometricConfig,
    pub width: usize,
    pub height: usize,
}

impl Done {
    /// The output from each source's totals and the gradient image.
    pub fn output(self, totals: &[NccTotals], grads: &[PlaneGrad]) -> PhotometricOutput<f32> {
        let (w, h) = (self.width, self.height);
        let (loss, per_source) = self.stats(totals);
        let mut out = PhotometricOutput { loss, per_source, grad_normal: vec![0.0; w * h * 3], grad_distance: vec![0.0; w * h], width: w, height: h };
        reduce::unpack_gradient(&mut out, grads);
        out
    }

    /// L_p and each source's statistics from each source's totals (and their visibility
    /// counts where the host has not counted).
    pub fn stats(self, totals: &[NccTotals]) -> (f64, Vec<SourceStats>) {
        let cap = self.config.max_pixels_per_source;
        let mut counted = self.counted.map(Vec::into_iter);
        let per_source: Vec<SourceStats> = totals.iter().map(|t| reduce::source_stats(counted.as_mut().and_then(Iterator::next), t, cap)).collect();
        (per_source.iter().fold(0.0, |sum, s| sum + s.loss), per_source)
    }
}
