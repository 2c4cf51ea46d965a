//! The trained parameters' optimiser (docs/method.md §Parameters): gs-core's [`Param`] names
//! the per-Gaussian arrays Adam optimises and their row widths; here are their learning rates
//! and the step on the host. The optimiser (gs-core's [`Adam`]) keys its groups by name; every
//! name comes from [`Param::name`] (checkpoints store them).

use crate::config::LearningRates;
use crate::error::{Result, TrainError};
use gs_core::{Adam, AdamConfig, Gaussians};
use gs_raster::GaussianGradients;

pub use gs_core::Param;

/// Initial learning rate of `param` (the means' is set every iteration by the schedule, so 0).
fn initial_lr(param: Param, lr: &LearningRates) -> f32 {
    match param {
        Param::Means => 0.0,
        Param::ShDc => lr.sh_dc,
        Param::ShRest => lr.sh_rest,
        Param::Opacity => lr.opacity,
        Param::LogScales => lr.scaling,
        Param::Rotations => lr.rotation,
    }
}

/// Adam with one zero-moment group per [`Param`] for `n` Gaussians.
pub fn new_optimiser(lr: &LearningRates, n: usize) -> Result<Adam> {
    let mut adam = Adam::new(AdamConfig::default());
    for p in Param::ALL {
        adam.add_group(p.name(), initial_lr(p, lr), n, p.row_width())?;
    }
    Ok(adam)
}

/// Sets the learning rate of `param`'s group.
pub fn set_lr(adam: &mut Adam, param: Param, lr: f32) -> Result<()> {
    adam.group_mut(param.name())?.lr = lr;
    Ok(())
}

/// One Adam step on every parameter array ([`gs_raster::adam_step`]) after checking the means'
/// gradient; `iteration` names a non-finite one.
pub fn adam_step(adam: &mut Adam, g: &mut Gaussians, grads: &GaussianGradients, iteration: u64) -> Result<()> {
    let finite = grads.means.as_flattened().iter().all(|x| x.is_finite());
    if !finite {
        return Err(TrainError::Diverged { iteration, problem: "gradient of the means is not finite".into() });
    }
    gs_raster::adam_step(adam, g, grads)?;
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
