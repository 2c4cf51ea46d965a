//! The typed layout of the trained parameters (docs/method.md §Parameters): which per-Gaussian arrays Adam
//! optimises, their row widths and learning rates. The optimiser (gs-core's [`Adam`]) keys
//! its groups by name; every name comes from [`Param::name`] here (checkpoints store them).

use crate::config::LearningRates;
use crate::error::{Result, TrainError};
use gs_core::{Adam, AdamConfig, Gaussians};
use gs_raster::GaussianGradients;

/// One optimised parameter array of the Gaussians (an Adam group).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Param {
    /// Means μ (3 per Gaussian); learning rate scheduled log-linearly ×r.
    Means,
    /// SH DC coefficients (3).
    ShDc,
    /// SH coefficients of degrees 1–3 (45).
    ShRest,
    /// Opacity logits (1).
    Opacity,
    /// Log-scales (3).
    LogScales,
    /// Rotation quaternions (4).
    Rotations,
}

impl Param {
    /// Every parameter, in the order of the optimiser groups (and of checkpoints).
    pub const ALL: [Param; 6] = [Param::Means, Param::ShDc, Param::ShRest, Param::Opacity, Param::LogScales, Param::Rotations];

    /// The optimiser group's name (stored in checkpoints).
    pub const fn name(self) -> &'static str {
        match self {
            Param::Means => "means",
            Param::ShDc => "sh_dc",
            Param::ShRest => "sh_rest",
            Param::Opacity => "opacity",
            Param::LogScales => "log_scales",
            Param::Rotations => "rotations",
        }
    }

    /// Scalars per Gaussian.
    pub const fn row_width(self) -> usize {
        match self {
            Param::Means | Param::ShDc | Param::LogScales => 3,
            Param::ShRest => 3 * (gs_core::sh::SH_COEFFS - 1),
            Param::Opacity => 1,
            Param::Rotations => 4,
        }
    }

    /// Initial learning rate (the means' is set every iteration by the schedule, so 0 here).
    fn initial_lr(self, lr: &LearningRates) -> f32 {
        match self {
            Param::Means => 0.0,
            Param::ShDc => lr.sh_dc,
            Param::ShRest => lr.sh_rest,
            Param::Opacity => lr.opacity,
            Param::LogScales => lr.scaling,
            Param::Rotations => lr.rotation,
        }
    }
}

/// Adam with one zero-moment group per [`Param`] for `n` Gaussians.
pub fn new_optimiser(lr: &LearningRates, n: usize) -> Result<Adam> {
    let mut adam = Adam::new(AdamConfig::default());
    for p in Param::ALL {
        adam.add_group(p.name(), p.initial_lr(lr), n, p.row_width())?;
    }
    Ok(adam)
}

/// Sets the learning rate of `param`'s group.
pub fn set_lr(adam: &mut Adam, param: Param, lr: f32) -> Result<()> {
    adam.group_mut(param.name())?.lr = lr;
    Ok(())
}

/// One Adam step on every parameter array. The SH DC and SH rest groups are updated in place
/// inside the Gaussians' 48-float SH records. `iteration` names a non-finite gradient.
pub fn adam_step(adam: &mut Adam, g: &mut Gaussians, grads: &GaussianGradients, iteration: u64) -> Result<()> {
    let finite = grads.means.as_flattened().iter().all(|x| x.is_finite());
    if !finite {
        return Err(TrainError::Diverged { iteration, problem: "gradient of the means is not finite".into() });
    }
    adam.step(Param::Means.name(), g.means.as_flattened_mut(), grads.means.as_flattened())?;
    let stride = 3 * gs_core::sh::SH_COEFFS;
    let (sh, sh_grads) = (g.sh.as_flattened_mut().as_flattened_mut(), grads.sh.as_flattened().as_flattened());
    adam.step_strided(Param::ShDc.name(), sh, sh_grads, stride, 0)?;
    adam.step_strided(Param::ShRest.name(), sh, sh_grads, stride, 3)?;
    adam.step(Param::Opacity.name(), &mut g.opacity_logits, &grads.opacity_logits)?;
    adam.step(Param::LogScales.name(), g.log_scales.as_flattened_mut(), grads.log_scales.as_flattened())?;
    adam.step(Param::Rotations.name(), g.rotations.as_flattened_mut(), grads.rotations.as_flattened())?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_matches_the_gaussians_records() {
        let g = Gaussians::with_len(2).unwrap();
        let widths = [g.means[0].len(), 3, g.sh[0].len() * 3 - 3, 1, g.log_scales[0].len(), g.rotations[0].len()];
        for (p, w) in Param::ALL.iter().zip(widths) {
            assert_eq!(p.row_width(), w, "{}", p.name());
        }
        let adam = new_optimiser(&LearningRates::default(), 5).unwrap();
        let names: Vec<&str> = adam.groups.iter().map(|g| g.name.as_str()).collect();
        assert_eq!(names, ["means", "sh_dc", "sh_rest", "opacity", "log_scales", "rotations"], "checkpoint group names");
        assert!(adam.groups.iter().zip(Param::ALL).all(|(g, p)| g.m.len() == 5 * p.row_width()));
    }
}
