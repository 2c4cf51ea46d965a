//! Surface extraction (docs/method.md §TSDF), one path for every depth source: depth maps (a trained
//! model's rendered plane depths, or given maps such as ground truth) are fused into a TSDF,
//! marching cubes extracts the surface, the clean-up keeps the components that hold a share of
//! the mesh (or the largest) and quadric-error simplification removes the triangles the
//! accuracy does not need (docs/method.md §meshing). Before fusing, pixels whose rendered
//! opacity is low and depths that the neighbouring views do not confirm
//! ([`gs_tsdf::filter_depths`]) are dropped, so floating sheets are not fused into surfaces.
//! One default-voxel rule ([`default_voxel`]): the world size of one pixel
//! at the fused surfaces, measured on up to [`FOOTPRINT_PROBES`] evenly spaced views of the
//! fusion itself, clamped to [r/1024, r/256] with r the extent of *all* the scene's cameras
//! (r/512 when nothing is fused), so holding out views (`--eval`) does not change the clamp.

use crate::error::{Result, TrainError};
use crate::model::TrainedModel;
use gs_core::{Camera, Image, NeighbourRule, Scene, TriangleMesh, View, source_view_candidates};
use gs_raster::{Rasterizer, RenderRequest};
use gs_tsdf::{
    BlockCensus, ComponentFilter, ComponentReport, ConsistencyConfig, ConsistencyReport, MemoryEstimate, SimplifyReport,
    SimplifyTarget, TsdfConfig, TsdfError, TsdfVolume, clean_mesh, filter_depths, format_bytes, simplify_mesh, simplify_mesh_graded,
};
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
    /// Rendered plane depths blend each pixel's contributions only until its transmittance
    /// falls to this ([`gs_raster::RenderRequest::geometry_cut`]): the depth of the front of
    /// each pixel's blend, nearer the true surface than the whole blend on curved objects. 0
    /// blends them all. Default [`DEFAULT_SURFACE_CUT`].
    pub surface_cut: f32,
    /// Optional single-view filter: drop depths whose depth normal is more than this many
    /// degrees from the viewing ray (docs/method.md §TSDF: 80).
    pub max_normal_angle_deg: Option<f64>,
    /// Multi-view depth consistency before fusion: each view's depths are checked against its
    /// neighbours (the L_p source-view rule, [`NeighbourRule::default`]); `None`: off, the
    /// default (measured on synth-bunny's exact depths it drops 9.6 % of them, the strips
    /// fewer than two neighbours see, and costs 3.5 % Chamfer; BENCHMARKS.md).
    pub consistency: Option<ConsistencyConfig>,
    /// Keep only the largest connected component (else the components of
    /// [`MeshOptions::min_component_share`]).
    pub largest_component_only: bool,
    /// Components with fewer than this share of the mesh's triangles (or fewer than
    /// [`MIN_COMPONENT_TRIANGLES`]) are removed; 0 keeps every component above that floor.
    pub min_component_share: f64,
    /// Taubin smoothing of the cleaned mesh before it is simplified (`None`: off, the default;
    /// BENCHMARKS.md §Validation suite, synth-bunny's mesh size).
    pub smoothing: Option<gs_tsdf::Smoothing>,
    /// Simplification of the cleaned mesh.
    pub simplify: Simplify,
    /// Fuse only where the view's mask is set (object scenes with masks).
    pub use_masks: bool,
    /// Block cap of the TSDF.
    pub max_blocks: usize,
    /// Fuse only inside this box (world units): see [`gs_tsdf::TsdfConfig::bounds`].
    pub bounds: Option<gs_tsdf::Aabb>,
    /// Refuse a fusion whose estimated peak memory (bytes; see [`gs_tsdf::fusion_memory`]) exceeds
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
            surface_cut: DEFAULT_SURFACE_CUT,
            max_normal_angle_deg: None,
            consistency: None,
            largest_component_only: false,
            min_component_share: DEFAULT_COMPONENT_SHARE,
            smoothing: None,
            simplify: Simplify::FootprintError(DEFAULT_SIMPLIFY_ERROR),
            use_masks: false,
            max_blocks: TsdfConfig::default().max_blocks,
            bounds: None,
            max_memory: None,
        }
    }
}

