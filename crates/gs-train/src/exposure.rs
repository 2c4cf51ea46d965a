//! Optional per-view exposure compensation: the rendered colour of training view k is corrected
//! by a per-channel affine map c' = exp(a_k)·c + b_k before the image loss, with (a_k, b_k)
//! learned by their own Adam (the idea of PGSR's and Hierarchical 3DGS's exposure compensation
//! for photos whose exposure or white balance varies; here per-channel gain and bias rather than
//! a full 3×4 matrix). The Gaussians then model the scene under one reference exposure: held-out
//! views and `vagsl render` use the identity (a = b = 0). Off by default (`--exposure` turns it
//! on); the learned values are written to `OUT/exposure.json`. The colour map and its backward
//! are gs-losses' (`apply_exposure`, `exposure_backward`; on the device `ExposureGpu`).

use crate::error::Result;
use gs_core::{Adam, AdamConfig, ExponentialLr};

pub use gs_losses::ExposureParams;

/// Learning rate at the first iteration. 1e-3 (→ 1e-4) learned the gains too slowly in short
/// runs: on the test of `tests/tests/exposure.rs` it gained 0.9 dB of held-out PSNR where
/// 1e-2 (→ 1e-3) gains 1.4 dB.
pub const EXPOSURE_LR_INIT: f64 = 1e-2;
/// Learning rate at the last iteration, log-linear in between.
pub const EXPOSURE_LR_FINAL: f64 = 1e-3;

/// The per-view parameters and their optimiser.
#[derive(Debug, Clone, PartialEq)]
pub struct Exposure {
    /// One entry per training view (index = slot in the trainer's `train_views`).
    pub params: Vec<ExposureParams>,
    /// Adam with one group "exposure" of `views × 6`.
    pub adam: Adam,
}

impl Exposure {
    /// Identity corrections for `views` training views.
    pub fn new(views: usize) -> Result<Self> {
        let mut adam = Adam::new(AdamConfig::default());
        adam.add_group("exposure", EXPOSURE_LR_INIT as f32, views, 6)?;
        Ok(Self { params: vec![[0.0; 6]; views], adam })
    }

    /// One Adam step with the gradient of view `slot` (every other view gets a zero gradient,
    /// as with one parameter tensor in PyTorch) at learning rate for iteration `it` of `total`.
    pub fn step(&mut self, slot: usize, grad: &ExposureParams, it: u64, total: u64) -> Result<()> {
        let lr = ExponentialLr::new(EXPOSURE_LR_INIT, EXPOSURE_LR_FINAL, total).at(it);
        self.adam.group_mut("exposure")?.lr = lr as f32;
        let mut g = vec![0.0f32; self.params.len() * 6];
        g[slot * 6..slot * 6 + 6].copy_from_slice(grad);
        self.adam.step("exposure", self.params.as_flattened_mut(), &g)?;
        Ok(())
    }
}

/// The corrected colour of a render whose colour stayed on the device (`colour`), made there
/// by `devices` for training slot `slot`; `None` without exposure compensation or a device
/// colour.
#[cfg(feature = "wgpu")]
pub(crate) fn correct_on_device(
    devices: &crate::devices::LossDevices,
    exposure: Option<&Exposure>,
    slot: usize,
    colour: Option<&gs_gpu::DeviceImage>,
) -> Result<Option<gs_gpu::DeviceImage>> {
    match (exposure, colour) {
        (Some(e), Some(c)) => Ok(Some(devices.apply_exposure(c, &e.params[slot])?)),
        _ => Ok(None),
    }
}

/// The exposure's backward on the device, where the colour and L_I's gradient stayed there:
/// `grads`' device colour gradient becomes ∂L/∂c, and view `slot`'s (a, b) take their Adam
/// step of iteration `it` of `total` (on the host, as [`Exposure::step`]).
#[cfg(feature = "wgpu")]
pub(crate) fn backward_on_device(
    devices: &crate::devices::LossDevices,
    exposure: Option<&mut Exposure>,
    (slot, it, total): (usize, u64, u64),
    colour: Option<&gs_gpu::DeviceImage>,
    grads: &mut crate::terms::GradientBuffers,
) -> Result<()> {
    if let (Some(e), Some(c), Some(g)) = (exposure, colour, grads.device_color.as_ref()) {
        let (gc, ge) = devices.exposure_backward(c, &e.params[slot], g)?;
        e.step(slot, &ge, it, total)?;
        grads.device_color = Some(gc);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use gs_core::Image;

    #[test]
    fn identity_at_zero_and_only_the_stepped_view_moves_first() {
        let img = Image::from_vec(2, 1, 3, vec![0.1, 0.2, 0.3, 0.4, 0.5, 0.6]).unwrap();
        assert_eq!(gs_losses::apply_exposure(&img, &[0.0; 6]).unwrap(), img);
        let mut e = Exposure::new(3).unwrap();
        e.step(1, &[1.0, -1.0, 0.5, 0.2, 0.0, -0.3], 1, 100).unwrap();
        assert_eq!(e.params[0], [0.0; 6]);
        assert_eq!(e.params[2], [0.0; 6]);
        // Adam's first step moves each coordinate by lr against the gradient's sign.
        let lr = ExponentialLr::new(EXPOSURE_LR_INIT, EXPOSURE_LR_FINAL, 100).at(1) as f32;
        assert!((e.params[1][0] + lr).abs() < 1e-6 && (e.params[1][1] - lr).abs() < 1e-6);
        assert_eq!(e.params[1][4], 0.0);
    }
}
