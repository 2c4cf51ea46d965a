//! The street scene: a generated scene longer than one training block, for partitioned
//! training (split along the ground plane, train each block, merge). A straight street along
//! +x, [`STREET_LENGTH`] long between textured facades at y = ±[`STREET_HALF_WIDTH`], with the
//! eight suite objects (`crate::objects`, scaled to street size) standing along both sides, a
//! textured ground plane and open sky. The cameras walk the centre line: at each station one
//! looks to the left and one to the right, leaning alternately forward and back, so every
//! object is seen by about ten views and no view sees the whole street. A deterministic
//! function of the seed, with exact GT like the suite's scenes. See docs/architecture.md
//! §Street scene.

mod meta;

use crate::error::Result;
use crate::geometry::{Builder, Geometry, Material};
use crate::objects;
use crate::render::{Renderer, Style};
use crate::{BuiltinOptions, BuiltinScene};
use glam::{DMat3, DVec3};
use gs_core::{Camera, Intrinsics, Rng};

/// Version of the street generator, recorded in `scene.json`; a change of the scene's pixels
/// must bump it.
pub const STREET_GENERATOR_VERSION: u32 = 1;
/// Length of the street: it runs along +x from x = 0 to x = `STREET_LENGTH` (metres).
pub const STREET_LENGTH: f64 = 14.0;
/// The facades stand at y = ±`STREET_HALF_WIDTH`.
pub const STREET_HALF_WIDTH: f64 = 2.5;
/// Height of the camera centres above the ground, before jitter.
pub const CAMERA_HEIGHT: f64 = 1.5;
/// Distance between camera stations along the centre line.
pub const STATION_SPACING: f64 = 0.35;
/// Field of view across the image width, degrees.
pub const STREET_FOV_DEG: f64 = 70.0;
/// Angle between a view direction and +x, degrees, at even and odd stations (forward and
/// back lean); mirrored for the cameras looking right.
pub const YAW_FROM_AXIS_DEG: [f64; 2] = [68.0, 112.0];
/// Downward pitch of the cameras before jitter, degrees.
pub const PITCH_DEG: f64 = 11.0;
/// Distance from the street's ends to the first and the last station.
const STATION_MARGIN: f64 = 0.2;
/// The facades reach this far past both ends of the street.
const FACADE_OVERHANG: f64 = 1.0;
/// Width of the one gap in each side's facades.
const GAP: f64 = 1.0;
/// Free space between an object's footprint and the facade behind it.
const FACADE_CLEARANCE: f64 = 0.1;
/// The ground rectangle reaches this far past the street's ends and behind the facades.
const GROUND_MARGIN: [f64; 2] = [3.0, 2.5];

type ObjectBuilder = fn(&mut Builder, f64);

/// The suite objects that stand in the street (shuffled along it by the seed).
const OBJECTS: [(&str, ObjectBuilder); 8] = [
    ("cup", objects::cup),
    ("knot", objects::knot),
    ("window", objects::window),
    ("table", objects::table),
    ("vase", objects::vase),
    ("stairs", objects::stairs),
    ("spring", objects::spring),
    ("pillars", objects::pillars),
];

/// One object standing in the street.
#[derive(Debug, Clone, PartialEq)]
pub struct StreetObject {
    /// The suite object it is (`cup`, `knot`, …).
    pub name: &'static str,
    /// Whether it stands on the left (+y) side.
    pub left: bool,
    /// Centre of its footprint on the ground, `[x, y]`.
    pub position: [f64; 2],
    /// Rotation about +z, degrees.
    pub yaw_deg: f64,
    /// Size factor of the suite builder (the suite's objects are built at about 1).
    pub scale: f64,
    /// Largest horizontal distance of its surface from `position`.
    pub footprint_radius: f64,
    /// World bounding box.
    pub bbox: ([f64; 3], [f64; 3]),
    /// Its triangles in the object mesh (and in the scene mesh: same indices).
    pub triangles: std::ops::Range<usize>,
}

/// One facade segment: a textured rectangle facing the street.
#[derive(Debug, Clone, PartialEq)]
pub struct FacadeSegment {
    /// Whether it stands on the left (y = +half width) side.
    pub left: bool,
    /// Its extent along x, `[start, end]`.
    pub x: [f64; 2],
    /// Its height.
    pub height: f64,
}