/// How [`fuse_mesh`] simplifies the cleaned mesh ([`gs_tsdf::simplify_mesh`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Simplify {
    /// The mesh as marching cubes made it.
    Off,
    /// Edge collapses while each vertex's error stays within this multiple of the pixel
    /// footprint at it (the smallest depth / fx over the fused views that image it), and never
    /// below this multiple of the voxel ([`gs_tsdf::simplify_mesh_graded`]).
    FootprintError(f64),
    /// At most this many triangles.
    Triangles(usize),
}

/// The absolute floor of the component clean-up, triangles.
pub const MIN_COMPONENT_TRIANGLES: usize = 50;

/// Default [`MeshOptions::surface_cut`]. On curved objects a trained model's blended plane
/// depth lies about one pixel footprint behind the true surface (training pulls the Gaussians
/// in to match the silhouettes: docs/method.md §TSDF), and the front of each pixel's blend lies
/// nearer it. Cutting the last 15 % of each pixel's opacity lowered the quick suite's mean
/// mesh error from 2.13 to 2.05× its floor (worst 2.97 → 2.94) and raised F1 from 0.60 to 0.66
/// of the floor's (worst 0.26 → 0.37); deeper cuts (0.3, 0.5, 0.7) raised F1 further but made
/// the worst scene's Chamfer worse (BENCHMARKS.md §Validation suite).
pub const DEFAULT_SURFACE_CUT: f32 = 0.15;

/// Default [`MeshOptions::min_component_share`].
pub const DEFAULT_COMPONENT_SHARE: f64 = 0.001;

/// Default [`Simplify::FootprintError`] multiple, judged on synth-bunny's default model and
/// three full-size suite scenes (BENCHMARKS.md §Validation suite): 0.3 keeps 7.3 % of
/// synth-bunny's fused triangles (463k; Chamfer +0.5 %, F1 −0.0004 against the unsimplified
/// mesh) and costs the suite scenes at most +0.7 % Chamfer and −0.004 F1 against 0.1 (which
/// keeps 17 %, free); 0.4 reaches synth-bunny's 5 % but costs the cup F1 0.006.
pub const DEFAULT_SIMPLIFY_ERROR: f64 = 0.3;

/// The depth filter's settings and what it dropped (`mesh.json`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DepthFilterReport {
    /// The settings applied.
    #[serde(flatten)]
    pub settings: ConsistencyConfig,
    /// What it did.
    #[serde(flatten)]
    pub result: ConsistencyReport,
    /// Seconds spent.
    pub seconds: f64,
}

/// The component clean-up's rule and what it removed (`mesh.json`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ComponentCleanup {
    /// `None` when only the largest component is kept.
    pub min_share: Option<f64>,
    /// The absolute floor, triangles.
    pub min_triangles: usize,
    /// What was removed.
    #[serde(flatten)]
    pub result: ComponentReport,
}

