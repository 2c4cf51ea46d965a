//! Input validation shared by both backends: configuration, Gaussians and camera, and the
//! output gradients given to a backward.

use crate::cpu::project::CamParams;
use crate::{OutputGradients, RasterConfig, RasterError, RenderRequest, Result};
use gs_core::{Camera, Gaussians, Image};

/// The largest screen-space low-pass filter accepted (px²): a blur of 3 px standard deviation.
pub const MAX_LOW_PASS: f32 = 9.0;

impl RasterConfig {
    /// Rejects out-of-range values (NaN included); every render and backward checks this first.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(RasterError::InvalidConfig(m));
        if !(self.near > 0.0 && self.near.is_finite()) {
            return bad(format!("near = {} must be positive and finite", self.near));
        }
        if !(self.far > self.near) {
            return bad(format!(
                "far = {} must exceed near = {}",
                self.far, self.near
            ));
        }
        if !(self.low_pass >= 0.0 && self.low_pass <= MAX_LOW_PASS) {
            return bad(format!("low_pass = {} px² must lie in [0, {MAX_LOW_PASS}]", self.low_pass));
        }
        if !(self.alpha_threshold > 0.0 && self.alpha_threshold <= 0.5) {
            return bad(format!(
                "alpha_threshold = {} must lie in (0, 0.5]",
                self.alpha_threshold
            ));
        }
        if !(self.plane_depth_min_denominator >= 0.0
            && self.plane_depth_min_denominator.is_finite())
        {
            return bad(format!(
                "plane_depth_min_denominator = {} must be ≥ 0",
                self.plane_depth_min_denominator
            ));
        }
        if !self.background.iter().all(|v| v.is_finite()) {
            return bad("background colour is not finite".into());
        }
        Ok(())
    }
}

impl RenderRequest {
    /// Rejects a geometry cut outside [0, 1) (NaN included).
    pub(crate) fn validate(&self) -> Result<()> {
        if !(self.geometry_cut >= 0.0 && self.geometry_cut < 1.0) {
            return Err(RasterError::InvalidConfig(format!(
                "geometry_cut = {} must lie in [0, 1)",
                self.geometry_cut
            )));
        }
        Ok(())
    }
}

/// Checks that the Gaussians' arrays agree in length, fit the u32 index range and have a
/// supported SH degree.
pub(crate) fn check_gaussians(g: &Gaussians) -> Result<()> {
    let n = g.means.len();
    let lens = [
        g.log_scales.len(),
        g.rotations.len(),
        g.opacity_logits.len(),
        g.sh.len(),
    ];
    if lens.iter().any(|&l| l != n) {
        return Err(RasterError::InvalidGaussians(format!(
            "array lengths differ: means {n}, log_scales {}, rotations {}, opacity {}, sh {}",
            lens[0], lens[1], lens[2], lens[3]
        )));
    }
    if n > u32::MAX as usize - 1 {
        return Err(RasterError::InvalidGaussians(format!(
            "{n} Gaussians exceed the u32 index range"
        )));
    }
    if g.sh_degree > gs_core::sh::MAX_SH_DEGREE {
        return Err(RasterError::InvalidGaussians(format!(
            "SH degree {} > 3",
            g.sh_degree
        )));
    }
    Ok(())
}

/// Validates the inputs of a render or backward and returns the f32 camera constants.
pub(crate) fn check_inputs(
    g: &Gaussians,
    camera: &Camera,
    cfg: &RasterConfig,
) -> Result<CamParams> {
    cfg.validate()?;
    check_gaussians(g)?;
    let (w, h) = (camera.width as usize, camera.height as usize);
    if w == 0 || h == 0 {
        return Err(RasterError::InvalidCamera(format!(
            "image size {w}x{h} is empty"
        )));
    }
    if w.saturating_mul(h) > gs_core::image::MAX_IMAGE_PIXELS {
        return Err(RasterError::InvalidCamera(format!(
            "image size {w}x{h} exceeds the cap of {} pixels",
            gs_core::image::MAX_IMAGE_PIXELS
        )));
    }
    let k = &camera.intrinsics;
    let finite = [k.fx, k.fy, k.cx, k.cy].iter().all(|v| v.is_finite()) && k.fx > 0.0 && k.fy > 0.0;
    if !finite || !camera.rotation.is_finite() || !camera.translation.is_finite() {
        return Err(RasterError::InvalidCamera(
            "non-finite pose or non-positive focal length".into(),
        ));
    }
    Ok(CamParams::new(camera))
}

/// One output gradient: it must belong to a rendered channel and match the render's size.
fn check_grad(
    img: Option<&Image>,
    rendered: bool,
    name: &str,
    w: u32,
    h: u32,
    c: usize,
) -> Result<()> {
    if let Some(im) = img {
        if !rendered {
            return Err(RasterError::InvalidGradients(format!(
                "gradient for {name} given but {name} was not rendered"
            )));
        }
        if im.width() != w as usize || im.height() != h as usize || im.channels() != c {
            return Err(RasterError::InvalidGradients(format!(
                "{name} gradient is {}x{}x{}, the render is {w}x{h}x{c}",
                im.width(),
                im.height(),
                im.channels()
            )));
        }
    }
    Ok(())
}

