//! Adaptive density control (docs/method.md §Densification, PGSR/AbsGS): screen-space gradient statistics,
//! clone / split / prune, opacity reset and the multi-view trim, applied to the Gaussians and
//! the optimiser's moments together so rows never fall out of step.

use crate::budget::GrowthLimit;
use crate::config::DensifyConfig;
use crate::error::Result;
use gs_core::gaussians::{inverse_sigmoid, rotation_matrix, sigmoid};
use gs_core::glam::Vec3;
use gs_core::{Adam, Gaussians, Rng};
use serde::Serialize;

/// Split factor of the scales: a split Gaussian's children have scales ÷ 1.6 (0.8·2).
pub const SPLIT_SCALE_DIVISOR: f32 = 1.6;
/// Opacity after a reset: min(opacity, 0.01).
pub const RESET_OPACITY: f32 = 0.01;

pub use gs_core::DensifyStats;

/// What one densification step did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct DensifyReport {
    /// Gaussians cloned.
    pub cloned: usize,
    /// Gaussians split (each replaced by two).
    pub split: usize,
    /// Gaussians pruned.
    pub pruned: usize,
    /// Whether the Gaussian cap limited the step.
    pub capped: bool,
    /// What bounded the growth of this step.
    pub limit: GrowthLimit,
    /// Whether the step ran on the device that holds the model ([`crate::refine::densify_on_device`]).
    pub on_device: bool,
}

/// How far one densification step may grow the model: the scheduled `target`
/// ([`crate::budget::Budget::target`]) and the user's hard `cap`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Growth {
    /// The schedule's target (usize::MAX without a budget).
    pub target: usize,
    /// `max_gaussians`.
    pub cap: usize,
}

impl Growth {
    /// How many Gaussians a step from `n` may add (a clone adds one, a split one net).
    pub fn room(&self, n: usize) -> usize {
        self.target.min(self.cap).saturating_sub(n)
    }

    /// What bounds a step that found `candidates` over the thresholds with `room` for them:
    /// the residual error when all fit, else the cap or the budget, whichever is lower.
    pub fn limit(&self, candidates: usize, room: usize) -> GrowthLimit {
        match candidates > room {
            false => GrowthLimit::Residual,
            true if self.cap <= self.target => GrowthLimit::Cap,
            true => GrowthLimit::Budget,
        }
    }
}

/// The densification settings as the device's density control takes them
/// ([`gs_raster::DensifyRule`]; the host's rule is [`densify_and_prune`]).
pub fn device_rule(cfg: &DensifyConfig, extent: f32, prune_big: bool, room: usize) -> gs_raster::DensifyRule {
    gs_raster::DensifyRule {
        grad_threshold: cfg.grad_threshold,
        abs_grad_threshold: cfg.abs_grad_threshold,
        small_limit: cfg.percent_dense * extent,
        max_screen_radius: cfg.max_screen_radius,
        max_abs_splits: cfg.max_abs_splits,
        min_opacity: cfg.min_opacity,
        max_world: cfg.max_world_scale * extent,
        prune_big,
        split_divisor: SPLIT_SCALE_DIVISOR,
        room,
    }
}

/// The densification score of Gaussian `i`: its mean screen-space gradient relative to the
/// clone/split threshold, or its mean absolute gradient relative to the AbsGS threshold,
/// whichever is larger — how wrong the images still are where it projects.
fn score(stats: &DensifyStats, cfg: &DensifyConfig, i: usize) -> f32 {
    let v = stats.visible_count[i].max(1) as f32;
    let g = stats.grad_sum[i] / v / cfg.grad_threshold.max(f32::MIN_POSITIVE);
    let a = stats.abs_grad_sum[i] / v / cfg.abs_grad_threshold.max(f32::MIN_POSITIVE);
    g.max(a)
}

