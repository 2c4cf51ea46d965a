//! The Gaussian budget a scene sets ("model only what a scene requires").
//!
//! PGSR's fixed gradient thresholds grow a model until about one Gaussian per *training* pixel
//! on a CPU-sized capture (946k for 35 × 240 × 180 pixels), and longer runs then give worse
//! meshes. Here the size follows the scene instead:
//!
//! - **Surface pixels.** A capture of `P` training pixels in which a surface point is seen by
//!   `K̄` training views on average holds about `P / K̄` distinct surface pixels. `K̄` is the
//!   mean number of training frusta that contain an initial Gaussian (SfM points lie on the
//!   seen surfaces; occlusion is ignored, so `K̄` is an upper bound and the budget errs small).
//! - **The budget** `B = ρ · P / K̄`, ρ = `densify.gaussians_per_surface_pixel`, never below the
//!   initial count and never above `max_gaussians` (the user's hard cap).
//! - **A block of a partitioned run** (`densify.region`, [`crate::region`]) grows only inside
//!   its region, so its budget counts only the surface there: each view contributes its pixels
//!   times the share of the points it sees that lie inside, over `K̄` of the inside points; the
//!   initial Gaussians outside are added as they are (kept, never grown). Blocks then share the
//!   whole scene's budget instead of each counting most of it.
//! - **Growth** is scheduled as in Taming 3DGS: the target rises linearly from the initial
//!   count to `B` over the first `growth_window` of the densification window. Each step may add
//!   at most `target − current` Gaussians, chosen where the images are still wrong (highest
//!   accumulated screen-space gradient, [`crate::densify`]); when fewer Gaussians pass the
//!   thresholds than the schedule allows, the residual error — not the budget — limits growth.

use crate::config::DensifyConfig;
use crate::region::GrowthRegion;
use gs_core::{Camera, Gaussians};
use serde::Serialize;

/// What bounded one densification step's growth.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GrowthLimit {
    /// Every Gaussian over the error thresholds was densified: the residual error limits growth.
    #[default]
    Residual,
    /// The scheduled target (rising to the budget) allowed fewer.
    Budget,
    /// The user's hard cap `max_gaussians` allowed fewer.
    Cap,
}

impl GrowthLimit {
    /// In words, for the run summary.
    pub fn describe(self) -> &'static str {
        match self {
            Self::Residual => "the residual error (no more Gaussians over the error thresholds)",
            Self::Budget => "the scene's budget",
            Self::Cap => "the --max-gaussians cap",
        }
    }
}

/// The Gaussian budget of a run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Budget {
    /// Σ over training views of width × height, P.
    pub training_pixels: u64,
    /// Mean number of training frusta containing an initial Gaussian, K̄.
    pub views_per_point: f64,
    /// P / K̄ (of the growth region's share of P, over K̄ of the points inside it, when a
    /// region is set).
    pub surface_pixels: f64,
    /// Gaussians at the start, N₀.
    pub initial: usize,
    /// Initial Gaussians outside the growth region (0 without one): in the budget as they are.
    pub outside_region: usize,
    /// With a growth region: Σ over views of its pixels × the share of the points it sees in
    /// the region (the P its surface pixels count).
    pub region_pixels: Option<f64>,
    /// The budget B (the initial count when budgets are off, ρ = 0: then only the thresholds
    /// and the cap bound growth).
    pub gaussians: usize,
    /// Whether a budget applies (ρ > 0).
    pub active: bool,
}

impl Budget {
    /// The budget of `init` (the run's initial Gaussians) seen by the training cameras `cams`.
    pub fn of_scene(cams: &[&Camera], init: &Gaussians, d: &DensifyConfig, max_gaussians: usize, near: f32) -> Self {
        let training_pixels: u64 = cams.iter().map(|c| c.width as u64 * c.height as u64).sum();
        let seen = sighting_counts(cams, &init.means, d.region.as_ref(), near as f64);
        let views_per_point = seen.views_per_point.max(1.0);
        let region_pixels = seen.region_pixels;
        let surface_pixels = region_pixels.unwrap_or(training_pixels as f64) / views_per_point;
        let initial = init.len();
        let outside_region = d.region.map_or(0, |r| init.means.iter().filter(|m| !r.contains(**m)).count());
        let active = d.gaussians_per_surface_pixel > 0.0;
        let gaussians = if active {
            ((d.gaussians_per_surface_pixel as f64 * surface_pixels).round() as usize + outside_region).max(initial).min(max_gaussians)
        } else {
            initial
        };
        Self { training_pixels, views_per_point, surface_pixels, initial, outside_region, region_pixels, gaussians, active }
    }

