//! Per-Gaussian projection (EWA splatting, docs/method.md §Rendering) and its backward.
//!
//! Forward: camera-space mean t = R_c μ + t_c, near/far cull, Jacobian J at t with t_x/t_z and
//! t_y/t_z clamped to ±1.3·tan(fov/2), Σ' = J R_c Σ R_cᵀ Jᵀ (formed as V Vᵀ with
//! V = J R_c R S, PSD by construction) + the low-pass filter (0.3 px² by default), optional antialiased compensation, conic
//! Σ'⁻¹, opacity-aware radius, SH colour, camera-facing normal n_c and plane distance d.
//! Backward: the exact derivative of the same f32 computation, recomputed from the parameters.

use crate::{RasterConfig, TILE_SIZE};
use glam::{Mat3, Vec3};
use gs_core::gaussians::{rotation_matrix, rotation_matrix_backward, sigmoid, smallest_axis};
use gs_core::sh::{SH_COEFFS, eval_sh_backward, normalize_backward, sh_to_color};
use gs_core::{Camera, Gaussians};

/// The default low-pass filter added to the diagonal of Σ' (px², 3DGS; `RasterConfig::low_pass`).
pub const LOW_PASS: f32 = 0.3;
/// Jacobian clamp factor: t_x/t_z is clamped to ±`JACOBIAN_CLAMP`·tan(fov_x/2).
pub const JACOBIAN_CLAMP: f32 = 1.3;
/// Floor of the antialiased compensation factor (gsplat `MIN_COMPENSATION`).
pub const MIN_COMPENSATION: f32 = 0.005;

/// Camera constants in f32 for the hot paths.
#[derive(Debug, Clone, Copy)]
pub(crate) struct CamParams {
    pub r: Mat3,
    pub t: Vec3,
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    pub width: u32,
    pub height: u32,
    pub tiles_x: u32,
    pub tiles_y: u32,
    pub lim_x: f32,
    pub lim_y: f32,
}

impl CamParams {
    pub fn new(camera: &Camera) -> Self {
        let k = &camera.intrinsics;
        let (fx, fy) = (k.fx as f32, k.fy as f32);
        let (w, h) = (camera.width, camera.height);
        Self {
            r: camera.rotation_f32(),
            t: camera.translation_f32(),
            fx,
            fy,
            cx: k.cx as f32,
            cy: k.cy as f32,
            width: w,
            height: h,
            tiles_x: w.div_ceil(TILE_SIZE),
            tiles_y: h.div_ceil(TILE_SIZE),
            lim_x: JACOBIAN_CLAMP * (w as f32 * 0.5 / fx),
            lim_y: JACOBIAN_CLAMP * (h as f32 * 0.5 / fy),
        }
    }
}

/// What the rasterizer needs of one visible Gaussian (its 2D footprint).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Splat {
    /// Projected mean, continuous pixel coordinates.
    pub x: f32,
    pub y: f32,
    /// Conic Σ'⁻¹ = [[ca, cb], [cb, cc]]; σ = ½(ca dx² + cc dy²) + cb dx dy.
    pub ca: f32,
    pub cb: f32,
    pub cc: f32,
    /// Opacity (after compensation).
    pub opacity: f32,
    /// ln(opacity / alpha_threshold): σ above this gives α below the threshold.
    pub sigma_max: f32,
    /// Axis-aligned half extents (px) of the alpha-threshold ellipse.
    pub ext_x: f32,
    pub ext_y: f32,
}

/// Blended per-Gaussian features: colour (0..3), camera-space normal n_c (3..6), plane
/// distance d (6), depth t_z (7).
pub(crate) type Features = [f32; 8];

/// The projection of one Gaussian that survived culling.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Projected {
    pub splat: Splat,
    pub features: Features,
    pub radius: u32,
    /// Tile rectangle `[x0, y0, x1, y1)`.
    pub rect: [u32; 4],
    pub depth: f32,
}

/// Geometry of one Gaussian's projection (camera-space mean, Jacobian, 2D covariance, conic,
/// opacity): what culling needs, computed before the appearance.
struct Geometry {
    t: Vec3,
    rot: Mat3,
    s: Vec3,
    j0: Vec3,
    j1: Vec3,
    clamped_x: bool,
    clamped_y: bool,
    p: Mat3,
    v0: Vec3,
    v1: Vec3,
    cov: [f32; 3],
    det: f32,
    conic: [f32; 3],
    o_raw: f32,
    comp: f32,
    comp_floored: bool,
    opacity: f32,
}

