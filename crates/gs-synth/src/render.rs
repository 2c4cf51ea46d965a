//! Cameras, shading and per-view rendering of the built-in scene.
//!
//! Shading model (linear RGB, no interreflection):
//! `colour = albedo·(ambient + light·max(n·l, 0)·vis) + k_s·light·max(n·h, 0)^shininess·vis`
//! with one directional light, hard shadows from shadow rays (`vis` ∈ {0, 1}) and `n` the
//! shading normal (interpolated vertex normals on the sphere and torus, face normals
//! elsewhere), flipped with the face normal towards the viewer.

use crate::bvh::{Bvh, pixel_ray};
use crate::error::Result;
use crate::geometry::{Geometry, Material};
use crate::texture::{albedo_styled, specular};
use glam::{DMat3, DVec3};
use gs_core::{Camera, Image, Intrinsics, Rng};
use rayon::prelude::*;

/// Direction **towards** the light (unit; elevation ≈ 52°, azimuth 35°).
pub const LIGHT_DIRECTION: [f64; 3] = [0.504320, 0.353129, 0.788011];
/// Linear RGB of the directional light.
pub const LIGHT_RGB: [f64; 3] = [0.85, 0.82, 0.78];
/// Linear RGB of the ambient term.
pub const AMBIENT_RGB: [f64; 3] = [0.18, 0.19, 0.22];
/// Linear RGB of rays that hit nothing (depth 0).
pub const SKY_RGB: [f64; 3] = [0.55, 0.68, 0.85];
/// Look-at target of the camera rings (centre of the objects), before jitter.
pub const TARGET: [f64; 3] = [0.0, -0.05, 0.28];
/// Distance of the cameras from the target, before jitter.
pub const RING_RADIUS: f64 = 3.0;
/// Elevations of the two camera rings, degrees.
pub const RING_ELEVATIONS: [f64; 2] = [20.0, 40.0];
/// Field of view across the longer image side, degrees.
pub const FOV_DEG: f64 = 50.0;
/// Offset of shadow-ray origins along the face normal (scene units; the scene is ~10 wide).
const SHADOW_EPS: f64 = 1e-6;

pub(crate) fn light_dir() -> DVec3 {
    DVec3::from_array(LIGHT_DIRECTION).normalize()
}

/// Lighting and texturing of a scene: the built-in scene's constants, or a suite scene's.
#[derive(Debug, Clone, PartialEq)]
pub struct Style {
    /// Unit direction towards the directional light.
    pub light_dir: DVec3,
    /// Linear RGB of the light.
    pub light_rgb: DVec3,
    /// Linear RGB of the ambient term.
    pub ambient_rgb: DVec3,
    /// Texture contrast of the objects in `[0, 1]`: 1 = full-contrast textures, towards 0 the
    /// albedo fades to each material's mean colour (weakly textured surfaces).
    pub texture_strength: f64,
    /// The same for the floor and the walls.
    pub background_strength: f64,
    /// Seed of the suite objects' texture noise.
    pub texture_seed: u64,
}

impl Style {
    /// The built-in scene's light and textures.
    pub fn builtin() -> Self {
        Self {
            light_dir: light_dir(),
            light_rgb: DVec3::from_array(LIGHT_RGB),
            ambient_rgb: DVec3::from_array(AMBIENT_RGB),
            texture_strength: 1.0,
            background_strength: 1.0,
            texture_seed: 0,
        }
    }
}

/// Where the cameras of a two-ring capture are.
#[derive(Debug, Clone, PartialEq)]
pub struct RingSpec {
    /// Look-at target before jitter.
    pub target: [f64; 3],
    /// Distance of the cameras from the target before jitter.
    pub radius: f64,
    /// Elevations of the lower and the upper ring, degrees.
    pub elevations: [f64; 2],
    /// Field of view across the longer image side, degrees.
    pub fov_deg: f64,
}

impl RingSpec {
    /// The built-in scene's rings.
    pub fn builtin() -> Self {
        Self {
            target: TARGET,
            radius: RING_RADIUS,
            elevations: RING_ELEVATIONS,
            fov_deg: FOV_DEG,
        }
    }
}

