//! Fusion piece by piece (docs/method.md §TSDF, "Piece by piece"): a scene too large for one
//! TSDF volume is fused as several, one at a time, and the pieces' surfaces are joined into the
//! mesh one volume would have made.
//!
//! Every point of space belongs to exactly one piece ([`FusionPieces::owner`]). A first pass
//! renders each view once and notes which pieces its depths touch, and how many TSDF blocks each
//! piece will hold (so a piece that would not fit is refused before anything is fused). Then
//! each piece in turn gets its own volume holding only the blocks near its points, fused from
//! exactly the views that touch those blocks, in the scene's view order. A block therefore holds
//! the same values in every piece that holds it and in a single volume, so marching cubes makes
//! the same triangles there; each piece keeps the triangles whose centroids it owns, and
//! vertices on the seams, computed from the same values, are joined by position. The clean-up
//! and simplification then run once on the joined mesh, as for one volume. Peak memory is the
//! largest piece's volume. The survey keeps the depth maps it rendered while they fit in a
//! quarter of the memory limit (and beside the largest piece); a view whose map was not kept is
//! rendered again for each piece it touches.

use crate::error::{Result, TrainError};
use crate::mesh::{DepthSource, FetchStats, Fetched, MeshOptions, MeshReport, Setup, finish, integrate, length_text, median, prepare};
use gs_core::glam::DVec3;
use gs_core::{Scene, TriangleMesh};
use gs_tsdf::{MemoryEstimate, TsdfVolume, block_centre, format_bytes, volume::BLOCK};
use serde::Serialize;
use std::collections::{HashMap, HashSet};

/// How space is split into the pieces of a fusion (e.g. the blocks of a partitioned capture).
pub trait FusionPieces: Sync {
    /// Number of pieces (at least 1).
    fn count(&self) -> usize;
    /// The one piece that owns the point `p`: every point of space belongs to exactly one.
    fn owner(&self, p: DVec3) -> usize;
    /// Whether `p` may lie within `reach` of a point that `piece` owns: never false when it
    /// does (true beyond only costs memory).
    fn near(&self, piece: usize, p: DVec3, reach: f64) -> bool;
    /// The piece's name for people ("block 03").
    fn name(&self, piece: usize) -> String;
}

/// One piece of a fusion piece by piece (`mesh.json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PieceReport {
    /// Its name.
    pub name: String,
    /// Views whose depths touch it, fused into its volume.
    pub views: usize,
    /// TSDF blocks of its volume.
    pub blocks: usize,
    /// Its volume's memory, bytes.
    pub tsdf_bytes: usize,
    /// Triangles it kept (their centroids are its own), before the clean-up.
    pub triangles: usize,
}

