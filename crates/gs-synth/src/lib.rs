//! # gs-synth
//!
//! The built-in scene of vagsl: a small procedural scene with **exact** ground truth, used by
//! `vagsl` when no scene is given and by tests. A textured sphere, box and torus stand on a
//! checkered floor inside four open-top walls under one directional light with hard shadows.
//! The scene is a set of tessellated triangle meshes and the ray tracer intersects exactly
//! those triangles (own [`Bvh`], f64 ray/triangle math), so the GT mesh *is* the rendered
//! geometry. Deterministic for a given seed, whatever the thread count.
//!
//! ```
//! use gs_synth::{BuiltinOptions, generate};
//! let opts = BuiltinOptions { width: 32, height: 24, views: 2, supersample: 1, points: 50, ..Default::default() };
//! let built = generate(&opts).unwrap();
//! assert_eq!(built.scene.views.len(), 2);
//! assert_eq!(built.scene.views[0].name, "0000.png");
//! // GT depth is camera-space z at the pixel-centre rays; back-project pixel (16, 12):
//! let cam = &built.scene.views[0].camera;
//! let z = built.gt_depth[0].get(16, 12, 0) as f64;
//! let p = cam.back_project(16.5, 12.5, z);
//! let bvh = gs_synth::Bvh::new(&built.scene_mesh).unwrap();
//! assert!(bvh.closest_point(p).distance < 1e-4);
//! ```
//!
//! What [`generate`] gives ([`BuiltinScene`]):
//! - `scene`: views `0000.png`, `0001.png`, … (RGB in `[0, 1]`, sRGB-encoded and quantised to
//!   `/255` as if read from an 8-bit PNG; object masks), cameras in COLMAP conventions with
//!   pixel centres at `i + 0.5`, and sparse points (hit points of random pixel-centre rays,
//!   perturbed by Gaussian noise, coloured by albedo) to initialise Gaussians from;
//! - `gt_depth`: camera-space z of the pixel-centre ray's first hit (0 = miss);
//! - `gt_normals`: world-space unit shading normal at the same hit (interpolated vertex
//!   normals on the sphere and torus, face normals elsewhere), oriented towards the camera
//!   together with the face normal; 0 = miss;
//! - `object_mesh` (sphere + box + torus) and `scene_mesh` (objects first, same indices, then
//!   floor and walls).
//!
//! Layout (world Z up, floor z = 0, arbitrary scene units): floor `[−4, 4]²`, walls at x, y = ±4 up to
//! z = 2.2; sphere r = 0.38 at (−0.55, 0.30), a 0.60 × 0.42 × 0.52 box yawed 30° at
//! (0.52, 0.32), a torus (R = 0.30, r = 0.11) tilted 35° at (0.02, −0.52); objects span about
//! 1.8 × 1.6 × 0.76. Cameras on two rings (20° and 40° elevation) of radius 3 around
//! (0, −0.05, 0.28); every pixel-centre ray of the default cameras hits geometry.

pub mod bvh;
pub mod error;
pub mod geometry;
mod objects;
pub mod render;
pub mod shapes;
pub mod street;
pub mod suite;
pub mod texture;
pub mod write;

pub use bvh::{Bvh, ClosestPoint, Hit, ViewCast, pixel_ray};
pub use error::{Result, SynthError};
pub use render::{LIGHT_DIRECTION, RingSpec, Style, ring_cameras, ring_cameras_with};
pub use street::{
    STREET_GENERATOR_VERSION, StreetOptions, StreetScene, generate_street, write_street,
};
pub use suite::{
    GENERATOR_VERSION, SUITE_SIZE, SceneSpec, SuiteOptions, SuiteScene, generate_suite_scene,
    scene_spec, write_suite_scene,
};
pub use write::write_scene;

use glam::DVec3;
use gs_core::{Image, Rng, Scene, ScenePoint, TriangleMesh, View};
use rayon::prelude::*;

/// Largest accepted image side.
pub const MAX_SIDE: u32 = 8192;
/// Largest accepted number of views.
pub const MAX_VIEWS: usize = 4096;
/// Largest accepted supersampling factor k (k × k samples per pixel).
pub const MAX_SUPERSAMPLE: u32 = 8;
/// Largest accepted total pixel count over all views (bounds memory at about 1 GiB).
pub const MAX_TOTAL_PIXELS: u64 = 1 << 25;
/// Largest accepted number of sparse points.
pub const MAX_POINTS: usize = 1_000_000;

