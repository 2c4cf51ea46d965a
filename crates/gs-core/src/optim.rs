//! Adam with per-group learning rates and the log-linear position schedule (3DGS).
//!
//! Each parameter group (means, SH DC, SH rest, opacity, log-scales, rotations) has its own
//! learning rate and its own moment buffers; moments are per scalar, so densification
//! extends, filters or resets them row by row together with the Gaussians.

use crate::error::{CoreError, Result};
use rayon::prelude::*;

/// Adam hyper-parameters shared by all groups (docs/method.md §Parameters: β = (0.9, 0.999), ε = 1e-15).
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

/// The bias-corrected factors of one Adam step of a group: `p -= step_size·m / (√v / bc2_sqrt
/// + ε)`. Computed once per group and step (in f64, as PyTorch does), then applied per scalar
/// by [`Adam::step_strided`] or by a device twin of it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GroupStep {
    /// lr / (1 − β1^t).
    pub step_size: f32,
    /// √(1 − β2^t).
    pub bc2_sqrt: f32,
}

impl ParamGroup {
    /// Counts one more step of this group and returns its bias-corrected factors.
    pub fn begin_step(&mut self, cfg: &AdamConfig) -> GroupStep {
        self.step += 1;
        let t = self.step.min(i32::MAX as u64) as i32;
        let bc1 = 1.0 - (cfg.beta1 as f64).powi(t);
        let bc2 = 1.0 - (cfg.beta2 as f64).powi(t);
        GroupStep { step_size: (self.lr as f64 / bc1) as f32, bc2_sqrt: bc2.sqrt() as f32 }
    }
}

/// One optimised parameter array of the Gaussians (an Adam group of a training run): the
/// typed layout that the trainer, its checkpoints and a device optimiser share.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Param {
    /// Means μ (3 per Gaussian).
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
            Param::ShRest => 3 * (crate::sh::SH_COEFFS - 1),
            Param::Opacity => 1,
            Param::Rotations => 4,
        }
    }
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
        let width = self.group_mut(name)?.row_width;
        self.step_strided(name, params, grads, width, 0)
    }

    /// [`Adam::step`] on group `name` whose rows sit inside wider records: row `r` of the group
    /// is `params[r·stride + offset ..][..row_width]` (and the same in `grads`). The SH DC and
    /// SH rest groups are both views of the Gaussians' 48-float SH records, updated in place
    /// instead of being gathered into copies and scattered back every iteration.
    pub fn step_strided(&mut self, name: &str, params: &mut [f32], grads: &[f32], stride: usize, offset: usize) -> Result<()> {
        let cfg = self.config;
        let g = self.group_mut(name)?;
        let width = g.row_width;
        let rows = g.m.len() / width.max(1);
        if width == 0 || offset + width > stride || params.len() != rows * stride || grads.len() != rows * stride {
            return Err(CoreError::Optimizer(format!(
                "group '{name}': {} parameters and {} gradients for {rows} rows of {width} at offset {offset} in records of {stride}",
                params.len(),
                grads.len(),
            )));
        }
        let GroupStep { step_size, bc2_sqrt } = g.begin_step(&cfg);
        // Element-wise, so the parallel split cannot change a single bit of the result.
        const ROWS_PER_TASK: usize = 4096;
        params
            .par_chunks_mut(ROWS_PER_TASK * stride)
            .zip(grads.par_chunks(ROWS_PER_TASK * stride))
            .zip(g.m.par_chunks_mut(ROWS_PER_TASK * width).zip(g.v.par_chunks_mut(ROWS_PER_TASK * width)))
            .for_each(|((p, gr), (m, v))| {
                let records = p.chunks_exact_mut(stride).zip(gr.chunks_exact(stride));
                for ((p, gr), (m, v)) in records.zip(m.chunks_exact_mut(width).zip(v.chunks_exact_mut(width))) {
                    let (p, gr) = (&mut p[offset..offset + width], &gr[offset..offset + width]);
                    for ((p, &gr), (m, v)) in p.iter_mut().zip(gr).zip(m.iter_mut().zip(v.iter_mut())) {
                        *m = cfg.beta1 * *m + (1.0 - cfg.beta1) * gr;
                        *v = cfg.beta2 * *v + (1.0 - cfg.beta2) * gr * gr;
                        let denom = v.sqrt() / bc2_sqrt + cfg.eps;
                        *p -= step_size * *m / denom;
                    }
                }
            });
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

    /// Zeroes the moments of columns `cols` (scalar offsets within a row) of every row of group
    /// `name`: used when a band of SH coefficients is dropped, so that no momentum moves them.
    pub fn zero_columns(&mut self, name: &str, cols: std::ops::Range<usize>) -> Result<()> {
        let g = self.group_mut(name)?;
        if cols.start > cols.end || cols.end > g.row_width {
            return Err(CoreError::Optimizer(format!(
                "group '{name}': columns {cols:?} outside rows of {}",
                g.row_width
            )));
        }
        let w = g.row_width;
        for buf in [&mut g.m, &mut g.v] {
            for row in buf.chunks_exact_mut(w) {
                row[cols.clone()].fill(0.0);
            }
        }
        Ok(())
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
        adam.zero_columns("means", 1..3).unwrap();
        let m = &adam.groups[0].m;
        assert!((m[0] - 0.1).abs() < 1e-6 && m[1..3] == [0.0, 0.0] && (m[3] - 0.3).abs() < 1e-6, "{m:?}");
        assert!(adam.zero_columns("means", 2..4).is_err());
    }

    #[test]
    fn strided_step_equals_gathered_step_bit_for_bit() {
        // 10,000 records of 5 floats: group "a" is floats 0..2, group "b" floats 2..5, as SH DC
        // and SH rest share one record. Enough rows to span several parallel tasks.
        let rows = 10_000;
        let mut params: Vec<f32> = (0..rows * 5).map(|i| ((i * 7919) % 1000) as f32 * 1e-3 - 0.5).collect();
        let grads: Vec<f32> = (0..rows * 5).map(|i| ((i * 104_729) % 997) as f32 * 1e-4 - 0.05).collect();
        let (mut strided, mut gathered) = (Adam::new(AdamConfig::default()), Adam::new(AdamConfig::default()));
        for adam in [&mut strided, &mut gathered] {
            adam.add_group("a", 1e-2, rows, 2).unwrap();
            adam.add_group("b", 3e-3, rows, 3).unwrap();
        }
        let split = |v: &[f32], lo: usize, hi: usize| -> Vec<f32> { v.chunks(5).flat_map(|r| r[lo..hi].to_vec()).collect() };
        let (mut pa, mut pb) = (split(&params, 0, 2), split(&params, 2, 5));
        for _ in 0..3 {
            strided.step_strided("a", &mut params, &grads, 5, 0).unwrap();
            strided.step_strided("b", &mut params, &grads, 5, 2).unwrap();
            gathered.step("a", &mut pa, &split(&grads, 0, 2)).unwrap();
            gathered.step("b", &mut pb, &split(&grads, 2, 5)).unwrap();
        }
        assert_eq!(split(&params, 0, 2), pa);
        assert_eq!(split(&params, 2, 5), pb);
        assert_eq!(strided, gathered);
        // A row that does not fit its record, or records of the wrong count: errors.
        assert!(strided.step_strided("b", &mut params, &grads, 5, 3).is_err());
        assert!(strided.step_strided("a", &mut params[..10], &grads[..10], 5, 0).is_err());
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