    /// The budget and how it came about, in words (ρ = `rho`), e.g. "244977 (1 per surface
    /// pixel × 2100000 training pixels ÷ 8.6 views per point)".
    pub fn describe(&self, rho: f32) -> String {
        match self.region_pixels {
            None => format!(
                "{} ({rho} per surface pixel × {} training pixels ÷ {:.1} views per point)",
                self.gaussians, self.training_pixels, self.views_per_point
            ),
            Some(p) => format!(
                "{} ({rho} per surface pixel × {p:.0} of the {} training pixels on the growth region ÷ {:.1} views per point, + {} initial Gaussians outside it)",
                self.gaussians, self.training_pixels, self.views_per_point, self.outside_region
            ),
        }
    }

    /// The most Gaussians densification may reach at 1-based iteration `it`: N₀ rising
    /// linearly to B over `growth_window` of [from, until]; `usize::MAX` without a budget.
    pub fn target(&self, it: u64, d: &DensifyConfig) -> usize {
        if !self.active {
            return usize::MAX;
        }
        let span = ((d.until.saturating_sub(d.from)) as f64 * d.growth_window.clamp(0.0, 1.0) as f64).max(1.0);
        let f = (it.saturating_sub(d.from) as f64 / span).min(1.0);
        let grow = self.gaussians.saturating_sub(self.initial) as f64;
        self.initial + (grow * f).round() as usize
    }
}

/// What the cameras see of the initial points ([`sighting_counts`]).
struct Sightings {
    /// Mean number of cameras containing a point of the region (every point without one).
    views_per_point: f64,
    /// With a region: Σ over cameras of its pixels × the share of the points it sees that lie
    /// in the region (0 for a camera that sees no point).
    region_pixels: Option<f64>,
}

