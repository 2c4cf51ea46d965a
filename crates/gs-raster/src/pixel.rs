//! Host-side per-pixel math shared by both backends: pixel rays, plane depth, assembling the
//! output images from the accumulators, and folding the output gradients per pixel.

use crate::cpu::CpuState;
use crate::cpu::project::CamParams;
use crate::{
    ForwardState, OutputGradients, PLANE_DEPTH_EPS, RasterConfig, RasterError, RenderOutput,
    RenderRequest, RenderStats, Result, StateInner,
};
use gs_core::Image;
use rayon::prelude::*;

/// Camera-space ray K⁻¹(u, v, 1) at the centre of pixel (x, y), in f32.
#[inline]
pub(crate) fn pixel_ray(cam: &CamParams, x: usize, y: usize) -> [f32; 3] {
    [
        ((x as f32 + 0.5) - cam.cx) / cam.fx,
        ((y as f32 + 0.5) - cam.cy) / cam.fy,
        1.0,
    ]
}

/// Plane depth and its denominator at one pixel; `None` where the denominator is at or below
/// the guard.
#[inline]
pub(crate) fn plane_depth_at(
    n: [f32; 3],
    d: f32,
    ray: [f32; 3],
    min_den: f32,
) -> Option<(f32, f32)> {
    let den = -(n[0] * ray[0] + n[1] * ray[1] + n[2] * ray[2]) + PLANE_DEPTH_EPS;
    if den > min_den && den.is_finite() {
        Some((d / den, den))
    } else {
        None
    }
}

/// Builds the requested images from per-pixel accumulators (shared by tiled and naive paths).
pub(crate) fn assemble(
    cam: &CamParams,
    cfg: &RasterConfig,
    req: &RenderRequest,
    acc: &[[f32; 8]],
    final_t: &[f32],
) -> Result<RenderOutput> {
    let (w, h) = (cam.width as usize, cam.height as usize);
    // Rows in parallel: every value is a pure function of its pixel, so the bytes do not
    // depend on the thread count.
    let img = |c: usize, f: &(dyn Fn(usize, usize, usize) -> f32 + Sync)| -> Result<Image> {
        let mut data = vec![0.0f32; w * h * c];
        if w > 0 {
            data.par_chunks_mut(w * c).enumerate().for_each(|(y, row)| {
                for (x, px) in row.chunks_mut(c).enumerate() {
                    for (ch, v) in px.iter_mut().enumerate() {
                        *v = f(x, y, ch);
                    }
                }
            });
        }
        Image::from_vec(w, h, c, data).map_err(|e| RasterError::InvalidCamera(e.to_string()))
    };
    let bg = cfg.background;
    let color = if req.color {
        Some(img(3, &|x, y, c| {
            acc[y * w + x][c] + final_t[y * w + x] * bg[c]
        })?)
    } else {
        None
    };
    let alpha = if req.alpha {
        Some(img(1, &|x, y, _| 1.0 - final_t[y * w + x])?)
    } else {
        None
    };
    let normal = if req.normal {
        Some(img(3, &|x, y, c| acc[y * w + x][3 + c])?)
    } else {
        None
    };
    let distance = if req.distance {
        Some(img(1, &|x, y, _| acc[y * w + x][6])?)
    } else {
        None
    };
    let plane_depth = if req.plane_depth {
        Some(img(1, &|x, y, _| {
            let a = &acc[y * w + x];
            plane_depth_at(
                [a[3], a[4], a[5]],
                a[6],
                pixel_ray(cam, x, y),
                cfg.plane_depth_min_denominator,
            )
            .map_or(0.0, |v| v.0)
        })?)
    } else {
        None
    };
    let expected_depth = if req.expected_depth {
        Some(img(1, &|x, y, _| {
            let a_sum = 1.0 - final_t[y * w + x];
            if a_sum > 0.0 {
                acc[y * w + x][7] / a_sum
            } else {
                0.0
            }
        })?)
    } else {
        None
    };
    Ok(RenderOutput {
        color,
        alpha,
        normal,
        distance,
        plane_depth,
        expected_depth,
        radii: Vec::new(),
        observed: None,
        stats: RenderStats::default(),
        final_t: Vec::new(),
        last_contributor: Vec::new(),
        #[cfg(feature = "wgpu")]
        device_color: None,
        #[cfg(feature = "wgpu")]
        device_surface: None,
        state: ForwardState(StateInner::Cpu(CpuState {
            n_gaussians: 0,
            width: cam.width,
            height: cam.height,
            request: *req,
            splats: Vec::new(),
            features: Vec::new(),
            order: Vec::new(),
            bins: crate::cpu::raster::Bins::default(),
            final_t: Vec::new(),
            last: Vec::new(),
            geo: Vec::new(),
        })),
    })
}

/// Per-pixel channel gradients of pixel (x, y) for the backward traversal (shared by both
/// backends): ∂L/∂(colour, Ñ, D, Σ w t_z) with plane depth folded into Ñ and D and expected
/// depth into the depth sum and alpha, and the coefficient of the T_final term
/// (g_A − bg·g_C − expected-depth term). `geo` holds per pixel Ñ (3), D, Σ w t_z (it may be
/// empty when neither plane depth nor expected depth gradients are given).
pub(crate) fn pixel_grads(
    cam: &CamParams,
    config: &RasterConfig,
    grads: &OutputGradients,
    final_t: &[f32],
    geo: &[[f32; 5]],
    x: usize,
    y: usize,
) -> ([f32; 8], f32) {
    let p = y * cam.width as usize + x;
    let bg = config.background;
    let min_den = config.plane_depth_min_denominator;
    let mut gc = [0.0f32; 8];
    let mut g_alpha = grads.alpha.map_or(0.0, |im| im.get(x, y, 0));
    if let Some(im) = grads.color {
        for c in 0..3 {
            gc[c] = im.get(x, y, c);
        }
        g_alpha -= bg[0] * gc[0] + bg[1] * gc[1] + bg[2] * gc[2];
    }
    if let Some(im) = grads.normal {
        for c in 0..3 {
            gc[3 + c] = im.get(x, y, c);
        }
    }
    if let Some(im) = grads.distance {
        gc[6] = im.get(x, y, 0);
    }
    if let Some(im) = grads.plane_depth {
        let gz = im.get(x, y, 0);
        let gs = &geo[p];
        let ray = pixel_ray(cam, x, y);
        if let Some((_, den)) = plane_depth_at([gs[0], gs[1], gs[2]], gs[3], ray, min_den) {
            // z = D / den, den = −Ñ·r + ε: ∂z/∂D = 1/den, ∂z/∂Ñ = D·r/den².
            gc[6] += gz / den;
            let k = gz * gs[3] / (den * den);
            for c in 0..3 {
                gc[3 + c] += k * ray[c];
            }
        }
    }
    if let Some(im) = grads.expected_depth {
        let a = 1.0 - final_t[p];
        if a > 0.0 {
            let ge = im.get(x, y, 0);
            let s = geo[p][4];
            gc[7] = ge / a;
            g_alpha -= ge * s / (a * a);
        }
    }
    (gc, g_alpha)
}