/// Keeps the `room` highest-scoring of the candidates `clone` ∪ `split` (ties by index), each
/// list staying in index order, so the random draws that follow are deterministic.
fn keep_best(clone: &mut Vec<usize>, split: &mut Vec<usize>, room: usize, stats: &DensifyStats, cfg: &DensifyConfig) {
    let mut all: Vec<(f32, usize)> = clone.iter().chain(split.iter()).map(|&i| (score(stats, cfg, i), i)).collect();
    all.sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let mut chosen = vec![false; stats.len()];
    for &(_, i) in all.iter().take(room) {
        chosen[i] = true;
    }
    clone.retain(|&i| chosen[i]);
    split.retain(|&i| chosen[i]);
}


/// Largest of the three scales of Gaussian `i`.
fn max_scale(g: &Gaussians, i: usize) -> f32 {
    g.scale(i).into_iter().fold(0.0f32, f32::max)
}

/// A position sampled from Gaussian `i`: μ + R·(s ⊙ n), n ~ N(0, I).
fn sample_position(g: &Gaussians, i: usize, rng: &mut Rng) -> [f32; 3] {
    sample_near(&gs_raster::BornParent { mean: g.means[i], log_scale: g.log_scales[i], rotation: g.rotations[i] }, rng)
}

/// A position sampled from a parent Gaussian: μ + R·(s ⊙ n), n ~ N(0, I) (3 draws). The one
/// rule of born positions, on the host and for the device's density control.
pub fn sample_near(parent: &gs_raster::BornParent, rng: &mut Rng) -> [f32; 3] {
    let s = parent.log_scale.map(f32::exp);
    let n = Vec3::new(rng.normal() * s[0], rng.normal() * s[1], rng.normal() * s[2]);
    let r = rotation_matrix(parent.rotation);
    (Vec3::from(parent.mean) + r * n).to_array()
}

/// Clone, split and prune (PGSR's `densify_and_prune` with AbsGS): `prune_big` also prunes
/// Gaussians too large on screen or in the world, `extent` is the scene extent r. Growth
/// (a clone adds one Gaussian, a split one net) happens only inside `cfg.region` (when set,
/// [`crate::region`]) and stops at `growth`'s target and cap; when
/// more candidates pass the thresholds than that allows, the highest-scoring ones are taken
/// (`score`). New Gaussians get zero Adam moments; statistics are reset for every Gaussian.
#[allow(clippy::too_many_arguments)]
pub fn densify_and_prune(
    g: &mut Gaussians,
    adam: &mut Adam,
    stats: &mut DensifyStats,
    cfg: &DensifyConfig,
    extent: f32,
    prune_big: bool,
    growth: Growth,
    rng: &mut Rng,
) -> Result<DensifyReport> {
    let n = g.len();
    let mut report = DensifyReport::default();
    let small_limit = cfg.percent_dense * extent;
    let mean_grad = |sum: &[f32], i: usize| if stats.visible_count[i] > 0 { sum[i] / stats.visible_count[i] as f32 } else { 0.0 };
    let mut clone = Vec::new();
    let mut split = Vec::new();
    let mut abs_split = Vec::new();
    for i in 0..n {
        if cfg.region.is_some_and(|r| !r.contains(g.means[i])) {
            continue;
        }
        let grad = mean_grad(&stats.grad_sum, i);
        let big = max_scale(g, i) > small_limit;
        if grad >= cfg.grad_threshold && !big {
            clone.push(i);
        } else if grad >= cfg.grad_threshold && big {
            split.push(i);
        } else if big && mean_grad(&stats.abs_grad_sum, i) >= cfg.abs_grad_threshold && stats.max_radius[i] > cfg.max_screen_radius {
            abs_split.push(i);
        }
    }
    abs_split.truncate(cfg.max_abs_splits);
    split.extend(abs_split);
    split.sort_unstable();
    // Clones add one Gaussian each, splits one net (two children replace the parent).
    let room = growth.room(n);
    report.limit = growth.limit(clone.len() + split.len(), room);
    report.capped = report.limit == GrowthLimit::Cap;
    if report.limit != GrowthLimit::Residual {
        keep_best(&mut clone, &mut split, room, stats, cfg);
    }
    let mut born = Gaussians::with_len(0)?;
    for &i in &clone {
        let mean = sample_position(g, i, rng);
        born.push(mean, g.log_scales[i], g.rotations[i], g.opacity_logits[i], g.sh[i]);
    }
    let shrink = SPLIT_SCALE_DIVISOR.ln();
    for &i in &split {
        let ls = g.log_scales[i].map(|v| v - shrink);
        for _ in 0..2 {
            let mean = sample_position(g, i, rng);
            born.push(mean, ls, g.rotations[i], g.opacity_logits[i], g.sh[i]);
        }
    }
    report.cloned = clone.len();
    report.split = split.len();
    // Prune: split parents, low opacity, and (after prune_big_after) huge ones.
    let mut keep = vec![true; n + born.len()];
    for &i in &split {
        keep[i] = false;
    }
    g.extend_from(&born);
    adam.extend_rows(born.len());
    let old_radius = stats.max_radius.clone();
    for (i, k) in keep.iter_mut().enumerate() {
        let too_big = prune_big
            && ((i < n && old_radius[i] > cfg.max_screen_radius) || max_scale(g, i) > cfg.max_world_scale * extent);
        if g.opacity(i) < cfg.min_opacity || too_big {
            *k = false;
        }
    }
    report.pruned = keep.iter().filter(|k| !**k).count() - split.len();
    retain_rows(g, adam, &mut keep)?;
    *stats = DensifyStats::new(g.len());
    Ok(report)
}

