//! The rasterizer's kernels: the camera uniform (its WGSL generated from the Rust definition)
//! and each kernel's sources and storage-binding table.

use crate::RasterConfig;
use crate::cpu::project::CamParams;
use gs_core::Gaussians;
use gs_core::sh::coeffs_for_degree;
use super::split::TileSplit;
use gs_gpu::{Binding, GeneratedStruct, GpuContext, Kernel};

gs_gpu::wgsl_struct! {
    /// Camera, config and frame constants of one render / backward (binding 0 of every
    /// kernel; WGSL `struct Cam`).
    pub(crate) struct CamUniform as "Cam" {
        /// Columns of the world-to-camera rotation R_c (xyz).
        r0: [f32; 4],
        r1: [f32; 4],
        r2: [f32; 4],
        /// Translation t_c (xyz).
        tc: [f32; 4],
        fx: f32,
        fy: f32,
        cx: f32,
        cy: f32,
        lim_x: f32,
        lim_y: f32,
        near: f32,
        far: f32,
        threshold: f32,
        antialiased: u32,
        sh_degree: u32,
        /// SH coefficients per colour channel in the upload ((degree + 1)²).
        nc: u32,
        width: u32,
        height: u32,
        tiles_x: u32,
        tiles_y: u32,
        /// Channel flags: 1 colour, 2 geometry (normal, distance), 4 depth sum, 8 observed.
        flags: u32,
        n: u32,
        /// `RenderRequest::geometry_cut` of a render (0 in a backward: the cut is forward only).
        geometry_cut: f32,
        /// `RasterConfig::low_pass` (px²).
        low_pass: f32,
        /// `RasterConfig::plane_depth_min_denominator`.
        min_den: f32,
        /// `RasterConfig::background` (red, green, blue).
        bg_r: f32,
        bg_g: f32,
        bg_b: f32,
    }
}

impl CamUniform {
    /// The uniform of camera `cam`, config `cfg` and Gaussians `g` with channel `flags` and
    /// geometry cut `geometry_cut`.
    pub(crate) fn new(cam: &CamParams, cfg: &RasterConfig, g: &Gaussians, flags: u32, geometry_cut: f32) -> Self {
        let r = cam.r;
        Self {
            r0: [r.x_axis.x, r.x_axis.y, r.x_axis.z, 0.0],
            r1: [r.y_axis.x, r.y_axis.y, r.y_axis.z, 0.0],
            r2: [r.z_axis.x, r.z_axis.y, r.z_axis.z, 0.0],
            tc: [cam.t.x, cam.t.y, cam.t.z, 0.0],
            fx: cam.fx,
            fy: cam.fy,
            cx: cam.cx,
            cy: cam.cy,
            lim_x: cam.lim_x,
            lim_y: cam.lim_y,
            near: cfg.near,
            far: cfg.far,
            threshold: cfg.alpha_threshold,
            antialiased: cfg.antialiased as u32,
            sh_degree: g.sh_degree,
            nc: coeffs_for_degree(g.sh_degree) as u32,
            width: cam.width,
            height: cam.height,
            tiles_x: cam.tiles_x,
            tiles_y: cam.tiles_y,
            flags,
            n: g.len() as u32,
            geometry_cut,
            low_pass: cfg.low_pass,
            min_den: cfg.plane_depth_min_denominator,
            bg_r: cfg.background[0],
            bg_g: cfg.background[1],
            bg_b: cfg.background[2],
        }
    }
}

const COMMON: &str = include_str!("common.wgsl");
const PROJ_COMMON: &str = include_str!("proj_common.wgsl");
/// Sigmoid and the quaternion's rotation matrix (also density control's, gpu/densify.rs).
pub(super) const PARAM_MATH: &str = include_str!("param_math.wgsl");

/// One kernel: entry point, its own source (after the camera struct and common.wgsl) and
/// its storage bindings (slots 2..).
struct Spec<'a> {
    entry: &'a str,
    sources: Vec<&'a str>,
    bindings: Vec<Binding<'a>>,
}