/// The simplification's settings and result (`mesh.json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SimplifyApplied {
    /// What was asked.
    pub target: Simplify,
    /// What meshoptimizer did.
    #[serde(flatten)]
    pub result: SimplifyReport,
    /// Seconds spent.
    pub seconds: f64,
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
    /// Triangles of the cleaned (and simplified) mesh.
    pub triangles: usize,
    /// The minimum rendered opacity of a fused pixel (`None` for given depth maps).
    pub min_alpha: Option<f32>,
    /// Pixels with a depth but a rendered opacity below `min_alpha`, not fused.
    pub pixels_below_min_alpha: u64,
    /// [`MeshOptions::surface_cut`] of the rendered depths (`None` for given depth maps).
    pub surface_cut: Option<f32>,
    /// The multi-view depth filter (`None`: off).
    pub depth_filter: Option<DepthFilterReport>,
    /// The component clean-up.
    pub components: ComponentCleanup,
    /// The smoothing before simplification (`None`: off).
    pub smoothing: Option<gs_tsdf::Smoothing>,
    /// The simplification (`None`: off).
    pub simplification: Option<SimplifyApplied>,
    /// Seconds spent rendering (or reading) the depth maps.
    pub render_seconds: f64,
    /// Seconds spent fusing and extracting.
    pub fuse_seconds: f64,
    /// The world size of one pixel at the fused surfaces: median over the views of each view's
    /// median fused depth / fx (`None` when nothing was fused). A voxel much
    /// finer than this only resolves per-pixel depth noise: the surface comes out speckled.
    pub pixel_footprint: Option<f64>,
    /// The pieces of a fusion piece by piece ([`crate::fuse_mesh_in_pieces`]); empty for one
    /// volume. `blocks` then sums the pieces' blocks and `tsdf_bytes` is the largest piece's.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub pieces: Vec<crate::mesh_pieces::PieceReport>,
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
pub(crate) fn median(mut values: Vec<f64>) -> Option<f64> {
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

/// One view's depth map ready to fuse, with its rendered colour (`None`: the photograph).
#[derive(Clone)]
pub(crate) struct Fetched {
    pub view: usize,
    pub depth: Image,
    pub color: Option<Image>,
}

impl Fetched {
    /// Bytes of its depth map and colour.
    pub fn bytes(&self) -> u64 {
        ((self.depth.data().len() + self.color.as_ref().map_or(0, |c| c.data().len())) * 4) as u64
    }
}

/// Running totals of the fetching.
#[derive(Default)]
pub(crate) struct FetchStats {
    pub seconds: f64,
    pub below_alpha: u64,
}

impl DepthSource<'_> {
    /// The depth map (and colour) of view `i` to fuse.
    pub(crate) fn fetch(&mut self, scene: &Scene, i: usize, opts: &MeshOptions, stats: &mut FetchStats) -> Result<Fetched> {
        let view = scene.views.get(i).ok_or_else(|| TrainError::InvalidScene(format!("view index {i} out of range")))?;
        let t0 = std::time::Instant::now();
        let fetched = match self {
            DepthSource::Rendered { model, rasterizer } => {
                let req = RenderRequest {
                    color: true,
                    alpha: true,
                    plane_depth: true,
                    radii: false,
                    geometry_cut: opts.surface_cut,
                    ..RenderRequest::default()
                };
                let out = model.render(rasterizer, i, &req)?;
                let mut depth = out.plane_depth.expect("requested");
                for (d, a) in depth.data_mut().iter_mut().zip(out.alpha.expect("requested").data()) {
                    if *a < opts.min_alpha {
                        stats.below_alpha += u64::from(*d > 0.0);
                        *d = 0.0;
                    }
                }
                Fetched { view: i, depth, color: out.color }
            }
            DepthSource::Given(read) => Fetched { view: i, depth: read(view)?, color: None },
        };
        stats.seconds += t0.elapsed().as_secs_f64();
        Ok(fetched)
    }
}