/// Removes the rows with `keep = false` from the Gaussians and the optimiser; never removes
/// the last Gaussian (the most opaque one stays), so a model is never empty.
pub fn retain_rows(g: &mut Gaussians, adam: &mut Adam, keep: &mut [bool]) -> Result<usize> {
    keep_one(keep, &g.opacity_logits);
    let removed = keep.iter().filter(|k| !**k).count();
    if removed > 0 {
        g.retain(keep)?;
        adam.retain_rows(keep)?;
    }
    Ok(removed)
}

/// The rule that no removal leaves the model empty: where `keep` keeps no row, the most
/// opaque (the first of equals, by `opacity_logits`, read only then) stays.
pub fn keep_one(keep: &mut [bool], opacity_logits: &[f32]) {
    if !keep.iter().any(|k| *k) && !keep.is_empty() {
        let best = (0..keep.len()).fold(0, |b, i| if opacity_logits[i] > opacity_logits[b] { i } else { b });
        keep[best] = true;
    }
}

/// Opacity reset: opacity = min(opacity, 0.01), with the opacity moments zeroed.
pub fn reset_opacity(g: &mut Gaussians, adam: &mut Adam) -> Result<()> {
    cap_opacities(g);
    adam.reset_group(crate::params::Param::Opacity.name())?;
    Ok(())
}

/// The opacity reset's parameters alone: every opacity above [`RESET_OPACITY`] takes it.
pub fn cap_opacities(g: &mut Gaussians) {
    let cap = inverse_sigmoid(RESET_OPACITY);
    for o in &mut g.opacity_logits {
        if sigmoid(*o) > RESET_OPACITY {
            *o = cap;
        }
    }
}

/// The multi-view trim's keep mask: the Gaussians observed in at least `min_views` views.
pub fn observed_enough(views_observed: &[u32], min_views: u32) -> Vec<bool> {
    views_observed.iter().map(|&c| c >= min_views).collect()
}

/// Multi-view trim: removes Gaussians observed (T > 0.5 while contributing) in fewer than
/// `min_views` of the training views; `views_observed[i]` counts the views. Returns how many.
pub fn trim_unobserved(g: &mut Gaussians, adam: &mut Adam, stats: &mut DensifyStats, views_observed: &[u32], min_views: u32) -> Result<usize> {
    let mut keep = observed_enough(views_observed, min_views);
    let removed = retain_rows(g, adam, &mut keep)?;
    if removed > 0 {
        // Keep the accumulated statistics of the survivors.
        stats.retain(&keep);
    }
    Ok(removed)
}

#[cfg(test)]
mod tests {
    use super::*;
    use gs_core::AdamConfig;