/// The posed cameras: `views` look-at cameras on two rings (elevations 20° and 40°, the
/// first `⌈views/2⌉` on the lower ring), all aimed at [`TARGET`], with seeded jitter of
/// elevation ±2°, azimuth ±3°, radius ±4 %, target ±0.03 per axis and roll ±2°. Square
/// pixels, `FOV_DEG` across the longer side, principal point at the image centre.
pub fn ring_cameras(width: u32, height: u32, views: usize, seed: u64) -> Result<Vec<Camera>> {
    ring_cameras_with(&RingSpec::builtin(), width, height, views, seed)
}

/// [`ring_cameras`] on the rings of `spec` (same jitter, same order of random draws).
pub fn ring_cameras_with(
    spec: &RingSpec,
    width: u32,
    height: u32,
    views: usize,
    seed: u64,
) -> Result<Vec<Camera>> {
    let f = 0.5 * width.max(height) as f64 / (0.5 * spec.fov_deg.to_radians()).tan();
    let k = Intrinsics::new(f, f, width as f64 / 2.0, height as f64 / 2.0);
    let mut rng = Rng::new(seed).fork(0x0CA3_E7A5);
    let n_low = views.div_ceil(2);
    let n_high = views / 2;
    let mut out = Vec::with_capacity(views);
    for v in 0..views {
        let (ring, idx, n) = if v < n_low {
            (0, v, n_low)
        } else {
            (1, v - n_low, n_high)
        };
        let mut j = |a: f64| rng.uniform_range(-a as f32, a as f32) as f64;
        let elev = (spec.elevations[ring] + j(2.0)).to_radians();
        let offset = if ring == 1 { 180.0 / n as f64 } else { 0.0 };
        let az = (360.0 * idx as f64 / n as f64 + offset + j(3.0)).to_radians();
        let radius = spec.radius * (1.0 + j(0.04));
        let target = DVec3::from_array(spec.target) + DVec3::new(j(0.03), j(0.03), j(0.03));
        let roll = j(2.0).to_radians();
        let eye =
            target + radius * DVec3::new(elev.cos() * az.cos(), elev.cos() * az.sin(), elev.sin());
        let up = DMat3::from_axis_angle((target - eye).normalize(), roll) * DVec3::Z;
        out.push(Camera::look_at(width, height, k, eye, target, up)?);
    }
    Ok(out)
}

/// sRGB encoding of a linear value (clipped to `[0, 1]`).
pub fn linear_to_srgb(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.0031308 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// sRGB-encodes and quantises to 8 bits, as an f32 of `k/255` (what a PNG round trip gives).
pub fn encode8(x: f64) -> f32 {
    ((linear_to_srgb(x) * 255.0).round() / 255.0) as f32
}

/// The surface hit by a ray, with everything shading needs.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Surface {
    pub t: f64,
    pub point: DVec3,
    pub material: Material,
    /// Shading normal, facing the viewer together with the face normal.
    pub normal: DVec3,
    /// Face normal, facing the viewer.
    pub face: DVec3,
}

/// Scene geometry plus its BVH and style.
pub(crate) struct Renderer {
    pub geom: Geometry,
    pub bvh: Bvh,
    pub style: Style,
}

/// Per-view render results.
pub(crate) struct ViewRender {
    pub image: Image,
    pub depth: Image,
    pub normal: Image,
    pub mask: Image,
}

impl Renderer {
    pub fn new(geom: Geometry, style: Style) -> Result<Self> {
        let bvh = Bvh::new(&geom.mesh)?;
        Ok(Self { geom, bvh, style })
    }

    /// Linear-RGB albedo at surface point `p` of `material` under this renderer's style.
    pub fn albedo(&self, material: Material, p: DVec3) -> DVec3 {
        albedo_styled(material, p, &self.style)
    }

