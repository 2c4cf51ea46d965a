//! What a trained model yields (method-spec §8, §9): the mesh fused from rendered plane depths
//! of the training views, and image metrics on held-out views.

use crate::error::{Result, TrainError};
use gs_core::{Gaussians, Image, Scene, TriangleMesh};
use gs_losses::{Lpips, psnr, ssim_metric};
use gs_raster::{RasterConfig, Rasterizer, RenderRequest};
use gs_tsdf::{ComponentFilter, TsdfConfig, TsdfVolume, clean_mesh};
use serde::Serialize;

/// Options of [`extract_mesh`] (Open3D's names).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MeshOptions {
    /// Voxel size v; `None` = r / 512 (method-spec §8).
    pub voxel_size: Option<f64>,
    /// Truncation; `None` = 4·v.
    pub sdf_trunc: Option<f64>,
    /// Depths beyond this are ignored; `None` = 3·r.
    pub depth_trunc: Option<f64>,
    /// Plane depths where the rendered alpha is below this are not fused.
    pub min_alpha: f32,
    /// Optional single-view filter: drop depths whose depth normal is more than this many
    /// degrees from the viewing ray (method-spec §8: 80).
    pub max_normal_angle_deg: Option<f64>,
    /// Keep only the largest connected component (else every component ≥ 50 triangles).
    pub largest_component_only: bool,
    /// Fuse only where the view's mask is set (object scenes with masks).
    pub use_masks: bool,
    /// Block cap of the TSDF.
    pub max_blocks: usize,
}

impl Default for MeshOptions {
    fn default() -> Self {
        Self {
            voxel_size: None,
            sdf_trunc: None,
            depth_trunc: None,
            min_alpha: 0.5,
            max_normal_angle_deg: None,
            largest_component_only: false,
            use_masks: false,
            max_blocks: TsdfConfig::default().max_blocks,
        }
    }
}

/// Numbers of a mesh extraction.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MeshReport {
    /// Voxel size used.
    pub voxel_size: f64,
    /// Truncation used.
    pub sdf_trunc: f64,
    /// Depth truncation used.
    pub depth_trunc: f64,
    /// Views fused.
    pub views: usize,
    /// TSDF blocks allocated.
    pub blocks: usize,
    /// TSDF memory, bytes.
    pub tsdf_bytes: usize,
    /// Vertices of the cleaned mesh.
    pub vertices: usize,
    /// Triangles of the cleaned mesh.
    pub triangles: usize,
    /// Seconds spent rendering the depth maps.
    pub render_seconds: f64,
    /// Seconds spent fusing and extracting.
    pub fuse_seconds: f64,
    /// The world size of one pixel at the fused surfaces: median over the views of each view's
    /// median fused depth / fx (`None` when nothing was fused). A voxel much
    /// finer than this only resolves per-pixel depth noise: the surface comes out speckled.
    pub pixel_footprint: Option<f64>,
}

/// A voxel finer than this fraction of the pixel footprint draws a warning from callers.
pub const FINE_VOXEL_FRACTION: f64 = 0.75;

/// Renders plane depth and colour of `views`, fuses them into a TSDF, runs marching cubes and
/// the clean-up (components ≥ 50 triangles or the largest, degenerate and unreferenced
/// elements removed). `extent` is the scene extent r for the defaults. Renders with
/// `rasterizer` (any backend) and the settings `raster`.
pub fn extract_mesh(
    gaussians: &Gaussians,
    scene: &Scene,
    views: &[usize],
    rasterizer: &mut Rasterizer,
    raster: &RasterConfig,
    extent: f64,
    opts: &MeshOptions,
) -> Result<(TriangleMesh, MeshReport)> {
    if views.is_empty() {
        return Err(TrainError::InvalidScene("no views to fuse into a mesh".into()));
    }
    let voxel = opts.voxel_size.unwrap_or(extent / 512.0);
    let depth_trunc = opts.depth_trunc.unwrap_or(3.0 * extent);
    let config = TsdfConfig {
        voxel_size: voxel,
        sdf_trunc: opts.sdf_trunc,
        depth_trunc,
        max_blocks: opts.max_blocks,
        max_normal_angle_deg: opts.max_normal_angle_deg,
        with_color: true,
    };
    let mut volume = TsdfVolume::new(config)?;
    let (mut render_s, mut fuse_s) = (0.0, 0.0);
    let mut footprints = Vec::with_capacity(views.len());
    let req = RenderRequest { color: true, alpha: true, plane_depth: true, ..RenderRequest::default() };
    for &i in views {
        let view = scene.views.get(i).ok_or_else(|| TrainError::InvalidScene(format!("view index {i} out of range")))?;
        let t0 = std::time::Instant::now();
        let out = rasterizer.render(gaussians, &view.camera, &req, raster)?;
        let mut depth = out.plane_depth.expect("requested");
        let alpha = out.alpha.expect("requested");
        for (d, a) in depth.data_mut().iter_mut().zip(alpha.data()) {
            if *a < opts.min_alpha {
                *d = 0.0;
            }
        }
        let color = out.color.expect("requested");
        let t1 = std::time::Instant::now();
        let mask = if opts.use_masks { view.mask.as_ref() } else { None };
        let fused = volume.integrate_view(i, &view.camera, &depth, Some(&color), mask)?;
        footprints.extend(fused.median_depth.map(|z| z as f64 / view.camera.intrinsics.fx));
        render_s += (t1 - t0).as_secs_f64();
        fuse_s += t1.elapsed().as_secs_f64();
    }
    let t = std::time::Instant::now();
    let raw = volume.extract_mesh()?;
    let filter = if opts.largest_component_only { ComponentFilter::Largest } else { ComponentFilter::MinTriangles(50) };
    let mesh = clean_mesh(&raw, filter)?;
    fuse_s += t.elapsed().as_secs_f64();
    let report = MeshReport {
        voxel_size: voxel,
        sdf_trunc: volume.config().truncation(),
        depth_trunc,
        views: views.len(),
        blocks: volume.block_count(),
        tsdf_bytes: volume.memory_bytes(),
        vertices: mesh.positions.len(),
        triangles: mesh.triangles.len(),
        render_seconds: render_s,
        fuse_seconds: fuse_s,
        pixel_footprint: (!footprints.is_empty()).then(|| {
            let mid = footprints.len() / 2;
            *footprints.select_nth_unstable_by(mid, f64::total_cmp).1
        }),
    };
    Ok((mesh, report))
}

