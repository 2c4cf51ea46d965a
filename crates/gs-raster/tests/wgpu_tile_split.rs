#![cfg(feature = "wgpu")]
//! The blends' tile split (docs/architecture.md §GPU, gs-raster `gpu/split.rs`): the other
//! parity tests run the adapter's own split (on lavapipe, 16 threads of 16 pixels); a GPU's
//! (a thread per pixel forward, 32 threads of 8 pixels backward) is checked here too, against
//! the CPU, on lavapipe.
//!
//! Without any wgpu adapter the test prints a skip message and returns (a failure under
//! `CI=true`).

#[allow(dead_code)] // the helpers the parity tests use and these do not
mod parity;

use gs_core::glam::DVec3;
use gs_raster::{GaussianGradients, RasterConfig, RasterError, RenderRequest, TileSplit, WgpuOptions, WgpuRasterizer};
use parity::compare::*;
use parity::scenes::*;

/// Each split against the CPU on partial tiles (97×61) and a list long enough for several
/// backward windows, repeating bit for bit; a split the kernels cannot take is refused.
#[test]
fn parity_with_each_tile_split() {
    for split in [TileSplit::HARDWARE, TileSplit::SOFTWARE] {
        let Some(mut r) = gpu(WgpuOptions { tile_split: Some(split), ..Default::default() }) else { return };
        let g = random_scene(600, 3, 21, 1.0, (-3.5, -2.0));
        let cfg = RasterConfig::default();
        for (c, cam) in cameras(97, 61).iter().enumerate() {
            parity(&mut r, &format!("{split:?} cam={c}"), &g, cam, &cfg);
        }
        let mut g = random_scene(3_000, 0, 22, 0.25, (-5.5, -5.0));
        for o in g.opacity_logits.iter_mut() {
            *o = gs_core::gaussians::inverse_sigmoid(0.01);
        }
        let cam = camera(32, 16, 40.0, DVec3::new(0.0, 0.0, -4.0));
        parity(&mut r, &format!("{split:?} long list"), &g, &cam, &cfg);
        let grads = Grads::new(cam.width, cam.height, 7);
        let runs: Vec<GaussianGradients> = (0..2)
            .map(|_| {
                let out = r.render(&g, &cam, &RenderRequest::all(), &cfg).unwrap();
                r.backward(&g, &cam, &cfg, &out, &grads.all()).unwrap()
            })
            .collect();
        assert_same_bits(&format!("{split:?} repeat"), &runs[0], &runs[1]);
    }
    let bad = WgpuRasterizer::with_options(WgpuOptions { tile_split: Some(TileSplit { forward_threads: 24, backward_threads: 32 }), ..Default::default() });
    assert!(matches!(bad, Err(RasterError::InvalidConfig(_))), "{bad:?}");
}