/// One camera of the path.
#[derive(Debug, Clone, PartialEq)]
pub struct StreetCamera {
    /// Station index along the street (two cameras per station).
    pub station: usize,
    /// Whether it looks to the left (+y).
    pub left: bool,
    /// Camera centre.
    pub eye: [f64; 3],
    /// Angle of the view direction from +x about +z, degrees (positive = left).
    pub yaw_deg: f64,
    /// Downward pitch, degrees.
    pub pitch_deg: f64,
}

/// Everything the seed decides: layout, cameras, light.
#[derive(Debug, Clone, PartialEq)]
pub struct StreetSpec {
    /// The seed.
    pub seed: u64,
    /// The objects in street order of their index in the object mesh.
    pub objects: Vec<StreetObject>,
    /// The facade segments, left side first, each side along +x.
    pub facades: Vec<FacadeSegment>,
    /// The camera path, in view order (`0000.png`, …).
    pub cameras: Vec<StreetCamera>,
    /// Light and textures.
    pub style: Style,
    /// Light azimuth and elevation, degrees.
    pub light_deg: [f64; 2],
}

/// Image size and sampling of the street scene.
#[derive(Debug, Clone, PartialEq)]
pub struct StreetOptions {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// k × k stratified samples per pixel.
    pub supersample: u32,
    /// Number of sparse points (two thirds on the objects and facades).
    pub points: usize,
}

impl StreetOptions {
    /// The record: 480×360, 3×3 supersampling, 8000 points.
    pub fn full() -> Self {
        Self {
            width: 480,
            height: 360,
            supersample: 3,
            points: 8000,
        }
    }

    /// For trying an idea (`--quick`): 200×150, 2×2 supersampling, 4000 points.
    pub fn quick() -> Self {
        Self {
            width: 200,
            height: 150,
            supersample: 2,
            points: 4000,
        }
    }
}

/// A rendered street: its spec and the views, GT maps and meshes (`built.object_mesh` is
/// what is scored: the objects, then the facades; the ground only is left out).
#[derive(Debug, Clone)]
pub struct StreetScene {
    /// What the seed decided.
    pub spec: StreetSpec,
    /// Views, sparse points, GT depth / normals / masks, scored and scene meshes.
    pub built: BuiltinScene,
}

fn dv(p: [f32; 3]) -> DVec3 {
    DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)
}

fn bounds(points: impl Iterator<Item = DVec3>) -> (DVec3, DVec3) {
    points.fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(p), hi.max(p)),
    )
}

/// Builds a suite object at `scale`, centres its footprint, rotates it by `yaw_deg` and puts it
/// at `x` on one side, its footprint `FACADE_CLEARANCE` in front of the facade; its parts
/// become `Part(part_base + k)`.
#[allow(clippy::too_many_arguments)]
fn place(
    b: &mut Builder,
    name: &'static str,
    build: ObjectBuilder,
    scale: f64,
    yaw_deg: f64,
    x: f64,
    left: bool,
    part_base: u8,
) -> StreetObject {
    let mut local = Builder::default();
    build(&mut local, scale);
    let (lo, hi) = bounds(local.positions.iter().map(|&p| dv(p)));
    let c = DVec3::new(0.5 * (lo.x + hi.x), 0.5 * (lo.y + hi.y), 0.0);
    let radius = local
        .positions
        .iter()
        .map(|&p| (dv(p) - c).truncate().length())
        .fold(0.0, f64::max);
    let side = if left { 1.0 } else { -1.0 };
    let at = DVec3::new(
        x,
        side * (STREET_HALF_WIDTH - FACADE_CLEARANCE - radius),
        0.0,
    );
    let rot = DMat3::from_rotation_z(yaw_deg.to_radians());
    let (base, first) = (b.positions.len() as u32, b.triangles.len());
    for (&p, &n) in local.positions.iter().zip(&local.normals) {
        let q = at + rot * (dv(p) - c);
        b.positions.push([q.x as f32, q.y as f32, q.z as f32]);
        b.normals.push(rot * n);
    }
    b.triangles
        .extend(local.triangles.iter().map(|t| t.map(|i| i + base)));
    b.material.extend(local.material.iter().map(|m| match *m {
        Material::Part(k) => Material::Part(part_base + k),
        other => other,
    }));
    b.smooth.extend_from_slice(&local.smooth);
    let (wlo, whi) = bounds(b.positions[base as usize..].iter().map(|&p| dv(p)));
    StreetObject {
        name,
        left,
        position: [at.x, at.y],
        yaw_deg,
        scale,
        footprint_radius: radius,
        bbox: (wlo.to_array(), whi.to_array()),
        triangles: first..b.triangles.len(),
    }
}

