//! What a wgpu render brings back: where each requested output lies in its staging buffer,
//! the copies into it, and the [`RenderOutput`] made from its bytes (a colour, surface or plane
//! depth kept on the device is not read back).

use super::kernels::{COUNTER_LONGEST_BLEND, COUNTER_LONGEST_TILE_LIST};
use super::{GpuState, WgpuRasterizer};
use crate::cpu::project::CamParams;
use crate::{ForwardState, RasterConfig, RasterError, RenderOutput, RenderRequest, RenderStats, Result, StateInner};
use gs_core::{Gaussians, Image};
use gs_gpu::{BufId, DeviceImage, Encoder};
use rayon::prelude::*;

/// Where each forward output lies in its staging buffer (`None`: not read back).
pub(super) struct Readback {
    /// The staging buffer the outputs are copied to (the rasterizer's own, or one of a batch).
    pub(super) staging: BufId,
    /// Accumulator planes read back (colour 0..3, Ñ and D 3..7, depth sum 7).
    pub(super) planes: Vec<usize>,
    pub(super) radii: Option<u64>,
    pub(super) final_t: Option<u64>,
    pub(super) last: Option<u64>,
    pub(super) counters: u64,
    pub(super) observed: u64,
    pub(super) planes_at: u64,
    /// The plane depth made on the device ([`device_plane_depth`]).
    pub(super) plane_depth: Option<u64>,
    /// The colour kept on the device ([`RenderRequest::color_on_device`]): written there, not
    /// read back.
    pub(super) colour: Option<DeviceImage>,
    /// The surface (z, Ñ, D, A) kept on the device as well ([`RenderRequest::surface_on_device`]).
    pub(super) surface: Option<DeviceImage>,
    pub(super) bytes: u64,
}

/// Whether a render's plane depth is made on the device and read back alone: plane depth
/// without the normal, the distance or the expected depth (a source view's depth, the
/// mesher's), so one plane comes back instead of the four it is made of.
fn device_plane_depth(request: &RenderRequest) -> bool {
    request.plane_depth && !request.normal && !request.distance && !request.expected_depth
}

impl Readback {
    /// Where the outputs of `request` go for `n` Gaussians and `npix` pixels, into `staging`
    /// except the `colour` kept on the device (given when the request keeps it there); the
    /// `surface` goes to the device as well.
    pub(super) fn new(request: &RenderRequest, n: u64, npix: u64, staging: BufId, (colour, surface): (Option<DeviceImage>, Option<DeviceImage>)) -> Self {
        // A plane depth kept in the surface does not come back.
        let request = &request.host_outputs();
        let mut planes = Vec::new();
        let host_colour = request.color && colour.is_none();
        if host_colour {
            planes.extend(0..3);
        }
        // Plane depth alone comes back as one plane made on the device.
        let depth_alone = device_plane_depth(request);
        if request.geo() && !depth_alone {
            planes.extend(3..7);
        }
        if request.expected_depth {
            planes.push(7);
        }
        let mut at = 0u64;
        let mut place = |wanted: bool, bytes: u64| {
            wanted.then(|| {
                at += bytes;
                at - bytes
            })
        };
        let radii = place(request.radii, (n * 4).next_multiple_of(8));
        // T_final makes the colour (background), the alpha and the expected depth; the
        // plane depth, normal and distance need neither it nor the last contributors.
        let final_t = place(request.traversal || host_colour || request.alpha || request.expected_depth, npix * 4);
        let last = place(request.traversal, npix * 4);
        let counters = at;
        let observed = counters + 64;
        let obs_bytes = if request.observed_back() { n * 4 } else { 0 };
        let planes_at = (observed + obs_bytes).next_multiple_of(8);
        let depth_at = planes_at + planes.len() as u64 * npix * 4;
        let plane_depth = depth_alone.then_some(depth_at);
        let bytes = depth_at + if depth_alone { npix * 4 } else { 0 };
        Self { staging, planes, radii, final_t, last, counters, observed, planes_at, plane_depth, colour, surface, bytes }
    }
}