/// Options of the built-in scene.
#[derive(Debug, Clone, PartialEq)]
pub struct BuiltinOptions {
    /// Image width in pixels (default 200).
    pub width: u32,
    /// Image height in pixels (default 150).
    pub height: u32,
    /// Number of views (default 32), half on each camera ring.
    pub views: usize,
    /// k: the colour of a pixel averages k × k stratified samples (default 2).
    pub supersample: u32,
    /// Seed of the camera jitter and the sparse points (default 20261123).
    pub seed: u64,
    /// Number of sparse points (default 3000): two thirds on the objects, the rest on the
    /// floor and walls.
    pub points: usize,
}

impl Default for BuiltinOptions {
    fn default() -> Self {
        Self {
            width: 200,
            height: 150,
            views: 32,
            supersample: 2,
            seed: 20261123,
            points: 3000,
        }
    }
}

impl BuiltinOptions {
    /// Checks every field against its documented range.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(SynthError::InvalidOptions(m));
        if self.width == 0 || self.height == 0 || self.width > MAX_SIDE || self.height > MAX_SIDE {
            return bad(format!(
                "image size {}x{} must be between 1 and {MAX_SIDE} on each side",
                self.width, self.height
            ));
        }
        if self.views == 0 || self.views > MAX_VIEWS {
            return bad(format!(
                "views = {} must be between 1 and {MAX_VIEWS}",
                self.views
            ));
        }
        if self.supersample == 0 || self.supersample > MAX_SUPERSAMPLE {
            return bad(format!(
                "supersample = {} must be between 1 and {MAX_SUPERSAMPLE}",
                self.supersample
            ));
        }
        let total = self.width as u64 * self.height as u64 * self.views as u64;
        if total > MAX_TOTAL_PIXELS {
            return bad(format!(
                "{} views of {}x{} are {total} pixels, more than the cap of {MAX_TOTAL_PIXELS}",
                self.views, self.width, self.height
            ));
        }
        if self.points > MAX_POINTS {
            return bad(format!(
                "points = {} exceeds the cap of {MAX_POINTS}",
                self.points
            ));
        }
        Ok(())
    }
}

/// Where a sparse point came from: the view and pixel whose pixel-centre ray hit the surface
/// point it was sampled at (before the noise).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PointSource {
    /// Index of the view in `scene.views`.
    pub view: usize,
    /// `(column, row)` of the pixel.
    pub pixel: [u32; 2],
}

/// The built-in scene with its exact ground truth.
#[derive(Debug, Clone)]
pub struct BuiltinScene {
    /// Views (`0000.png`, …, images + object masks) and sparse points.
    pub scene: Scene,
    /// Per view, `[H][W][1]` camera-space z of the pixel-centre hit, 0 = miss.
    pub gt_depth: Vec<Image>,
    /// Per view, `[H][W][3]` world-space unit shading normal facing the camera, 0 = miss.
    pub gt_normals: Vec<Image>,
    /// The objects only (sphere, box, torus).
    pub object_mesh: TriangleMesh,
    /// Everything that was rendered: the objects first (same vertex and triangle indices as
    /// `object_mesh`), then the floor and the four walls.
    pub scene_mesh: TriangleMesh,
    /// Per sparse point, the view and pixel it was sampled from.
    pub point_sources: Vec<PointSource>,
    /// Standard deviation of the Gaussian noise added to the sparse points (0.3 % of the
    /// objects' bounding-box diagonal).
    pub point_sigma: f64,
    /// A human-readable summary (layout, sizes, counts).
    pub description: String,
}

/// Generates the built-in scene. Rows and views are rendered in parallel on the current rayon
/// pool; the result is bit-identical for a given `opts`, whatever the thread count.
pub fn generate(opts: &BuiltinOptions) -> Result<BuiltinScene> {
    opts.validate()?;
    let renderer = render::Renderer::new(geometry::build(), render::Style::builtin())?;
    let cameras = ring_cameras(opts.width, opts.height, opts.views, opts.seed)?;
    let mut built = render_scene(&renderer, cameras, opts)?;
    built.description = format!(
        "gs-synth built-in scene: textured sphere, box and torus on a checkered floor in an \
         open-top room ([-4,4]^2 x [0,2.2]), one directional light with hard shadows; \
         {} views of {}x{} ({}x{} supersampling, seed {}), two camera rings (20 and 40 deg); \
         {} object triangles, {} scene triangles; {} sparse points (sigma {:.4}); \
         object bbox diagonal {:.4}, scene extent {:.4}",
        opts.views,
        opts.width,
        opts.height,
        opts.supersample,
        opts.supersample,
        opts.seed,
        built.object_mesh.triangles.len(),
        built.scene_mesh.triangles.len(),
        built.scene.points.len(),
        built.point_sigma,
        bbox_diagonal(&built.object_mesh),
        built.scene.extent(),
    );
    Ok(built)
}

