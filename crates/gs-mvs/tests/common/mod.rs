//! The ray-cast scene and camera arc the device parity tests share.

use gs_core::glam::DVec3;
use gs_core::{Camera, Intrinsics};
use gs_mvs::analytic_scene::{AnalyticScene, AxisBox};

/// A textured ground with a box on it.
pub fn box_scene() -> AnalyticScene {
    AnalyticScene {
        boxes: vec![AxisBox { min: DVec3::new(-0.25, -0.2, 0.0), max: DVec3::new(0.15, 0.2, 0.45) }],
        frequency: 5.0,
    }
}

/// `n` cameras of `w`×`h` on an arc around the box, at azimuths `first + k·step` (radians),
/// their principal points a little off centre.
pub fn arc_cameras(w: u32, h: u32, n: usize, first: f64, step: f64) -> Vec<Camera> {
    let f = w as f64 * 0.9;
    let k = Intrinsics::new(f, f, w as f64 / 2.0 + 0.1, h as f64 / 2.0 - 0.2);
    (0..n)
        .map(|i| {
            let a = first + step * i as f64;
            Camera::look_at(w, h, k, DVec3::new(2.2 * a.sin(), -2.2 * a.cos(), 1.6), DVec3::new(0.0, 0.1, 0.1), DVec3::Z).unwrap()
        })
        .collect()
}