/// View-dependent appearance of one projected Gaussian: SH colour along the viewing direction
/// and the camera-space normal / plane distance. Only computed for Gaussians that survive
/// culling (the SH evaluation is the costliest part of a projection).
struct Appearance {
    dir_raw: Vec3,
    color: [f32; 3],
    clamped: [bool; 3],
    axis: usize,
    flip: f32,
    n_c: Vec3,
    dist: f32,
}

/// Internals of the forward computation, recomputed by the backward.
struct Internals {
    geo: Geometry,
    app: Appearance,
}

fn geometry(g: &Gaussians, i: usize, cam: &CamParams, cfg: &RasterConfig) -> Option<Geometry> {
    let mean = Vec3::from(g.means[i]);
    let t = cam.r * mean + cam.t;
    if !(t.is_finite() && t.z > cfg.near && t.z <= cfg.far) {
        return None;
    }
    let ls = g.log_scales[i];
    let s = Vec3::new(ls[0].exp(), ls[1].exp(), ls[2].exp());
    if !s.is_finite() {
        return None;
    }
    let rot = rotation_matrix(g.rotations[i]);
    let inv_z = 1.0 / t.z;
    let txz = t.x * inv_z;
    let tyz = t.y * inv_z;
    let cxz = txz.clamp(-cam.lim_x, cam.lim_x);
    let cyz = tyz.clamp(-cam.lim_y, cam.lim_y);
    let clamped_x = cxz != txz;
    let clamped_y = cyz != tyz;
    let j0 = Vec3::new(cam.fx * inv_z, 0.0, -cam.fx * cxz * inv_z);
    let j1 = Vec3::new(0.0, cam.fy * inv_z, -cam.fy * cyz * inv_z);
    let m = Mat3::from_cols(rot.x_axis * s.x, rot.y_axis * s.y, rot.z_axis * s.z);
    let p = cam.r * m;
    let v0 = Vec3::new(j0.dot(p.x_axis), j0.dot(p.y_axis), j0.dot(p.z_axis));
    let v1 = Vec3::new(j1.dot(p.x_axis), j1.dot(p.y_axis), j1.dot(p.z_axis));
    let cov = [v0.dot(v0), v0.dot(v1), v1.dot(v1)];
    let (a, b, c) = (cov[0] + cfg.low_pass, cov[1], cov[2] + cfg.low_pass);
    let det = a * c - b * b;
    if !(det > 0.0 && det.is_finite()) {
        return None;
    }
    let o_raw = sigmoid(g.opacity_logits[i]);
    let (comp, comp_floored) = if cfg.antialiased {
        let det_o = cov[0] * cov[2] - cov[1] * cov[1];
        let ratio = det_o / det;
        let floor = MIN_COMPENSATION * MIN_COMPENSATION;
        if ratio > floor {
            (ratio.sqrt(), false)
        } else {
            (MIN_COMPENSATION, true)
        }
    } else {
        (1.0, false)
    };
    let opacity = o_raw * comp;
    if !(opacity >= cfg.alpha_threshold) {
        return None;
    }
    let inv_det = 1.0 / det;
    let conic = [c * inv_det, -b * inv_det, a * inv_det];
    Some(Geometry {
        t,
        rot,
        s,
        j0,
        j1,
        clamped_x,
        clamped_y,
        p,
        v0,
        v1,
        cov: [a, b, c],
        det,
        conic,
        o_raw,
        comp,
        comp_floored,
        opacity,
    })
}

/// The appearance of Gaussian `i` seen from `cam`, given its projection geometry.
fn appearance(g: &Gaussians, i: usize, cam: &CamParams, geo: &Geometry) -> Appearance {
    let t = geo.t;
    let dir_raw = cam.r.transpose() * t; // = μ − C in world coordinates
    let len = dir_raw.length();
    let dir = if len > 0.0 { dir_raw / len } else { Vec3::ZERO };
    let (color, clamped) = sh_to_color(g.sh_degree, &g.sh[i], dir.to_array());
    let axis = smallest_axis(g.log_scales[i]);
    let n0 = cam.r * geo.rot.col(axis);
    let flip = if n0.dot(t) > 0.0 { -1.0 } else { 1.0 };
    let n_c = n0 * flip;
    let dist = -n_c.dot(t);
    Appearance { dir_raw, color, clamped, axis, flip, n_c, dist }
}