    fn model(n: usize) -> (Gaussians, Adam) {
        let mut g = Gaussians::with_len(0).unwrap();
        for i in 0..n {
            let mut sh = [[0.0; 3]; 16];
            sh[0] = [i as f32; 3];
            g.push([i as f32, 0.0, 0.0], [(0.01f32).ln(); 3], [1.0, 0.0, 0.0, 0.0], 0.0, sh);
        }
        let mut adam = Adam::new(AdamConfig::default());
        for p in crate::params::Param::ALL {
            adam.add_group(p.name(), 1e-3, n, p.row_width()).unwrap();
        }
        (g, adam)
    }

    /// Gradients whose screen-space norms are `norms` (the same for the AbsGS sum).
    fn screen_grads(norms: &[f32]) -> gs_raster::GaussianGradients {
        gs_raster::GaussianGradients {
            mean2d: norms.iter().map(|&g| [0.6 * g, 0.8 * g]).collect(),
            mean2d_abs: norms.iter().map(|&g| [0.0, g]).collect(),
            ..gs_raster::GaussianGradients::zeros(norms.len())
        }
    }

    /// A Gaussian with a large gradient in the view it covers (100 pixels) and none in three
    /// views that graze it (1 pixel each) crosses the threshold only with Pixel-GS's weights.
    #[test]
    fn pixel_weights_judge_a_gaussian_by_the_views_it_covers() {
        let cfg = DensifyConfig::default();
        let (covered, grazing) = (screen_grads(&[5e-4]), screen_grads(&[0.0]));
        let (mut views, mut pixels) = (DensifyStats::new(1), DensifyStats::new(1));
        views.accumulate(&[9], None, &covered.mean2d, &covered.mean2d_abs, 1.0);
        pixels.accumulate(&[9], Some(&[100]), &covered.mean2d, &covered.mean2d_abs, 1.0);
        for _ in 0..3 {
            views.accumulate(&[2], None, &grazing.mean2d, &grazing.mean2d_abs, 1.0);
            pixels.accumulate(&[2], Some(&[1]), &grazing.mean2d, &grazing.mean2d_abs, 1.0);
        }
        assert_eq!((views.visible_count[0], pixels.visible_count[0]), (4, 103));
        let mean = |st: &DensifyStats| st.grad_sum[0] / st.visible_count[0] as f32;
        assert!((mean(&views) - 1.25e-4).abs() < 1e-9 && mean(&views) < cfg.grad_threshold);
        assert!((mean(&pixels) - 5e-4 * 100.0 / 103.0).abs() < 1e-9 && mean(&pixels) >= cfg.grad_threshold);
        assert_eq!(pixels.max_radius[0], 9.0);
        // A view in which no pixel shows it in front adds nothing but its radius.
        pixels.accumulate(&[30], Some(&[0]), &covered.mean2d, &covered.mean2d_abs, 1.0);
        assert_eq!((pixels.visible_count[0], pixels.max_radius[0]), (103, 30.0));
        // Unit weights are the plain per-view sums, bit for bit.
        let mut ones = DensifyStats::new(1);
        ones.accumulate(&[9], Some(&[1]), &covered.mean2d, &covered.mean2d_abs, 1.0);
        let mut plain = DensifyStats::new(1);
        plain.accumulate(&[9], None, &covered.mean2d, &covered.mean2d_abs, 1.0);
        assert_eq!(ones, plain);
    }

    #[test]
    fn clone_split_prune_keep_rows_in_step() {
        let (mut g, mut adam) = model(4);
        g.log_scales[1] = [(1.0f32).ln(); 3]; // big: split
        g.opacity_logits[3] = -10.0; // transparent: pruned
        let mut st = DensifyStats::new(4);
        st.grad_sum = vec![1e-3, 1e-3, 0.0, 0.0];
        st.visible_count = vec![1, 1, 1, 1];
        let cfg = DensifyConfig { percent_dense: 0.1, ..Default::default() };
        let mut rng = Rng::new(1);
        let r = densify_and_prune(&mut g, &mut adam, &mut st, &cfg, 1.0, false, Growth { target: usize::MAX, cap: 100 }, &mut rng).unwrap();
        assert_eq!((r.cloned, r.split, r.pruned, r.capped), (1, 1, 1, false));
        // 4 + 1 clone + 2 children − 1 parent − 1 pruned = 5.
        assert_eq!(g.len(), 5);
        g.validate().unwrap();
        for grp in &adam.groups {
            assert_eq!(grp.m.len(), 5 * grp.row_width, "{}", grp.name);
        }
        // Survivors in order: 0, 2 (originals), clone of 0, two children of 1.
        assert_eq!(g.sh.iter().map(|s| s[0][0]).collect::<Vec<_>>(), vec![0.0, 2.0, 0.0, 1.0, 1.0]);
        assert!((g.log_scales[3][0].exp() - 1.0 / 1.6).abs() < 1e-5);
        assert_eq!(st.len(), 5);
    }

