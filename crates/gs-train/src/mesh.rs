//! Surface extraction (docs/method.md §TSDF), one path for every depth source: depth maps (a trained
//! model's rendered plane depths, or given maps such as ground truth) are fused into a TSDF,
//! marching cubes extracts the surface and the clean-up keeps the components ≥ 50 triangles
//! (or the largest). One default-voxel rule ([`default_voxel`]): the world size of one pixel
//! at the fused surfaces, measured on up to [`FOOTPRINT_PROBES`] evenly spaced views of the
//! fusion itself, clamped to [r/1024, r/256] with r the extent of *all* the scene's cameras
//! (r/512 when nothing is fused), so holding out views (`--eval`) does not change the clamp.

use crate::error::{Result, TrainError};
use crate::model::TrainedModel;
use gs_core::{Image, Scene, TriangleMesh, View};
use gs_raster::{Rasterizer, RenderRequest};
use gs_tsdf::{BlockCensus, ComponentFilter, MemoryEstimate, TsdfConfig, TsdfError, TsdfVolume, clean_mesh, format_bytes};
use serde::Serialize;

/// Options of [`fuse_mesh`] (Open3D's names).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MeshOptions {
    /// Voxel size v; `None` = [`default_voxel`] of the fused views' pixel footprint.
    pub voxel_size: Option<f64>,
    /// Truncation; `None` = 4·v.
    pub sdf_trunc: Option<f64>,
    /// Depths beyond this are ignored; `None` = 3·r (r as in [`default_voxel`]).
    pub depth_trunc: Option<f64>,
    /// Rendered plane depths where the rendered alpha is below this are not fused.
    pub min_alpha: f32,
    /// Optional single-view filter: drop depths whose depth normal is more than this many
    /// degrees from the viewing ray (docs/method.md §TSDF: 80).
    pub max_normal_angle_deg: Option<f64>,
    /// Keep only the largest connected component (else every component ≥ 50 triangles).
    pub largest_component_only: bool,
    /// Fuse only where the view's mask is set (object scenes with masks).
    pub use_masks: bool,
    /// Block cap of the TSDF.
    pub max_blocks: usize,
    /// Fuse only inside this box (world units): see [`gs_tsdf::TsdfConfig::bounds`].
    pub bounds: Option<gs_tsdf::Aabb>,
    /// Refuse a fusion whose estimated peak memory (bytes; see [`gs_tsdf::memory`]) exceeds
    /// this, before allocating it; the block cap is lowered to what fits, so an estimate that
    /// falls short still stops with an error. `None`: no estimate, only `max_blocks`.
    pub max_memory: Option<u64>,
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
            bounds: None,
            max_memory: None,
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
    /// Seconds spent rendering (or reading) the depth maps.
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

/// Views whose depth maps measure the pixel footprint before a fusion with the default voxel.
pub const FOOTPRINT_PROBES: usize = 8;

/// The default voxel: the pixel `footprint` (median depth / fx) when known — finer only fuses
/// per-pixel depth noise, coarser loses detail the images hold — clamped to [r/1024, r/256]
/// (memory, sanity) with r the extent of all the scene's cameras; r/512 without a footprint.
pub fn default_voxel(scene: &Scene, footprint: Option<f64>) -> f64 {
    let r = scene.extent();
    match footprint {
        Some(f) if f.is_finite() && f > 0.0 => f.clamp(r / 1024.0, r / 256.0),
        _ => r / 512.0,
    }
}

/// Median of the positive depths of `depth` divided by `fx`, or `None` when it has none.
fn median_footprint(depth: &Image, fx: f64) -> Option<f64> {
    let mut d: Vec<f32> = depth.data().iter().copied().filter(|z| z.is_finite() && *z > 0.0).collect();
    if d.is_empty() {
        return None;
    }
    let mid = d.len() / 2;
    Some(*d.select_nth_unstable_by(mid, f32::total_cmp).1 as f64 / fx)
}