/// Checks every given output gradient against the rendered channels and the image size.
pub(crate) fn check_all_grads(
    grads: &OutputGradients,
    req: &RenderRequest,
    w: u32,
    h: u32,
) -> Result<()> {
    let geo_grads = grads.normal.is_some() || grads.distance.is_some() || grads.plane_depth.is_some();
    #[cfg(feature = "wgpu")]
    let geo_grads = geo_grads || grads.device_geometry.is_some() || grads.device_plane.is_some();
    if req.applied_cut() > 0.0 && geo_grads {
        return Err(RasterError::InvalidGradients(format!(
            "geometry gradients of a render with geometry_cut = {} (the cut is forward only)",
            req.geometry_cut
        )));
    }
    check_grad(grads.color, req.color, "color", w, h, 3)?;
    #[cfg(feature = "wgpu")]
    check_device_color(grads, req, w, h)?;
    #[cfg(feature = "wgpu")]
    check_device_geometry(grads, req, w, h)?;
    #[cfg(feature = "wgpu")]
    check_device_plane(grads, req, w, h)?;
    check_grad(grads.alpha, req.alpha, "alpha", w, h, 1)?;
    check_grad(grads.normal, req.normal, "normal", w, h, 3)?;
    check_grad(grads.distance, req.distance, "distance", w, h, 1)?;
    check_grad(grads.plane_depth, req.plane_depth, "plane_depth", w, h, 1)?;
    check_grad(
        grads.expected_depth,
        req.expected_depth,
        "expected_depth",
        w,
        h,
        1,
    )
}

/// The device colour gradient, if any: of a render with colour, `w × h × 3`, and not beside
/// a host colour gradient.
#[cfg(feature = "wgpu")]
fn check_device_color(grads: &OutputGradients, req: &RenderRequest, w: u32, h: u32) -> Result<()> {
    let Some(g) = grads.device_color else { return Ok(()) };
    let problem = if grads.color.is_some() {
        "given both on the host and on the device".to_string()
    } else if !req.color {
        "given but the render has no colour".to_string()
    } else if (g.width(), g.height(), g.channels()) != (w as usize, h as usize, 3) {
        format!("is {}×{}×{}, needs {w}×{h}×3", g.width(), g.height(), g.channels())
    } else {
        return Ok(());
    };
    Err(RasterError::InvalidGradients(format!("the device colour gradient {problem}")))
}

/// The device geometry gradients, if any: of a render with geometry (its cut is checked with
/// the host's geometry gradients), `w × h × 3` and `w × h × 1`.
#[cfg(feature = "wgpu")]
fn check_device_geometry(grads: &OutputGradients, req: &RenderRequest, w: u32, h: u32) -> Result<()> {
    let Some(g) = grads.device_geometry else { return Ok(()) };
    let size = |im: &gs_gpu::DeviceImage| (im.width(), im.height(), im.channels());
    let (wu, hu) = (w as usize, h as usize);
    let problem = if !req.geo() {
        "given but the render has no geometry (normal, distance or plane depth)".to_string()
    } else {
        match (size(g.normal), size(g.plane_depth)) {
            (n, z) if n == (wu, hu, 3) && z == (wu, hu, 1) => return Ok(()),
            ((a, b, c), (d, e, f)) => format!("are {a}×{b}×{c} and {d}×{e}×{f}, need {w}×{h}×3 and {w}×{h}×1"),
        }
    };
    Err(RasterError::InvalidGradients(format!("the device geometry gradients {problem}")))
}

/// The device plane gradient, if any: of a render with geometry (its cut is checked with the
/// host's geometry gradients), `w × h × 4` with a finite weight.
#[cfg(feature = "wgpu")]
fn check_device_plane(grads: &OutputGradients, req: &RenderRequest, w: u32, h: u32) -> Result<()> {
    let Some(g) = grads.device_plane else { return Ok(()) };
    let size = (g.gradient.width(), g.gradient.height(), g.gradient.channels());
    let problem = if !req.geo() {
        "given but the render has no geometry (normal, distance or plane depth)".to_string()
    } else if !g.weight.is_finite() {
        format!("has the weight {}", g.weight)
    } else if size != (w as usize, h as usize, gs_gpu::PLANE_GRAD_CHANNELS) {
        format!("is {}×{}×{}, needs {w}×{h}×{}", size.0, size.1, size.2, gs_gpu::PLANE_GRAD_CHANNELS)
    } else {
        return Ok(());
    };
    Err(RasterError::InvalidGradients(format!("the device plane gradient {problem}")))
}

/// Checks that a forward state of `(n, width, height)` belongs to these inputs (`usable` is
/// false for a state that cannot be differentiated, e.g. one from `render_naive`); `note` ends
/// the error message.
pub(crate) fn check_forward_matches(
    (n, width, height): (usize, u32, u32),
    usable: bool,
    g: &Gaussians,
    cam: &CamParams,
    note: &str,
) -> Result<()> {
    if n != g.len() || width != cam.width || height != cam.height || !usable {
        return Err(RasterError::InvalidGradients(format!(
            "forward state ({n} Gaussians, {width}x{height}) does not match the inputs ({} Gaussians, {}x{}){note}",
            g.len(),
            cam.width,
            cam.height
        )));
    }
    Ok(())
}