fn internals(g: &Gaussians, i: usize, cam: &CamParams, cfg: &RasterConfig) -> Option<Internals> {
    let geo = geometry(g, i, cam, cfg)?;
    let app = appearance(g, i, cam, &geo);
    Some(Internals { geo, app })
}

/// The tiles `[first, end)` along one axis of `tiles` whose pixels have centres within `half`
/// of `c`: pixel i (centre i + 0.5) is inside when |i + 0.5 − c| ≤ half (empty when none).
/// The twin of project.wgsl's `tile_span`.
fn tile_span(c: f32, half: f32, tiles: u32) -> (u32, u32) {
    let ts = TILE_SIZE as f32;
    let first = ((c - half - 0.5) / ts).floor().clamp(0.0, tiles as f32) as u32;
    let end = ((c + half - 0.5) / ts).floor().clamp(-1.0, tiles as f32 - 1.0) as i64 + 1;
    (first, end.max(0) as u32)
}

/// Projects Gaussian `i`; `None` when it is culled (behind/near/far, degenerate, transparent,
/// non-finite or off-image).
pub(crate) fn project(
    g: &Gaussians,
    i: usize,
    cam: &CamParams,
    cfg: &RasterConfig,
) -> Option<Projected> {
    let geo = geometry(g, i, cam, cfg)?;
    let t = geo.t;
    let x = cam.fx * t.x / t.z + cam.cx;
    let y = cam.fy * t.y / t.z + cam.cy;
    let sigma_max = (geo.opacity / cfg.alpha_threshold).ln();
    let level = (2.0 * sigma_max).max(0.0).sqrt();
    let [a, _, c] = geo.cov;
    let mid = 0.5 * (a + c);
    let lambda_max = mid + (mid * mid - geo.det).max(0.0).sqrt();
    let radius_f = (level * lambda_max.sqrt()).ceil();
    let ext_x = level * a.sqrt();
    let ext_y = level * c.sqrt();
    let finite = x.is_finite()
        && y.is_finite()
        && radius_f > 0.0
        && radius_f.is_finite()
        && ext_x.is_finite()
        && ext_y.is_finite()
        && geo.conic.iter().all(|v| v.is_finite());
    if !finite {
        return None;
    }
    // A Gaussian is visible when the square of its radius reaches a tile (the culling rule,
    // which the densification statistics count on). Its tile list holds only the tiles of
    // its α-threshold box, one pixel wider than the box the blend clips each tile to, so no
    // rounding of that clip can reach a tile left out: the same pixels blend, fewer tiles are
    // listed (docs/method.md §Rendering).
    let (tx0, tx1) = tile_span(x, radius_f, cam.tiles_x);
    let (ty0, ty1) = tile_span(y, radius_f, cam.tiles_y);
    if tx0 >= tx1 || ty0 >= ty1 {
        return None;
    }
    let tight = |c: f32, ext: f32, lo: u32, hi: u32, tiles: u32| {
        let (a, b) = tile_span(c, ext + 1.0, tiles);
        let a = a.max(lo);
        (a, b.min(hi).max(a))
    };
    let (tx0, tx1) = tight(x, ext_x, tx0, tx1, cam.tiles_x);
    let (ty0, ty1) = tight(y, ext_y, ty0, ty1, cam.tiles_y);
    // Only now, for a Gaussian that reaches the image, the view-dependent appearance.
    let app = appearance(g, i, cam, &geo);
    let features = [app.color[0], app.color[1], app.color[2], app.n_c.x, app.n_c.y, app.n_c.z, app.dist, t.z];
    if !features.iter().all(|v| v.is_finite()) {
        return None;
    }
    let radius = radius_f.min(u32::MAX as f32) as u32;
    Some(Projected {
        splat: Splat {
            x,
            y,
            ca: geo.conic[0],
            cb: geo.conic[1],
            cc: geo.conic[2],
            opacity: geo.opacity,
            sigma_max,
            ext_x,
            ext_y,
        },
        features,
        radius,
        rect: [tx0, ty0, tx1, ty1],
        depth: t.z,
    })
}