gs_gpu::wgsl_struct! {
    /// The screen-space gradient of one Gaussian (WGSL `struct ScreenGrad`): one tile's share
    /// (a per-intersection partial of `raster_bwd`) or, summed over its tiles in a fixed
    /// order by `grad_reduce`, the whole of it (read by `project_bwd`). 64 bytes.
    pub(crate) struct ScreenGrad as "ScreenGrad" {
        /// dL/d(x, y) of the projected centre, pixels.
        mean2d: [f32; 2],
        /// Σ |dL/dx|, Σ |dL/dy| over pixels (the densification statistic).
        mean2d_abs: [f32; 2],
        /// dL/d of the conic's a, b (the off-diagonal, counted once), c.
        conic_a: f32,
        conic_b: f32,
        conic_c: f32,
        /// dL/d opacity (after the sigmoid and antialiasing compensation).
        opacity: f32,
        /// dL/d of the blend channels 0..4: colour r, g, b and normal x.
        channels_lo: [f32; 4],
        /// dL/d of the blend channels 4..8: normal y, z, distance D, depth sum.
        channels_hi: [f32; 4],
    }
}

gs_gpu::wgsl_struct! {
    /// One Gaussian's parameters other than SH, as `project` and `project_bwd` read them
    /// (WGSL `struct ParamRecord`; the host's [`Gaussians`] arrays, interleaved). 44 bytes.
    pub(crate) struct ParamRecord as "ParamRecord" {
        mean: [f32; 3],
        log_scale: [f32; 3],
        /// The unit quaternion (w, x, y, z), unnormalised.
        rot_w: f32,
        rot_x: f32,
        rot_y: f32,
        rot_z: f32,
        opacity_logit: f32,
    }
}

gs_gpu::wgsl_struct! {
    /// One SH coefficient of one Gaussian, all three colour channels (WGSL `struct ShCoeff`):
    /// Gaussian `i`'s coefficient `k` is record `i·nc + k` (`nc` coefficients of the active
    /// degree). The SH parameters and their gradients. 12 bytes.
    pub(crate) struct ShCoeff as "ShCoeff" {
        rgb: [f32; 3],
    }
}

gs_gpu::wgsl_struct! {
    /// One projected Gaussian, what the blends read per intersection (WGSL `struct Splat`,
    /// written by `project`). 68 bytes.
    pub(crate) struct Splat as "Splat" {
        /// Projected centre, pixels.
        x: f32,
        y: f32,
        /// The 2D conic (inverse covariance) a, b, c.
        conic_a: f32,
        conic_b: f32,
        conic_c: f32,
        /// Opacity after the sigmoid and the antialiasing compensation.
        opacity: f32,
        /// Largest σ at which α still reaches the threshold.
        sigma_max: f32,
        /// Half extents of the α-threshold box, pixels.
        ext_x: f32,
        ext_y: f32,
        /// The blend channels: colour r, g, b, camera normal x, y, z, distance D, depth t_z.
        channels: [f32; 8],
    }
}

gs_gpu::wgsl_struct! {
    /// One projected Gaussian's tile rectangle [x0, x1) × [y0, y1) and its pixel radius
    /// (WGSL `struct TileRect`; radius 0 = culled). 20 bytes.
    pub(crate) struct TileRect as "TileRect" {
        x0: u32,
        y0: u32,
        x1: u32,
        y1: u32,
        radius: u32,
    }
}

gs_gpu::wgsl_struct! {
    /// One Gaussian's parameter gradients other than SH, written by `project_bwd` (WGSL
    /// `struct ParamGrad`), and the densification statistics in NDC units. 60 bytes.
    pub(crate) struct ParamGrad as "ParamGrad" {
        /// dL/d of each parameter, in the parameters' own record.
        param: ParamRecord,
        /// dL/d of the projected centre in NDC (x, y).
        mean2d_x: f32,
        mean2d_y: f32,
        /// Σ |dL/dx|, Σ |dL/dy| in NDC.
        mean2d_abs_x: f32,
        mean2d_abs_y: f32,
    }
}

