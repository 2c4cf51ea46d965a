//! Analytic depth maps of simple scenes (spheres, boxes), for tests, benches and examples.

use gs_core::glam::DVec3;
use gs_core::{Camera, Image};
use rayon::prelude::*;

/// A primitive an analytic scene is made of.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Primitive {
    /// A solid sphere seen from outside.
    Sphere {
        /// Centre.
        center: DVec3,
        /// Radius.
        radius: f64,
    },
    /// An axis-aligned box: seen from outside it is a solid; from inside, a room (its walls).
    Box {
        /// Lower corner.
        min: DVec3,
        /// Upper corner.
        max: DVec3,
    },
}

impl Primitive {
    /// Ray parameter of the first hit with `t > 0` along `o + t·d`.
    fn hit(&self, o: DVec3, d: DVec3) -> Option<f64> {
        match *self {
            Primitive::Sphere { center, radius } => {
                let oc = o - center;
                let a = d.dot(d);
                let b = oc.dot(d);
                let c = oc.dot(oc) - radius * radius;
                let disc = b * b - a * c;
                if disc < 0.0 {
                    return None;
                }
                let s = disc.sqrt();
                let t0 = (-b - s) / a;
                let t1 = (-b + s) / a;
                if t0 > 0.0 {
                    Some(t0)
                } else if t1 > 0.0 {
                    Some(t1)
                } else {
                    None
                }
            }
            Primitive::Box { min, max } => {
                let inv = d.recip();
                let ta = (min - o) * inv;
                let tb = (max - o) * inv;
                let tn = ta.min(tb).max_element();
                let tf = ta.max(tb).min_element();
                if tn > tf || tf <= 0.0 {
                    None
                } else if tn > 0.0 {
                    Some(tn)
                } else {
                    Some(tf)
                }
            }
        }
    }

    /// Signed distance of `p` to the primitive's surface, positive outside (for a box seen as a
    /// solid).
    pub fn signed_distance(&self, p: DVec3) -> f64 {
        match *self {
            Primitive::Sphere { center, radius } => (p - center).length() - radius,
            Primitive::Box { min, max } => {
                let c = (min + max) * 0.5;
                let h = (max - min) * 0.5;
                let q = (p - c).abs() - h;
                q.max(DVec3::ZERO).length() + q.max_element().min(0.0)
            }
        }
    }
}

/// Depth map (camera z at pixel centres, 0 where every ray misses) of the primitives.
pub fn render_depth(camera: &Camera, scene: &[Primitive]) -> Image {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let o = camera.center();
    let rt = camera.rotation.transpose();
    let mut data = vec![0.0f32; w * h];
    data.par_chunks_mut(w).enumerate().for_each(|(j, row)| {
        for (i, px) in row.iter_mut().enumerate() {
            // The ray K⁻¹p̄ has camera z = 1, so the ray parameter is the camera z.
            let d = rt * camera.ray(i as f64 + 0.5, j as f64 + 0.5);
            let t = scene.iter().filter_map(|p| p.hit(o, d)).fold(f64::INFINITY, f64::min);
            if t.is_finite() {
                *px = t as f32;
            }
        }
    });
    Image::from_vec(w, h, 1, data).expect("size matches")
}

/// `n` cameras of size `width × height` on a sphere of radius `distance` around `target`
/// (a Fibonacci spiral restricted to elevations in [−60°, 75°]), all looking at `target`,
/// with a horizontal field of view of about 60°.
pub fn orbit_cameras(n: usize, width: u32, height: u32, target: DVec3, distance: f64) -> Vec<Camera> {
    let f = width as f64 / (2.0 * (30f64).to_radians().tan());
    let k = gs_core::Intrinsics::new(f, f, width as f64 / 2.0, height as f64 / 2.0);
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let (lo, hi) = ((-60f64).to_radians().sin(), 75f64.to_radians().sin());
    (0..n)
        .map(|i| {
            let s = lo + (hi - lo) * (i as f64 + 0.5) / n as f64;
            let c = (1.0 - s * s).sqrt();
            let a = golden * i as f64;
            let eye = target + DVec3::new(c * a.cos(), c * a.sin(), s) * distance;
            Camera::look_at(width, height, k, eye, target, DVec3::Z).expect("eye differs from target")
        })
        .collect()
}