/// Image metrics of one view.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ViewMetrics {
    /// Image name.
    pub name: String,
    /// PSNR, dB.
    pub psnr: f64,
    /// SSIM (method-spec §5.1 window).
    pub ssim: f64,
    /// LPIPS-alex v0.1 (when computed).
    pub lpips: Option<f64>,
    /// Fraction of the image inside the view's mask (masked evaluation only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mask_fraction: Option<f64>,
}

/// Metrics over a set of views, with their means.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ImageMetrics {
    /// Per view.
    pub views: Vec<ViewMetrics>,
    /// Mean PSNR.
    pub psnr: f64,
    /// Mean SSIM.
    pub ssim: f64,
    /// Mean LPIPS.
    pub lpips: Option<f64>,
    /// True when the metrics are of the object inside each view's mask: PSNR over the mask's
    /// pixels, SSIM and LPIPS of render and photo both composited on black outside it.
    pub masked: bool,
}

/// Renders `views` and scores them against their images (PSNR, SSIM and, with `lpips`,
/// LPIPS-alex). Rendered colours are clamped to [0, 1] as an 8-bit export would be. With
/// `masked` every view needs a mask and only the object inside it is scored (see
/// [`ImageMetrics::masked`]); a view without one is an error naming it.
pub fn evaluate_images(
    gaussians: &Gaussians,
    scene: &Scene,
    views: &[usize],
    rasterizer: &mut Rasterizer,
    raster: &RasterConfig,
    lpips: Option<&Lpips>,
    masked: bool,
) -> Result<ImageMetrics> {
    if views.is_empty() {
        return Err(TrainError::InvalidScene("no views to evaluate (train with --eval to hold out test views)".into()));
    }
    let req = RenderRequest { color: true, alpha: false, ..RenderRequest::default() };
    let mut out = Vec::with_capacity(views.len());
    for &i in views {
        let view = scene.views.get(i).ok_or_else(|| TrainError::InvalidScene(format!("view index {i} out of range")))?;
        let mut img: Image = rasterizer.render(gaussians, &view.camera, &req, raster)?.color.expect("requested");
        img.data_mut().iter_mut().for_each(|v| *v = v.clamp(0.0, 1.0));
        let metrics = if masked {
            let mask = view.mask.as_ref().ok_or_else(|| {
                TrainError::InvalidScene(format!("view {} has no mask (masked evaluation needs masks/<stem>.png for every view)", view.name))
            })?;
            let named = |e: gs_losses::LossError| TrainError::InvalidScene(format!("mask of view {}: {e}", view.name));
            let (render_obj, photo_obj) = (
                gs_losses::masked_on_black(&img, mask).map_err(named)?,
                gs_losses::masked_on_black(&view.image, mask).map_err(named)?,
            );
            ViewMetrics {
                name: view.name.clone(),
                psnr: gs_losses::psnr_masked(&img, &view.image, mask).map_err(named)?,
                ssim: ssim_metric(&render_obj, &photo_obj)?,
                lpips: lpips.map(|l| l.distance(&render_obj, &photo_obj)).transpose()?,
                mask_fraction: Some(mask.data().iter().filter(|m| **m >= 0.5).count() as f64 / mask.data().len() as f64),
            }
        } else {
            ViewMetrics {
                name: view.name.clone(),
                psnr: psnr(&img, &view.image)?,
                ssim: ssim_metric(&img, &view.image)?,
                lpips: lpips.map(|l| l.distance(&img, &view.image)).transpose()?,
                mask_fraction: None,
            }
        };
        out.push(metrics);
    }
    let k = out.len() as f64;
    Ok(ImageMetrics {
        psnr: out.iter().map(|v| v.psnr).sum::<f64>() / k,
        ssim: out.iter().map(|v| v.ssim).sum::<f64>() / k,
        lpips: lpips.map(|_| out.iter().filter_map(|v| v.lpips).sum::<f64>() / k),
        views: out,
        masked,
    })
}
