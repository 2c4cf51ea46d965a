//! The CPU backward: per-tile reverse traversal merged in tile order, then the projection
//! backward per Gaussian.

use super::project::{self, CamParams, SplatGrad};
use super::raster;
use crate::pixel::pixel_grads;
use crate::validate::{check_all_grads, check_forward_matches, check_inputs};
use crate::{
    GaussianGradients, OutputGradients, RasterConfig, RasterError, RenderOutput, Result, TILE_SIZE,
};
use gs_core::{Camera, Gaussians};
use rayon::prelude::*;

/// Backward pass: gradients of the Gaussian parameters given gradients of the rendered maps.
/// `gaussians`, `camera` and `config` must be those of the `forward` render.
pub fn backward(
    gaussians: &Gaussians,
    camera: &Camera,
    config: &RasterConfig,
    forward: &RenderOutput,
    grads: &OutputGradients,
) -> Result<GaussianGradients> {
    let cam = check_inputs(gaussians, camera, config)?;
    let Some(st) = forward.state.cpu() else {
        return Err(RasterError::InvalidGradients(
            "the forward render came from the wgpu backend; call backward on the same WgpuRasterizer".into(),
        ));
    };
    check_forward_matches(
        (st.n_gaussians, st.width, st.height),
        !st.final_t.is_empty(),
        gaussians,
        &cam,
        " or is not from render()",
    )?;
    let (w, h) = (cam.width, cam.height);
    check_all_grads(grads, &st.request, w, h)?;
    #[cfg(feature = "wgpu")]
    if grads.device_color.is_some() || grads.device_geometry.is_some() || grads.device_plane.is_some() {
        return Err(RasterError::InvalidGradients("gradients on a device given to the CPU backward".into()));
    }
    let color = grads.color.is_some();
    let geo = grads.normal.is_some() || grads.distance.is_some() || grads.plane_depth.is_some();
    let depth = grads.expected_depth.is_some();
    let n = gaussians.len();
    let mut out = GaussianGradients::zeros(n);
    if st.bins.ids.is_empty() || !(color || geo || depth || grads.alpha.is_some()) {
        return Ok(out);
    }
    let ctx = raster::Ctx {
        splats: &st.splats,
        features: &st.features,
        bins: &st.bins,
        width: w,
        height: h,
        tiles_x: cam.tiles_x,
        threshold: config.alpha_threshold,
        geometry_cut: 0.0,
    };
    let wu = w as usize;
    let pixel_grads =
        |x: usize, y: usize| pixel_grads(&cam, config, grads, &st.final_t, &st.geo, x, y);
    let ts = TILE_SIZE as usize;
    let gin = |tile: usize| -> raster::TileGradIn {
        let tx = tile % cam.tiles_x as usize;
        let ty = tile / cam.tiles_x as usize;
        let (x0, y0) = (tx * ts, ty * ts);
        let tw = (wu - x0).min(ts);
        let th = (h as usize - y0).min(ts);
        let mut g_ch = Vec::with_capacity(tw * th);
        let mut g_final = Vec::with_capacity(tw * th);
        for ly in 0..th {
            for lx in 0..tw {
                let (gc, ga) = pixel_grads(x0 + lx, y0 + ly);
                g_ch.push(gc);
                g_final.push(ga);
            }
        }
        raster::TileGradIn { g_ch, g_final }
    };
    let px = raster::PixelState {
        final_t: &st.final_t,
        last: &st.last,
    };
    let per_tile = raster::backward_tiles(&ctx, &px, &gin, color, geo, depth);
    // Deterministic merge in tile order.
    let mut sg = vec![SplatGrad::default(); n];
    let mut touched = vec![false; n];
    for list in &per_tile {
        for (cid, g) in list {
            let gid = st.order[*cid as usize] as usize;
            sg[gid].add(g);
            touched[gid] = true;
        }
    }
    drop(per_tile);
    project_grads(gaussians, &cam, config, &sg, &touched, &mut out);
    Ok(out)
}

/// Projection backward of every touched Gaussian from its merged splat gradient, written in
/// place chunk by chunk (disjoint slices, no atomics); `mean2d` in NDC units.
fn project_grads(
    gaussians: &Gaussians,
    cam: &CamParams,
    config: &RasterConfig,
    sg: &[SplatGrad],
    touched: &[bool],
    out: &mut GaussianGradients,
) {
    let (sx, sy) = (0.5 * cam.width as f32, 0.5 * cam.height as f32);
    const CHUNK: usize = 512;
    let GaussianGradients {
        means,
        log_scales,
        rotations,
        opacity_logits,
        sh,
        mean2d,
        mean2d_abs,
    } = out;
    means
        .par_chunks_mut(CHUNK)
        .zip(log_scales.par_chunks_mut(CHUNK))
        .zip(rotations.par_chunks_mut(CHUNK))
        .zip(opacity_logits.par_chunks_mut(CHUNK))
        .zip(sh.par_chunks_mut(CHUNK))
        .zip(mean2d.par_chunks_mut(CHUNK))
        .zip(mean2d_abs.par_chunks_mut(CHUNK))
        .enumerate()
        .for_each(|(c, ((((((gm, gl), gr), go), gs), g2), ga))| {
            for j in 0..gm.len() {
                let i = c * CHUNK + j;
                if !touched[i] {
                    continue;
                }
                if let Some(pg) = project::project_backward(gaussians, i, cam, config, &sg[i]) {
                    gm[j] = pg.mean;
                    gl[j] = pg.log_scale;
                    gr[j] = pg.rotation;
                    go[j] = pg.opacity_logit;
                    gs[j] = pg.sh;
                    g2[j] = [sg[i].xy[0] * sx, sg[i].xy[1] * sy];
                    ga[j] = [sg[i].abs_xy[0] * sx, sg[i].abs_xy[1] * sy];
                }
            }
        });
}
