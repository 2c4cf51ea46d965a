//! The tiled CPU forward (`render`) and the naive per-pixel reference (`render_naive`).

use super::project::{self, CamParams, Features, Splat};
use super::{CpuState, raster};
use crate::pixel::assemble;
use crate::validate::check_inputs;
use crate::{
    ForwardState, RasterConfig, RenderOutput, RenderRequest, RenderStats, Result, StateInner,
    TILE_SIZE,
};
use gs_core::{Camera, Gaussians};
use rayon::prelude::*;

/// Projects every Gaussian (in parallel): splats, features, radii, rects, depths.
struct Projection {
    splats: Vec<Splat>,
    features: Vec<Features>,
    radii: Vec<u32>,
    rects: Vec<[u32; 4]>,
    depths: Vec<f32>,
    visible: Vec<u32>,
}

/// Validates the inputs and projects every Gaussian (the common start of both renders).
fn checked_projection(
    g: &Gaussians,
    camera: &Camera,
    cfg: &RasterConfig,
) -> Result<(CamParams, Projection)> {
    let cam = check_inputs(g, camera, cfg)?;
    let proj = project_all(g, &cam, cfg);
    Ok((cam, proj))
}

fn project_all(g: &Gaussians, cam: &CamParams, cfg: &RasterConfig) -> Projection {
    let n = g.len();
    let mut p = Projection {
        splats: vec![Splat::default(); n],
        features: vec![[0.0; 8]; n],
        radii: vec![0; n],
        rects: vec![[0; 4]; n],
        depths: vec![0.0; n],
        visible: Vec::new(),
    };
    // Each task writes its own rows of the arrays in place (no per-Gaussian Option buffer to
    // allocate and copy out); culled rows keep radius 0.
    const ROWS: usize = 1024;
    p.splats
        .par_chunks_mut(ROWS)
        .zip(p.features.par_chunks_mut(ROWS))
        .zip(p.radii.par_chunks_mut(ROWS))
        .zip(p.rects.par_chunks_mut(ROWS))
        .zip(p.depths.par_chunks_mut(ROWS))
        .enumerate()
        .for_each(|(k, ((((splats, features), radii), rects), depths))| {
            for j in 0..splats.len() {
                if let Some(pr) = project::project(g, k * ROWS + j, cam, cfg) {
                    splats[j] = pr.splat;
                    features[j] = pr.features;
                    radii[j] = pr.radius;
                    rects[j] = pr.rect;
                    depths[j] = pr.depth;
                }
            }
        });
    // A projected Gaussian has radius ≥ 1 (culling requires a positive radius).
    p.visible = (0..n as u32).filter(|&i| p.radii[i as usize] > 0).collect();
    p
}

