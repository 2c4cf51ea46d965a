//! An image that stays on the device between the kernels of two crates (docs/architecture.md
//! §GPU): the rasterizer writes its rendered colour into one, the image loss reads it and
//! writes its gradient into another, which the rasterizer's backward reads. Nothing crosses to
//! the host unless [`DeviceImage::read`] is called. The layout is that of gs-core's host
//! `Image`: row-major `[H][W][C]` f32.
//!
//! Each image owns its buffer (no pool aliasing): a later render or loss evaluation cannot
//! overwrite an image that someone still holds.

use crate::{GpuContext, GpuError, Result};

crate::wgsl_struct! {
    /// One pixel of a rendered surface as the per-pixel losses read it (WGSL `struct
    /// SurfaceTexel`): the rasterizer writes a [`DeviceImage`] of these (6 channels, in this
    /// order), gs-losses' normal terms (z, Ñ, A) and gs-mvs' L_p (Ñ, D) bind it as
    /// `array<SurfaceTexel>`. 24 bytes.
    pub struct SurfaceTexel as "SurfaceTexel" {
        /// The plane depth z.
        z: f32,
        /// The rendered normal Ñ.
        normal: [f32; 3],
        /// The rendered distance D.
        distance: f32,
        /// The accumulated alpha A = 1 − T_final.
        alpha: f32,
    }
}

crate::wgsl_struct! {
    /// One pixel's gradient of a loss with respect to the rendered plane (WGSL `struct
    /// PlaneGrad`): ∂/∂Ñ and ∂/∂D. gs-mvs' L_p writes a [`DeviceImage`] of these (4 channels,
    /// in this order) and the rasterizer's backward reads it. 16 bytes.
    pub struct PlaneGrad as "PlaneGrad" {
        /// ∂/∂Ñ.
        n: [f32; 3],
        /// ∂/∂D.
        d: f32,
    }
}

/// Values of one [`PlaneGrad`]: the channel count of a plane-gradient [`DeviceImage`].
pub const PLANE_GRAD_CHANNELS: usize = std::mem::size_of::<PlaneGrad>() / 4;

/// Values of one [`SurfaceTexel`]: the channel count of a surface [`DeviceImage`].
pub const SURFACE_CHANNELS: usize = std::mem::size_of::<SurfaceTexel>() / 4;

/// `width · height · channels` f32 values on one device, row-major `[H][W][C]`.
#[derive(Clone)]
pub struct DeviceImage {
    buffer: wgpu::Buffer,
    device: wgpu::Device,
    width: usize,
    height: usize,
    channels: usize,
}

impl std::fmt::Debug for DeviceImage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "DeviceImage({}×{}×{})", self.width, self.height, self.channels)
    }
}

impl DeviceImage {
    /// A new image of `width × height × channels` values on `ctx`'s device (contents
    /// unspecified until a kernel or copy writes them), or an error when it is empty or larger
    /// than one storage binding.
    pub fn new(ctx: &GpuContext, label: &'static str, width: usize, height: usize, channels: usize) -> Result<Self> {
        let n = width.checked_mul(height).and_then(|p| p.checked_mul(channels));
        let bytes = n.and_then(|n| u64::try_from(n).ok()?.checked_mul(4));
        let Some(bytes) = bytes.filter(|&b| b > 0 && b <= ctx.max_storage_binding()) else {
            return Err(GpuError::Device(format!(
                "a device image of {width}×{height}×{channels} values is empty or larger than one storage binding ({} bytes)",
                ctx.max_storage_binding()
            )));
        };
        let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let buffer = ctx.device().create_buffer(&wgpu::BufferDescriptor { label: Some(label), size: bytes, usage, mapped_at_creation: false });
        Ok(Self { buffer, device: ctx.device().clone(), width, height, channels })
    }

    /// A new image holding `values` (`width · height · channels` of them, written through the
    /// queue and counted in the context's ledger).
    pub fn upload(ctx: &GpuContext, label: &'static str, (width, height, channels): (usize, usize, usize), values: &[f32]) -> Result<Self> {
        let image = Self::new(ctx, label, width, height, channels)?;
        if values.len() != image.len() {
            return Err(GpuError::Device(format!("{} values given for a device image of {width}×{height}×{channels}", values.len())));
        }
        ctx.write_buffer(&image.buffer, 0, bytemuck::cast_slice(values));
        Ok(image)
    }

    /// Its buffer (bind it whole, or copy from it).
    pub fn buffer(&self) -> &wgpu::Buffer {
        &self.buffer
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Values per pixel.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Values in all (`width · height · channels`).
    pub fn len(&self) -> usize {
        self.width * self.height * self.channels
    }

    /// Whether it holds no value (never: [`DeviceImage::new`] refuses empty images).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Bytes it holds.
    pub fn bytes(&self) -> u64 {
        4 * self.len() as u64
    }

    /// The binding of its pixels `first .. first + count` (a band of rows, for a kernel that
    /// works band by band).
    pub fn pixels(&self, first: u64, count: u64) -> crate::Bind<'_> {
        let texel = 4 * self.channels as u64;
        crate::Bind::range(&self.buffer, first * texel, count * texel)
    }

    /// Whether it lives on `ctx`'s device (an image of another device cannot be bound there).
    pub fn is_on(&self, ctx: &GpuContext) -> bool {
        &self.device == ctx.device()
    }

    /// Its values on the host (one round trip, counted in the context's ledger): for tests and
    /// for the rare caller that needs them there after all.
    pub fn read(&self, ctx: &GpuContext) -> Result<Vec<f32>> {
        if !self.is_on(ctx) {
            return Err(GpuError::Device("a device image read through another device's context".into()));
        }
        Ok(bytemuck::pod_collect_to_vec(&ctx.download(&self.buffer, 0, self.bytes())?))
    }
}
