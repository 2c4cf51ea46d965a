//! What the street scene's folder says about itself: the one-line description, `scene.json`
//! (street axis and extent, objects, facades, the camera path) and `README.md`.

use super::{
    CAMERA_HEIGHT, GROUND_MARGIN, PITCH_DEG, STATION_SPACING, STREET_FOV_DEG,
    STREET_GENERATOR_VERSION, STREET_HALF_WIDTH, STREET_LENGTH, StreetOptions, StreetScene,
    StreetSpec, YAW_FROM_AXIS_DEG,
};
use crate::BuiltinScene;

/// A human-readable summary of a rendered street.
pub(super) fn description(spec: &StreetSpec, built: &BuiltinScene, opts: &StreetOptions) -> String {
    let names: Vec<&str> = spec.objects.iter().map(|o| o.name).collect();
    format!(
        "gs-synth street scene (seed {}): a straight street along +x, {STREET_LENGTH} m long and \
         {} m wide between {} textured facade segments (2.3-2.8 m high, one gap per side), a \
         textured ground plane and open sky; {} objects along both sides ({}); {} views of {}x{} \
         ({}x{} supersampling) from {} stations every {STATION_SPACING} m on the centre line at \
         {CAMERA_HEIGHT} m, looking left and right; light azimuth {:.1} elevation {:.1} deg; \
         {} scored triangles (objects and facades), {} scene triangles; {} sparse points \
         (sigma {:.4})",
        spec.seed,
        2.0 * STREET_HALF_WIDTH,
        spec.facades.len(),
        spec.objects.len(),
        names.join(", "),
        built.scene.views.len(),
        opts.width,
        opts.height,
        opts.supersample,
        opts.supersample,
        spec.cameras.len() / 2,
        spec.light_deg[0],
        spec.light_deg[1],
        built.object_mesh.triangles.len(),
        built.scene_mesh.triangles.len(),
        built.scene.points.len(),
        built.point_sigma,
    )
}

impl StreetScene {
    /// The parameters written to `scene.json`: the street's axis and extent, the ground, the
    /// objects, the facades, the camera path (one entry per view) and the light.
    pub fn metadata(&self, opts: &StreetOptions) -> serde_json::Value {
        let s = &self.spec;
        let b = &self.built;
        let (lo, hi) = b.object_mesh.bounds().unwrap_or(([0.0; 3], [0.0; 3]));
        let objects: Vec<_> = s
            .objects
            .iter()
            .map(|o| {
                serde_json::json!({
                    "name": o.name, "side": side(o.left), "position": o.position,
                    "yaw_deg": o.yaw_deg, "scale": o.scale, "footprint_radius": o.footprint_radius,
                    "bbox_min": o.bbox.0, "bbox_max": o.bbox.1,
                    "triangles": [o.triangles.start, o.triangles.end],
                })
            })
            .collect();
        let facades: Vec<_> = s
            .facades
            .iter()
            .map(|f| serde_json::json!({ "side": side(f.left), "x": f.x, "height": f.height }))
            .collect();
        let path: Vec<_> = s
            .cameras
            .iter()
            .zip(&b.scene.views)
            .map(|(c, v)| {
                serde_json::json!({
                    "image": v.name, "station": c.station, "side": side(c.left), "eye": c.eye,
                    "yaw_deg": c.yaw_deg, "pitch_deg": c.pitch_deg,
                })
            })
            .collect();
        let [gx, gy] = GROUND_MARGIN;
        serde_json::json!({
            "generator": "gs-synth street",
            "generator_version": STREET_GENERATOR_VERSION,
            "name": "street",
            "about": "a scene larger than one block, for partitioned training",
            "seed": s.seed,
            "width": opts.width,
            "height": opts.height,
            "supersample": opts.supersample,
            "points": b.scene.points.len(),
            "point_sigma": b.point_sigma,
            "views": b.scene.views.len(),
            "street": {
                "axis": [1.0, 0.0, 0.0], "up": [0.0, 0.0, 1.0], "start": [0.0, 0.0, 0.0],
                "end": [STREET_LENGTH, 0.0, 0.0], "length": STREET_LENGTH,
                "width": 2.0 * STREET_HALF_WIDTH, "facade_y": [STREET_HALF_WIDTH, -STREET_HALF_WIDTH],
            },
            "ground": { "z": 0.0, "x": [-gx, STREET_LENGTH + gx], "y": [-(STREET_HALF_WIDTH + gy), STREET_HALF_WIDTH + gy] },
            "cameras": {
                "model": "PINHOLE", "fov_x_deg": STREET_FOV_DEG, "height": CAMERA_HEIGHT,
                "stations": s.cameras.len() / 2, "station_spacing": STATION_SPACING,
                "yaw_from_axis_deg": YAW_FROM_AXIS_DEG, "pitch_deg": PITCH_DEG,
                "path": path,
            },
            "objects": objects,
            "facades": facades,
            "light": { "azimuth_deg": s.light_deg[0], "elevation_deg": s.light_deg[1], "direction": s.style.light_dir.to_array() },
            "scored": {
                "what": "objects and facades (gt_mesh.ply); the ground is left out",
                "triangles": b.object_mesh.triangles.len(),
                "bbox_min": lo, "bbox_max": hi,
                "bbox_diagonal": crate::bbox_diagonal(&b.object_mesh),
            },
            "scene_triangles": b.scene_mesh.triangles.len(),
        })
    }

