//! The validation suite: [`SUITE_SIZE`] object scenes, each a deterministic function of
//! `(index, seed)`, made the way synth-bunny is (an object on a textured floor in a four-walled
//! open-top room, a two-ring camera capture, exact GT) but with procedurally built objects
//! (cups, knots, frames with holes, thin legs and rods, stairs, springs, colonnades) and with
//! what a method's defaults must survive varied per scene: texture strength, walls close to
//! the camera ring or seen at grazing angles, light direction, ring radius and elevation, and
//! the number of views (12–60: scene 8 is a sparse capture). See docs/architecture.md §Validation suite.

use crate::error::{Result, SynthError};
use crate::geometry::{Builder, Geometry};
use crate::objects;
use crate::render::{Renderer, RingSpec, Style, ring_cameras_with};
use glam::DVec3;
use gs_core::{Camera, Rng};

/// Number of scenes in the suite.
pub const SUITE_SIZE: usize = 9;

/// Everything that defines one suite scene besides the image size.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneSpec {
    /// Position in the suite.
    pub index: usize,
    /// Short name, e.g. `cup` (folder names are `NN-name`).
    pub name: &'static str,
    /// What the scene tests, in words.
    pub about: &'static str,
    /// The seed the scene was made with.
    pub seed: u64,
    /// Number of views (half on each ring).
    pub views: usize,
    /// The camera rings.
    pub ring: RingSpec,
    /// Room half extents along x and y, and wall height.
    pub room: [f64; 3],
    /// Light and textures.
    pub style: Style,
    /// Light azimuth and elevation, degrees (the direction in `style`).
    pub light_deg: [f64; 2],
    /// Size factor applied to the object (seeded, about 0.92–1.08).
    pub scale: f64,
}

impl SceneSpec {
    /// The folder name of the scene, `NN-name`.
    pub fn folder_name(&self) -> String {
        format!("{:02}-{}", self.index, self.name)
    }
}

/// Fixed per-scene choices: name, what it tests, views, ring radius and elevations, room,
/// object texture strength, light azimuth / elevation.
struct Base {
    name: &'static str,
    about: &'static str,
    views: usize,
    radius: f64,
    elevations: [f64; 2],
    target_z: f64,
    room: [f64; 3],
    strength: f64,
    light: [f64; 2],
}

const BASES: [Base; SUITE_SIZE] = [
    Base {
        name: "cup",
        about: "open cup (thin rim, deep concavity) with a tube handle and a ball",
        views: 36,
        radius: 2.6,
        elevations: [22.0, 42.0],
        target_z: 0.25,
        room: [3.6, 3.6, 2.0],
        strength: 0.8,
        light: [35.0, 52.0],
    },
    Base {
        name: "knot",
        about: "trefoil-knot tube on a thin post, walls close behind the camera ring",
        views: 40,
        radius: 2.3,
        elevations: [20.0, 38.0],
        target_z: 0.45,
        room: [2.75, 2.75, 2.0],
        strength: 1.0,
        light: [120.0, 60.0],
    },
    Base {
        name: "window",
        about: "weakly textured frame with a hole, a ball seen through it, a flat ring; low light",
        views: 30,
        radius: 2.8,
        elevations: [15.0, 35.0],
        target_z: 0.35,
        room: [3.5, 3.5, 2.0],
        strength: 0.3,
        light: [210.0, 30.0],
    },
    Base {
        name: "table",
        about: "slab on four thin legs over a cone (hidden concavity), narrow room: side walls at grazing angles",
        views: 24,
        radius: 2.0,
        elevations: [25.0, 45.0],
        target_z: 0.3,
        room: [4.0, 2.3, 2.0],
        strength: 0.6,
        light: [300.0, 55.0],
    },
    Base {
        name: "vase",
        about: "almost untextured vase with a narrow neck, a thin pole and a rod on the floor; low ring",
        views: 48,
        radius: 2.7,
        elevations: [12.0, 28.0],
        target_z: 0.35,
        room: [3.6, 3.6, 2.0],
        strength: 0.15,
        light: [60.0, 45.0],
    },
    Base {
        name: "stairs",
        about: "stepped block and a thin arch, strong texture, high ring, 60 views",
        views: 60,
        radius: 2.5,
        elevations: [35.0, 60.0],
        target_z: 0.25,
        room: [3.4, 3.4, 2.0],
        strength: 1.0,
        light: [150.0, 65.0],
    },
    Base {
        name: "spring",
        about: "helical spring beside a thin-walled bowl, walls close to the ring",
        views: 32,
        radius: 2.2,
        elevations: [20.0, 40.0],
        target_z: 0.25,
        room: [2.6, 2.6, 2.0],
        strength: 0.5,
        light: [10.0, 40.0],
    },
    Base {
        name: "pillars",
        about: "six thin pillars under a ring and a ball, few views (20), long room",
        views: 20,
        radius: 2.1,
        elevations: [18.0, 35.0],
        target_z: 0.35,
        room: [2.5, 4.0, 2.0],
        strength: 0.7,
        light: [250.0, 50.0],
    },
    Base {
        name: "chair",
        about: "chair with thin legs and a slatted back over a ball, sparse capture (12 views)",
        views: 12,
        radius: 2.4,
        elevations: [20.0, 40.0],
        target_z: 0.4,
        room: [3.2, 3.2, 2.0],
        strength: 0.6,
        light: [95.0, 50.0],
    },
];