/// Median of `values` (None when empty).
fn median(mut values: Vec<f64>) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let mid = values.len() / 2;
    Some(*values.select_nth_unstable_by(mid, f64::total_cmp).1)
}

/// Where the depth maps of a fusion come from.
pub enum DepthSource<'a> {
    /// A model's rendered plane depth and colour; pixels with alpha below
    /// [`MeshOptions::min_alpha`] are not fused.
    Rendered {
        /// The model.
        model: &'a TrainedModel<'a>,
        /// The rasterizer that renders it.
        rasterizer: &'a mut Rasterizer,
    },
    /// Given depth maps (camera z, 0 = none), one per view, coloured by the photographs.
    Given(&'a mut dyn FnMut(&View) -> Result<Image>),
}

impl DepthSource<'_> {
    /// The depth map (and colour) of `view` (index `i`) to fuse.
    fn depth_of(&mut self, i: usize, view: &View, min_alpha: f32) -> Result<(Image, Option<Image>)> {
        match self {
            DepthSource::Rendered { model, rasterizer } => {
                let req = RenderRequest { color: true, alpha: true, plane_depth: true, ..RenderRequest::default() };
                let out = model.render(rasterizer, i, &req)?;
                let mut depth = out.plane_depth.expect("requested");
                for (d, a) in depth.data_mut().iter_mut().zip(out.alpha.expect("requested").data()) {
                    if *a < min_alpha {
                        *d = 0.0;
                    }
                }
                Ok((depth, out.color))
            }
            DepthSource::Given(read) => Ok((read(view)?, None)),
        }
    }
}

/// Fuses the depth maps of `views` (indices into `scene.views`) from `source` into a TSDF, runs
/// marching cubes and the clean-up (components ≥ 50 triangles or the largest, degenerate and
/// unreferenced elements removed).
pub fn fuse_mesh(scene: &Scene, views: &[usize], mut source: DepthSource<'_>, opts: &MeshOptions) -> Result<(TriangleMesh, MeshReport)> {
    if views.is_empty() {
        return Err(TrainError::InvalidScene("no views to fuse into a mesh".into()));
    }
    let (mut render_s, mut fuse_s) = (0.0, 0.0);
    // Without a given voxel, the first views' depth maps (kept for the fusion) measure the footprint.
    let mut probed: Vec<(usize, Image, Option<Image>)> = Vec::new();
    if opts.voxel_size.is_none() || opts.max_memory.is_some() {
        let t0 = std::time::Instant::now();
        for k in 0..FOOTPRINT_PROBES.min(views.len()) {
            let i = views[k * views.len() / FOOTPRINT_PROBES.min(views.len())];
            let view = scene.views.get(i).ok_or_else(|| TrainError::InvalidScene(format!("view index {i} out of range")))?;
            let (depth, color) = source.depth_of(i, view, opts.min_alpha)?;
            probed.push((i, depth, color));
        }
        render_s += t0.elapsed().as_secs_f64();
    }
    let probe_footprint = median(
        probed.iter().filter_map(|(i, d, _)| median_footprint(d, scene.views[*i].camera.intrinsics.fx)).collect(),
    );
    let voxel = opts.voxel_size.unwrap_or_else(|| default_voxel(scene, probe_footprint));
    let depth_trunc = opts.depth_trunc.unwrap_or(3.0 * scene.extent());
    let mut config = TsdfConfig {
        voxel_size: voxel,
        sdf_trunc: opts.sdf_trunc,
        depth_trunc,
        max_blocks: opts.max_blocks,
        max_normal_angle_deg: opts.max_normal_angle_deg,
        with_color: true,
        bounds: opts.bounds,
    };
    if let Some(limit) = opts.max_memory {
        config.max_blocks = config.max_blocks.min((limit / MemoryEstimate::bytes_per_block(true)).max(1) as usize);
        check_memory(scene, views.len(), &probed, &config, opts.use_masks, limit, probe_footprint)?;
    }
    let mut volume = TsdfVolume::new(config)?;
    let mut footprints = Vec::with_capacity(views.len());
    for &i in views {
        let view = scene.views.get(i).ok_or_else(|| TrainError::InvalidScene(format!("view index {i} out of range")))?;
        let t0 = std::time::Instant::now();
        let (depth, color) = match probed.iter().position(|(p, _, _)| *p == i) {
            Some(k) => {
                let (_, d, c) = probed.swap_remove(k);
                (d, c)
            }
            None => source.depth_of(i, view, opts.min_alpha)?,
        };
        let t1 = std::time::Instant::now();
        let mask = if opts.use_masks { view.mask.as_ref() } else { None };
        let fused = volume
            .integrate_view(i, &view.camera, &depth, Some(color.as_ref().unwrap_or(&view.image)), mask)
            .map_err(|e| match (e, opts.max_memory) {
                (TsdfError::BlockCapExceeded { needed, .. }, Some(limit)) => TrainError::MemoryLimit(format!(
                    "fusing view '{}' needs {needed} TSDF blocks, about {}, more than the memory limit of {}; \
                     use a larger --voxel-size than {} or raise --max-memory",
                    view.name,
                    format_bytes(MemoryEstimate::for_blocks(needed as u64, true).peak_bytes()),
                    format_bytes(limit),
                    short(voxel)
                )),
                (e, _) => TrainError::InvalidScene(format!("view '{}': {e}", view.name)),
            })?;
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
        pixel_footprint: median(footprints),
    };
    Ok((mesh, report))
}

