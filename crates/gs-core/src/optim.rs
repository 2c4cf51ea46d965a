//! Adam with per-group learning rates and the log-linear position schedule (3DGS).
//!
//! Each parameter group (means, SH DC, SH rest, opacity, log-scales, rotations) has its own
//! learning rate and its own moment buffers; moments are per scalar, so densification
//! extends, filters or resets them row by row together with the Gaussians.

use crate::error::{CoreError, Result};

/// Adam hyper-parameters shared by all groups (method-spec §3: β = (0.9, 0.999), ε = 1e-15).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdamConfig {
    /// First-moment decay β1.
    pub beta1: f32,
    /// Second-moment decay β2.
    pub beta2: f32,
    /// Denominator ε.
    pub eps: f32,
}

impl Default for AdamConfig {
    fn default() -> Self {
        Self { beta1: 0.9, beta2: 0.999, eps: 1e-15 }
    }
}

/// One parameter group: a learning rate, the number of scalars per row (e.g. 3 for means) and
/// the first/second moments.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamGroup {
    /// Group name (e.g. `"means"`).
    pub name: String,
    /// Current learning rate.
    pub lr: f32,
    /// Scalars per Gaussian.
    pub row_width: usize,
    /// Number of steps taken (for bias correction).
    pub step: u64,
    /// First moments, one per scalar.
    pub m: Vec<f32>,
    /// Second moments, one per scalar.
    pub v: Vec<f32>,
}

/// Adam over named parameter groups.
#[derive(Debug, Clone, PartialEq)]
pub struct Adam {
    /// Hyper-parameters.
    pub config: AdamConfig,
    /// Groups in insertion order.
    pub groups: Vec<ParamGroup>,
}

impl Adam {
    /// An optimiser without groups.
    pub fn new(config: AdamConfig) -> Self {
        Self { config, groups: Vec::new() }
    }

    /// Adds a group of `rows × row_width` scalars with zero moments.
    pub fn add_group(&mut self, name: &str, lr: f32, rows: usize, row_width: usize) -> Result<()> {
        if self.groups.iter().any(|g| g.name == name) {
            return Err(CoreError::Optimizer(format!("group '{name}' exists already")));
        }
        if !(lr.is_finite() && lr >= 0.0) || row_width == 0 {
            return Err(CoreError::Optimizer(format!("group '{name}': bad lr {lr} or row width {row_width}")));
        }
        self.groups.push(ParamGroup {
            name: name.to_string(),
            lr,
            row_width,
            step: 0,
            m: vec![0.0; rows * row_width],
            v: vec![0.0; rows * row_width],
        });
        Ok(())
    }

    /// The group called `name`.
    pub fn group_mut(&mut self, name: &str) -> Result<&mut ParamGroup> {
        self.groups
            .iter_mut()
            .find(|g| g.name == name)
            .ok_or_else(|| CoreError::Optimizer(format!("no group '{name}'")))
    }

    /// One Adam step on group `name`: `params -= lr·m̂/(√v̂ + ε)` with bias-corrected moments
    /// (PyTorch's formula).
    pub fn step(&mut self, name: &str, params: &mut [f32], grads: &[f32]) -> Result<()> {
        let cfg = self.config;
        let g = self.group_mut(name)?;
        if params.len() != g.m.len() || grads.len() != g.m.len() {
            return Err(CoreError::Optimizer(format!(
                "group '{name}': {} parameters and {} gradients for {} moments",
                params.len(),
                grads.len(),
                g.m.len()
            )));
        }
        g.step += 1;
        let bc1 = 1.0 - (cfg.beta1 as f64).powi(g.step.min(i32::MAX as u64) as i32);
        let bc2 = 1.0 - (cfg.beta2 as f64).powi(g.step.min(i32::MAX as u64) as i32);
        let step_size = (g.lr as f64 / bc1) as f32;
        let bc2_sqrt = bc2.sqrt() as f32;
        for ((p, &gr), (m, v)) in params.iter_mut().zip(grads).zip(g.m.iter_mut().zip(g.v.iter_mut())) {
            *m = cfg.beta1 * *m + (1.0 - cfg.beta1) * gr;
            *v = cfg.beta2 * *v + (1.0 - cfg.beta2) * gr * gr;
            let denom = v.sqrt() / bc2_sqrt + cfg.eps;
            *p -= step_size * *m / denom;
        }
        Ok(())
    }

    /// Keeps the rows whose `keep` flag is true in every group (pruning).
    pub fn retain_rows(&mut self, keep: &[bool]) -> Result<()> {
        for g in &mut self.groups {
            if g.m.len() != keep.len() * g.row_width {
                return Err(CoreError::Optimizer(format!(
                    "group '{}': retain mask of {} rows for {} rows",
                    g.name,
                    keep.len(),
                    g.m.len() / g.row_width
                )));
            }
            let w = g.row_width;
            let filter = |buf: &mut Vec<f32>| {
                let mut out = Vec::with_capacity(buf.len());
                for (row, &k) in buf.chunks_exact(w).zip(keep) {
                    if k {
                        out.extend_from_slice(row);
                    }
                }
                *buf = out;
            };
            filter(&mut g.m);
            filter(&mut g.v);
        }
        Ok(())
    }