gs_gpu::wgsl_struct! {
    /// One pixel's loss gradients as the reverse blend reads them (WGSL `struct PixelGrad`,
    /// folded on the host): dL/d of the eight blend channels and of the final transmittance.
    /// 36 bytes.
    pub(crate) struct PixelGrad as "PixelGrad" {
        channels: [f32; 8],
        final_t: f32,
    }
}

gs_gpu::wgsl_struct! {
    /// One pixel's loss gradients when only the colour (and alpha) has any (WGSL `struct
    /// ColourGrad`): a colour-only backward uploads these instead of [`PixelGrad`]s, whose
    /// other five channels would be zeros. 16 bytes.
    pub(crate) struct ColourGrad as "ColourGrad" {
        /// The colour channels' gradients (named as [`PixelGrad`]'s, whose first three they
        /// are, so that one WGSL body adds into either record).
        channels: [f32; 3],
        final_t: f32,
    }
}

/// `raster_bwd`'s read of a pixel's gradients from `PixelGrad` records.
const PIXEL_GRAD_FULL: &str = "fn pixel_grad(p: u32) -> PixelGrad {\n    return pixgrad[p];\n}\n";

/// `raster_bwd`'s read of a pixel's gradients from `ColourGrad` records: the other channels
/// are zeros, as the host's fold makes them without geometry gradients.
const PIXEL_GRAD_COLOUR: &str = "fn pixel_grad(p: u32) -> PixelGrad {
    let c = pixgrad[p];
    var g: PixelGrad;
    for (var k = 0u; k < 8u; k++) {
        g.channels[k] = 0.0;
    }
    for (var k = 0u; k < 3u; k++) {
        g.channels[k] = c.channels[k];
    }
    g.final_t = c.final_t;
    return g;
}
";

gs_gpu::wgsl_struct! {
    /// One pixel's reverse-blend state between windows of its tile list (WGSL
    /// `struct BlendState`): the transmittance and the eight "behind" sums. 36 bytes.
    pub(crate) struct BlendState as "BlendState" {
        t: f32,
        behind: [f32; 8],
    }
}

impl ParamRecord {
    /// Gaussian `i`'s record from the host's arrays.
    pub(crate) fn of(g: &Gaussians, i: usize) -> Self {
        let [rot_w, rot_x, rot_y, rot_z] = g.rotations[i];
        Self { mean: g.means[i], log_scale: g.log_scales[i], rot_w, rot_x, rot_y, rot_z, opacity_logit: g.opacity_logits[i] }
    }

    /// The quaternion (w, x, y, z).
    pub(crate) fn rotation(&self) -> [f32; 4] {
        [self.rot_w, self.rot_x, self.rot_y, self.rot_z]
    }
}

