#![cfg(feature = "wgpu")]
//! A render whose colour stays on the device (`RenderRequest::color_on_device`) and a backward
//! whose colour gradient comes from there (`OutputGradients::device_color`): the image round
//! trip of a training step's colour, removed (docs/architecture.md §GPU). The device's colour
//! and the backward's gradients are compared bit for bit with the host path's on the same
//! rasterizer, and the ledger shows what no longer crosses.
//!
//! Without any wgpu adapter the tests print a skip message and return (a failure under
//! `CI=true`).

#[allow(dead_code)] // the helpers the parity tests use and these do not
mod parity;

use gs_core::glam::DVec3;
use gs_core::{Camera, Gaussians, Image};
use gs_gpu::DeviceImage;
use gs_raster::{GaussianGradients, OutputGradients, RasterConfig, RenderOutput, RenderRequest, WgpuOptions, WgpuRasterizer};
use parity::scenes::*;

/// A background that is not black, so that the T_final · background terms count.
fn config() -> RasterConfig {
    RasterConfig { background: [0.25, 0.5, 0.75], ..RasterConfig::default() }
}

/// `request` rendered with its colour on the host and then on the device: both outputs and the
/// bytes each read back.
fn both(r: &mut WgpuRasterizer, g: &Gaussians, cam: &Camera, request: RenderRequest) -> ((RenderOutput, u64), (RenderOutput, u64)) {
    let cfg = config();
    let mut run = |req: RenderRequest| {
        let before = r.context().transfers();
        let out = r.render(g, cam, &req, &cfg).unwrap();
        (out, (r.context().transfers() - before).bytes_down)
    };
    let host = run(RenderRequest { color_on_device: false, ..request });
    let device = run(RenderRequest { color_on_device: true, ..request });
    (host, device)
}

#[test]
fn a_colour_kept_on_the_device_has_the_host_colours_bits_and_does_not_come_back() {
    let Some(mut r) = gpu(WgpuOptions::default()) else { return };
    let cam = &cameras(80, 56)[0];
    let g = random_scene(400, 2, 31, 1.0, (-3.5, -2.0));
    // A first render of the size counts its intersections (one readback more): not compared.
    r.render(&g, cam, &RenderRequest::default(), &config()).unwrap();
    for (label, request) in [
        ("colour alone", RenderRequest { color: true, alpha: false, radii: false, ..RenderRequest::default() }),
        ("colour and alpha", RenderRequest::default()),
        ("colour and geometry", RenderRequest { normal: true, distance: true, plane_depth: true, ..RenderRequest::default() }),
    ] {
        let ((host, host_bytes), (device, device_bytes)) = both(&mut r, &g, cam, request);
        assert!(device.color.is_none() && host.device_color.is_none(), "{label}");
        let colour = device.device_color.as_ref().expect("kept on the device").read(r.context()).unwrap();
        assert_eq!(Some(colour.as_slice()), host.color.as_ref().map(Image::data), "{label}: the colour's bits");
        assert_eq!(device.alpha.as_ref().map(Image::data), host.alpha.as_ref().map(Image::data), "{label}: alpha");
        assert_eq!(device.plane_depth.as_ref().map(Image::data), host.plane_depth.as_ref().map(Image::data), "{label}: plane depth");
        // Three planes less come back, and T_final unless the alpha needs it.
        let npix = 80 * 56 * 4;
        let saved = if request.alpha { 3 * npix } else { 4 * npix };
        assert_eq!(host_bytes - device_bytes, saved, "{label}: bytes read back");
    }
}

#[test]
fn a_render_without_intersections_keeps_the_background_on_the_device() {
    let Some(mut r) = gpu(WgpuOptions::default()) else { return };
    let cam = camera(40, 24, 50.0, DVec3::new(0.0, 0.0, -4.0));
    // Behind the camera: nothing is blended.
    let mut g = random_scene(50, 0, 5, 0.2, (-3.0, -2.0));
    g.means.iter_mut().for_each(|m| m[2] = -20.0);
    let request = RenderRequest { color_on_device: true, ..RenderRequest::default() };
    let out = r.render(&g, &cam, &request, &config()).unwrap();
    assert_eq!(out.stats.intersections, 0);
    let colour = out.device_color.as_ref().unwrap().read(r.context()).unwrap();
    assert!(colour.chunks_exact(3).all(|px| px == [0.25, 0.5, 0.75]), "the background alone");
}