/// The spec of suite scene `index` (0-based, below [`SUITE_SIZE`]) for `seed`: the seed jitters
/// the object's size (±8 %), the light (azimuth ±20°, elevation ±8°), the texture noise and the
/// cameras; everything else is fixed per index. `None` for an index outside the suite.
pub fn scene_spec(index: usize, seed: u64) -> Option<SceneSpec> {
    let b = BASES.get(index)?;
    let mut rng = Rng::new(seed).fork(0x5017_E000 + index as u64);
    let mut j = |a: f64| rng.uniform_range(-a as f32, a as f32) as f64;
    let scale = 1.0 + j(0.08);
    let az = b.light[0] + j(20.0);
    let el = b.light[1] + j(8.0);
    let (a, e) = (az.to_radians(), el.to_radians());
    let light_dir = DVec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin());
    let style = Style {
        light_dir,
        light_rgb: DVec3::new(1.0, 0.97, 0.92),
        ambient_rgb: DVec3::new(0.20, 0.22, 0.26),
        texture_strength: b.strength,
        background_strength: (0.5 + 0.5 * b.strength).min(1.0),
        texture_seed: seed.wrapping_mul(31).wrapping_add(index as u64),
    };
    Some(SceneSpec {
        index,
        name: b.name,
        about: b.about,
        seed,
        views: b.views,
        ring: RingSpec {
            target: [0.0, 0.0, b.target_z * scale],
            radius: b.radius,
            elevations: b.elevations,
            fov_deg: 50.0,
        },
        room: b.room,
        style,
        light_deg: [az, el],
        scale,
    })
}

/// Image size and sampling of a suite scene (the scene itself is [`scene_spec`]'s).
#[derive(Debug, Clone, PartialEq)]
pub struct SuiteOptions {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// k × k stratified samples per pixel.
    pub supersample: u32,
    /// Number of sparse points (two thirds on the object).
    pub points: usize,
}

impl SuiteOptions {
    /// The record: 480×360 (synth-bunny's size), 3×3 supersampling, 6000 points.
    pub fn full() -> Self {
        Self {
            width: 480,
            height: 360,
            supersample: 3,
            points: 6000,
        }
    }

    /// For trying an idea (`--quick`): 200×150 (the built-in scene's size), 2×2, 3000 points.
    pub fn quick() -> Self {
        Self {
            width: 200,
            height: 150,
            supersample: 2,
            points: 3000,
        }
    }
}

/// A rendered suite scene: its spec and the views, GT maps and meshes.
#[derive(Debug, Clone)]
pub struct SuiteScene {
    /// What the scene is.
    pub spec: SceneSpec,
    /// Views, sparse points, GT depth / normals / masks, object and scene meshes.
    pub built: crate::BuiltinScene,
}