/// Over (at most 20,000 evenly strided) points, which cameras contain each point in front of
/// the near plane: the mean count over the region's points, and each camera's pixels weighted
/// by the share of its points inside the region.
fn sighting_counts(cams: &[&Camera], means: &[[f32; 3]], region: Option<&GrowthRegion>, near: f64) -> Sightings {
    let mut per_cam = vec![(0u64, 0u64); cams.len()];
    let (mut total, mut count) = (0u64, 0u64);
    for m in means.iter().step_by(means.len().div_ceil(20_000).max(1)) {
        let inside = region.is_none_or(|r| r.contains(*m));
        let p = gs_core::glam::DVec3::new(m[0] as f64, m[1] as f64, m[2] as f64);
        for (k, c) in cams.iter().enumerate() {
            if c.world_to_camera(p).z > near && c.project(p).is_some_and(|(uv, _)| c.contains(uv)) {
                per_cam[k].0 += 1;
                if inside {
                    per_cam[k].1 += 1;
                    total += 1;
                }
            }
        }
        count += inside as u64;
    }
    let views_per_point = if count > 0 { total as f64 / count as f64 } else { 1.0 };
    let share = |&(seen, inside): &(u64, u64)| if seen > 0 { inside as f64 / seen as f64 } else { 0.0 };
    let region_pixels = region.map(|_| cams.iter().zip(&per_cam).map(|(c, n)| c.width as f64 * c.height as f64 * share(n)).sum());
    Sightings { views_per_point, region_pixels }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_budget_follows_surface_pixels_and_the_schedule() {
        let cams = gs_core::scene::camera_ring(8);
        let mut g = Gaussians::with_len(0).unwrap();
        for i in 0..100 {
            g.push([0.01 * i as f32, 0.0, 0.0], [-3.0; 3], [1.0, 0.0, 0.0, 0.0], 0.0, [[0.0; 3]; 16]);
        }
        let refs: Vec<&Camera> = cams.iter().collect();
        let k = sighting_counts(&refs, &g.means, None, 0.01).views_per_point;
        assert!(k > 1.0 && k <= 8.0, "{k}");
        let d = DensifyConfig { gaussians_per_surface_pixel: 0.5, from: 100, until: 1100, growth_window: 0.5, ..Default::default() };
        let b = Budget::of_scene(&refs, &g, &d, 1_000_000, 0.01);
        let p: u64 = cams.iter().map(|c| c.width as u64 * c.height as u64).sum();
        assert_eq!(b.training_pixels, p);
        assert_eq!(b.gaussians, (0.5 * p as f64 / k).round() as usize);
        assert!(b.gaussians > 100);
        assert_eq!(b.target(100, &d), 100);
        assert_eq!(b.target(600, &d), b.gaussians);
        assert_eq!(b.target(5000, &d), b.gaussians);
        let mid = b.target(350, &d);
        assert!(mid > 100 && mid < b.gaussians);
        // The cap wins; ρ = 0 switches the budget off.
        assert_eq!(Budget::of_scene(&refs, &g, &d, 150, 0.01).gaussians, 150);
        let off = Budget::of_scene(&refs, &g, &DensifyConfig { gaussians_per_surface_pixel: 0.0, ..d }, 1000, 0.01);
        assert!(!off.active && off.target(500, &d) == usize::MAX);
    }

    #[test]
    fn a_growth_region_counts_only_its_surface() {
        let cams = gs_core::scene::camera_ring(8);
        let refs: Vec<&Camera> = cams.iter().collect();
        let mut g = Gaussians::with_len(0).unwrap();
        for i in 0..100 {
            g.push([0.01 * i as f32 - 0.5, 0.0, 0.0], [-3.0; 3], [1.0, 0.0, 0.0, 0.0], 0.0, [[0.0; 3]; 16]);
        }
        let d = DensifyConfig { gaussians_per_surface_pixel: 0.5, ..Default::default() };
        let whole = Budget::of_scene(&refs, &g, &d, 10_000_000, 0.01);
        // The half x < 0 (50 points) on the ground plane z = 0 spanned by x and y.
        let half = GrowthRegion { origin: [0.0; 3], u: [1.0, 0.0, 0.0], v: [0.0, 1.0, 0.0], min: [-10.0, -10.0], max: [-0.005, 10.0] };
        let d_half = DensifyConfig { region: Some(half), ..d.clone() };
        let b = Budget::of_scene(&refs, &g, &d_half, 10_000_000, 0.01);
        assert_eq!(b.outside_region, 50);
        assert_eq!(whole.outside_region, 0);
        // Every camera sees both halves, so half of each view's pixels count, over the same K̄.
        let seen = sighting_counts(&refs, &g.means, Some(&half), 0.01);
        let region_pixels = seen.region_pixels.expect("a region's pixels");
        assert!(sighting_counts(&refs, &g.means, None, 0.01).region_pixels.is_none());
        let all = whole.training_pixels as f64;
        assert!(region_pixels > 0.3 * all && region_pixels < 0.7 * all, "{region_pixels}");
        assert_eq!(b.gaussians, (0.5 * region_pixels / seen.views_per_point).round() as usize + 50);
        assert!(b.gaussians < whole.gaussians, "{} against {}", b.gaussians, whole.gaussians);
        assert_eq!(b.region_pixels, Some(region_pixels));
        assert!(b.describe(0.5).contains("on the growth region") && b.describe(0.5).contains("+ 50 initial Gaussians outside it"));
        assert!(whole.region_pixels.is_none() && whole.describe(0.5).ends_with("views per point)"));
        // A region holding no point: the initial Gaussians are the budget.
        let none = GrowthRegion { min: [50.0, 50.0], max: [60.0, 60.0], ..half };
        let b = Budget::of_scene(&refs, &g, &DensifyConfig { region: Some(none), ..d }, 10_000_000, 0.01);
        assert_eq!((b.gaussians, b.outside_region), (100, 100));
    }
}