    #[test]
    fn the_cap_stops_growth() {
        let (mut g, mut adam) = model(4);
        let mut st = DensifyStats::new(4);
        st.grad_sum = vec![1.0; 4];
        st.visible_count = vec![1; 4];
        st.grad_sum[2] = 2.0;
        let growth = Growth { target: usize::MAX, cap: 6 };
        let r = densify_and_prune(&mut g, &mut adam, &mut st, &DensifyConfig::default(), 100.0, false, growth, &mut Rng::new(0)).unwrap();
        assert!(r.capped && r.cloned == 2 && g.len() == 6 && r.limit == GrowthLimit::Cap);
        // The best-scoring candidates are densified: Gaussian 2 (score 2) and then 0 (ties by index).
        assert_eq!(g.sh.iter().map(|s| s[0][0]).collect::<Vec<_>>(), vec![0.0, 1.0, 2.0, 3.0, 0.0, 2.0]);
        // The schedule's target below the cap: the budget limits.
        let (mut g, mut adam) = model(4);
        let mut st = DensifyStats::new(4);
        st.grad_sum = vec![1.0; 4];
        st.visible_count = vec![1; 4];
        let growth = Growth { target: 5, cap: 100 };
        let r = densify_and_prune(&mut g, &mut adam, &mut st, &DensifyConfig::default(), 100.0, false, growth, &mut Rng::new(0)).unwrap();
        assert!(!r.capped && r.cloned == 1 && g.len() == 5 && r.limit == GrowthLimit::Budget);
    }

    #[test]
    fn only_the_growth_region_grows() {
        // Gaussians at x = 0..4 all over the thresholds; the region holds x in [0.5, 2.5].
        let (mut g, mut adam) = model(4);
        let mut st = DensifyStats::new(4);
        st.grad_sum = vec![1.0; 4];
        st.visible_count = vec![1; 4];
        let region = crate::region::GrowthRegion { origin: [0.0; 3], u: [1.0, 0.0, 0.0], v: [0.0, 1.0, 0.0], min: [0.5, -1.0], max: [2.5, 1.0] };
        let cfg = DensifyConfig { region: Some(region), ..Default::default() };
        let growth = Growth { target: usize::MAX, cap: 100 };
        let r = densify_and_prune(&mut g, &mut adam, &mut st, &cfg, 100.0, false, growth, &mut Rng::new(0)).unwrap();
        assert_eq!((r.cloned, r.split), (2, 0));
        // The originals stay, the clones are of 1 and 2 only.
        assert_eq!(g.sh.iter().map(|s| s[0][0]).collect::<Vec<_>>(), vec![0.0, 1.0, 2.0, 3.0, 1.0, 2.0]);
    }

    #[test]
    fn reset_and_trim() {
        let (mut g, mut adam) = model(3);
        g.opacity_logits[2] = -8.0;
        reset_opacity(&mut g, &mut adam).unwrap();
        assert!((g.opacity(0) - 0.01).abs() < 1e-6 && g.opacity(2) < 0.01);
        let mut st = DensifyStats::new(3);
        assert_eq!(trim_unobserved(&mut g, &mut adam, &mut st, &[5, 1, 2], 2).unwrap(), 1);
        assert_eq!(g.len(), 2);
        assert_eq!(adam.groups[0].m.len(), 6);
        // Never empty.
        assert_eq!(trim_unobserved(&mut g, &mut adam, &mut st, &[0, 0], 2).unwrap(), 1);
        assert_eq!(g.len(), 1);
    }
}
