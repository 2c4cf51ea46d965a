//! Peak-memory estimate of a training run, made before training allocates its caches and grows
//! the model, so that a run that cannot fit is refused in seconds rather than killed hours in.
//!
//! The peak is the sum of what a run holds at its end: the Gaussians at the budget (or the
//! `max_gaussians` cap) with their parameters, Adam moments, gradients, densification
//! statistics, the rasterizer's per-Gaussian data and a densification copy; the decoded photos
//! (and masks) of every view; the per-view caches filled as views are visited (edge guides,
//! grey images of L_p, coarse-to-fine pyramids, VGG feature maps of L_f, reused source-view
//! depths); the buffers of one render and its losses at the largest view; and the program with
//! its network weights. Every
//! term rounds up, so the estimate is an upper bound (RELIABILITY.md compares it with measured
//! peaks).

use crate::budget::Budget;
use crate::config::TrainConfig;
use gs_core::Scene;
use gs_features::ExtractOptions;
use gs_tsdf::format_bytes;

/// Bytes per Gaussian at the peak: 59 parameters (236 B), Adam's two moments (472 B), their
/// gradients (236 B), densification statistics (16 B), the rasterizer's projected record and
/// tile keys (≈ 330 B) and the copy densification makes while it grows the arrays (≈ 710 B).
pub const BYTES_PER_GAUSSIAN: u64 = 2048;

/// Bytes per pixel of the largest training view for one render and its losses: colour, depth,
/// normal, alpha and their gradients, the SSIM and normal-term maps, and the rasterizer's
/// per-pixel state (≈ 100 f32 values, rounded up).
pub const RENDER_BYTES_PER_PIXEL: u64 = 512;

/// Bytes per pixel of the VGG16 forward pass while a feature map is extracted: the input and
/// output activations of a 64-channel layer at full resolution (f32), with their borders.
pub const VGG_BYTES_PER_PIXEL: u64 = 2 * 64 * 4 + 64;

/// The program, its libraries and the bundled network weights (VGG16 to conv3_3 and LPIPS).
pub const BASE_BYTES: u64 = 96 << 20;

/// A run's estimated peak memory, by part.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TrainMemoryEstimate {
    /// Gaussians assumed at the peak.
    pub gaussians: u64,
    /// Whether that count is the `max_gaussians` cap rather than the scene's budget.
    pub capped: bool,
    /// Bytes of the Gaussians with optimiser state, gradients and rasterizer records.
    pub gaussian_bytes: u64,
    /// Views whose photos are held.
    pub views: u64,
    /// Bytes of the decoded photos and masks.
    pub image_bytes: u64,
    /// Bytes of the edge guides, grey images and coarse-to-fine pyramids of the training views.
    pub view_cache_bytes: u64,
    /// Bytes of the VGG feature maps of L_f and one forward pass (0 without L_f).
    pub feature_bytes: u64,
    /// Bytes of the reused source-view plane depths (0 unless `source_depth_max_age` > 0).
    pub source_depth_bytes: u64,
    /// Bytes of one render and its losses at the largest training view.
    pub render_bytes: u64,
    /// Bytes of the program and its weights.
    pub base_bytes: u64,
}

/// The estimate of training `train_views` of `scene` with `config`, given the run's budget and
/// the Gaussians it holds now (a resumed run may already hold more than its budget).
pub fn estimate(scene: &Scene, train_views: &[usize], config: &TrainConfig, budget: &Budget, current: usize) -> TrainMemoryEstimate {
    let capped = !budget.active || config.densify.gaussians_per_surface_pixel <= 0.0;
    let gaussians = if capped { config.max_gaussians } else { budget.gaussians.min(config.max_gaussians) }.max(current) as u64;
    let bytes = |img: &gs_core::Image| img.data().len() as u64 * 4;
    let image_bytes = scene.views.iter().map(|v| bytes(&v.image) + v.mask.as_ref().map_or(0, bytes)).sum();
    let pixels = |i: usize| (scene.views[i].camera.width as u64) * (scene.views[i].camera.height as u64);
    let train_pixels: u64 = train_views.iter().map(|&i| pixels(i)).sum();
    let largest = train_views.iter().map(|&i| pixels(i)).max().unwrap_or(0);
    // Edge guide (∇I and δ, 8 B/px); L_p's grey image (4 B/px, ncc_scale² more when finer);
    // coarse-to-fine pyramids (12 B/px × (1/4 + 1/16 + …) < 4 B/px).
    let mut per_pixel = 8;
    if config.losses.photometric {
        per_pixel += 4 * u64::from(config.ncc_scale).pow(2);
    }
    if config.coarse_to_fine.levels > 0 {
        per_pixel += 4;
    }
    let feature_bytes = if config.has_feature_phase() {
        let opts = ExtractOptions::at(config.feature_layer);
        let maps: u64 = train_views
            .iter()
            .map(|&i| opts.bytes_per_image(scene.views[i].camera.width as usize, scene.views[i].camera.height as usize) as u64)
            .sum();
        maps + largest * VGG_BYTES_PER_PIXEL
    } else {
        0
    };
    TrainMemoryEstimate {
        gaussians,
        capped,
        gaussian_bytes: gaussians.saturating_mul(BYTES_PER_GAUSSIAN),
        views: scene.views.len() as u64,
        image_bytes,
        view_cache_bytes: train_pixels * per_pixel,
        feature_bytes,
        source_depth_bytes: if config.source_depth_max_age > 0 { train_pixels * 4 } else { 0 },
        render_bytes: largest * RENDER_BYTES_PER_PIXEL,
        base_bytes: BASE_BYTES,
    }
}