/// Facade segments of both sides: 2.5–4 m long (the last up to 5 m), 2.3–2.8 m high (from
/// the cameras' height and pitch, little above that is ever seen), from
/// `FACADE_OVERHANG` before the street to as far past it, with one `GAP` wide opening per side
/// at a segment boundary between x = 3 and x = 11.
fn facades(b: &mut Builder, rng: &mut Rng) -> Vec<FacadeSegment> {
    let mut out = Vec::new();
    for left in [true, false] {
        let (start, end) = (-FACADE_OVERHANG, STREET_LENGTH + FACADE_OVERHANG);
        let mut cuts = vec![start];
        while end - cuts[cuts.len() - 1] > 5.0 {
            let last = cuts[cuts.len() - 1];
            cuts.push(last + rng.uniform_range(2.5, 4.0) as f64);
        }
        cuts.push(end);
        let inner: Vec<usize> = (1..cuts.len() - 1)
            .filter(|&i| (3.0..=11.0).contains(&cuts[i]))
            .collect();
        let gap = (!inner.is_empty()).then(|| inner[rng.below(inner.len() as u64) as usize]);
        let side = if left { 1.0 } else { -1.0 };
        let y = side * STREET_HALF_WIDTH;
        for i in 0..cuts.len() - 1 {
            let x0 = cuts[i] + if gap == Some(i) { 0.5 * GAP } else { 0.0 };
            let x1 = cuts[i + 1] - if gap == Some(i + 1) { 0.5 * GAP } else { 0.0 };
            let height = rng.uniform_range(2.3, 2.8) as f64;
            let corners = [(x0, 0.0), (x1, 0.0), (x1, height), (x0, height)]
                .map(|(x, z)| DVec3::new(x, y, z));
            b.rectangle(corners, -side * DVec3::Y, Material::Facade(out.len() as u8));
            out.push(FacadeSegment {
                left,
                x: [x0, x1],
                height,
            });
        }
    }
    out
}

/// The street's geometry for `seed`: the objects (materials `Part`), then the facades (scored
/// too), then the ground.
pub fn build_street(seed: u64) -> (Geometry, Vec<StreetObject>, Vec<FacadeSegment>) {
    let mut rng = Rng::new(seed).fork(0x57EE_7000);
    let mut order: Vec<usize> = (0..OBJECTS.len()).collect();
    rng.shuffle(&mut order);
    let mut b = Builder::default();
    let n = OBJECTS.len();
    let first_x = 2.2;
    let step = (STREET_LENGTH - 2.0 * first_x) / (n - 1) as f64;
    let mut objs = Vec::with_capacity(n);
    for (k, &i) in order.iter().enumerate() {
        let mut j = |a: f64| rng.uniform_range(-a as f32, a as f32) as f64;
        let scale = 1.0 + j(0.06);
        let yaw = j(35.0);
        let x = first_x + k as f64 * step + j(0.25);
        let (name, f) = OBJECTS[i];
        objs.push(place(
            &mut b,
            name,
            f,
            scale,
            yaw,
            x,
            k % 2 == 0,
            3 * k as u8,
        ));
    }
    let segments = facades(&mut b, &mut rng);
    let (tris, verts) = (b.triangles.len(), b.positions.len());
    let [gx, gy] = GROUND_MARGIN;
    let (x0, x1, y) = (-gx, STREET_LENGTH + gx, STREET_HALF_WIDTH + gy);
    let ground = [(x0, -y), (x1, -y), (x1, y), (x0, y)].map(|(x, y)| DVec3::new(x, y, 0.0));
    b.rectangle(ground, DVec3::Z, Material::Floor);
    (b.finish(tris, verts), objs, segments)
}