/// Every kernel of the rasterizer (the scan and sort live in gs-gpu).
fn specs() -> Vec<Spec<'static>> {
    use Binding as B;
    let (f, u, au, sg) = ("array<f32>", "array<u32>", "array<atomic<u32>>", "array<ScreenGrad>");
    let (par, sh, spl, rect, pg) =
        ("array<ParamRecord>", "array<ShCoeff>", "array<Splat>", "array<TileRect>", "array<ParamGrad>");
    let spec = |entry, sources: &[&'static str], bindings: &[Binding<'static>]| Spec {
        entry,
        sources: sources.to_vec(),
        bindings: bindings.to_vec(),
    };
    vec![
        spec(
            "project",
            &[include_str!("project.wgsl"), PROJ_COMMON, PARAM_MATH],
            &[
                B::read("params", par),
                B::read("sh", sh),
                B::write("splat", spl),
                B::write("proj", rect),
                B::write("keys", u),
                B::write("vals", u),
                B::write("counters", au),
                B::write("radii", u),
            ],
        ),
        spec(
            "project_bwd",
            &[include_str!("project_bwd.wgsl"), PROJ_COMMON, PARAM_MATH],
            &[
                B::read("params", par),
                B::read("sh", sh),
                B::read("proj", rect),
                B::read("gacc", sg),
                B::write("gout", pg),
                B::write("gout_sh", sh),
            ],
        ),
        spec(
            "isect_count",
            &[include_str!("isect_count.wgsl")],
            &[
                B::read("keys", u),
                B::read("vals", u),
                B::read("proj", rect),
                B::write("counts", u),
                B::write("counters", au),
            ],
        ),
        spec(
            "isect_emit",
            &[include_str!("isect_emit.wgsl")],
            &[
                B::read("keys", u),
                B::read("vals", u),
                B::read("proj", rect),
                B::read("offsets", u),
                B::write("tile_keys", u),
                B::write("tile_vals", u),
                B::write("isect_gid", u),
            ],
        ),
        spec(
            "tile_ranges",
            &[include_str!("tile_ranges.wgsl")],
            &[B::write("tile_keys", u), B::write("ranges", u), B::read("counters", u)],
        ),
        spec(
            "pad_keys",
            &[include_str!("tile_ranges.wgsl")],
            &[B::write("tile_keys", u), B::write("ranges", u), B::read("counters", u)],
        ),
        spec(
            "isect_link",
            &[include_str!("isect_link.wgsl")],
            &[
                B::read("eidx", u),
                B::read("isect_gid", u),
                B::write("gids", u),
                B::write("isect_pos", u),
                B::read("counters", u),
            ],
        ),
        spec(
            "raster_fwd",
            &[include_str!("raster_fwd.wgsl")],
            &[
                B::read("ranges", u),
                B::read("gids", u),
                B::read("splat", spl),
                B::write("acc", f),
                B::write("final_t", f),
                B::write("last", u),
                B::write("observed", au),
                B::write("counters", au),
            ],
        ),
        spec(
            "plane_depth_plane",
            &[include_str!("plane_depth.wgsl"), include_str!("plane_depth_plane.wgsl")],
            &[B::read("acc", f), B::write("depth", f)],
        ),
        spec(
            "colour_out",
            &[include_str!("colour_out.wgsl")],
            &[B::read("acc", f), B::read("final_t", f), B::write("image", f)],
        ),
        spec(
            "surface_out",
            &[include_str!("plane_depth.wgsl"), include_str!("surface_out.wgsl")],
            &[B::read("acc", f), B::read("final_t", f), B::write("surface", "array<SurfaceTexel>")],
        ),
        spec(
            "geometry_grad_add",
            &[include_str!("plane_depth.wgsl"), include_str!("geometry_grad.wgsl")],
            &[B::read("acc", f), B::read("normal_grad", f), B::read("depth_grad", f), B::write("pixgrad", "array<PixelGrad>")],
        ),
        spec(
            "plane_grad_add",
            &[include_str!("plane_grad.wgsl")],
            &[B::read("plane_grad", "array<PlaneGrad>"), B::write("pixgrad", "array<PixelGrad>")],
        ),
        raster_bwd_spec(PIXEL_GRAD_FULL, "array<PixelGrad>"),
        raster_bwd_spec(PIXEL_GRAD_COLOUR, "array<ColourGrad>"),
        colour_grad_spec("array<PixelGrad>"),
        colour_grad_spec("array<ColourGrad>"),
        spec(
            "grad_reduce",
            &[include_str!("grad_reduce.wgsl")],
            &[
                B::read("depth_ids", u),
                B::read("offsets", u),
                B::read("isect_pos", u),
                B::read("partials", sg),
                B::write("gacc", sg),
            ],
        ),
    ]
}

