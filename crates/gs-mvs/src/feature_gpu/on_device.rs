//! L_f where the step's other terms already are (docs/architecture.md §GPU): the reference's
//! plane depth is the rendered surface's z, υω of each (source, pixel) is the record L_p made
//! on the device for the same views in the same step ([`DeviceVisibility`]), and the gradient
//! image stays on the device, to be added, times λ4, into the geometry gradient the backward
//! reads ([`FeatureGpu::add_gradient`]). Only each source's totals, with those of L_p's row
//! counts (the visibility statistics), come back: no depth goes to the host, no weight comes up.

use super::reduce::AlignTotals;
use super::{AlignFrame, AlignPair, AlignResult, FeatureGpu, align_frame, gpu_error, pair_record};
use crate::error::{MvsError, Result};
use crate::feature_alignment::{FeatureSourceStats, add_source_sums};
use crate::geometry::PairGeometry;
use crate::photometric_gpu::{DeviceVisibility, VisTexel};
use gs_core::Camera;
use gs_features::FeatureMap;
use gs_gpu::{Bind, Binding, DeviceImage, GeneratedStruct, GpuContext, Kernel, PassUniform, PendingRead, SurfaceTexel, bytes_of};

/// A view of [`FeatureGpu::start_on_device`]: its camera, feature maps and the key they are
/// kept under on the device.
#[derive(Clone, Copy)]
pub struct DeviceAlignView<'a> {
    /// The camera.
    pub camera: &'a Camera,
    /// The feature maps.
    pub features: &'a FeatureMap,
    /// The key of `features` on the device.
    pub key: u64,
}

/// L_f started on the device: its readback and the gradient image the passes write.
pub struct PendingFeatures {
    read: PendingRead,
    sources: usize,
    gradient: DeviceImage,
}

/// What [`FeatureGpu::finish_on_device`] gives: the values, the gradient on the device.
pub struct FeaturesOnDevice {
    /// L_f, averaged over the sources (not multiplied by λ4).
    pub loss: f64,
    /// Each source's statistics.
    pub per_source: Vec<FeatureSourceStats>,
    /// ∂L_f/∂z_r of each reference pixel, `[H][W]` f32 on the device.
    pub gradient: DeviceImage,
}

/// The pair kernel's storage bindings on the device's inputs, by name (slot order): L_p's
/// visibility records and the rendered surface in place of the host's f32 arrays.
const BINDINGS: [Binding<'static>; 5] = [
    Binding::read("pairs", "array<AlignPair>"),
    Binding::read("weights", "array<VisTexel>"),
    Binding::read("depth", "array<SurfaceTexel>"),
    Binding::read("maps", "array<f32>"),
    Binding::write("results", "array<AlignResult>"),
];

/// How the device kernel reads its inputs.
const ACCESS: &str = "fn pair_weight(e: u32) -> f32 { return weights[e].weight; }\nfn ref_depth(p: u32) -> f32 { return depth[p].z; }\n";

/// The apply pass's storage bindings.
const APPLY_BINDINGS: [Binding<'static>; 2] = [Binding::read("gradient", "array<f32>"), Binding::write("sum", "array<f32>")];

fn structs() -> [GeneratedStruct; 5] {
    use gs_gpu::GeneratedStruct as G;
    [G::of::<AlignFrame>(), G::of::<AlignPair>(), G::of::<AlignResult>(), G::of::<VisTexel>(), G::of::<SurfaceTexel>()]
}

fn parts() -> [String; 3] {
    [gs_gpu::declarations(&structs()), ACCESS.into(), include_str!("align.wgsl").into()]
}

fn apply_parts() -> [String; 2] {
    [gs_gpu::declarations(&[GeneratedStruct::of::<AlignFrame>()]), include_str!("apply.wgsl").into()]
}

/// The device kernel's whole WGSL source.
pub fn device_kernel_source() -> String {
    gs_gpu::kernel_source(&parts().each_ref().map(String::as_str), &BINDINGS)
}

/// The apply pass's whole WGSL source.
pub fn apply_kernel_source() -> String {
    gs_gpu::kernel_source(&apply_parts().each_ref().map(String::as_str), &APPLY_BINDINGS)
}

/// The device variant of the pair kernel and the apply pass, compiled once per executor.
pub(super) struct Kernels {
    pair: Kernel,
    apply: Kernel,
}

impl Kernels {
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let pair = Kernel::new(ctx, "align_pair", &parts().each_ref().map(String::as_str), &BINDINGS).map_err(gpu_error)?;
        let apply = Kernel::new(ctx, "align_apply", &apply_parts().each_ref().map(String::as_str), &APPLY_BINDINGS).map_err(gpu_error)?;
        Ok(Self { pair, apply })
    }
}