impl WgpuRasterizer {
    /// The [`Readback`] of a render of `request` on `cam` into `staging`, with new device
    /// images for its colour and its surface where the request keeps them on the device.
    pub(super) fn readback(&self, request: &RenderRequest, cam: &CamParams, n: u64, staging: BufId) -> Result<Readback> {
        let (w, h) = (cam.width as usize, cam.height as usize);
        let image = |wanted: bool, label, channels| match wanted {
            true => DeviceImage::new(&self.ctx, label, w, h, channels).map(Some).map_err(|e| RasterError::Gpu(e.to_string())),
            false => Ok(None),
        };
        let colour = image(request.color && request.color_on_device, "rendered colour", 3)?;
        let surface_wanted = request.surface_on_device && request.geo();
        let surface = image(surface_wanted, "rendered surface", gs_gpu::SURFACE_CHANNELS)?;
        Ok(Readback::new(request, n, (w * h) as u64, staging, (colour, surface)))
    }
}

impl WgpuRasterizer {
    /// Copies T_final, last contributors, counters, observed counts and the requested planes
    /// to the staging buffer.
    pub(super) fn copy_outputs(
        &self,
        enc: &mut Encoder,
        cam: &CamParams,
        request: &RenderRequest,
        bands: &[(u32, u32, u64, u64)],
        n: u32,
        rb: &Readback,
    ) {
        let (p, b) = (&self.pool, &self.bufs);
        let npix = cam.width as u64 * cam.height as u64;
        let nn = n as u64;
        let staging = p.buffer(rb.staging);
        let e = &mut enc.encoder;
        if let Some(at) = rb.final_t {
            e.copy_buffer_to_buffer(p.buffer(b.final_t), 0, staging, at, npix * 4);
        }
        if let Some(at) = rb.last {
            e.copy_buffer_to_buffer(p.buffer(b.last), 0, staging, at, npix * 4);
        }
        e.copy_buffer_to_buffer(p.buffer(b.counters), 0, staging, rb.counters, 64);
        if let Some(at) = rb.plane_depth {
            e.copy_buffer_to_buffer(p.buffer(b.depth_plane), 0, staging, at, npix * 4);
        }
        if request.observed_back() && nn > 0 {
            e.copy_buffer_to_buffer(p.buffer(b.observed), 0, staging, rb.observed, nn * 4);
        }
        self.copy_planes(enc, &rb.planes, bands, npix, (rb.staging, rb.planes_at));
    }

    /// Copies the accumulator `planes` (band-planar on the device) whole and in order to the
    /// staging buffer `staging` from byte `at`, each `npix` values.
    pub(super) fn copy_planes(&self, enc: &mut Encoder, planes: &[usize], bands: &[(u32, u32, u64, u64)], npix: u64, (staging, at): (BufId, u64)) {
        let (p, b) = (&self.pool, &self.bufs);
        let e = &mut enc.encoder;
        for (k, &plane) in planes.iter().enumerate() {
            for &(_, _, p0, bp) in bands {
                e.copy_buffer_to_buffer(p.buffer(b.acc), p0 * 32 + plane as u64 * bp * 4, p.buffer(staging), at + (k as u64 * npix + p0) * 4, bp * 4);
            }
        }
    }

