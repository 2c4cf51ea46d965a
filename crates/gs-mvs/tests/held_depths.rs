#![cfg(feature = "wgpu")]
//! Plane depths kept on the device (`ViewKeys::keep_reference_depth`, `SourceDepth::Held`): a
//! reference's depth stays in L_p's arena, and a later evaluation that takes that view as a
//! source reads it there, with the result the same depth given from the host gives, bit for
//! bit. A selection made on the host reads such depths back first. Without a wgpu adapter the
//! tests print one SKIPPED line (a failure under `CI=true`).

use gs_core::Camera;
use gs_gpu::{GpuContext, GpuOptions};
use gs_mvs::analytic_scene::AnalyticMaps;
use gs_mvs::{DeviceSource, PhotometricConfig, PhotometricGpu, PhotometricOnDevice, PhotometricReference, PhotometricSource, SourceDepth, SurfaceReference, ViewKeys};

mod common;

fn gpu() -> Option<(PhotometricGpu, GpuContext)> {
    let c = gs_testdata::wgpu_context!(&GpuOptions::default())?;
    Some((PhotometricGpu::new(&c).unwrap_or_else(|e| panic!("the L_p kernels on an adapter that exists: {e}")), c))
}

/// Three cameras of the box scene and their maps.
fn scene(w: u32, h: u32) -> (Vec<Camera>, Vec<AnalyticMaps>) {
    let s = common::box_scene();
    let cams = common::arc_cameras(w, h, 3, -0.25, 0.25);
    let maps = cams.iter().map(|c| s.render(c)).collect();
    (cams, maps)
}

/// View `k` as a host reference.
fn reference<'a>(cams: &'a [Camera], maps: &'a [AnalyticMaps], k: usize) -> PhotometricReference<'a, f32> {
    let m = &maps[k];
    PhotometricReference { camera: &cams[k], normal: (&m.normal).into(), distance: (&m.distance).into(), plane_depth: (&m.plane_depth).into(), grey: (&m.grey).into() }
}

/// View `k` as a source whose depth is on the host.
fn source<'a>(cams: &'a [Camera], maps: &'a [AnalyticMaps], k: usize) -> PhotometricSource<'a, f32> {
    PhotometricSource { camera: &cams[k], plane_depth: (&maps[k].plane_depth).into(), grey: (&maps[k].grey).into() }
}

/// Evaluates view 0 as the reference against views 1 and 2 (their depths at version 5), keeping
/// its depth under key 0 at `version`.
fn keep_view_0(g: &mut PhotometricGpu, ctx: &GpuContext, (cams, maps): (&[Camera], &[AnalyticMaps]), config: &PhotometricConfig, version: u64) {
    let r = reference(cams, maps, 0);
    let surface = gs_mvs::upload_surface(ctx, &r).unwrap();
    let on_device = SurfaceReference { camera: r.camera, surface: &surface, plane_depth: None, grey: r.grey };
    let sources: Vec<DeviceSource<'_>> = [1, 2].map(|k| source(cams, maps, k).into()).to_vec();
    let keys = ViewKeys { views: &[0, 1, 2], depth_versions: &[5, 5], keep_reference_depth: Some(version) };
    let started = g.start_on_device(&on_device, &sources, Some(keys), config).unwrap();
    g.finish_on_device(started).unwrap();
}

/// L_p of view 1 against views 0 and 2, view 0's depth held on the device (version 7) or given
/// from the host: (loss or host output, per-source statistics, gradient values).
fn view_1(g: &mut PhotometricGpu, ctx: &GpuContext, (cams, maps): (&[Camera], &[AnalyticMaps]), config: &PhotometricConfig, held: bool) -> (f64, Vec<gs_mvs::SourceStats>, Vec<f32>) {
    let r = reference(cams, maps, 1);
    let surface = gs_mvs::upload_surface(ctx, &r).unwrap();
    let on_device = SurfaceReference { camera: r.camera, surface: &surface, plane_depth: None, grey: r.grey };
    let mut first: DeviceSource<'_> = source(cams, maps, 0).into();
    if held {
        first.plane_depth = SourceDepth::Held;
    }
    let sources = [first, source(cams, maps, 2).into()];
    let keys = ViewKeys { views: &[1, 0, 2], depth_versions: &[7, 5], keep_reference_depth: None };
    let started = g.start_on_device(&on_device, &sources, Some(keys), config).unwrap();
    match g.finish_on_device(started).unwrap() {
        PhotometricOnDevice::Device { loss, per_source, gradient } => (loss, per_source, gradient.read(ctx).unwrap()),
        PhotometricOnDevice::Host(out) => (out.loss, out.per_source, out.grad_distance),
    }
}