    pub fn surface(&self, o: DVec3, d: DVec3) -> Option<Surface> {
        let hit = self.bvh.intersect(o, d, 0.0, f64::INFINITY)?;
        let (mut n, mut face) = self.geom.shading_normal(hit.triangle, hit.u, hit.v);
        if face.dot(d) > 0.0 {
            n = -n;
            face = -face;
        }
        Some(Surface {
            t: hit.t,
            point: o + hit.t * d,
            material: self.geom.material[hit.triangle as usize],
            normal: n,
            face,
        })
    }

    /// Whether the light reaches `s` (front-lit and no shadow-ray hit).
    pub fn lit(&self, s: &Surface) -> bool {
        let l = self.style.light_dir;
        s.face.dot(l) > 0.0
            && s.normal.dot(l) > 0.0
            && !self
                .bvh
                .occluded(s.point + SHADOW_EPS * s.face, l, 0.0, f64::INFINITY)
    }

    /// Linear RGB of surface `s` seen along `d`, given its light visibility.
    pub fn shade_surface(&self, s: &Surface, d: DVec3, visible: bool) -> DVec3 {
        let l = self.style.light_dir;
        let light = self.style.light_rgb;
        let a = self.albedo(s.material, s.point);
        let mut c = a * self.style.ambient_rgb;
        if visible {
            let (ks, shininess) = specular(s.material);
            let h = (l - d.normalize()).normalize();
            c += a * light * s.normal.dot(l).max(0.0);
            c += light * ks * s.normal.dot(h).max(0.0).powf(shininess);
        }
        c
    }

    /// Linear RGB seen along the ray.
    pub fn radiance(&self, o: DVec3, d: DVec3) -> DVec3 {
        match self.surface(o, d) {
            None => DVec3::from_array(SKY_RGB),
            Some(s) => self.shade_surface(&s, d, self.lit(&s)),
        }
    }