/// `raster_bwd` reading its per-pixel gradients through `read` from `pixgrad` records of
/// type `records` (two variants: every channel, or the colour alone).
fn raster_bwd_spec(read: &'static str, records: &'static str) -> Spec<'static> {
    use Binding as B;
    let (u, f) = ("array<u32>", "array<f32>");
    Spec {
        entry: "raster_bwd",
        sources: vec![include_str!("raster_bwd.wgsl"), read],
        bindings: vec![
            B::read("ranges", u),
            B::read("gids", u),
            B::read("splat", "array<Splat>"),
            B::read("final_t", f),
            B::read("last", u),
            B::read("pixgrad", records),
            B::write("partials", "array<ScreenGrad>"),
            B::write("bstate", "array<BlendState>"),
        ],
    }
}

/// `colour_grad_add` adding a device colour gradient into `pixgrad` records of type `records`
/// (the same two record types as `raster_bwd`'s; one WGSL body serves both).
fn colour_grad_spec(records: &'static str) -> Spec<'static> {
    use Binding as B;
    Spec {
        entry: "colour_grad_add",
        sources: vec![include_str!("colour_grad.wgsl")],
        bindings: vec![B::read("colour_grad", "array<f32>"), B::write("pixgrad", records)],
    }
}

/// The full source list of a spec: the generated camera and gradient structs, common.wgsl,
/// its own.
fn sources<'a>(decls: &'a str, spec: &Spec<'a>) -> Vec<&'a str> {
    let mut s = vec![decls, COMMON];
    s.extend(spec.sources.iter().copied());
    s
}

/// The `counters` entry holding the longest list position any pixel blended (`raster_fwd`'s
/// integer atomicMax, the same in any order): the backward's window count.
pub(crate) const COUNTER_LONGEST_BLEND: usize = 8;
/// The `counters` entry holding the longest tile list (`raster_fwd`, first window): a render
/// that guessed its window count checks it.
pub(crate) const COUNTER_LONGEST_TILE_LIST: usize = 9;

/// The compiled kernels of the rasterizer.
pub(crate) struct Kernels {
    pub project: Kernel,
    pub project_bwd: Kernel,
    pub isect_count: Kernel,
    pub isect_emit: Kernel,
    pub tile_ranges: Kernel,
    pub pad_keys: Kernel,
    pub isect_link: Kernel,
    pub raster_fwd: Kernel,
    pub plane_depth: Kernel,
    /// The rendered colour into a device image (`RenderRequest::color_on_device`).
    pub colour_out: Kernel,
    /// The rendered surface (z, Ñ, D, A) into a device image (`RenderRequest::surface_on_device`).
    pub surface_out: Kernel,
    /// The normal terms' device gradients added into [`PixelGrad`] records.
    pub geometry_grad_add: Kernel,
    /// A loss's device gradient of Ñ and D (L_p's `PlaneGrad`s) added into [`PixelGrad`] records.
    pub plane_grad_add: Kernel,
    pub raster_bwd: Kernel,
    /// `raster_bwd` on [`ColourGrad`] records (a backward with colour gradients alone).
    pub raster_bwd_colour: Kernel,
    /// A device colour gradient added into [`PixelGrad`] records.
    pub colour_grad_add: Kernel,
    /// A device colour gradient added into [`ColourGrad`] records.
    pub colour_grad_add_colour: Kernel,
    pub grad_reduce: Kernel,
}

/// The camera uniform and every storage record: one list, so that every struct the kernels
/// declare is also the one the layout test checks.
fn generated_structs() -> [GeneratedStruct; 12] {
    [
        GeneratedStruct::of::<CamUniform>(),
        GeneratedStruct::of::<ScreenGrad>(),
        GeneratedStruct::of::<ParamRecord>(),
        GeneratedStruct::of::<ShCoeff>(),
        GeneratedStruct::of::<Splat>(),
        GeneratedStruct::of::<TileRect>(),
        GeneratedStruct::of::<ParamGrad>(),
        GeneratedStruct::of::<PixelGrad>(),
        GeneratedStruct::of::<ColourGrad>(),
        GeneratedStruct::of::<BlendState>(),
        GeneratedStruct::of::<gs_gpu::SurfaceTexel>(),
        GeneratedStruct::of::<gs_gpu::PlaneGrad>(),
    ]
}

/// The generated WGSL declarations every kernel starts with, and the host's constants they
/// share (with the blend kernels' tile split).
fn decls(split: TileSplit) -> String {
    let mut d = gs_gpu::declarations(&generated_structs());
    d.push_str(&split.wgsl());
    d.push_str(&format!("const PLANE_DEPTH_EPS: f32 = {:?};\n", crate::PLANE_DEPTH_EPS));
    d.push_str(&format!("const LONGEST_BLEND: u32 = {}u;\nconst LONGEST_TILE_LIST: u32 = {}u;\n", COUNTER_LONGEST_BLEND, COUNTER_LONGEST_TILE_LIST));
    d
}

impl Kernels {
    /// Compiles every kernel, the blends for `split`.
    pub fn new(ctx: &GpuContext, split: TileSplit) -> gs_gpu::Result<Self> {
        let decls = decls(split);
        let mut k = specs()
            .into_iter()
            .map(|s| Kernel::new(ctx, s.entry, &sources(&decls, &s), &s.bindings));
        let mut next = || k.next().expect("one kernel per spec");
        Ok(Self {
            project: next()?,
            project_bwd: next()?,
            isect_count: next()?,
            isect_emit: next()?,
            tile_ranges: next()?,
            pad_keys: next()?,
            isect_link: next()?,
            raster_fwd: next()?,
            plane_depth: next()?,
            colour_out: next()?,
            surface_out: next()?,
            geometry_grad_add: next()?,
            plane_grad_add: next()?,
            raster_bwd: next()?,
            raster_bwd_colour: next()?,
            colour_grad_add: next()?,
            colour_grad_add_colour: next()?,
            grad_reduce: next()?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gs_gpu::{PassUniform, WgslStruct, bytes_of, check_layout, kernel_source};

    /// Every kernel's full source (exactly what the device compiles) parses and validates, and each of its
    /// generated structs has the Rust offsets and sizes (naga's layouter against
    /// `offset_of!` / `size_of`).
    #[test]
    fn host_and_wgsl_struct_layouts_agree_in_every_kernel() {
        for split in [TileSplit::HARDWARE, TileSplit::SOFTWARE] {
            let decls = decls(split);
            for s in specs() {
                let src = kernel_source(&sources(&decls, &s), &s.bindings);
                // gs-gpu's prelude declares `Pass`; the rest come from this crate's list.
                check_layout::<PassUniform>(&src).unwrap_or_else(|e| panic!("{}: {e}", s.entry));
                gs_gpu::check_layouts(&generated_structs(), &src).unwrap_or_else(|e| panic!("{}: {e}", s.entry));
                gs_gpu::validate_kernel(&src).unwrap_or_else(|e| panic!("{} ({split:?}): {e}", s.entry));
            }
        }
        assert_eq!(std::mem::size_of::<CamUniform>(), 160);
        assert_eq!(std::mem::size_of::<ScreenGrad>(), 64);
        let sizes = [bytes_of::<ParamRecord>(1), bytes_of::<ShCoeff>(1), bytes_of::<Splat>(1)];
        assert_eq!(sizes, [44, 12, 68]);
        assert_eq!([bytes_of::<TileRect>(1), bytes_of::<ParamGrad>(1)], [20, 60]);
        assert_eq!([bytes_of::<PixelGrad>(1), bytes_of::<BlendState>(1), bytes_of::<ColourGrad>(1)], [36, 36, 16]);
    }

    /// A field added to the WGSL side only (a hand-written `Cam`) is caught.
    #[test]
    fn a_field_added_on_one_side_fails_the_check() {
        let edited = CamUniform::wgsl_decl()
            .replace("    low_pass: f32,\n", "    low_pass: f32,\n    extra: u32,\n");
        assert!(check_layout::<CamUniform>(&edited).is_err());
    }
}