#[test]
fn a_kept_reference_depth_serves_later_as_a_source() {
    let Some((mut g, ctx)) = gpu() else { return };
    let (cams, maps) = scene(64, 48);
    let views = (&cams[..], &maps[..]);
    let config = PhotometricConfig::default();
    keep_view_0(&mut g, &ctx, views, &config, 7);
    let pixels = 64 * 48;
    assert!(g.holds_depth(0, pixels, 7) && !g.holds_depth(0, pixels, 8));
    let kept = g.held_depths(&[(0, pixels, 7), (0, pixels, 6)]).unwrap();
    let want = maps[0].plane_depth.data();
    assert!(kept[0].as_ref().unwrap().iter().zip(want).all(|(a, b)| a.to_bits() == b.to_bits()), "the surface's z, bit for bit");
    assert!(kept[1].is_none(), "another version is not held");
    // Every grey image and view 2's depth are held: nothing per pixel goes up.
    let before = ctx.transfers();
    let on_device = view_1(&mut g, &ctx, views, &config, true);
    // Less the test's upload of view 1's surface (24 bytes a pixel).
    let up = (ctx.transfers() - before).bytes_up - 24 * pixels as u64;
    assert!(up < 4 * pixels as u64, "{up} bytes went up: view 0's depth stayed on the device");
    // A fresh executor given view 0's depth from the host: the same bits.
    let (mut fresh, fresh_ctx) = gpu().unwrap();
    let from_host = view_1(&mut fresh, &fresh_ctx, views, &config, false);
    assert_eq!(on_device, from_host);
    assert!(on_device.0 > 0.0 && on_device.2.iter().any(|&x| x != 0.0), "a loss and a gradient to compare");
    // A held depth the arena does not hold is refused, naming it.
    let r = reference(&cams, &maps, 1);
    let surface = gs_mvs::upload_surface(&ctx, &r).unwrap();
    let on_device = SurfaceReference { camera: r.camera, surface: &surface, plane_depth: None, grey: r.grey };
    let mut gone: DeviceSource<'_> = source(&cams, &maps, 0).into();
    gone.plane_depth = SourceDepth::Held;
    let keys = ViewKeys { views: &[1, 0], depth_versions: &[8], keep_reference_depth: None };
    let err = g.start_on_device(&on_device, &[gone], Some(keys), &config).err().expect("refused").to_string();
    assert!(err.contains("source 0") && err.contains("version 8"), "{err}");
    assert!(g.start_on_device(&on_device, &[gone], None, &config).is_err(), "a held depth needs its key");
}

/// Where the host selects (here: an image no patch fits, so the device selection does not
/// apply), the held depth and the reference's depth are read back from the device: the host's
/// visibility statistics are those of the depths given from the host.
#[test]
fn a_host_selection_reads_held_depths_back() {
    let Some((mut g, ctx)) = gpu() else { return };
    let (cams, maps) = scene(8, 6);
    let views = (&cams[..], &maps[..]);
    let config = PhotometricConfig { patch_size: 9, ..Default::default() };
    keep_view_0(&mut g, &ctx, views, &config, 7);
    let held = view_1(&mut g, &ctx, views, &config, true);
    let reference = reference(&cams, &maps, 1);
    let want = gs_mvs::photometric_loss(&reference, &[source(&cams, &maps, 0), source(&cams, &maps, 2)], &config).unwrap();
    assert_eq!(held.1, want.per_source);
    assert!(want.per_source[0].visibility.n_upsilon > 0, "visibility to compare");
}

/// A held depth that a call's own placement drops (grey images larger than the arena's slots
/// start it again, empty) is refused, and forgotten: it never passes for a depth later.
#[test]
fn a_held_depth_dropped_by_larger_slots_is_refused_and_forgotten() {
    let Some((mut g, ctx)) = gpu() else { return };
    let (cams, maps) = scene(64, 48);
    let config = PhotometricConfig::default();
    keep_view_0(&mut g, &ctx, (&cams, &maps), &config, 7);
    let pixels = 64 * 48;
    assert!(g.holds_depth(0, pixels, 7));
    let s = common::box_scene();
    let greys: Vec<gs_core::Image> = cams.iter().map(|c| s.render(&c.resized(128, 96).unwrap()).grey).collect();
    let r = reference(&cams, &maps, 1);
    let surface = gs_mvs::upload_surface(&ctx, &r).unwrap();
    let on_device = SurfaceReference { camera: r.camera, surface: &surface, plane_depth: None, grey: (&greys[1]).into() };
    let held = DeviceSource { camera: &cams[0], plane_depth: SourceDepth::Held, grey: (&greys[0]).into() };
    let keys = ViewKeys { views: &[1, 0], depth_versions: &[7], keep_reference_depth: None };
    let err = g.start_on_device(&on_device, &[held], Some(keys), &config).err().expect("refused").to_string();
    assert!(err.contains("source 0") && err.contains("evicted"), "{err}");
    assert!(!g.holds_depth(0, pixels, 7), "forgotten, not passed off as a depth");
}