/// Fuses the depth maps of `views` (indices into `scene.views`) from `source` into a TSDF, runs
/// marching cubes, the clean-up (components of [`MeshOptions::min_component_share`] or the
/// largest, degenerate and unreferenced elements removed) and the simplification. With
/// [`MeshOptions::consistency`] every view's depth map is held until all are filtered.
pub fn fuse_mesh(scene: &Scene, views: &[usize], mut source: DepthSource<'_>, opts: &MeshOptions) -> Result<(TriangleMesh, MeshReport)> {
    let rendered = matches!(source, DepthSource::Rendered { .. });
    let mut stats = FetchStats::default();
    let (mut held, Setup { voxel, depth_trunc, config, probe_footprint }) = prepare(scene, views, &mut source, opts, &mut stats)?;
    if let Some(limit) = opts.max_memory {
        let kept = opts.consistency.map_or(0, |_| held_bytes(scene, views, rendered));
        check_memory(scene, views.len(), &held, &config, opts.use_masks, (limit, kept), probe_footprint)?;
    }
    let depth_filter = match opts.consistency {
        Some(cfg) => {
            let mut all = Vec::with_capacity(views.len());
            for &i in views {
                match held.iter().position(|f| f.view == i) {
                    Some(k) => all.push(held.swap_remove(k)),
                    None => all.push(source.fetch(scene, i, opts, &mut stats)?),
                }
            }
            held = all;
            Some(filter_held(scene, &mut held, cfg)?)
        }
        None => None,
    };
    let mut volume = TsdfVolume::new(config)?;
    let t = std::time::Instant::now();
    let mut footprints = Vec::with_capacity(views.len());
    let mut fetch_s = 0.0;
    for &i in views {
        let f = match held.iter().position(|f| f.view == i) {
            Some(k) => held.swap_remove(k),
            None => {
                let before = stats.seconds;
                let f = source.fetch(scene, i, opts, &mut stats)?;
                fetch_s += stats.seconds - before;
                f
            }
        };
        footprints.extend(integrate(&mut volume, scene, &f, opts, None)?);
    }
    let raw = volume.extract_mesh()?;
    let fuse_seconds = t.elapsed().as_secs_f64() - fetch_s;
    let footprint = median(footprints);
    let cameras = scene.cameras_of(views);
    let (mesh, components, simplification) = finish(&raw, opts, voxel, &cameras)?;
    let report = MeshReport {
        voxel_size: voxel,
        sdf_trunc: volume.config().truncation(),
        depth_trunc,
        views: views.len(),
        blocks: volume.block_count(),
        tsdf_bytes: volume.memory_bytes(),
        vertices: mesh.positions.len(),
        triangles: mesh.triangles.len(),
        min_alpha: rendered.then_some(opts.min_alpha),
        pixels_below_min_alpha: stats.below_alpha,
        surface_cut: rendered.then_some(opts.surface_cut),
        depth_filter,
        components,
        smoothing: opts.smoothing,
        simplification,
        render_seconds: stats.seconds,
        fuse_seconds,
        pixel_footprint: footprint,
        pieces: Vec::new(),
    };
    Ok((mesh, report))
}

/// The grid of a fusion: its voxel, depth truncation and TSDF configuration.
pub(crate) struct Setup {
    pub voxel: f64,
    pub depth_trunc: f64,
    /// With [`MeshOptions::max_memory`], its block cap is lowered to what the limit holds.
    pub config: TsdfConfig,
    /// The median pixel footprint of the probed views.
    pub probe_footprint: Option<f64>,
}

/// Checks `views`, fetches the probe views that measure the pixel footprint (held for the
/// fusion; none with a given voxel and no memory limit) and sets up the grid.
pub(crate) fn prepare(
    scene: &Scene,
    views: &[usize],
    source: &mut DepthSource<'_>,
    opts: &MeshOptions,
    stats: &mut FetchStats,
) -> Result<(Vec<Fetched>, Setup)> {
    if views.is_empty() {
        return Err(TrainError::InvalidScene("no views to fuse into a mesh".into()));
    }
    if let Some(i) = views.iter().find(|&&i| i >= scene.views.len()) {
        return Err(TrainError::InvalidScene(format!("view index {i} out of range")));
    }
    let mut held: Vec<Fetched> = Vec::new();
    if opts.voxel_size.is_none() || opts.max_memory.is_some() {
        for k in 0..FOOTPRINT_PROBES.min(views.len()) {
            let i = views[k * views.len() / FOOTPRINT_PROBES.min(views.len())];
            held.push(source.fetch(scene, i, opts, stats)?);
        }
    }
    let probe_footprint =
        median(held.iter().filter_map(|f| median_footprint(&f.depth, scene.views[f.view].camera.intrinsics.fx)).collect());
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
    }
    Ok((held, Setup { voxel, depth_trunc, config, probe_footprint }))
}