impl TrainMemoryEstimate {
    /// The estimated peak in bytes.
    pub fn peak_bytes(&self) -> u64 {
        [
            self.gaussian_bytes,
            self.image_bytes,
            self.view_cache_bytes,
            self.feature_bytes,
            self.source_depth_bytes,
            self.render_bytes,
            self.base_bytes,
        ]
            .iter()
            .fold(0u64, |a, &b| a.saturating_add(b))
    }

    /// The parts in words: "34699 Gaussians at the scene's budget with their optimiser state
    /// 68.0 MiB, the photos of 50 views 175.8 MiB, …".
    pub fn describe(&self) -> String {
        let whose = if self.capped { "the --max-gaussians cap" } else { "the scene's budget" };
        let mut parts = vec![
            format!("{} Gaussians ({whose}) with their optimiser state and gradients {}", self.gaussians, format_bytes(self.gaussian_bytes)),
            format!("the photos of {} views at training resolution {}", self.views, format_bytes(self.image_bytes)),
            format!("per-view caches (edge guides, grey images, pyramids) {}", format_bytes(self.view_cache_bytes)),
        ];
        if self.feature_bytes > 0 {
            parts.push(format!("VGG feature maps of L_f {}", format_bytes(self.feature_bytes)));
        }
        if self.source_depth_bytes > 0 {
            parts.push(format!("reused source-view depths {}", format_bytes(self.source_depth_bytes)));
        }
        parts.push(format!("render and loss buffers {}", format_bytes(self.render_bytes)));
        parts.push(format!("program and network weights {}", format_bytes(self.base_bytes)));
        parts.join(", ")
    }

    /// `Ok` when the peak fits `limit` bytes, else an error with the estimate in words and
    /// what to change.
    pub fn check(&self, limit: u64) -> crate::Result<()> {
        if self.peak_bytes() <= limit {
            return Ok(());
        }
        let features = if self.feature_bytes > 0 { ", turn off L_f (--no-features)" } else { "" };
        Err(crate::TrainError::MemoryLimit(format!(
            "training needs about {} at its peak, more than the memory limit of {}: {}; train at a lower resolution (-r 2, --width), lower --max-gaussians{features}, or raise --max-memory",
            format_bytes(self.peak_bytes()),
            format_bytes(limit),
            self.describe()
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_check_names_the_parts_and_the_flag() {
        let e = TrainMemoryEstimate {
            gaussians: 1000,
            capped: false,
            gaussian_bytes: 1000 * BYTES_PER_GAUSSIAN,
            views: 2,
            image_bytes: 10 << 20,
            view_cache_bytes: 1 << 20,
            feature_bytes: 0,
            source_depth_bytes: 0,
            render_bytes: 1 << 20,
            base_bytes: BASE_BYTES,
        };
        assert_eq!(e.peak_bytes(), 1000 * 2048 + (12 << 20) + BASE_BYTES);
        let with_depths = TrainMemoryEstimate { source_depth_bytes: 1 << 20, ..e };
        assert_eq!(with_depths.peak_bytes(), e.peak_bytes() + (1 << 20));
        assert!(with_depths.describe().contains("reused source-view depths 1.0 MiB") && !e.describe().contains("depths"));
        assert!(e.check(e.peak_bytes()).is_ok());
        let m = e.check(10 << 20).unwrap_err().to_string();
        assert!(m.contains("more than the memory limit of 10.0 MiB") && m.contains("--max-memory"), "{m}");
        assert!(m.contains("1000 Gaussians (the scene's budget)") && !m.contains("L_f"), "{m}");
    }
}