    /// Appends `rows` rows with zero moments to every group (densification).
    pub fn extend_rows(&mut self, rows: usize) {
        for g in &mut self.groups {
            let n = rows * g.row_width;
            g.m.extend(std::iter::repeat_n(0.0, n));
            g.v.extend(std::iter::repeat_n(0.0, n));
        }
    }

    /// Zeroes the moments of group `name` (used after an opacity reset, as 3DGS does).
    pub fn reset_group(&mut self, name: &str) -> Result<()> {
        let g = self.group_mut(name)?;
        g.m.fill(0.0);
        g.v.fill(0.0);
        Ok(())
    }
}

/// The 3DGS log-linear learning-rate schedule (`get_expon_lr_func`): `lr_init` at step 0 to
/// `lr_final` at `max_steps`, interpolated in log space, with an optional sinusoidal warm-up
/// delay. Used for the means with `lr_init = 1.6e-4·r`, `lr_final = 1.6e-6·r`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExponentialLr {
    /// Learning rate at step 0.
    pub lr_init: f64,
    /// Learning rate at `max_steps` and after.
    pub lr_final: f64,
    /// Steps of the warm-up delay (0 = none).
    pub delay_steps: u64,
    /// Multiplier at step 0 of the delay.
    pub delay_mult: f64,
    /// Length of the decay.
    pub max_steps: u64,
}

impl ExponentialLr {
    /// A schedule without delay.
    pub fn new(lr_init: f64, lr_final: f64, max_steps: u64) -> Self {
        Self { lr_init, lr_final, delay_steps: 0, delay_mult: 1.0, max_steps }
    }

    /// Learning rate at `step`.
    pub fn at(&self, step: u64) -> f64 {
        if self.lr_init == 0.0 && self.lr_final == 0.0 {
            return 0.0;
        }
        let delay = if self.delay_steps > 0 {
            let x = (step as f64 / self.delay_steps as f64).clamp(0.0, 1.0);
            self.delay_mult + (1.0 - self.delay_mult) * (0.5 * std::f64::consts::PI * x).sin()
        } else {
            1.0
        };
        let t = if self.max_steps == 0 { 1.0 } else { (step as f64 / self.max_steps as f64).clamp(0.0, 1.0) };
        delay * (self.lr_init.ln() * (1.0 - t) + self.lr_final.ln() * t).exp()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adam_matches_a_hand_computed_two_step_example() {
        // p0 = 1, lr = 0.1, g1 = 0.5, g2 = -0.2, β = (0.9, 0.999), ε = 1e-8.
        // Step 1: m = 0.05, v = 0.00025; m̂ = 0.5, v̂ = 0.25; p = 1 − 0.1·0.5/(0.5 + 1e-8).
        // Step 2: m = 0.045 − 0.02 = 0.025, v = 0.00024975 + 0.00004 = 0.00028975;
        //         m̂ = 0.025/0.19, v̂ = 0.00028975/0.001999; p −= 0.1·m̂/(√v̂ + 1e-8).
        let mut adam = Adam::new(AdamConfig { beta1: 0.9, beta2: 0.999, eps: 1e-8 });
        adam.add_group("x", 0.1, 1, 1).unwrap();
        let mut p = [1.0f32];
        adam.step("x", &mut p, &[0.5]).unwrap();
        let p1 = 1.0 - 0.1 * 0.5 / (0.5 + 1e-8);
        assert!((p[0] as f64 - p1).abs() < 1e-6, "{} vs {p1}", p[0]);
        adam.step("x", &mut p, &[-0.2]).unwrap();
        let m_hat = 0.025 / 0.19;
        let v_hat: f64 = 0.00028975 / (1.0 - 0.999f64 * 0.999);
        let p2 = p1 - 0.1 * m_hat / (v_hat.sqrt() + 1e-8);
        assert!((p[0] as f64 - p2).abs() < 1e-6, "{} vs {p2}", p[0]);
        assert_eq!(adam.groups[0].step, 2);
    }

    #[test]
    fn rows_follow_densification() {
        let mut adam = Adam::new(AdamConfig::default());
        adam.add_group("means", 1e-3, 3, 3).unwrap();
        let mut p = vec![0.0; 9];
        adam.step("means", &mut p, &[1.0, 1.0, 1.0, 2.0, 2.0, 2.0, 3.0, 3.0, 3.0]).unwrap();
        adam.retain_rows(&[true, false, true]).unwrap();
        assert_eq!(adam.groups[0].m.len(), 6);
        assert!((adam.groups[0].m[3] - 0.3).abs() < 1e-6);
        adam.extend_rows(2);
        assert_eq!(adam.groups[0].m.len(), 12);
        assert!(adam.step("means", &mut p, &[0.0; 9]).is_err());
        assert!(adam.retain_rows(&[true]).is_err());
        assert!(adam.add_group("means", 1.0, 1, 1).is_err());
    }

    #[test]
    fn exponential_schedule_is_log_linear() {
        let s = ExponentialLr::new(1.6e-4, 1.6e-6, 30_000);
        assert!((s.at(0) - 1.6e-4).abs() < 1e-12);
        assert!((s.at(30_000) - 1.6e-6).abs() < 1e-12);
        assert!((s.at(15_000) - 1.6e-5).abs() < 1e-10);
        assert!((s.at(60_000) - 1.6e-6).abs() < 1e-12);
        let delayed = ExponentialLr { delay_steps: 100, delay_mult: 0.01, ..s };
        assert!((delayed.at(0) - 1.6e-6).abs() < 1e-12);
    }
}
