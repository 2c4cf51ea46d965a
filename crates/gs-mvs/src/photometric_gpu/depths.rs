//! Plane depths that stay on the device (docs/architecture.md §GPU): a reference's rendered
//! depth (the surface's z) is copied into L_p's arena under its view's key and a version
//! (`keep_depth.wgsl`), so that a later evaluation that takes this view as a source reads it
//! there ([`SourceDepth::Held`]) and it never crosses to the host. The host reads such depths
//! back only where it needs them: a selection made on the host, or the caller's checkpoint
//! ([`PhotometricGpu::held_depths`]).

use super::{DEPTH_PART, PhotometricGpu, ViewKeys, gpu_error};
use crate::error::{MvsError, Result};
use crate::geometry::MapView;
use crate::photometric::PhotometricSource;
use gs_core::Camera;
use gs_gpu::{Bind, Binding, DeviceImage, GeneratedStruct, GpuContext, Kernel, PassUniform};

/// Where a source's plane depth is for [`PhotometricGpu::start_on_device`].
#[derive(Debug, Clone, Copy)]
pub enum SourceDepth<'a> {
    /// On the host, 1 channel of the source camera's size: it goes up into the arena once a
    /// version.
    Host(MapView<'a, f32>),
    /// On the device alone: the arena holds it under the source's key at its version
    /// ([`ViewKeys::depth_versions`]), kept there by an evaluation that had this view as its
    /// reference ([`ViewKeys::keep_reference_depth`]); the source camera's size.
    Held,
}

/// A source view of [`PhotometricGpu::start_on_device`]: as [`PhotometricSource`], with a plane
/// depth that may be on the device alone.
#[derive(Debug, Clone, Copy)]
pub struct DeviceSource<'a> {
    /// Source camera.
    pub camera: &'a Camera,
    /// Its rendered plane depth (for υ and ω only).
    pub plane_depth: SourceDepth<'a>,
    /// Grey GT source image, 1 channel, W_s×H_s or s·W_s × s·H_s.
    pub grey: MapView<'a, f32>,
}

impl<'a> From<PhotometricSource<'a, f32>> for DeviceSource<'a> {
    fn from(s: PhotometricSource<'a, f32>) -> Self {
        Self { camera: s.camera, plane_depth: SourceDepth::Host(s.plane_depth), grey: s.grey }
    }
}

