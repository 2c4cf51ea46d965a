//! Analytic test scenes (a textured ground plane plus axis-aligned boxes), ray cast exactly,
//! giving the "rendered" maps L_p and L_f consume — used by tests and benches, and handy for
//! checking an integration without a rasterizer.

use gs_core::glam::DVec3;
use gs_core::{Camera, Image};

/// An axis-aligned box (an occluder).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisBox {
    /// Minimum corner.
    pub min: DVec3,
    /// Maximum corner.
    pub max: DVec3,
}

/// The ground plane z = 0 (world) and boxes, textured by a smooth procedural grey pattern.
#[derive(Debug, Clone, PartialEq)]
pub struct AnalyticScene {
    /// Occluders standing on or above the ground.
    pub boxes: Vec<AxisBox>,
    /// Spatial frequency scale of the texture (radians per scene unit ≈ 6·frequency).
    pub frequency: f64,
}

/// Exact maps of one camera: what a perfect renderer would produce.
#[derive(Debug, Clone, PartialEq)]
pub struct AnalyticMaps {
    /// Camera-space z at pixel centres (0 = miss).
    pub depth: Image,
    /// Camera-space unit normal facing the camera, Ñ (0 = miss).
    pub normal: Image,
    /// D = −Ñ·x (0 = miss).
    pub distance: Image,
    /// z = D / (−Ñ·r + 1e-8) (0 = miss).
    pub plane_depth: Image,
    /// Grey image (texture at the hit point; 0 = miss).
    pub grey: Image,
}

impl AnalyticScene {
    /// The closest hit of the ray `origin + t·dir`, t > 0: `(t, world normal)`.
    pub fn cast(&self, origin: DVec3, dir: DVec3) -> Option<(f64, DVec3)> {
        let mut best: Option<(f64, DVec3)> = None;
        if dir.z.abs() > 1e-12 {
            let t = -origin.z / dir.z;
            if t > 1e-9 {
                best = Some((t, DVec3::Z));
            }
        }
        for b in &self.boxes {
            let inv = dir.recip();
            let t1 = (b.min - origin) * inv;
            let t2 = (b.max - origin) * inv;
            let tmin = t1.min(t2);
            let tmax = t1.max(t2);
            let enter = tmin.max_element();
            let exit = tmax.min_element();
            if enter <= exit && enter > 1e-9 && best.is_none_or(|(bt, _)| enter < bt) {
                // The entering face is the axis of the largest tmin.
                let axis = if tmin.x >= tmin.y && tmin.x >= tmin.z {
                    0
                } else if tmin.y >= tmin.z {
                    1
                } else {
                    2
                };
                let mut n = DVec3::ZERO;
                n[axis] = -dir[axis].signum();
                best = Some((enter, n));
            }
        }
        best
    }

    /// Grey texture value at a world point, in about [0.1, 0.9].
    pub fn texture(&self, p: DVec3) -> f64 {
        let f = self.frequency;
        0.5 + 0.18 * (f * (1.3 * p.x + 0.7 * p.y + 0.9 * p.z)).sin()
            + 0.12 * (f * (-0.6 * p.x + 1.1 * p.y + 0.4 * p.z) + 0.5).sin()
            + 0.1 * (f * (2.3 * p.x - 1.9 * p.y + 1.7 * p.z) + 1.0).sin()
    }

    /// Ray casts every pixel centre of `camera`.
    pub fn render(&self, camera: &Camera) -> AnalyticMaps {
        let (w, h) = (camera.width as usize, camera.height as usize);
        let mut depth = vec![0.0f32; w * h];
        let mut normal = vec![0.0f32; w * h * 3];
        let mut distance = vec![0.0f32; w * h];
        let mut plane = vec![0.0f32; w * h];
        let mut grey = vec![0.0f32; w * h];
        let centre = camera.center();
        let rt = camera.rotation.transpose();
        for j in 0..h {
            for i in 0..w {
                let ray = camera.ray(i as f64 + 0.5, j as f64 + 0.5);
                let dir = rt * ray;
                if let Some((t, nw)) = self.cast(centre, dir) {
                    let p = centre + dir * t;
                    let x = camera.world_to_camera(p);
                    let mut n = camera.rotation * nw;
                    if n.dot(ray) > 0.0 {
                        n = -n;
                    }
                    let d = -n.dot(x);
                    let k = j * w + i;
                    depth[k] = x.z as f32;
                    normal[3 * k..3 * k + 3].copy_from_slice(&n.as_vec3().to_array());
                    distance[k] = d as f32;
                    plane[k] = (d / (-n.dot(ray) + 1e-8)) as f32;
                    grey[k] = self.texture(p) as f32;
                }
            }
        }
        let img = |c, v| Image::from_vec(w, h, c, v).expect("sizes set above");
        AnalyticMaps {
            depth: img(1, depth),
            normal: img(3, normal),
            distance: img(1, distance),
            plane_depth: img(1, plane),
            grey: img(1, grey),
        }
    }
}