/// Bytes of the depth maps (and rendered colours) held for the depth filter.
fn held_bytes(scene: &Scene, views: &[usize], rendered: bool) -> u64 {
    let per_pixel = if rendered { 16 } else { 4 };
    views.iter().map(|&i| scene.views[i].camera.width as u64 * scene.views[i].camera.height as u64 * per_pixel).sum()
}

/// Runs the multi-view depth filter over `held` (every fused view, in fusion order).
fn filter_held(scene: &Scene, held: &mut [Fetched], cfg: ConsistencyConfig) -> Result<DepthFilterReport> {
    let t = std::time::Instant::now();
    let cameras: Vec<&Camera> = held.iter().map(|f| &scene.views[f.view].camera).collect();
    let neighbours = source_view_candidates(&cameras, &NeighbourRule::default());
    let mut depths: Vec<&mut Image> = held.iter_mut().map(|f| &mut f.depth).collect();
    let result = filter_depths(&cameras, &mut depths, &neighbours, &cfg)
        .map_err(|e| TrainError::InvalidScene(format!("depth filter: {e}")))?;
    Ok(DepthFilterReport { settings: cfg, result, seconds: t.elapsed().as_secs_f64() })
}

/// Integrates one fetched view; returns its pixel footprint (median fused depth / fx).
pub(crate) fn integrate(
    volume: &mut TsdfVolume,
    scene: &Scene,
    f: &Fetched,
    opts: &MeshOptions,
    keep: Option<gs_tsdf::BlockFilter<'_>>,
) -> Result<Option<f64>> {
    let voxel = volume.config().voxel_size;
    let view = &scene.views[f.view];
    let mask = if opts.use_masks { view.mask.as_ref() } else { None };
    let fused = volume
        .integrate_view(f.view, &view.camera, &f.depth, Some(f.color.as_ref().unwrap_or(&view.image)), mask, keep)
        .map_err(|e| match (e, opts.max_memory) {
            (TsdfError::BlockCapExceeded { needed, .. }, Some(limit)) => TrainError::MemoryLimit(format!(
                "fusing view '{}' needs {needed} TSDF blocks, about {}, more than the memory limit of {}; \
                 use a larger --voxel-size than {} or raise --max-memory",
                view.name,
                format_bytes(MemoryEstimate::for_blocks(needed as u64, true).peak_bytes()),
                format_bytes(limit),
                length_text(voxel)
            )),
            (e, _) => TrainError::InvalidScene(format!("view '{}': {e}", view.name)),
        })?;
    Ok(fused.median_depth.map(|z| z as f64 / view.camera.intrinsics.fx))
}

/// The clean-up and simplification of the raw marching-cubes mesh. [`Simplify::FootprintError`]
/// bounds each vertex by a multiple of the pixel footprint at it ([`gs_tsdf::pixel_footprints`]
/// over the fused views' `cameras`), never below the `voxel`: the fusion resolves nothing
/// finer, and surfaces seen only from afar (a far wall) are simplified more than the object.
pub(crate) fn finish(raw: &TriangleMesh, opts: &MeshOptions, voxel: f64, cameras: &[&Camera]) -> Result<(TriangleMesh, ComponentCleanup, Option<SimplifyApplied>)> {
    let filter = if opts.largest_component_only {
        ComponentFilter::Largest
    } else {
        ComponentFilter::MinShare { share: opts.min_component_share, min_triangles: MIN_COMPONENT_TRIANGLES }
    };
    let (mesh, result) = clean_mesh(raw, filter)?;
    let mesh = match opts.smoothing {
        Some(sm) => gs_tsdf::smooth_mesh(&mesh, sm)?,
        None => mesh,
    };
    let components = ComponentCleanup {
        min_share: (!opts.largest_component_only).then_some(opts.min_component_share),
        min_triangles: MIN_COMPONENT_TRIANGLES,
        result,
    };
    let t = std::time::Instant::now();
    let (mesh, result) = match opts.simplify {
        Simplify::Off => return Ok((mesh, components, None)),
        Simplify::FootprintError(k) => {
            let bounds: Vec<f64> =
                gs_tsdf::pixel_footprints(&mesh.positions, cameras).into_iter().map(|f| k * f.unwrap_or(voxel).max(voxel)).collect();
            simplify_mesh_graded(&mesh, &bounds)?
        }
        Simplify::Triangles(n) => simplify_mesh(&mesh, SimplifyTarget::Triangles(n))?,
    };
    Ok((mesh, components, Some(SimplifyApplied { target: opts.simplify, result, seconds: t.elapsed().as_secs_f64() })))
}

