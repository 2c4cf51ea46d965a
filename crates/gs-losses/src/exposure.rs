//! Per-view exposure compensation's colour map and its backward (the CPU reference; its device
//! twin is [`crate::exposure_gpu`]): the rendered colour of a training view is corrected by a
//! per-channel affine map c' = exp(a)·c + b before the image loss (gs-train's `exposure`
//! learns (a, b) per view; docs/method.md §Parameters, "Exposure").

use crate::error::{LossError, Result};
use gs_core::Image;

/// Parameters of one view: log-gains (R, G, B) then biases (R, G, B).
pub type ExposureParams = [f32; 6];

/// The gains exp(a) of `e`, per channel.
pub fn exposure_gains(e: &ExposureParams) -> [f32; 3] {
    [e[0].exp(), e[1].exp(), e[2].exp()]
}

/// c' = exp(a)·c + b per channel of an RGB image.
pub fn apply_exposure(color: &Image, e: &ExposureParams) -> Result<Image> {
    check_rgb(color, "the colour to correct")?;
    let gain = exposure_gains(e);
    let data = color.data().iter().enumerate().map(|(k, &c)| gain[k % 3] * c + e[3 + k % 3]).collect();
    Ok(Image::from_vec(color.width(), color.height(), 3, data)?)
}

/// Backward of [`apply_exposure`]: from ∂L/∂c' to ∂L/∂c (returned image) and ∂L/∂(a, b) (summed
/// over the pixels in f64).
pub fn exposure_backward(color: &Image, e: &ExposureParams, grad_out: &Image) -> Result<(Image, ExposureParams)> {
    check_rgb(color, "the corrected colour")?;
    if (grad_out.width(), grad_out.height(), grad_out.channels()) != (color.width(), color.height(), 3) {
        return Err(LossError::ShapeMismatch(format!(
            "the exposure's output gradient is {}x{}x{}, its colour {}x{}x3",
            grad_out.width(),
            grad_out.height(),
            grad_out.channels(),
            color.width(),
            color.height()
        )));
    }
    let gain = exposure_gains(e);
    let mut ge = [0.0f64; 6];
    let mut gc = Vec::with_capacity(color.data().len());
    for (k, (&c, &g)) in color.data().iter().zip(grad_out.data()).enumerate() {
        let ch = k % 3;
        gc.push(g * gain[ch]);
        ge[ch] += (g * gain[ch] * c) as f64;
        ge[3 + ch] += g as f64;
    }
    Ok((Image::from_vec(color.width(), color.height(), 3, gc)?, ge.map(|v| v as f32)))
}

fn check_rgb(color: &Image, what: &str) -> Result<()> {
    match color.channels() {
        3 => Ok(()),
        c => Err(LossError::Channels(format!("{what} has {c} channels, not 3"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gs_core::Rng;
    use gs_core::gradcheck::{GradCheck, check_gradient};

    #[test]
    fn backward_matches_finite_differences() {
        let mut rng = Rng::new(7);
        let (w, h) = (5, 4);
        let color: Vec<f32> = (0..w * h * 3).map(|_| rng.uniform_f64() as f32).collect();
        let weights: Vec<f32> = (0..w * h * 3).map(|_| rng.uniform_f64() as f32 - 0.5).collect();
        let e0: ExposureParams = [0.1, -0.2, 0.05, 0.02, -0.01, 0.03];
        // L = Σ w ⊙ c' as a function of (c, a, b).
        let loss = |x: &[f64]| -> f64 {
            let c = Image::from_vec(w, h, 3, x[..w * h * 3].iter().map(|&v| v as f32).collect()).unwrap();
            let e: ExposureParams = std::array::from_fn(|k| x[w * h * 3 + k] as f32);
            apply_exposure(&c, &e).unwrap().data().iter().zip(&weights).map(|(a, b)| (*a * *b) as f64).sum()
        };
        let img = Image::from_vec(w, h, 3, color.clone()).unwrap();
        let (gc, ge) = exposure_backward(&img, &e0, &Image::from_vec(w, h, 3, weights.clone()).unwrap()).unwrap();
        let mut x: Vec<f64> = color.iter().map(|&v| v as f64).collect();
        x.extend(e0.iter().map(|&v| v as f64));
        let mut analytic: Vec<f64> = gc.data().iter().map(|&v| v as f64).collect();
        analytic.extend(ge.iter().map(|&v| v as f64));
        let rep = check_gradient(loss, &x, &analytic, &GradCheck { eps: 1e-3, rtol: 2e-3, atol: 1e-4, indices: None });
        assert!(rep.is_ok(), "{rep:?}");
    }
}