/// The backward of `out` with `grads`, its colour gradient given on the host or (uploaded
/// first) on the device.
fn backward(r: &mut WgpuRasterizer, g: &Gaussians, cam: &Camera, out: &RenderOutput, grads: OutputGradients<'_>, on_device: bool) -> GaussianGradients {
    let colour = grads.color.expect("a colour gradient");
    let image = DeviceImage::upload(r.context(), "colour gradient", (colour.width(), colour.height(), 3), colour.data()).unwrap();
    let grads = match on_device {
        true => OutputGradients { color: None, device_color: Some(&image), ..grads },
        false => grads,
    };
    r.backward(g, cam, &config(), out, &grads).unwrap()
}

#[test]
fn a_colour_gradient_on_the_device_back_propagates_as_on_the_host() {
    let Some(mut r) = gpu(WgpuOptions::default()) else { return };
    let cam = &cameras(72, 48)[1];
    let g = random_scene(350, 3, 41, 1.0, (-3.5, -2.0));
    let gr = Grads::new(72, 48, 7);
    let request = RenderRequest { normal: true, distance: true, plane_depth: true, color_on_device: true, ..RenderRequest::default() };
    let out = r.render(&g, cam, &request, &config()).unwrap();
    for (label, grads) in [
        ("colour alone", OutputGradients { color: Some(&gr.color), ..OutputGradients::default() }),
        ("colour and alpha", OutputGradients { color: Some(&gr.color), alpha: Some(&gr.alpha), ..OutputGradients::default() }),
        (
            "colour and geometry",
            OutputGradients { color: Some(&gr.color), normal: Some(&gr.normal), distance: Some(&gr.distance), plane_depth: Some(&gr.plane_depth), ..OutputGradients::default() },
        ),
    ] {
        let host = backward(&mut r, &g, cam, &out, grads, false);
        let device = backward(&mut r, &g, cam, &out, grads, true);
        assert_eq!(device, host, "{label}: the same gradients");
        assert!(host.means.iter().any(|m| m.iter().any(|v| *v != 0.0)), "{label}: something flowed back");
    }
}

#[test]
fn a_colour_only_backward_from_the_device_uploads_nothing_per_pixel() {
    let Some(mut r) = gpu(WgpuOptions::default()) else { return };
    let cam = &cameras(64, 48)[2];
    let g = random_scene(300, 1, 43, 1.0, (-3.5, -2.0));
    let gr = Grads::new(64, 48, 9);
    let request = RenderRequest { alpha: false, color_on_device: true, ..RenderRequest::default() };
    let out = r.render(&g, cam, &request, &config()).unwrap();
    let image = DeviceImage::upload(r.context(), "colour gradient", (64, 48, 3), gr.color.data()).unwrap();
    let before = r.context().transfers();
    let grads = OutputGradients { device_color: Some(&image), ..OutputGradients::default() };
    r.backward(&g, cam, &config(), &out, &grads).unwrap();
    let written = (r.context().transfers() - before).bytes_up;
    assert!(written < 64 * 48 * 4, "{written} bytes written: the per-pixel records are made on the device");
}

#[test]
fn a_device_colour_gradient_is_checked() {
    let Some(mut r) = gpu(WgpuOptions::default()) else { return };
    let cam = &cameras(32, 24)[0];
    let g = random_scene(100, 0, 3, 1.0, (-3.5, -2.0));
    let out = r.render(&g, cam, &RenderRequest { color_on_device: true, ..RenderRequest::default() }, &config()).unwrap();
    let ctx = r.context().clone();
    let wrong = DeviceImage::new(&ctx, "wrong size", 16, 24, 3).unwrap();
    let err = r.backward(&g, cam, &config(), &out, &OutputGradients { device_color: Some(&wrong), ..OutputGradients::default() }).unwrap_err();
    assert!(err.to_string().contains("16×24×3, needs 32×24×3"), "{err}");
    let host = Image::from_vec(32, 24, 3, vec![0.0; 32 * 24 * 3]).unwrap();
    let right = DeviceImage::new(&ctx, "right size", 32, 24, 3).unwrap();
    let both = OutputGradients { color: Some(&host), device_color: Some(&right), ..OutputGradients::default() };
    let err = r.backward(&g, cam, &config(), &out, &both).unwrap_err();
    assert!(err.to_string().contains("both on the host and on the device"), "{err}");
    // The CPU backend renders the colour to the host and refuses a device gradient.
    let cpu = gs_raster::render(&g, cam, &RenderRequest { color_on_device: true, ..RenderRequest::default() }, &config()).unwrap();
    assert!(cpu.color.is_some() && cpu.device_color.is_none());
    let err = gs_raster::backward(&g, cam, &config(), &cpu, &OutputGradients { device_color: Some(&right), ..OutputGradients::default() }).unwrap_err();
    assert!(err.to_string().contains("CPU backward"), "{err}");
}