/// [`crate::fuse_mesh`] piece by piece: the same mesh (up to the order of its vertices and
/// triangles, and so of the simplification's choices) within the memory of the largest piece.
/// The multi-view depth filter needs every view's depth map at once and is refused here.
pub fn fuse_mesh_in_pieces(
    scene: &Scene,
    views: &[usize],
    mut source: DepthSource<'_>,
    opts: &MeshOptions,
    pieces: &dyn FusionPieces,
) -> Result<(TriangleMesh, MeshReport)> {
    if opts.consistency.is_some() {
        return Err(TrainError::InvalidConfig(
            "the multi-view depth filter holds every view's depth map at once, so it cannot fuse piece by piece; fuse in one volume, or leave the filter off".into(),
        ));
    }
    if pieces.count() == 0 {
        return Err(TrainError::InvalidConfig("a fusion piece by piece needs at least one piece".into()));
    }
    let rendered = matches!(source, DepthSource::Rendered { .. });
    let mut stats = FetchStats::default();
    let (probed, Setup { voxel, depth_trunc, config, .. }) = prepare(scene, views, &mut source, opts, &mut stats)?;
    // A piece holds every block within this distance of its points: the blocks that the cubes
    // of its triangles read (a cube reaches one voxel into the next block).
    let reach = 3f64.sqrt() * (BLOCK as f64 + 2.0) * voxel;
    let keep = |piece: usize| move |key: [i32; 3]| pieces.near(piece, block_centre(key, voxel), reach);
    let Survey { touching, census, mut kept, kept_bytes } = survey(scene, views, probed, &mut source, opts, pieces, &config, &keep, &mut stats)?;
    // Every view was fetched once so far; count what those renders dropped, as one volume would.
    let below_alpha = stats.below_alpha;
    if let Some(limit) = opts.max_memory
        && let Some((k, &blocks)) = census.iter().enumerate().max_by_key(|(_, b)| **b)
    {
        let bytes = MemoryEstimate::for_blocks(blocks as u64, true).peak_bytes();
        if bytes.saturating_add(kept_bytes) > limit {
            // The largest piece fits only without the kept depth maps: render them again.
            kept.iter_mut().for_each(|f| *f = None);
        }
        if bytes > limit {
            return Err(TrainError::MemoryLimit(format!(
                "fusing {} at voxel size {} needs about {} ({blocks} TSDF blocks with marching cubes), more than the memory limit of {}; use a larger --voxel-size or raise --max-memory",
                pieces.name(k),
                length_text(voxel),
                format_bytes(bytes),
                format_bytes(limit)
            )));
        }
    }
    let t = std::time::Instant::now();
    let render_before = stats.seconds;
    let mut joined = Joined::default();
    let mut reports = Vec::with_capacity(pieces.count());
    let mut footprint_of: Vec<Option<f64>> = vec![None; scene.views.len()];
    let mut last_piece = vec![0; scene.views.len()];
    for (k, piece_views) in touching.iter().enumerate() {
        piece_views.iter().for_each(|&i| last_piece[i] = k);
    }
    for (k, piece_views) in touching.iter().enumerate() {
        let mut volume = TsdfVolume::new(config.clone())?;
        let filter = keep(k);
        for &i in piece_views {
            let f = match &kept[i] {
                Some(_) if last_piece[i] == k => kept[i].take().expect("kept"),
                Some(f) => f.clone(),
                None => source.fetch(scene, i, opts, &mut stats)?,
            };
            let footprint = integrate(&mut volume, scene, &f, opts, Some(&filter))?;
            footprint_of[i] = footprint_of[i].or(footprint);
        }
        let raw = volume.extract_mesh()?;
        let triangles = joined.add(&raw, |p| pieces.owner(p) == k);
        reports.push(PieceReport {
            name: pieces.name(k),
            views: piece_views.len(),
            blocks: volume.block_count(),
            tsdf_bytes: volume.memory_bytes(),
            triangles,
        });
    }
    let fuse_seconds = t.elapsed().as_secs_f64() - (stats.seconds - render_before);
    let cameras = scene.cameras_of(views);
    let (mesh, components, simplification) = finish(&joined.mesh, opts, voxel, &cameras)?;
    let report = MeshReport {
        voxel_size: voxel,
        sdf_trunc: config.truncation(),
        depth_trunc,
        views: views.len(),
        blocks: reports.iter().map(|r| r.blocks).sum(),
        tsdf_bytes: reports.iter().map(|r| r.tsdf_bytes).max().unwrap_or(0),
        vertices: mesh.positions.len(),
        triangles: mesh.triangles.len(),
        min_alpha: rendered.then_some(opts.min_alpha),
        pixels_below_min_alpha: below_alpha,
        surface_cut: rendered.then_some(opts.surface_cut),
        depth_filter: None,
        components,
        smoothing: opts.smoothing,
        simplification,
        render_seconds: stats.seconds,
        fuse_seconds,
        pixel_footprint: median(footprint_of.into_iter().flatten().collect()),
        pieces: reports,
    };
    Ok((mesh, report))
}