impl<'a> DeviceSource<'a> {
    /// The source as the host's code reads it, with `held` as its depth where that is on the
    /// device alone (an empty view of the camera's size where the caller has not read it back:
    /// only the size is then read, by the device selection).
    pub(super) fn on_host(&self, held: Option<&'a [f32]>) -> PhotometricSource<'a, f32> {
        let (w, h) = (self.camera.width as usize, self.camera.height as usize);
        let plane_depth = match self.plane_depth {
            SourceDepth::Host(d) => d,
            SourceDepth::Held => MapView { width: w, height: h, channels: 1, data: held.unwrap_or(&[]) },
        };
        PhotometricSource { camera: self.camera, plane_depth, grey: self.grey }
    }

    /// Whether its depth is on the device alone.
    pub(super) fn held(&self) -> bool {
        matches!(self.plane_depth, SourceDepth::Held)
    }
}

/// The copy kernel's storage bindings, by name (slot order).
const KEEP_BINDINGS: [Binding<'static>; 2] = [Binding::read("surface", "array<SurfaceTexel>"), Binding::write("greys", "array<f32>")];

/// The copy kernel's parts: the generated record, then `keep_depth.wgsl`.
fn keep_parts() -> [String; 2] {
    [gs_gpu::declarations(&[GeneratedStruct::of::<gs_gpu::SurfaceTexel>()]), include_str!("keep_depth.wgsl").into()]
}

/// The copy kernel's whole WGSL source.
pub fn keep_depth_kernel_source() -> String {
    gs_gpu::kernel_source(&keep_parts().each_ref().map(String::as_str), &KEEP_BINDINGS)
}

/// The copy kernel, compiled once per executor.
pub(super) fn keep_depth_kernel(ctx: &GpuContext) -> Result<Kernel> {
    Kernel::new(ctx, "keep_depth", &keep_parts().each_ref().map(String::as_str), &KEEP_BINDINGS).map_err(gpu_error)
}

impl PhotometricGpu {
    /// Copies `surface`'s plane depth (each texel's z; a rendered surface of gs-gpu
    /// `SurfaceTexel`s on this executor's device) into the arena under `key` at `version`,
    /// where a later evaluation finds it as a [`SourceDepth::Held`] (e.g. a source view's depth
    /// rendered for a step); `false` when the arena cannot take it (nothing is then kept).
    pub fn keep_depth(&mut self, surface: &DeviceImage, key: u64, version: u64) -> Result<bool> {
        if !surface.is_on(&self.ctx) || surface.channels() != gs_gpu::SURFACE_CHANNELS {
            return Err(MvsError::InvalidInput(format!("a depth to keep from a {}-channel image of another device or kind", surface.channels())));
        }
        let floats = surface.width() * surface.height();
        let Some(offset) = self.greys.place_filled(&self.ctx, (key, DEPTH_PART), floats, version) else {
            return Ok(false);
        };
        let mut enc = self.disp.encoder();
        self.ctx.push_error_scopes();
        let binds = [Bind::whole(surface.buffer()), self.greys.bind()];
        let pass = PassUniform { n: floats as u32, base: offset, ..Default::default() };
        self.disp.dispatch_1d(&mut enc, &self.keep, &binds, pass).map_err(gpu_error)?;
        self.disp.submit(enc);
        self.ctx.pop_error_scopes().map_err(gpu_error)?;
        Ok(true)
    }

    /// Whether the arena holds the plane depth of the view named `key` (`floats` values) at
    /// `version`, e.g. one kept by [`ViewKeys::keep_reference_depth`].
    pub fn holds_depth(&self, key: u64, floats: usize, version: u64) -> bool {
        self.greys.holds((key, DEPTH_PART), floats, version)
    }

    /// Whether the arena can hold the grey image and the plane depth of `views` views at once
    /// (each at most `floats` values): a caller that keys at most that many views never loses
    /// a depth held on the device alone to an eviction.
    pub fn holds_every_view(&self, views: usize, floats: usize) -> bool {
        self.greys.capacity(&self.ctx, floats) >= 2 * views
    }

    /// The plane depths held under each `(key, floats, version)` of `items`, read back at one
    /// wait (`None` where the arena does not hold it): what the host keeps of depths that stayed
    /// on the device (a checkpoint, a host selection).
    pub fn held_depths(&self, items: &[(u64, usize, u64)]) -> Result<Vec<Option<Vec<f32>>>> {
        let items: Vec<_> = items.iter().map(|&(key, floats, version)| ((key, DEPTH_PART), floats, version)).collect();
        self.greys.read_held(&self.ctx, &items).map_err(gpu_error)
    }

    /// The held depths of `sources` (in order; `None` for a depth on the host), read back for a
    /// selection on the host; an error names a source whose depth the arena no longer holds.
    pub(super) fn read_back_held(&self, sources: &[DeviceSource<'_>], keys: Option<ViewKeys<'_>>) -> Result<Vec<Option<Vec<f32>>>> {
        let held: Vec<usize> = (0..sources.len()).filter(|&k| sources[k].held()).collect();
        let Some(keys) = keys.filter(|_| !held.is_empty()) else {
            return Ok(vec![None; sources.len()]);
        };
        let items: Vec<_> = held.iter().map(|&k| (keys.views[k + 1], pixels(sources[k].camera), keys.depth_versions[k])).collect();
        let mut read = self.held_depths(&items)?.into_iter();
        let mut out = vec![None; sources.len()];
        for &k in &held {
            out[k] = Some(read.next().flatten().ok_or_else(|| not_held(k, keys.depth_versions[k]))?);
        }
        Ok(out)
    }

    /// Checks that the arena holds every held depth of `sources` at its version.
    pub(super) fn check_held(&self, sources: &[DeviceSource<'_>], keys: Option<ViewKeys<'_>>) -> Result<()> {
        for (k, s) in sources.iter().enumerate().filter(|(_, s)| s.held()) {
            let Some(keys) = keys else {
                return Err(MvsError::InvalidInput(format!("source {k}'s plane depth is held on the device, but no view keys name it")));
            };
            if !self.holds_depth(keys.views[k + 1], pixels(s.camera), keys.depth_versions[k]) {
                return Err(not_held(k, keys.depth_versions[k]));
            }
        }
        Ok(())
    }
}

/// The pixels of `camera` (a plane depth's values).
fn pixels(camera: &Camera) -> usize {
    camera.width as usize * camera.height as usize
}

fn not_held(k: usize, version: u64) -> MvsError {
    MvsError::InvalidInput(format!("source {k}'s plane depth (version {version}) is not held on the device"))
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_copy_kernel_matches_its_records() {
        let src = super::keep_depth_kernel_source();
        gs_gpu::check_layouts(&[gs_gpu::GeneratedStruct::of::<gs_gpu::SurfaceTexel>()], &src).unwrap();
        gs_gpu::validate_kernel(&src).unwrap_or_else(|e| panic!("{e}"));
    }
}
