//! Small f64 scenes for the unit tests (analytic ground plane + box, two or three cameras).

use crate::analytic_scene::{AnalyticMaps, AnalyticScene, AxisBox};
use gs_core::glam::DVec3;
use gs_core::{Camera, Intrinsics};

pub(crate) struct SmallScene {
    pub cams: Vec<Camera>,
    pub maps: Vec<AnalyticMaps>,
}

pub(crate) fn to_f64(img: &gs_core::Image) -> Vec<f64> {
    img.data().iter().map(|&v| v as f64).collect()
}

/// The textured ground with a box that [`small_scene`] renders.
pub(crate) fn small_analytic_scene() -> AnalyticScene {
    AnalyticScene {
        boxes: vec![AxisBox {
            min: DVec3::new(-0.25, -0.2, 0.0),
            max: DVec3::new(0.15, 0.2, 0.45),
        }],
        frequency: 5.0,
    }
}

/// `n` cameras on an arc looking at a textured ground with a box, `w×h` pixels.
pub(crate) fn small_scene(w: u32, h: u32, n: usize) -> SmallScene {
    let f = w as f64 * 0.9;
    let k = Intrinsics::new(f, f, w as f64 / 2.0 + 0.1, h as f64 / 2.0 - 0.2);
    let scene = small_analytic_scene();
    let cams: Vec<Camera> = (0..n)
        .map(|i| {
            let a = -0.25 + 0.25 * i as f64;
            Camera::look_at(
                w,
                h,
                k,
                DVec3::new(2.2 * a.sin(), -2.2 * a.cos(), 1.6),
                DVec3::new(0.0, 0.1, 0.1),
                DVec3::Z,
            )
            .unwrap()
        })
        .collect();
    let maps = cams.iter().map(|c| scene.render(c)).collect();
    SmallScene { cams, maps }
}