    /// Builds the [`RenderOutput`] (images, radii, counters, device-state handle) from the
    /// staging bytes, with the longest list position any pixel blended (the backward's
    /// window count).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn forward_output(
        &self,
        g: &Gaussians,
        cam: &CamParams,
        config: &RasterConfig,
        request: &RenderRequest,
        rb: &Readback,
        bytes: &[u8],
        visible: usize,
        total: u32,
    ) -> Result<(RenderOutput, u32)> {
        let n = g.len();
        let npix = cam.width as usize * cam.height as usize;
        let u32s = |off: u64, count: usize| -> Vec<u32> {
            bytemuck::pod_collect_to_vec(&bytes[off as usize..off as usize + count * 4])
        };
        let f32s = |off: u64, count: usize| -> Vec<f32> {
            bytemuck::pod_collect_to_vec(&bytes[off as usize..off as usize + count * 4])
        };
        let radii = rb.radii.map_or_else(Vec::new, |at| u32s(at, n));
        let mut acc = vec![[0.0f32; 8]; npix];
        // Without intersections nothing was blended: T = 1 and no contributor anywhere.
        let (final_t, last, counters, observed) = if total > 0 {
            for (k, &p) in rb.planes.iter().enumerate() {
                let plane = f32s(rb.planes_at + k as u64 * npix as u64 * 4, npix);
                acc.par_iter_mut().zip(plane).for_each(|(a, v)| a[p] = v);
            }
            (
                rb.final_t.map_or_else(Vec::new, |at| f32s(at, npix)),
                rb.last.map_or_else(Vec::new, |at| u32s(at, npix)),
                counters_of(bytes, rb),
                request.observed_back().then(|| u32s(rb.observed, n)),
            )
        } else {
            (
                rb.final_t.map_or_else(Vec::new, |_| vec![1.0; npix]),
                rb.last.map_or_else(Vec::new, |_| vec![0; npix]),
                vec![0; 16],
                request.observed_back().then(|| vec![0; n]),
            )
        };
        // A colour kept on the device is not assembled here.
        let on_host = RenderRequest { color: request.color && rb.colour.is_none(), ..request.host_outputs() };
        let mut out = crate::pixel::assemble(cam, config, &on_host, &acc, &final_t)?;
        out.device_color = rb.colour.clone();
        out.device_surface = rb.surface.clone();
        // The device's plane depth replaces the one assembled from planes that did not come
        // back (without intersections both are 0).
        if let Some(at) = rb.plane_depth.filter(|_| total > 0) {
            let plane = f32s(at, npix);
            out.plane_depth = Some(Image::from_vec(cam.width as usize, cam.height as usize, 1, plane).map_err(|e| RasterError::InvalidCamera(e.to_string()))?);
        }
        out.radii = radii;
        out.observed = observed;
        out.stats = RenderStats {
            visible,
            intersections: total as usize,
            forward_pairs: counters[4] as u64 | (counters[5] as u64) << 32,
            backward_pairs: counters[6] as u64 | (counters[7] as u64) << 32,
            box_pairs: 0,
        };
        let geo = if (on_host.plane_depth || request.expected_depth) && rb.plane_depth.is_none() {
            acc.par_iter().map(|a| [a[3], a[4], a[5], a[6], a[7]]).collect()
        } else {
            Vec::new()
        };
        out.state = ForwardState(StateInner::Gpu(GpuState {
            rasterizer: self.id,
            generation: self.generation,
            n,
            width: cam.width,
            height: cam.height,
            request: *request,
            total,
            final_t: final_t.clone(),
            geo,
        }));
        out.final_t = final_t;
        out.last_contributor = last;
        Ok((out, counters[COUNTER_LONGEST_BLEND]))
    }
}

/// The 16 counters in the staging bytes of a render that copied them.
pub(super) fn counters_of(bytes: &[u8], rb: &Readback) -> Vec<u32> {
    bytemuck::pod_collect_to_vec(&bytes[rb.counters as usize..rb.counters as usize + 64])
}

/// The longest tile list of a render with `total` intersections (its counters come back only
/// when it has any).
pub(super) fn longest_tile_list(bytes: &[u8], rb: &Readback, total: u64) -> u32 {
    if total == 0 {
        return 0;
    }
    counters_of(bytes, rb)[COUNTER_LONGEST_TILE_LIST]
}