/// Diagonal of a mesh's bounding box (0 for an empty mesh).
pub(crate) fn bbox_diagonal(mesh: &TriangleMesh) -> f64 {
    mesh.bounds().map_or(0.0, |(lo, hi)| {
        (DVec3::from_array(hi.map(f64::from)) - DVec3::from_array(lo.map(f64::from))).length()
    })
}

/// Renders every camera of a scene (in parallel) and samples its sparse points with noise of
/// 0.3 % of the objects' bounding-box diagonal; the description is left empty for the caller.
pub(crate) fn render_scene(
    renderer: &render::Renderer,
    cameras: Vec<gs_core::Camera>,
    opts: &BuiltinOptions,
) -> Result<BuiltinScene> {
    let sigma = 0.003 * bbox_diagonal(&renderer.geom.object_mesh());
    render_scene_with_sigma(renderer, cameras, opts, sigma)
}

/// [`render_scene`] with the sparse points' noise standard deviation given.
pub(crate) fn render_scene_with_sigma(
    renderer: &render::Renderer,
    cameras: Vec<gs_core::Camera>,
    opts: &BuiltinOptions,
    point_sigma: f64,
) -> Result<BuiltinScene> {
    let renders: Vec<render::ViewRender> = cameras
        .par_iter()
        .map(|c| renderer.render_view(c, opts.supersample))
        .collect::<Result<_>>()?;
    let object_mesh = renderer.geom.object_mesh();
    let (points, point_sources) = sample_points(renderer, &cameras, opts, point_sigma);

    let mut views = Vec::with_capacity(cameras.len());
    let mut gt_depth = Vec::with_capacity(cameras.len());
    let mut gt_normals = Vec::with_capacity(cameras.len());
    for (i, (camera, r)) in cameras.into_iter().zip(renders).enumerate() {
        views.push(View {
            name: format!("{i:04}.png"),
            camera,
            image: r.image,
            mask: Some(r.mask),
        });
        gt_depth.push(r.depth);
        gt_normals.push(r.normal);
    }
    Ok(BuiltinScene {
        scene: Scene {
            views,
            points,
            held_out: None,
        },
        gt_depth,
        gt_normals,
        object_mesh,
        scene_mesh: renderer.geom.mesh.clone(),
        point_sources,
        point_sigma,
        description: String::new(),
    })
}

/// Sparse points: hit points of random pixel-centre rays (two thirds on the objects, one third
/// on the floor/walls; rejection sampling, sequential and seeded), perturbed by isotropic
/// Gaussian noise of standard deviation `sigma`, coloured by the sRGB-encoded albedo at the
/// unperturbed point. Stops after `50 × points` draws, so it may return fewer points when the
/// objects are hardly visible.
fn sample_points(
    renderer: &render::Renderer,
    cameras: &[gs_core::Camera],
    opts: &BuiltinOptions,
    sigma: f64,
) -> (Vec<ScenePoint>, Vec<PointSource>) {
    let mut rng = Rng::new(opts.seed).fork(0x5EED_9017);
    let want_obj = opts.points * 2 / 3;
    let want_bg = opts.points - want_obj;
    let (mut n_obj, mut n_bg) = (0, 0);
    let mut points = Vec::with_capacity(opts.points);
    let mut sources = Vec::with_capacity(opts.points);
    let mut draws = 0usize;
    while (n_obj < want_obj || n_bg < want_bg) && draws < 50 * opts.points {
        draws += 1;
        let view = rng.below(cameras.len() as u64) as usize;
        let cam = &cameras[view];
        let x = rng.below(cam.width as u64) as u32;
        let y = rng.below(cam.height as u64) as u32;
        let (o, d) = pixel_ray(cam, x as f64 + 0.5, y as f64 + 0.5);
        let Some(s) = renderer.surface(o, d) else {
            continue;
        };
        let slot = if s.material.is_object() {
            &mut n_obj
        } else {
            &mut n_bg
        };
        if *slot
            >= if s.material.is_object() {
                want_obj
            } else {
                want_bg
            }
        {
            continue;
        }
        *slot += 1;
        let a = renderer.albedo(s.material, s.point);
        let noise = DVec3::new(
            rng.normal() as f64,
            rng.normal() as f64,
            rng.normal() as f64,
        ) * sigma;
        points.push(ScenePoint {
            position: s.point + noise,
            color: [a.x, a.y, a.z].map(render::encode8),
        });
        sources.push(PointSource {
            view,
            pixel: [x, y],
        });
    }
    (points, sources)
}