/// Renders suite scene `index` for `seed`. Bit-identical for the same arguments whatever the
/// thread count. The cameras are rebuilt from their COLMAP quaternions, so the GT maps belong to
/// exactly the poses a reader of the written `images.txt` gets.
pub fn generate_suite_scene(index: usize, seed: u64, opts: &SuiteOptions) -> Result<SuiteScene> {
    let spec = scene_spec(index, seed).ok_or_else(|| {
        SynthError::InvalidOptions(format!(
            "scene {index} does not exist: the suite has scenes 0 to {}",
            SUITE_SIZE - 1
        ))
    })?;
    let bopts = crate::BuiltinOptions {
        width: opts.width,
        height: opts.height,
        views: spec.views,
        supersample: opts.supersample,
        seed: seed ^ (index as u64).wrapping_mul(0x9E37_79B9),
        points: opts.points,
    };
    bopts.validate()?;
    let renderer = Renderer::new(build_geometry(&spec), spec.style.clone())?;
    let cameras = ring_cameras_with(&spec.ring, opts.width, opts.height, spec.views, bopts.seed)?
        .into_iter()
        .map(|c| {
            Camera::from_quaternion(
                c.width,
                c.height,
                c.intrinsics,
                c.quaternion(),
                c.translation.to_array(),
            )
        })
        .collect::<std::result::Result<Vec<_>, _>>()?;
    let mut built = crate::render_scene(&renderer, cameras, &bopts)?;
    let [hx, hy, h] = spec.room;
    built.description = format!(
        "gs-synth suite scene {} '{}' (seed {}): {}; room [-{hx},{hx}]x[-{hy},{hy}]x[0,{h}]; \
         {} views of {}x{} ({}x{} supersampling) on rings at {:.0} and {:.0} deg, radius {}; \
         object texture strength {}, light azimuth {:.1} elevation {:.1} deg; {} object triangles; \
         object bbox diagonal {:.4}",
        spec.index,
        spec.name,
        seed,
        spec.about,
        spec.views,
        opts.width,
        opts.height,
        opts.supersample,
        opts.supersample,
        spec.ring.elevations[0],
        spec.ring.elevations[1],
        spec.ring.radius,
        spec.style.texture_strength,
        spec.light_deg[0],
        spec.light_deg[1],
        built.object_mesh.triangles.len(),
        crate::bbox_diagonal(&built.object_mesh),
    );
    Ok(SuiteScene { spec, built })
}

/// Version of the suite's generator, recorded in `scene.json`: a change of any scene's pixels
/// must bump it, so that cached scene folders are regenerated.
pub const GENERATOR_VERSION: u32 = 1;

impl SuiteScene {
    /// The parameters written to `scene.json`.
    pub fn metadata(&self, opts: &SuiteOptions) -> serde_json::Value {
        let s = &self.spec;
        let (lo, hi) = self
            .built
            .object_mesh
            .bounds()
            .unwrap_or(([0.0; 3], [0.0; 3]));
        serde_json::json!({
            "generator": "gs-synth suite",
            "generator_version": GENERATOR_VERSION,
            "index": s.index,
            "name": s.name,
            "about": s.about,
            "seed": s.seed,
            "width": opts.width,
            "height": opts.height,
            "supersample": opts.supersample,
            "points": self.built.scene.points.len(),
            "point_sigma": self.built.point_sigma,
            "views": s.views,
            "ring": { "target": s.ring.target, "radius": s.ring.radius, "elevations_deg": s.ring.elevations, "fov_deg": s.ring.fov_deg },
            "room": { "half_x": s.room[0], "half_y": s.room[1], "wall_height": s.room[2] },
            "light": { "azimuth_deg": s.light_deg[0], "elevation_deg": s.light_deg[1], "direction": s.style.light_dir.to_array() },
            "texture_strength": { "object": s.style.texture_strength, "background": s.style.background_strength },
            "scale": s.scale,
            "object": {
                "triangles": self.built.object_mesh.triangles.len(),
                "bbox_min": lo,
                "bbox_max": hi,
                "bbox_diagonal": crate::bbox_diagonal(&self.built.object_mesh),
            },
            "scene_triangles": self.built.scene_mesh.triangles.len(),
        })
    }