/// The camera path for `seed`: stations every [`STATION_SPACING`] along the centre line from
/// `STATION_MARGIN` after the start to as far before the end, two cameras each (left, then
/// right) at [`CAMERA_HEIGHT`], yaw [`YAW_FROM_AXIS_DEG`] alternating by station, pitched down
/// [`PITCH_DEG`]; seeded jitter of the centre ±5 cm per axis, yaw ±2°, pitch ±1.5°, roll ±1°.
/// Square pixels, [`STREET_FOV_DEG`] across the width, principal point at the centre. Each
/// camera is rebuilt from its COLMAP quaternion, so the GT belongs to the written poses.
pub fn street_cameras(
    seed: u64,
    width: u32,
    height: u32,
) -> Result<(Vec<Camera>, Vec<StreetCamera>)> {
    let f = 0.5 * width as f64 / (0.5 * STREET_FOV_DEG.to_radians()).tan();
    let k = Intrinsics::new(f, f, width as f64 / 2.0, height as f64 / 2.0);
    let span = STREET_LENGTH - 2.0 * STATION_MARGIN;
    let stations = (span / STATION_SPACING).round() as usize + 1;
    let x_first = 0.5 * (STREET_LENGTH - (stations - 1) as f64 * STATION_SPACING);
    let mut rng = Rng::new(seed).fork(0x57EE_7CA3);
    let (mut cams, mut path) = (Vec::new(), Vec::new());
    for s in 0..stations {
        for left in [true, false] {
            let mut j = |a: f64| rng.uniform_range(-a as f32, a as f32) as f64;
            let side = if left { 1.0 } else { -1.0 };
            let yaw_deg = side * (YAW_FROM_AXIS_DEG[s % 2] + j(2.0));
            let pitch_deg = PITCH_DEG + j(1.5);
            let roll = j(1.0).to_radians();
            let x = x_first + s as f64 * STATION_SPACING;
            let eye = DVec3::new(x + j(0.05), j(0.05), CAMERA_HEIGHT + j(0.05));
            let (yaw, pitch) = (yaw_deg.to_radians(), pitch_deg.to_radians());
            let d = DVec3::new(
                pitch.cos() * yaw.cos(),
                pitch.cos() * yaw.sin(),
                -pitch.sin(),
            );
            let up = DMat3::from_axis_angle(d, roll) * DVec3::Z;
            let c = Camera::look_at(width, height, k, eye, eye + d, up)?;
            let c = Camera::from_quaternion(
                width,
                height,
                k,
                c.quaternion(),
                c.translation.to_array(),
            )?;
            cams.push(c);
            path.push(StreetCamera {
                station: s,
                left,
                eye: eye.to_array(),
                yaw_deg,
                pitch_deg,
            });
        }
    }
    Ok((cams, path))
}

/// The light and textures for `seed`: light azimuth anywhere, elevation 50–65°, full-contrast
/// textures everywhere.
fn street_style(seed: u64) -> (Style, [f64; 2]) {
    let mut rng = Rng::new(seed).fork(0x57EE_7119);
    let az = rng.uniform_range(0.0, 360.0) as f64;
    let el = rng.uniform_range(50.0, 65.0) as f64;
    let (a, e) = (az.to_radians(), el.to_radians());
    let style = Style {
        light_dir: DVec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin()),
        light_rgb: DVec3::new(1.0, 0.97, 0.92),
        ambient_rgb: DVec3::new(0.20, 0.22, 0.26),
        texture_strength: 1.0,
        background_strength: 1.0,
        texture_seed: seed.wrapping_mul(31).wrapping_add(0x57),
    };
    (style, [az, el])
}

/// Renders the street for `seed`. Bit-identical for the same arguments whatever the thread
/// count. The sparse points' noise is 0.3 % of the objects' mean bounding-box diagonal.
pub fn generate_street(seed: u64, opts: &StreetOptions) -> Result<StreetScene> {
    let (cameras, path) = street_cameras(seed, opts.width, opts.height)?;
    let bopts = BuiltinOptions {
        width: opts.width,
        height: opts.height,
        views: cameras.len(),
        supersample: opts.supersample,
        seed,
        points: opts.points,
    };
    bopts.validate()?;
    let (geom, objects, facades) = build_street(seed);
    let (style, light_deg) = street_style(seed);
    let renderer = Renderer::new(geom, style.clone())?;
    let mean_diag = objects
        .iter()
        .map(|o| (DVec3::from_array(o.bbox.1) - DVec3::from_array(o.bbox.0)).length())
        .sum::<f64>()
        / objects.len() as f64;
    let mut built = crate::render_scene_with_sigma(&renderer, cameras, &bopts, 0.003 * mean_diag)?;
    let spec = StreetSpec {
        seed,
        objects,
        facades,
        cameras: path,
        style,
        light_deg,
    };
    built.description = meta::description(&spec, &built, opts);
    Ok(StreetScene { spec, built })
}