/// The first pass: every view's depth map once (the `probed` ones as already fetched); for each
/// piece, the views that touch it (in `views`' order) and the number of TSDF blocks it will hold.
#[allow(clippy::too_many_arguments)]
fn survey<F: Fn([i32; 3]) -> bool + Sync>(
    scene: &Scene,
    views: &[usize],
    mut probed: Vec<Fetched>,
    source: &mut DepthSource<'_>,
    opts: &MeshOptions,
    pieces: &dyn FusionPieces,
    config: &gs_tsdf::TsdfConfig,
    keep: &impl Fn(usize) -> F,
    stats: &mut FetchStats,
) -> Result<Survey> {
    // Probing allocates nothing, so it is not held to the memory limit's block cap.
    let probe = TsdfVolume::new(gs_tsdf::TsdfConfig { max_blocks: opts.max_blocks, ..config.clone() })?;
    let n = pieces.count();
    let mut touching = vec![Vec::new(); n];
    let mut blocks: Vec<HashSet<[i32; 3]>> = vec![HashSet::new(); n];
    let mut kept: Vec<Option<Fetched>> = (0..scene.views.len()).map(|_| None).collect();
    let (budget, mut kept_bytes) = (opts.max_memory.map_or(0, |limit| limit / KEPT_SHARE), 0u64);
    for &i in views {
        let f = match probed.iter().position(|f| f.view == i) {
            Some(k) => probed.swap_remove(k),
            None => source.fetch(scene, i, opts, stats)?,
        };
        let view = &scene.views[i];
        let mask = if opts.use_masks { view.mask.as_ref() } else { None };
        let keys = probe.probe_blocks(&view.camera, &f.depth, mask).map_err(|e| TrainError::InvalidScene(format!("view '{}': {e}", view.name)))?;
        for (k, set) in blocks.iter_mut().enumerate() {
            let filter = keep(k);
            // A view touching only blocks already counted still updates them.
            let mut touches = false;
            set.extend(keys.iter().filter(|&&key| filter(key)).inspect(|_| touches = true));
            if touches {
                touching[k].push(i);
            }
        }
        let bytes = f.bytes();
        if kept_bytes + bytes <= budget {
            kept_bytes += bytes;
            kept[i] = Some(f);
        }
    }
    Ok(Survey { touching, census: blocks.iter().map(HashSet::len).collect(), kept, kept_bytes })
}

/// What the first pass found: per piece, the views touching it and its block count; and the
/// depth maps kept for the second pass (by view), within a [`KEPT_SHARE`] of the memory limit.
struct Survey {
    touching: Vec<Vec<usize>>,
    census: Vec<usize>,
    kept: Vec<Option<Fetched>>,
    kept_bytes: u64,
}

/// The survey keeps depth maps for the pieces in up to 1/`KEPT_SHARE` of the memory limit (none
/// without a limit), so a view is rendered again only where they would not fit.
const KEPT_SHARE: u64 = 4;

/// The pieces' triangles joined into one mesh. A vertex of a piece is joined to an earlier
/// piece's vertex at the same position (the same grid edge, computed from the same values);
/// within a piece, vertices stay as marching cubes made them, since distinct vertices of one
/// volume may coincide (a surface through a voxel centre) without being joined there.
#[derive(Default)]
struct Joined {
    mesh: TriangleMesh,
    earlier: HashMap<[u32; 3], u32>,
}

impl Joined {
    /// Adds the triangles of `raw` whose centroids `own` accepts; returns how many.
    fn add(&mut self, raw: &TriangleMesh, own: impl Fn(DVec3) -> bool) -> usize {
        let mut local: HashMap<u32, u32> = HashMap::new();
        let mut added = 0;
        for t in &raw.triangles {
            let p = t.map(|v| DVec3::from(raw.positions[v as usize].map(f64::from)));
            if !own((p[0] + p[1] + p[2]) / 3.0) {
                continue;
            }
            let tri = t.map(|v| {
                *local.entry(v).or_insert_with(|| {
                    let pos = raw.positions[v as usize];
                    if let Some(&g) = self.earlier.get(&pos.map(f32::to_bits)) {
                        return g;
                    }
                    self.mesh.positions.push(pos);
                    if let Some(c) = &raw.colors {
                        self.mesh.colors.get_or_insert_with(Vec::new).push(c[v as usize]);
                    }
                    (self.mesh.positions.len() - 1) as u32
                })
            });
            self.mesh.triangles.push(tri);
            added += 1;
        }
        for (&v, &g) in &local {
            self.earlier.entry(raw.positions[v as usize].map(f32::to_bits)).or_insert(g);
        }
        added
    }
}

/// [`crate::extract_mesh`] piece by piece: a trained model's training views' rendered plane
/// depths fused as `pieces`.
pub fn extract_mesh_in_pieces(
    model: &crate::TrainedModel<'_>,
    rasterizer: &mut gs_raster::Rasterizer,
    opts: &MeshOptions,
    pieces: &dyn FusionPieces,
) -> Result<(TriangleMesh, MeshReport)> {
    fuse_mesh_in_pieces(model.scene, model.train, DepthSource::Rendered { model, rasterizer }, opts, pieces)
}
