//! The densification statistics (docs/method.md §Densification): per Gaussian, the screen-space
//! gradients summed over the views that saw it between two densification steps. Shared by
//! the trainer's density control and the rasterizer's device step, which accumulates them
//! on a resident model (gs-raster `adam_params.wgsl`), so both twins keep one layout.

/// The length of a screen-space gradient (x, y): what densification compares with its
/// thresholds.
pub fn screen_norm([x, y]: [f32; 2]) -> f32 {
    (x * x + y * y).sqrt()
}

/// Per-Gaussian statistics accumulated between densification steps.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DensifyStats {
    /// Σ over views of ‖∂L/∂μ₂ᴅ‖ (signed accumulation per view, norm per view).
    pub grad_sum: Vec<f32>,
    /// Σ over views of the AbsGS norm ‖(Σ|∂L/∂x|, Σ|∂L/∂y|)‖.
    pub abs_grad_sum: Vec<f32>,
    /// Views in which the Gaussian was visible (radius > 0); with Pixel-GS's weights
    /// (`DensifyConfig::pixel_weighted`) the pixels where it was seen in front, summed over views.
    pub visible_count: Vec<u32>,
    /// Largest screen radius seen, pixels.
    pub max_radius: Vec<f32>,
}

impl DensifyStats {
    /// Zeroed statistics for `n` Gaussians.
    pub fn new(n: usize) -> Self {
        Self { grad_sum: vec![0.0; n], abs_grad_sum: vec![0.0; n], visible_count: vec![0; n], max_radius: vec![0.0; n] }
    }

    /// Number of Gaussians tracked.
    pub fn len(&self) -> usize {
        self.grad_sum.len()
    }

    /// Whether no Gaussian is tracked.
    pub fn is_empty(&self) -> bool {
        self.grad_sum.is_empty()
    }

    /// Keeps the statistics of the rows with `keep = true` (after the model dropped the others).
    pub fn retain(&mut self, keep: &[bool]) {
        let filter = |v: &mut Vec<f32>| {
            let mut k = keep.iter();
            v.retain(|_| *k.next().unwrap_or(&false));
        };
        filter(&mut self.grad_sum);
        filter(&mut self.abs_grad_sum);
        filter(&mut self.max_radius);
        let mut k = keep.iter();
        self.visible_count.retain(|_| *k.next().unwrap_or(&false));
    }

    /// Adds one view's gradients for the Gaussians visible in it (radius > 0); the view was
    /// rendered at 1/`scale` of the training size, so its radii count `scale` times. With
    /// `pixels` (the render's observed counts: Pixel-GS's weights), each gradient counts as many
    /// times as the Gaussian has pixels in front, so the means become pixel-weighted means.
    pub fn accumulate(&mut self, radii: &[u32], pixels: Option<&[u32]>, mean2d: &[[f32; 2]], mean2d_abs: &[[f32; 2]], scale: f32) {
        for (i, &r) in radii.iter().enumerate() {
            if r > 0 {
                let weight = pixels.map_or(1, |p| p[i]);
                let w = weight as f32;
                self.grad_sum[i] += w * screen_norm(mean2d[i]);
                self.abs_grad_sum[i] += w * screen_norm(mean2d_abs[i]);
                self.visible_count[i] = self.visible_count[i].saturating_add(weight);
                self.max_radius[i] = self.max_radius[i].max(r as f32 * scale);
            }
        }
    }
}