/// Generates the street for `seed` and writes it to the new folder `dir` (the suite's layout;
/// an existing folder is refused).
pub fn write_street(dir: &std::path::Path, seed: u64, opts: &StreetOptions) -> Result<StreetScene> {
    let scene = generate_street(seed, opts)?;
    crate::write::write_scene(dir, &scene.built, &scene.metadata(opts), &scene.readme())?;
    Ok(scene)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn objects_stand_apart_on_the_ground_between_the_facades_and_the_centre_line() {
        for seed in [1, 2, 3, 20261126] {
            let (g, objs, facades) = build_street(seed);
            g.mesh.validate().unwrap();
            assert_eq!(objs.len(), OBJECTS.len());
            let mut names: Vec<_> = objs.iter().map(|o| o.name).collect();
            names.sort();
            names.dedup();
            assert_eq!(names.len(), OBJECTS.len());
            for (i, o) in objs.iter().enumerate() {
                let (lo, hi) = o.bbox;
                assert!(
                    lo[2] > -3e-3 && lo[2] < 1e-3,
                    "{}: lowest {}",
                    o.name,
                    lo[2]
                );
                assert!(hi[2] < 1.6, "{}: top {}", o.name, hi[2]);
                assert!(
                    lo[0] > 0.5 && hi[0] < STREET_LENGTH - 0.5,
                    "{}: {lo:?} {hi:?}",
                    o.name
                );
                let inner = if o.left { lo[1] } else { -hi[1] };
                let outer = if o.left { hi[1] } else { -lo[1] };
                assert!(
                    inner > 0.6 && outer < STREET_HALF_WIDTH - 0.1,
                    "{}: {lo:?} {hi:?}",
                    o.name
                );
                for p in &objs[i + 1..] {
                    let d = DVec3::new(
                        o.position[0] - p.position[0],
                        o.position[1] - p.position[1],
                        0.0,
                    );
                    assert!(
                        d.length() > o.footprint_radius + p.footprint_radius,
                        "{} and {}",
                        o.name,
                        p.name
                    );
                }
            }
            let scored = g.object_triangles;
            assert!((0..scored).all(|t| g.material[t].is_object()));
            assert!((scored..g.material.len()).all(|t| g.material[t] == Material::Floor));
            for left in [true, false] {
                let side: Vec<_> = facades.iter().filter(|f| f.left == left).collect();
                let gaps = side
                    .windows(2)
                    .filter(|w| w[1].x[0] - w[0].x[1] > 0.5)
                    .count();
                assert_eq!(gaps, 1, "seed {seed}: one gap per side");
                assert!(side[0].x[0] < 0.0 && side[side.len() - 1].x[1] > STREET_LENGTH);
            }
        }
        assert_ne!(build_street(1).1, build_street(2).1);
    }

    #[test]
    fn cameras_walk_the_centre_line_looking_sideways() {
        let (cams, path) = street_cameras(5, 64, 48).unwrap();
        assert_eq!(cams.len(), path.len());
        assert!((60..=96).contains(&cams.len()), "{} views", cams.len());
        for (c, p) in cams.iter().zip(&path) {
            let e = c.center();
            assert!((e - DVec3::from_array(p.eye)).length() < 1e-9);
            assert!(e.y.abs() < 0.06 && (e.z - CAMERA_HEIGHT).abs() < 0.06);
            assert!(e.x > 0.0 && e.x < STREET_LENGTH);
            let a = c.optical_axis();
            assert_eq!(a.y > 0.0, p.left);
            let from_axis = a.y.abs().atan2(a.x).to_degrees();
            assert!((65.0..=115.0).contains(&from_axis), "{from_axis}");
            assert!(a.z < -0.1 && a.z > -0.4, "pitch {}", a.z);
        }
        let last = path.last().unwrap();
        assert_eq!(last.station + 1, cams.len() / 2);
    }
}