/// Gradients of the loss w.r.t. the 2D quantities of one Gaussian, summed over its pixels
/// (one record per tile intersection, merged per Gaussian).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct SplatGrad {
    /// ∂L/∂(x, y) of the projected mean (pixels).
    pub xy: [f32; 2],
    /// ∂L/∂(ca, cb, cc) of the conic (σ = ½ ca dx² + cb dx dy + ½ cc dy²).
    pub conic: [f32; 3],
    /// ∂L/∂opacity (after compensation).
    pub opacity: f32,
    /// ∂L/∂features (colour, n_c, d, t_z).
    pub features: [f32; 8],
    /// Σ over pixels of |∂L/∂x|, |∂L/∂y| (AbsGS).
    pub abs_xy: [f32; 2],
}

impl SplatGrad {
    #[inline]
    pub fn add(&mut self, o: &SplatGrad) {
        for k in 0..2 {
            self.xy[k] += o.xy[k];
            self.abs_xy[k] += o.abs_xy[k];
        }
        for k in 0..3 {
            self.conic[k] += o.conic[k];
        }
        self.opacity += o.opacity;
        for k in 0..8 {
            self.features[k] += o.features[k];
        }
    }
}

/// Parameter gradients of one Gaussian.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ParamGrad {
    pub mean: [f32; 3],
    pub log_scale: [f32; 3],
    pub rotation: [f32; 4],
    pub opacity_logit: f32,
    pub sh: [[f32; 3]; SH_COEFFS],
}