/// A voxel size in few digits (`0.01293`, `1.000e-9`).
fn short(v: f64) -> String {
    if v.abs() >= 1e-3 { format!("{v:.5}") } else { format!("{v:.3e}") }
}

/// Refuses a fusion whose [`BlockCensus`] estimate over the `probed` depth maps exceeds `limit`
/// bytes, naming the estimate, the limit and a voxel that would fit.
fn check_memory(
    scene: &Scene,
    views: usize,
    probed: &[(usize, Image, Option<Image>)],
    config: &TsdfConfig,
    use_masks: bool,
    limit: u64,
    footprint: Option<f64>,
) -> Result<()> {
    let voxel = config.voxel_size;
    let refuse = |what: String, blocks: u64| {
        let bytes = MemoryEstimate::for_blocks(blocks, true).peak_bytes();
        // Blocks scale as 1/voxel² on a surface sheet; never suggest finer than a pixel.
        let fits = voxel * (1.1 * bytes as f64 / limit as f64).sqrt();
        let fits = footprint.map_or(fits, |f| fits.max(f));
        TrainError::MemoryLimit(format!(
            "{what} at voxel size {} needs about {} ({blocks} TSDF blocks of {} each, with marching cubes), \
             more than the memory limit of {}; use --voxel-size {fits:.3e} or larger, or raise --max-memory",
            short(voxel),
            format_bytes(bytes),
            format_bytes(MemoryEstimate::bytes_per_block(true)),
            format_bytes(limit)
        ))
    };
    let mut census = BlockCensus::new(config.clone())?;
    for (i, depth, _) in probed {
        let view = &scene.views[*i];
        let mask = if use_masks { view.mask.as_ref() } else { None };
        match census.add(&view.camera, depth, mask) {
            Err(TsdfError::BlockCapExceeded { needed, .. }) => {
                let n = census.probes() + 1;
                return Err(refuse(format!("fusing {n} of the {views} views alone"), needed as u64));
            }
            r => r?,
        }
    }
    let est = census.estimate(views);
    if est.peak_bytes() > limit {
        return Err(refuse(format!("fusing {views} views"), est.blocks));
    }
    Ok(())
}

/// The mesh of a trained model fused from its training views' rendered plane depths.
pub fn extract_mesh(model: &TrainedModel<'_>, rasterizer: &mut Rasterizer, opts: &MeshOptions) -> Result<(TriangleMesh, MeshReport)> {
    fuse_mesh(model.scene, model.train, DepthSource::Rendered { model, rasterizer }, opts)
}