    /// Renders one view: the image (k×k stratified samples per pixel, averaged in linear RGB,
    /// clipped, sRGB-encoded, quantised to /255) and the pixel-centre GT maps.
    pub fn render_view(&self, camera: &Camera, supersample: u32) -> Result<ViewRender> {
        let (w, h) = (camera.width as usize, camera.height as usize);
        let mut image = Image::new(w, h, 3)?;
        let mut depth = Image::new(w, h, 1)?;
        let mut normal = Image::new(w, h, 3)?;
        let mut mask = Image::new(w, h, 1)?;
        let k = supersample as usize;
        let inv_n = 1.0 / (k * k) as f64;
        image
            .data_mut()
            .par_chunks_mut(3 * w)
            .zip(depth.data_mut().par_chunks_mut(w))
            .zip(normal.data_mut().par_chunks_mut(3 * w))
            .zip(mask.data_mut().par_chunks_mut(w))
            .enumerate()
            .for_each(|(y, (((irow, drow), nrow), mrow))| {
                for x in 0..w {
                    let mut acc = DVec3::ZERO;
                    for sy in 0..k {
                        for sx in 0..k {
                            let u = x as f64 + (sx as f64 + 0.5) / k as f64;
                            let v = y as f64 + (sy as f64 + 0.5) / k as f64;
                            let (o, d) = pixel_ray(camera, u, v);
                            acc += self.radiance(o, d);
                        }
                    }
                    let c = acc * inv_n;
                    irow[3 * x] = encode8(c.x);
                    irow[3 * x + 1] = encode8(c.y);
                    irow[3 * x + 2] = encode8(c.z);
                    let (o, d) = pixel_ray(camera, x as f64 + 0.5, y as f64 + 0.5);
                    if let Some(s) = self.surface(o, d) {
                        drow[x] = s.t as f32;
                        nrow[3 * x] = s.normal.x as f32;
                        nrow[3 * x + 1] = s.normal.y as f32;
                        nrow[3 * x + 2] = s.normal.z as f32;
                        mrow[x] = if s.material.is_object() { 1.0 } else { 0.0 };
                    }
                }
            });
        Ok(ViewRender {
            image,
            depth,
            normal,
            mask,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry;

    fn srgb_to_linear(x: f64) -> f64 {
        if x <= 0.04045 {
            x / 12.92
        } else {
            ((x + 0.055) / 1.055).powf(2.4)
        }
    }

    #[test]
    fn srgb_encoding_is_quantised_and_monotone() {
        assert_eq!(encode8(0.0), 0.0);
        assert_eq!(encode8(1.0), 1.0);
        assert_eq!(encode8(2.0), 1.0);
        let mut prev = 0.0;
        for i in 0..=1000 {
            let v = encode8(i as f64 / 1000.0);
            assert!(v >= prev);
            assert_eq!((v * 255.0).round() / 255.0, v);
            prev = v;
        }
        assert!((srgb_to_linear(linear_to_srgb(0.3)) - 0.3).abs() < 1e-12);
    }

    #[test]
    fn cameras_look_at_the_objects_and_stay_in_the_room() {
        let cams = ring_cameras(64, 48, 10, 7).unwrap();
        assert_eq!(cams.len(), 10);
        for c in &cams {
            let (px, _) = c.project(DVec3::from_array(TARGET)).unwrap();
            assert!(
                (px.x - 32.0).abs() < 3.0 && (px.y - 24.0).abs() < 3.0,
                "{px}"
            );
            let e = c.center();
            assert!(
                e.x.abs() < geometry::ROOM_HALF && e.y.abs() < geometry::ROOM_HALF && e.z > 0.5
            );
        }
        // Lower ring first.
        assert!(cams[0].center().z < cams[9].center().z);
        // Seeded: same seed same cameras, other seed other jitter.
        assert_eq!(cams, ring_cameras(64, 48, 10, 7).unwrap());
        assert_ne!(cams, ring_cameras(64, 48, 10, 8).unwrap());
    }

    /// Floor pixels are either fully lit (colour = the unshadowed prediction) or in shadow
    /// (ambient only); a visible fraction must be in shadow (some of it cast by the objects),
    /// and shadowed pixels must be the ones whose shadow ray is blocked.
    #[test]
    fn shadows_darken_part_of_the_floor() {
        let r = Renderer::new(geometry::build(), Style::builtin()).unwrap();
        // A view from the 40° ring looking down on the floor around the objects.
        let cams = ring_cameras(80, 60, 2, 3).unwrap();
        let cam = &cams[1];
        let view = r.render_view(cam, 1).unwrap();
        let (mut floor, mut shadowed, mut lit_ok, mut object_shadow) =
            (0usize, 0usize, 0usize, 0usize);
        for y in 0..60 {
            for x in 0..80 {
                let (o, d) = pixel_ray(cam, x as f64 + 0.5, y as f64 + 0.5);
                let Some(s) = r.surface(o, d) else { continue };
                if s.material != Material::Floor {
                    continue;
                }
                floor += 1;
                let unshadowed = r.shade_surface(&s, d, true);
                let ambient = r.shade_surface(&s, d, false);
                let got = srgb_to_linear(view.image.get(x, y, 1) as f64);
                // Quantisation tolerance on the linear value of the green channel.
                let tol = 0.01 + 0.02 * unshadowed.y;
                if (got - ambient.y.min(1.0)).abs() < tol && unshadowed.y > 2.0 * ambient.y {
                    shadowed += 1;
                    // The shadow ray really is blocked (by an object or a wall).
                    let hit = r.bvh.intersect(
                        s.point + SHADOW_EPS * s.face,
                        light_dir(),
                        0.0,
                        f64::INFINITY,
                    );
                    let hit = hit.expect("a shadowed floor pixel whose shadow ray is free");
                    if r.geom.material[hit.triangle as usize].is_object() {
                        object_shadow += 1;
                    }
                } else if (got - unshadowed.y.min(1.0)).abs() < tol {
                    lit_ok += 1;
                }
            }
        }
        assert!(floor > 1000, "floor pixels {floor}");
        assert!(
            shadowed as f64 > 0.01 * floor as f64,
            "shadowed {shadowed} of {floor}"
        );
        assert!(
            object_shadow as f64 > 0.005 * floor as f64,
            "object shadows {object_shadow} of {floor}"
        );
        assert_eq!(
            shadowed + lit_ok,
            floor,
            "pixels matching neither prediction"
        );
    }
}