/// Backward of [`project`] for Gaussian `i` given the gradients of its 2D quantities.
/// Returns `None` when the Gaussian was culled (no gradient).
pub(crate) fn project_backward(
    g: &Gaussians,
    i: usize,
    cam: &CamParams,
    cfg: &RasterConfig,
    sg: &SplatGrad,
) -> Option<ParamGrad> {
    let it = internals(g, i, cam, cfg)?;
    let t = it.geo.t;
    let inv_z = 1.0 / t.z;
    let mut g_t = Vec3::ZERO;
    // Projected mean x = fx t.x / t.z + cx.
    g_t.x += sg.xy[0] * cam.fx * inv_z;
    g_t.y += sg.xy[1] * cam.fy * inv_z;
    g_t.z -= (sg.xy[0] * cam.fx * t.x + sg.xy[1] * cam.fy * t.y) * inv_z * inv_z;
    // Depth feature t_z.
    g_t.z += sg.features[7];
    // Distance d = −n_c·t.
    let g_d = sg.features[6];
    let mut g_nc = Vec3::new(sg.features[3], sg.features[4], sg.features[5]);
    g_nc -= g_d * t;
    g_t -= g_d * it.app.n_c;
    // Opacity: o = sigmoid(logit)·comp.
    let g_op = sg.opacity;
    let g_oraw = g_op * it.geo.comp;
    let g_logit = g_oraw * it.geo.o_raw * (1.0 - it.geo.o_raw);
    // Conic → blurred covariance: dL/dCov = −Q G Q with G the symmetric gradient of Q.
    let [qa, qb, qc] = it.geo.conic;
    let (ga, gb, gc) = (sg.conic[0], 0.5 * sg.conic[1], sg.conic[2]);
    // (Q G) then (Q G) Q for 2×2 symmetric matrices.
    let m00 = qa * ga + qb * gb;
    let m01 = qa * gb + qb * gc;
    let m10 = qb * ga + qc * gb;
    let m11 = qb * gb + qc * gc;
    let mut gcov_a = -(m00 * qa + m01 * qb);
    let mut gcov_b = -(m00 * qb + m01 * qc); // per off-diagonal entry
    let mut gcov_c = -(m10 * qb + m11 * qc);
    // Antialiased compensation comp = sqrt(det_o / det_b).
    if cfg.antialiased && !it.geo.comp_floored {
        let g_comp = g_op * it.geo.o_raw;
        let [a, b, c] = it.geo.cov;
        let det_b = it.geo.det;
        let lp = cfg.low_pass;
        let det_o = (a - lp) * (c - lp) - b * b;
        let k = 0.5 / it.geo.comp / (det_b * det_b);
        gcov_a += g_comp * k * ((c - lp) * det_b - det_o * c);
        gcov_c += g_comp * k * ((a - lp) * det_b - det_o * a);
        // d/dB of the ratio, with B appearing in both off-diagonal entries: split evenly.
        gcov_b += 0.5 * g_comp * k * (-2.0 * b * det_b + 2.0 * b * det_o);
    }
    // cov = V Vᵀ: dL/dV = 2 G V with G = [[ga, gb], [gb, gc]].
    let gv0 = 2.0 * (gcov_a * it.geo.v0 + gcov_b * it.geo.v1);
    let gv1 = 2.0 * (gcov_b * it.geo.v0 + gcov_c * it.geo.v1);
    // V_r[k] = J_r · P_col_k.
    let p = it.geo.p;
    let g_j0 = p * gv0;
    let g_j1 = p * gv1;
    let g_p = Mat3::from_cols(
        it.geo.j0 * gv0.x + it.geo.j1 * gv1.x,
        it.geo.j0 * gv0.y + it.geo.j1 * gv1.y,
        it.geo.j0 * gv0.z + it.geo.j1 * gv1.z,
    );
    let g_m = cam.r.transpose() * g_p;
    let mut g_rot = Mat3::from_cols(
        g_m.x_axis * it.geo.s.x,
        g_m.y_axis * it.geo.s.y,
        g_m.z_axis * it.geo.s.z,
    );
    let g_log_scale = [
        g_m.x_axis.dot(it.geo.rot.x_axis) * it.geo.s.x,
        g_m.y_axis.dot(it.geo.rot.y_axis) * it.geo.s.y,
        g_m.z_axis.dot(it.geo.rot.z_axis) * it.geo.s.z,
    ];
    // J = [[fx/z, 0, −fx·cxz/z], [0, fy/z, −fy·cyz/z]] with cxz = clamp(x/z).
    let z2 = inv_z * inv_z;
    g_t.z += -g_j0.x * cam.fx * z2 - g_j1.y * cam.fy * z2;
    if it.geo.clamped_x {
        // J02 = −fx·lim/z: no dependence on t.x.
        let cxz = (t.x * inv_z).clamp(-cam.lim_x, cam.lim_x);
        g_t.z += g_j0.z * cam.fx * cxz * z2;
    } else {
        // J02 = −fx t.x / z².
        g_t.x += -g_j0.z * cam.fx * z2;
        g_t.z += g_j0.z * 2.0 * cam.fx * t.x * z2 * inv_z;
    }
    if it.geo.clamped_y {
        let cyz = (t.y * inv_z).clamp(-cam.lim_y, cam.lim_y);
        g_t.z += g_j1.z * cam.fy * cyz * z2;
    } else {
        g_t.y += -g_j1.z * cam.fy * z2;
        g_t.z += g_j1.z * 2.0 * cam.fy * t.y * z2 * inv_z;
    }
    // Normal n_c = flip · R_c · rot[:, axis].
    let g_nw = cam.r.transpose() * g_nc * it.app.flip;
    let col = g_rot.col(it.app.axis) + g_nw;
    *g_rot.col_mut(it.app.axis) = col;
    let g_q = rotation_matrix_backward(g.rotations[i], g_rot);
    // Colour: SH at dir = normalize(R_cᵀ t), zero gradient in clamped channels.
    let mut g_col = [sg.features[0], sg.features[1], sg.features[2]];
    for ch in 0..3 {
        if it.app.clamped[ch] {
            g_col[ch] = 0.0;
        }
    }
    let len = it.app.dir_raw.length();
    let dir = if len > 0.0 {
        it.app.dir_raw / len
    } else {
        Vec3::ZERO
    };
    let (g_sh, g_dir) = eval_sh_backward(g.sh_degree, &g.sh[i], dir.to_array(), g_col);
    let g_dir_raw = Vec3::from(normalize_backward(it.app.dir_raw.to_array(), g_dir));
    g_t += cam.r * g_dir_raw;
    let _ = it.app.color;
    let g_mean = cam.r.transpose() * g_t;
    Some(ParamGrad {
        mean: g_mean.to_array(),
        log_scale: g_log_scale,
        rotation: g_q,
        opacity_logit: g_logit,
        sh: g_sh,
    })
}