/// Renders the requested maps of `gaussians` seen by `camera` (tiled, parallel over tiles).
pub fn render(
    gaussians: &Gaussians,
    camera: &Camera,
    request: &RenderRequest,
    config: &RasterConfig,
) -> Result<RenderOutput> {
    request.validate()?;
    let (cam, proj) = checked_projection(gaussians, camera, config)?;
    let (order, bins) = raster::bin(
        &proj.visible,
        &proj.depths,
        &proj.rects,
        cam.tiles_x,
        cam.tiles_y,
        config.max_intersections,
    )?;
    // Compact the visible splats in depth order (tile lists then read them sequentially).
    let splats: Vec<Splat> = order.iter().map(|&i| proj.splats[i as usize]).collect();
    let features: Vec<Features> = order.iter().map(|&i| proj.features[i as usize]).collect();
    let ctx = raster::Ctx {
        splats: &splats,
        features: &features,
        bins: &bins,
        width: cam.width,
        height: cam.height,
        tiles_x: cam.tiles_x,
        threshold: config.alpha_threshold,
        geometry_cut: request.applied_cut(),
    };
    let geo = request.geo();
    let tiles = raster::forward_tiles(
        &ctx,
        request.color,
        geo,
        request.expected_depth,
        request.observed,
    );
    // Scatter tile results into image-sized buffers (serial, in tile order).
    let (w, h) = (cam.width as usize, cam.height as usize);
    let npix = w * h;
    let mut acc = vec![[0.0f32; 8]; npix];
    let mut final_t = vec![1.0f32; npix];
    let mut last = vec![0u32; npix];
    let mut stats = RenderStats {
        visible: proj.visible.len(),
        intersections: bins.ids.len(),
        ..Default::default()
    };
    let mut observed = request.observed.then(|| vec![0u32; gaussians.len()]);
    for (tile, out) in tiles.iter().enumerate() {
        let tx = tile % cam.tiles_x as usize;
        let ty = tile / cam.tiles_x as usize;
        let (x0, y0) = (tx * TILE_SIZE as usize, ty * TILE_SIZE as usize);
        let tw = (w - x0).min(TILE_SIZE as usize);
        for (lp, a) in out.acc.iter().enumerate() {
            let (lx, ly) = (lp % tw, lp / tw);
            let gp = (y0 + ly) * w + x0 + lx;
            acc[gp] = *a;
            final_t[gp] = out.final_t[lp];
            last[gp] = out.last[lp];
            stats.forward_pairs += out.traversed[lp] as u64;
            stats.backward_pairs += out.last[lp] as u64;
        }
        stats.box_pairs += out.box_pairs;
        if let Some(obs) = observed.as_mut() {
            for (k, &cid) in bins.tile(tile).iter().enumerate() {
                obs[order[cid as usize] as usize] += out.observed[k];
            }
        }
    }
    drop(tiles);
    let mut out = assemble(&cam, config, request, &acc, &final_t)?;
    out.radii = proj.radii;
    out.observed = observed;
    out.stats = stats;
    let geo_state = if geo || request.expected_depth {
        acc.iter().map(|a| [a[3], a[4], a[5], a[6], a[7]]).collect()
    } else {
        Vec::new()
    };
    out.state = ForwardState(StateInner::Cpu(CpuState {
        n_gaussians: gaussians.len(),
        width: cam.width,
        height: cam.height,
        request: *request,
        splats,
        features,
        order,
        bins,
        final_t: final_t.clone(),
        last: last.clone(),
        geo: geo_state,
    }));
    out.final_t = final_t;
    out.last_contributor = last;
    Ok(out)
}

/// Naive per-pixel reference: for every pixel, every visible Gaussian in (depth, index) order,
/// no tiles, single-threaded. Same projection and blending constants as [`render`]; used by
/// tests (tiled == naive) and by the bench for the speed ratio. Forward only.
pub fn render_naive(
    gaussians: &Gaussians,
    camera: &Camera,
    request: &RenderRequest,
    config: &RasterConfig,
) -> Result<RenderOutput> {
    request.validate()?;
    let (cam, proj) = checked_projection(gaussians, camera, config)?;
    let mut order = proj.visible.clone();
    order.sort_by(|&a, &b| {
        proj.depths[a as usize]
            .total_cmp(&proj.depths[b as usize])
            .then(a.cmp(&b))
    });
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut acc = vec![[0.0f32; 8]; w * h];
    let mut final_t = vec![1.0f32; w * h];
    let mut observed = vec![0u32; gaussians.len()];
    for y in 0..h {
        for x in 0..w {
            let (a, t) = raster::naive_pixel(
                &proj.splats,
                &proj.features,
                &order,
                x as f32 + 0.5,
                y as f32 + 0.5,
                config.alpha_threshold,
                request.applied_cut(),
                &mut observed,
            );
            acc[y * w + x] = a;
            final_t[y * w + x] = t;
        }
    }
    let mut out = assemble(&cam, config, request, &acc, &final_t)?;
    out.radii = proj.radii;
    out.observed = request.observed.then_some(observed);
    out.stats.visible = proj.visible.len();
    out.final_t = final_t;
    Ok(out)
}
