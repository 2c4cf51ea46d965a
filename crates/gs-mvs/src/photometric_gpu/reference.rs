//! The reference view of a device L_p evaluation: its rendered plane (Ñ, D) given on the host,
//! or kept on the device in the rasterizer's surface image, so that it never crosses to the
//! host (docs/architecture.md §GPU). Where the host selects L_p's pixels (υ/ω, the pixel
//! selection) it reads the plane depth, from the surface if it does not have it.

use super::gpu_error;
use crate::error::{MvsError, Result};
use crate::geometry::MapView;
use crate::photometric::{PhotometricOutput, PhotometricReference, PhotometricSource, check_inputs, check_views, photometric_loss};
use gs_core::Camera;
use gs_gpu::{DeviceImage, GpuContext, SURFACE_CHANNELS, SurfaceTexel};

/// The reference view of [`super::PhotometricGpu::start_on_device`]: as
/// [`PhotometricReference`], with the rendered Ñ and D in a surface image on the device.
#[derive(Debug, Clone, Copy)]
pub struct SurfaceReference<'a> {
    /// Reference camera.
    pub camera: &'a Camera,
    /// The rendered surface: gs-gpu `SurfaceTexel`s of the camera's size (Ñ and D are read).
    pub surface: &'a DeviceImage,
    /// Plane depth, 1 channel, where the host has it; `None` reads the surface's z: on the
    /// device where υ, ω and the selection run there, and read back where the host selects.
    pub plane_depth: Option<MapView<'a, f32>>,
    /// Grey GT reference image, 1 channel, W×H or s·W × s·H.
    pub grey: MapView<'a, f32>,
}

/// Where a reference's rendered plane (Ñ, D) is.
#[derive(Clone, Copy)]
pub(super) enum Plane<'a> {
    Host { normal: MapView<'a, f32>, distance: MapView<'a, f32> },
    Device(&'a DeviceImage),
}

/// What an evaluation reads of its reference. A plane depth the host does not have
/// ([`SurfaceReference::plane_depth`] `None`) is an empty view of the camera's size: the device
/// selection reads the surface's z, and the host's code gets it from
/// [`RefView::surface_depth`] first.
#[derive(Clone, Copy)]
pub(super) struct RefView<'a> {
    pub camera: &'a Camera,
    pub plane_depth: MapView<'a, f32>,
    pub grey: MapView<'a, f32>,
    pub plane: Plane<'a>,
}

impl<'a> RefView<'a> {
    /// A host reference.
    pub fn of_host(r: &PhotometricReference<'a, f32>) -> Self {
        Self { camera: r.camera, plane_depth: r.plane_depth, grey: r.grey, plane: Plane::Host { normal: r.normal, distance: r.distance } }
    }

    /// A reference whose plane is on `ctx`'s device; an error names a surface of another
    /// device, size or channel count.
    pub fn of_device(r: &SurfaceReference<'a>, ctx: &GpuContext) -> Result<Self> {
        let s = r.surface;
        let (w, h) = (r.camera.width as usize, r.camera.height as usize);
        if !s.is_on(ctx) {
            return Err(MvsError::InvalidInput("the reference surface lives on another device".into()));
        }
        if (s.width(), s.height(), s.channels()) != (w, h, SURFACE_CHANNELS) {
            return Err(MvsError::SizeMismatch {
                map: "reference surface".into(),
                expected: format!("{w}x{h}x{SURFACE_CHANNELS}"),
                got: format!("{}x{}x{}", s.width(), s.height(), s.channels()),
            });
        }
        let plane_depth = r.plane_depth.unwrap_or(MapView { width: w, height: h, channels: 1, data: &[] });
        Ok(Self { camera: r.camera, plane_depth, grey: r.grey, plane: Plane::Device(s) })
    }

    /// The plane depth of a reference whose plane is on the device (its surface's z), read
    /// back; an error for a plane on the host.
    pub fn surface_depth(&self, ctx: &GpuContext) -> Result<Vec<f32>> {
        let Plane::Device(surface) = self.plane else {
            return Err(MvsError::InvalidInput("a plane on the host has no surface to read".into()));
        };
        surface_depth(ctx, surface)
    }