impl FeatureGpu {
    /// Starts L_f of `reference`, whose rendered surface (gs-gpu `SurfaceTexel`s of its
    /// camera's size) is `surface`, against `sources`, weighing each pair by `visibility`: the
    /// υ/ω L_p made on the device from this surface for these views (`lp_views`: the keys L_p
    /// named them by, the reference's first; `depth_versions`: the sources' depths L_p read).
    /// `None` where it does not apply (another surface's or views' visibility, maps too large
    /// for the arena, a pair result too large for one binding): the caller evaluates L_f from
    /// depths on the host. [`FeatureGpu::finish_on_device`] reads it; the readback shares a
    /// wait with others started on the device before it.
    pub fn start_on_device(
        &mut self,
        (reference, surface): (&DeviceAlignView<'_>, &DeviceImage),
        sources: &[DeviceAlignView<'_>],
        (lp_views, depth_versions): (&[u64], &[u64]),
        visibility: &DeviceVisibility,
    ) -> Result<Option<PendingFeatures>> {
        check_views(reference, surface, sources, &self.ctx)?;
        let (w, h, n) = (surface.width(), surface.height(), sources.len());
        if n == 0 || !visibility.is_of(surface, lp_views, depth_versions) || bytes_of::<AlignResult>(w * h) > self.ctx.max_storage_binding() {
            return Ok(None);
        }
        let maps: Vec<(u64, &FeatureMap)> = std::iter::once(reference).chain(sources).map(|v| (v.key, v.features)).collect();
        let Some(offsets) = self.place_maps(&maps) else {
            return Ok(None);
        };
        let frame = align_frame(reference.camera, reference.features, offsets[0], n);
        let pairs: Vec<AlignPair> =
            sources.iter().zip(&offsets[1..]).map(|(s, &o)| pair_record(&PairGeometry::new(reference.camera, s.camera), s.features, o)).collect();
        let gradient = DeviceImage::new(&self.ctx, "L_f gradient", w, h, 1).map_err(gpu_error)?;
        let total_bytes = self.begin(&frame, &pairs);
        let b = &self.bufs;
        self.pool.ensure(b.staging, total_bytes);
        let p = &self.pool;
        let mut enc = self.disp.encoder();
        enc.encoder.clear_buffer(gradient.buffer(), 0, None);
        self.ctx.push_error_scopes();
        let binds = [p.whole(b.pairs), Bind::whole(&visibility.texels), Bind::whole(surface.buffer()), self.arena.bind(), p.whole(b.results)];
        let recorded = self
            .encode_sources(&mut enc, &frame, &self.device.pair, &binds, Bind::whole(gradient.buffer()))
            .and_then(|_| self.encode_totals(&mut enc, &frame, Some(Bind::whole(&visibility.rows))));
        let staging = p.buffer(b.staging);
        enc.encoder.copy_buffer_to_buffer(p.buffer(b.totals), 0, staging, 0, total_bytes);
        self.disp.submit(enc);
        self.ctx.pop_error_scopes().map_err(gpu_error)?;
        recorded.map_err(gpu_error)?;
        let read = self.ctx.request_read(staging, total_bytes);
        Ok(Some(PendingFeatures { read, sources: n, gradient }))
    }

    /// The values of an evaluation started by [`FeatureGpu::start_on_device`] (one wait,
    /// unless an earlier wait brought them), its gradient image on the device.
    pub fn finish_on_device(&mut self, pending: PendingFeatures) -> Result<FeaturesOnDevice> {
        let PendingFeatures { read, sources, gradient } = pending;
        let totals: Vec<AlignTotals> = self.ctx.finish_read(read, bytemuck::pod_collect_to_vec).map_err(gpu_error)?;
        let mut out = FeaturesOnDevice { loss: 0.0, per_source: Vec::with_capacity(sources), gradient };
        for t in &totals {
            add_source_sums((&mut out.loss, &mut out.per_source), t.visibility(), [t.sums()], sources);
        }
        Ok(out)
    }

    /// `target += weight · gradient`, pixel by pixel on the device (`apply.wgsl`, the host's
    /// `x += w·y`): L_f's gradient image added into the plane-depth gradient the backward
    /// reads, after the terms added there before it. Both are 1-channel images of one size on
    /// this executor's device.
    pub fn add_gradient(&mut self, gradient: &DeviceImage, weight: f32, target: &DeviceImage) -> Result<()> {
        let shape = |i: &DeviceImage| (i.width(), i.height(), i.channels());
        if !gradient.is_on(&self.ctx) || !target.is_on(&self.ctx) || shape(gradient) != shape(target) || gradient.channels() != 1 {
            let words = |i: &DeviceImage| format!("{}×{}×{}", i.width(), i.height(), i.channels());
            return Err(MvsError::InvalidInput(format!(
                "an L_f gradient of {} values added into a plane-depth gradient of {} (1-channel images of one size on one device)",
                words(gradient),
                words(target)
            )));
        }
        let pixels = gradient.len() as u32;
        self.disp.write_frame(&AlignFrame { width: gradient.width() as u32, height: gradient.height() as u32, weight, ..Default::default() });
        let mut enc = self.disp.encoder();
        self.ctx.push_error_scopes();
        let binds = [Bind::whole(gradient.buffer()), Bind::whole(target.buffer())];
        let recorded = self.disp.dispatch_1d(&mut enc, &self.device.apply, &binds, PassUniform { n: pixels, ..Default::default() });
        self.disp.submit(enc);
        self.ctx.pop_error_scopes().map_err(gpu_error)?;
        recorded.map_err(gpu_error)
    }
}

/// Checks the views of a device evaluation: a surface of the reference camera's size on this
/// device, and feature maps with the reference's channels.
fn check_views(reference: &DeviceAlignView<'_>, surface: &DeviceImage, sources: &[DeviceAlignView<'_>], ctx: &GpuContext) -> Result<()> {
    let (w, h) = (reference.camera.width as usize, reference.camera.height as usize);
    if !surface.is_on(ctx) {
        return Err(MvsError::InvalidInput("the reference surface lives on another device".into()));
    }
    if (surface.width(), surface.height(), surface.channels()) != (w, h, gs_gpu::SURFACE_CHANNELS) {
        return Err(MvsError::SizeMismatch {
            map: "reference surface".into(),
            expected: format!("{w}x{h}x{}", gs_gpu::SURFACE_CHANNELS),
            got: format!("{}x{}x{}", surface.width(), surface.height(), surface.channels()),
        });
    }
    let c = reference.features.channels();
    if c == 0 {
        return Err(MvsError::InvalidInput("reference feature maps have no channels".into()));
    }
    if let Some((k, s)) = sources.iter().enumerate().find(|(_, s)| s.features.channels() != c) {
        return Err(MvsError::InvalidInput(format!("source {k} features have {} channels, the reference's have {c}", s.features.channels())));
    }
    Ok(())
}