/// A length for people: five decimals in the usual range, scientific notation outside it
/// (`0.01293`, `1.000e-9`, and 1e300 as `1.000e300`, not as 301 digits).
pub fn length_text(x: f64) -> String {
    if x == 0.0 || (1e-3..1e6).contains(&x.abs()) { format!("{x:.5}") } else { format!("{x:.3e}") }
}

/// Refuses a fusion whose [`BlockCensus`] estimate over the `probed` depth maps, plus `kept`
/// bytes of depth maps held for the depth filter, exceeds `limit` bytes, naming the estimate,
/// the limit and a voxel that would fit.
fn check_memory(
    scene: &Scene,
    views: usize,
    probed: &[Fetched],
    config: &TsdfConfig,
    use_masks: bool,
    (limit, kept): (u64, u64),
    footprint: Option<f64>,
) -> Result<()> {
    let voxel = config.voxel_size;
    let refuse = |what: String, blocks: u64| {
        let bytes = MemoryEstimate::for_blocks(blocks, true).peak_bytes();
        // Blocks scale as 1/voxel² on a surface sheet; never suggest finer than a pixel.
        let room = limit.saturating_sub(kept).max(1);
        let fits = voxel * (1.1 * bytes as f64 / room as f64).sqrt();
        let fits = footprint.map_or(fits, |f| fits.max(f));
        let held = if kept > 0 {
            format!(" plus {} of depth maps held for the depth filter (without --depth-filter none are held),", format_bytes(kept))
        } else {
            String::new()
        };
        TrainError::MemoryLimit(format!(
            "{what} at voxel size {} needs about {} ({blocks} TSDF blocks of {} each, with marching cubes),{held} \
             more than the memory limit of {}; use --voxel-size {fits:.3e} or larger, or raise --max-memory",
            length_text(voxel),
            format_bytes(bytes),
            format_bytes(MemoryEstimate::bytes_per_block(true)),
            format_bytes(limit)
        ))
    };
    let mut census = BlockCensus::new(config.clone())?;
    for f in probed {
        let view = &scene.views[f.view];
        let mask = if use_masks { view.mask.as_ref() } else { None };
        match census.add(&view.camera, &f.depth, mask) {
            Err(TsdfError::BlockCapExceeded { needed, .. }) => {
                let n = census.probes() + 1;
                return Err(refuse(format!("fusing {n} of the {views} views alone"), needed as u64));
            }
            r => r?,
        }
    }
    let est = census.estimate(views);
    if est.peak_bytes().saturating_add(kept) > limit {
        return Err(refuse(format!("fusing {views} views"), est.blocks));
    }
    Ok(())
}

/// The mesh of a trained model fused from its training views' rendered plane depths.
pub fn extract_mesh(model: &TrainedModel<'_>, rasterizer: &mut Rasterizer, opts: &MeshOptions) -> Result<(TriangleMesh, MeshReport)> {
    fuse_mesh(model.scene, model.train, DepthSource::Rendered { model, rasterizer }, opts)
}