    /// The checks of [`photometric_loss`]'s inputs.
    pub fn check(&self, sources: &[PhotometricSource<'_, f32>], config: &crate::PhotometricConfig) -> Result<()> {
        match self.plane {
            Plane::Host { normal, distance } => check_inputs(&self.with_plane(normal, distance), sources, config),
            Plane::Device(_) => check_views((self.camera, &self.plane_depth, &self.grey), sources, config),
        }
    }

    /// L_p on the host (the reference), for what the device cannot hold: a plane on the device
    /// is read back first (one round trip).
    pub fn host_loss(&self, ctx: &GpuContext, sources: &[PhotometricSource<'_, f32>], config: &crate::PhotometricConfig) -> Result<PhotometricOutput<f32>> {
        match self.plane {
            Plane::Host { normal, distance } => photometric_loss(&self.with_plane(normal, distance), sources, config),
            Plane::Device(surface) => {
                let texels = read_texels(ctx, surface)?;
                let normal: Vec<f32> = texels.iter().flat_map(|t| t.normal).collect();
                let distance: Vec<f32> = texels.iter().map(|t| t.distance).collect();
                let z: Vec<f32> = texels.iter().map(|t| t.z).collect();
                let (w, h) = (surface.width(), surface.height());
                let mut reference = self.with_plane(MapView::new(w, h, 3, &normal)?, MapView::new(w, h, 1, &distance)?);
                if reference.plane_depth.data.is_empty() {
                    reference.plane_depth = MapView::new(w, h, 1, &z)?;
                }
                photometric_loss(&reference, sources, config)
            }
        }
    }

    /// The host reference with this view's camera, plane depth and grey image.
    fn with_plane<'b>(&self, normal: MapView<'b, f32>, distance: MapView<'b, f32>) -> PhotometricReference<'b, f32>
    where
        'a: 'b,
    {
        PhotometricReference { camera: self.camera, normal, distance, plane_depth: self.plane_depth, grey: self.grey }
    }
}

/// The plane depth (each texel's z) of a rendered surface on `ctx`'s device (gs-gpu
/// `SurfaceTexel`s), read back.
pub fn surface_depth(ctx: &GpuContext, surface: &DeviceImage) -> Result<Vec<f32>> {
    Ok(read_texels(ctx, surface)?.iter().map(|t| t.z).collect())
}

/// The texels of a surface on the device, read back.
fn read_texels(ctx: &GpuContext, surface: &DeviceImage) -> Result<Vec<SurfaceTexel>> {
    Ok(bytemuck::pod_collect_to_vec(&ctx.download(surface.buffer(), 0, surface.bytes()).map_err(gpu_error)?))
}

/// A host reference's rendered surface as a device image of `SurfaceTexel`s (plane depth z,
/// Ñ, D; A 0), the record the rasterizer keeps it in: what [`SurfaceReference::surface`] binds,
/// for a caller whose planes are on the host (tests, benches).
pub fn upload_surface(ctx: &GpuContext, reference: &PhotometricReference<'_, f32>) -> Result<DeviceImage> {
    let mut texels = plane_texels(&reference.normal, &reference.distance);
    if reference.plane_depth.data.len() != texels.len() {
        return Err(MvsError::InvalidInput(format!("a plane depth of {} values for {} pixels", reference.plane_depth.data.len(), texels.len())));
    }
    texels.iter_mut().zip(reference.plane_depth.data).for_each(|(t, &z)| t.z = z);
    let (w, h) = (reference.normal.width, reference.normal.height);
    DeviceImage::upload(ctx, "L_p reference surface", (w, h, SURFACE_CHANNELS), bytemuck::cast_slice(&texels)).map_err(gpu_error)
}

/// The surface records of a host plane (Ñ and D; the plane depth and A, which L_p does not
/// read, 0).
pub(super) fn plane_texels(normal: &MapView<'_, f32>, distance: &MapView<'_, f32>) -> Vec<SurfaceTexel> {
    let normals: &[[f32; 3]] = bytemuck::cast_slice(normal.data);
    normals.iter().zip(distance.data).map(|(&n, &d)| SurfaceTexel { z: 0.0, normal: n, distance: d, alpha: 0.0 }).collect()
}