    /// `README.md` of the scene folder: what it is, its files and how it is scored.
    pub fn readme(&self) -> String {
        let s = &self.spec;
        format!(
            "# Suite scene {folder}\n\n{desc}.\n\nMade by `vagsl synth` (gs-synth's suite generator, version \
             {GENERATOR_VERSION}); the same index, seed and size give the same bytes. Parameters: `scene.json`.\n\n\
             ## Files (synth-bunny's layout)\n\n\
             - `images/NNNN.png`: 8-bit sRGB renders (Lambert + ambient + Blinn-Phong, hard shadows, \
             supersampled); `masks/NNNN.png`: 255 where the pixel-centre ray hits the object first.\n\
             - `sparse/0/*.txt`: COLMAP text model, one PINHOLE camera, pixel centres at i + 0.5; \
             sparse points are noisy surface samples (sigma {sigma:.4}) without tracks.\n\
             - `gt/depth_NNNN.npy`: float32 camera z of the pixel-centre hit (0 = miss); \
             `gt/normal_NNNN.npy`: float32 world unit normals facing the camera.\n\
             - `gt_mesh.ply`: the object only (what is scored); `gt_scene_mesh.ply`: object first, \
             then floor and walls.\n\n\
             ## Scoring (object protocol)\n\n\
             `vagsl eval-mesh --pred MESH --gt gt_mesh.ply --crop-to-gt 0.05 --min-z 0.005`: crop to the \
             object's box grown by 5 %, floor removed, tau = 0.5 % of the box diagonal. The GT-depth \
             floor is `vagsl mesh {dir} --depth-dir {dir}/gt` scored the same way (`scripts/suite.sh` \
             does both).\n",
            folder = s.folder_name(),
            desc = self.built.description,
            sigma = self.built.point_sigma,
            dir = "SCENE",
        )
    }
}

/// Generates suite scene `index` for `seed` and writes it to the new folder `dir`.
pub fn write_suite_scene(
    dir: &std::path::Path,
    index: usize,
    seed: u64,
    opts: &SuiteOptions,
) -> Result<SuiteScene> {
    let scene = generate_suite_scene(index, seed, opts)?;
    crate::write::write_scene(dir, &scene.built, &scene.metadata(opts), &scene.readme())?;
    Ok(scene)
}

/// The geometry of a suite scene: its object (materials `Part(k)`) first, then the room.
pub fn build_geometry(spec: &SceneSpec) -> Geometry {
    let mut b = Builder::default();
    let s = spec.scale;
    match spec.index {
        0 => objects::cup(&mut b, s),
        1 => objects::knot(&mut b, s),
        2 => objects::window(&mut b, s),
        3 => objects::table(&mut b, s),
        4 => objects::vase(&mut b, s),
        5 => objects::stairs(&mut b, s),
        6 => objects::spring(&mut b, s),
        7 => objects::pillars(&mut b, s),
        _ => objects::chair(&mut b, s),
    }
    let (tris, verts) = (b.triangles.len(), b.positions.len());
    let [hx, hy, h] = spec.room;
    b.room(hx, hy, h);
    b.finish(tris, verts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_object_is_valid_rests_on_the_floor_and_fits_the_room() {
        for i in 0..SUITE_SIZE {
            let spec = scene_spec(i, 7).unwrap();
            let g = build_geometry(&spec);
            g.mesh.validate().unwrap();
            let (lo, hi) = g.object_mesh().bounds().unwrap();
            assert!(
                lo[2] > -3e-3 && lo[2] < 1e-3,
                "{}: lowest point {}",
                spec.name,
                lo[2]
            );
            assert!(
                hi[2] < 1.2 && lo[0] > -1.0 && hi[0] < 1.0 && lo[1] > -1.0 && hi[1] < 1.0,
                "{}: {lo:?} {hi:?}",
                spec.name
            );
            assert!((0..g.object_triangles).all(|t| g.material[t].is_object()));
            assert!((g.object_triangles..g.material.len()).all(|t| !g.material[t].is_object()));
        }
        assert!(scene_spec(SUITE_SIZE, 7).is_none());
    }
}