    /// `README.md` of the scene folder: what it is, what it tests, its files and how it is
    /// scored.
    pub fn readme(&self) -> String {
        format!(
            "# Street scene\n\n{desc}.\n\n\
             A scene larger than one block: no view sees more than a few metres of the street, and \
             each object is seen by a dozen or so views from the stations next to it. It tests \
             partitioned training: split the scene along its ground plane into blocks (by camera \
             centres and sparse points), train each block as its own job, merge the blocks, and \
             score the merged mesh and held-out views against the exact GT.\n\n\
             Made by `vagsl synth --street` (gs-synth's street generator, version \
             {STREET_GENERATOR_VERSION}); the same seed and size give the same bytes. Parameters, \
             the street's axis and extent, the objects, the facades and the camera path (one entry \
             per image): `scene.json`.\n\n\
             ## Files (the suite's layout)\n\n\
             - `images/NNNN.png`: 8-bit sRGB renders (Lambert + ambient + Blinn-Phong, hard shadows, \
             supersampled; rays that hit nothing see the sky colour); `masks/NNNN.png`: 255 where \
             the pixel-centre ray hits an object or a facade first (not the ground, not the sky).\n\
             - `sparse/0/*.txt`: COLMAP text model, one PINHOLE camera, pixel centres at i + 0.5; \
             sparse points are noisy surface samples (sigma {sigma:.4}, two thirds on the objects \
             and facades) without tracks.\n\
             - `gt/depth_NNNN.npy`: float32 camera z of the pixel-centre hit (0 = sky); \
             `gt/normal_NNNN.npy`: float32 world unit normals facing the camera (0 = sky).\n\
             - `gt_mesh.ply`: what is scored, the objects and the facades (everything but the \
             ground); `gt_scene_mesh.ply`: the same first, then the ground.\n\n\
             ## Scoring\n\n\
             `vagsl eval-mesh --pred MESH --gt gt_mesh.ply --crop-to-gt 0.05 --min-z 0.005`: crop \
             to the scored box grown by 5 %, ground removed (z above 0.005), as in the suite's \
             object protocol. The GT-depth floor is `vagsl mesh SCENE --depth-dir SCENE/gt` \
             scored the same way.\n",
            desc = self.built.description,
            sigma = self.built.point_sigma,
        )
    }
}

fn side(left: bool) -> &'static str {
    if left { "left" } else { "right" }
}
