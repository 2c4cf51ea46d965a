//! Scenes, cameras, per-pixel gradients and the adapter of the parity tests.

use gs_core::glam::DVec3;
use gs_core::{Camera, Gaussians, Image, Intrinsics, Rng};
use gs_raster::{OutputGradients, WgpuOptions, WgpuRasterizer};

/// A wgpu rasterizer on this machine's adapter, or `None` (skip) when there is none locally;
/// panics in CI.
pub fn gpu(opts: WgpuOptions) -> Option<WgpuRasterizer> {
    match WgpuRasterizer::with_options(opts) {
        Ok(r) => {
            eprintln!("wgpu adapter: {}", r.adapter_description());
            Some(r)
        }
        Err(e) => {
            gs_testdata::skip_or_fail!(&format!("no wgpu adapter: {e}"), "install mesa-vulkan-drivers for lavapipe");
            None
        }
    }
}

pub fn camera(w: u32, h: u32, f: f64, eye: DVec3) -> Camera {
    Camera::look_at(
        w,
        h,
        Intrinsics::new(f, f * 1.05, w as f64 * 0.5 + 0.3, h as f64 * 0.5 - 0.2),
        eye,
        DVec3::new(0.1, 0.05, 0.0),
        DVec3::new(0.1, -1.0, 0.0),
    )
    .unwrap()
}

pub fn cameras(w: u32, h: u32) -> Vec<Camera> {
    let f = w.max(h) as f64 * 0.9;
    vec![
        camera(w, h, f, DVec3::new(0.4, -0.3, -4.0)),
        camera(w, h, f * 0.6, DVec3::new(-2.5, 0.8, -2.0)),
        camera(w, h, f * 1.4, DVec3::new(1.0, 2.0, 3.0)),
    ]
}

/// `n` random Gaussians in a cube of half-size `spread` around the origin.
pub fn random_scene(n: usize, degree: u32, seed: u64, spread: f32, scale: (f32, f32)) -> Gaussians {
    let mut rng = Rng::new(seed);
    let mut g = Gaussians::with_len(0).unwrap();
    g.sh_degree = degree;
    for _ in 0..n {
        let mean = [
            rng.uniform_range(-spread, spread),
            rng.uniform_range(-spread, spread),
            rng.uniform_range(-spread, spread),
        ];
        let ls = [
            rng.uniform_range(scale.0, scale.1),
            rng.uniform_range(scale.0, scale.1),
            rng.uniform_range(scale.0 - 1.5, scale.1 - 1.0),
        ];
        let q = [rng.normal(), rng.normal(), rng.normal(), rng.normal()];
        let o: f32 = rng.uniform_range(0.05, 0.995);
        let mut sh = [[0.0f32; 3]; 16];
        for (k, c) in sh.iter_mut().enumerate() {
            for v in c.iter_mut() {
                *v = if k == 0 {
                    rng.uniform_range(-1.5, 1.5)
                } else {
                    0.3 * rng.normal()
                };
            }
        }
        g.push(mean, ls, q, gs_core::gaussians::inverse_sigmoid(o), sh);
    }
    g
}

pub fn random_image(w: u32, h: u32, c: usize, rng: &mut Rng) -> Image {
    let data = (0..w as usize * h as usize * c)
        .map(|_| rng.uniform_range(-1.0, 1.0))
        .collect();
    Image::from_vec(w as usize, h as usize, c, data).unwrap()
}

/// Random per-pixel output gradients of every channel.
pub struct Grads {
    pub color: Image,
    pub alpha: Image,
    pub normal: Image,
    pub distance: Image,
    pub plane_depth: Image,
    pub expected_depth: Image,
}

impl Grads {
    pub fn new(w: u32, h: u32, seed: u64) -> Self {
        let mut rng = Rng::new(seed);
        Self {
            color: random_image(w, h, 3, &mut rng),
            alpha: random_image(w, h, 1, &mut rng),
            normal: random_image(w, h, 3, &mut rng),
            distance: random_image(w, h, 1, &mut rng),
            plane_depth: random_image(w, h, 1, &mut rng),
            expected_depth: random_image(w, h, 1, &mut rng),
        }
    }
    pub fn all(&self) -> OutputGradients<'_> {
        OutputGradients {
            color: Some(&self.color),
            alpha: Some(&self.alpha),
            normal: Some(&self.normal),
            distance: Some(&self.distance),
            plane_depth: Some(&self.plane_depth),
            expected_depth: Some(&self.expected_depth),
            ..OutputGradients::default()
        }
    }
}
