//! The loss terms' device executors, passed to the terms explicitly through
//! [`crate::terms::TermInputs`] (docs/architecture.md §GPU): L_p's patches
//! ([`gs_mvs::PhotometricGpu`]), L_f's feature alignment ([`gs_mvs::FeatureGpu`]), L_I
//! ([`gs_losses::ImageLossGpu`]: L1, D-SSIM and the edge term), L_nc with L_ns
//! ([`gs_losses::NormalGpu`]) and L_f's VGG16 maps of each view ([`gs_features::Vgg16Gpu`]), on
//! the wgpu rasterizer's own device (one context, cloned).
//! Without the `wgpu` feature there are none and the CPU reference evaluates every term.

/// Which of the terms with a device kernel built only for the runs that use them a run
/// uses: L_p and L_f.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TermsUsed {
    /// L_p runs in some phase.
    pub photometric: bool,
    /// L_f runs in some phase ([`crate::TrainConfig::has_feature_phase`]).
    pub features: bool,
    /// Exposure compensation is on ([`crate::TrainConfig::exposure`]).
    pub exposure: bool,
}

impl TermsUsed {
    /// The terms `config` uses.
    pub fn of(config: &crate::TrainConfig) -> Self {
        Self { photometric: config.losses.photometric, features: config.has_feature_phase(), exposure: config.exposure }
    }
}

/// The device executors of one run (each `None` where its term runs on the CPU).
#[derive(Debug, Default)]
pub struct LossDevices {
    /// L_p's patches.
    #[cfg(feature = "wgpu")]
    pub photometric: Option<std::cell::RefCell<gs_mvs::PhotometricGpu>>,
    /// L_f's feature alignment.
    #[cfg(feature = "wgpu")]
    pub features: Option<std::cell::RefCell<gs_mvs::FeatureGpu>>,
    /// L_I (L1, D-SSIM and the edge term).
    #[cfg(feature = "wgpu")]
    pub image: Option<std::cell::RefCell<gs_losses::ImageLossGpu>>,
    /// L_nc and L_ns.
    #[cfg(feature = "wgpu")]
    pub normal: Option<std::cell::RefCell<gs_losses::NormalGpu>>,
    /// L_f's VGG16 feature maps (once a view), on a hardware adapter only.
    #[cfg(feature = "wgpu")]
    pub vgg: Option<std::cell::RefCell<gs_features::Vgg16Gpu>>,
    /// The exposure correction before L_I and its backward.
    #[cfg(feature = "wgpu")]
    pub exposure: Option<std::cell::RefCell<gs_losses::ExposureGpu>>,
    /// The adapter they run on, in words.
    adapter: Option<String>,
    /// Their device (to read back an image one of them kept there).
    #[cfg(feature = "wgpu")]
    context: Option<gs_gpu::GpuContext>,
}

impl LossDevices {
    /// The executors on the device of `rasterizer` when it runs on wgpu (L_p's and L_f's only
    /// when the run uses them); none for the CPU rasterizer. An error names the kernel that
    /// failed to build.
    pub(crate) fn for_rasterizer(rasterizer: &gs_raster::Rasterizer, uses: TermsUsed) -> Result<Self, String> {
        #[cfg(feature = "wgpu")]
        if let Some(ctx) = rasterizer.gpu_context() {
            let photometric = match uses.photometric {
                true => Some(gs_mvs::PhotometricGpu::new(ctx).map_err(|e| format!("L_p: {e}"))?.into()),
                false => None,
            };
            let (features, vgg) = match uses.features {
                true => {
                    // On a software adapter the device is this CPU, where the host's extractor is
                    // about 100 times faster than the kernels (BENCHMARKS.md, stop 62).
                    let vgg = match ctx.is_software() {
                        true => None,
                        false => {
                            let net = gs_features::Vgg16::bundled().map_err(|e| format!("L_f's VGG16: {e}"))?;
                            Some(gs_features::Vgg16Gpu::new(ctx, &net).map_err(|e| format!("L_f's VGG16: {e}"))?.into())
                        }
                    };
                    (Some(gs_mvs::FeatureGpu::new(ctx).map_err(|e| format!("L_f: {e}"))?.into()), vgg)
                }
                false => (None, None),
            };
            let image = Some(gs_losses::ImageLossGpu::new(ctx).map_err(|e| format!("L_I: {e}"))?.into());
            let normal = Some(gs_losses::NormalGpu::new(ctx).map_err(|e| format!("L_nc and L_ns: {e}"))?.into());
            let exposure = match uses.exposure {
                true => Some(gs_losses::ExposureGpu::new(ctx).map_err(|e| format!("exposure compensation: {e}"))?.into()),
                false => None,
            };
            return Ok(Self { photometric, features, image, normal, vgg, exposure, adapter: Some(ctx.description()), context: Some(ctx.clone()) });
        }
        let _ = (rasterizer, uses);
        Ok(Self::default())
    }

    /// L_I of `rendered` against the photo `gt` of training slot `slot`: started on the device
    /// when there is an executor for it (which keeps each slot's photo and guide there, by
    /// `view_key`), else [`gs_losses::image_loss()`] (the reference), made at once.
    pub fn start_image_loss<'d>(
        &'d self,
        rendered: &gs_core::Image,
        gt: &gs_core::Image,
        guide: Option<&gs_losses::EdgeGuide>,
        slot: usize,
        cfg: &gs_losses::ImageLossConfig,
    ) -> gs_losses::Result<Deferred<'d, gs_losses::ImageLossOutput, gs_losses::LossError>> {
        #[cfg(feature = "wgpu")]
        if let Some(d) = &self.image {
            let pending = d.borrow_mut().start(rendered, gt, guide, Some(view_key(slot, gt.width(), gt.height())), cfg)?;
            return Ok(Deferred::later(move || d.borrow_mut().finish(pending)));
        }
        #[cfg(not(feature = "wgpu"))]
        let _ = slot;
        Ok(Deferred::ready(gs_losses::image_loss(rendered, gt, guide, cfg)?))
    }

    /// [`LossDevices::start_image_loss`] of a rendered colour kept on the device (the wgpu
    /// rasterizer's, which must be this executor's device): its gradient stays there.
    #[cfg(feature = "wgpu")]
    pub fn start_image_loss_on_device<'d>(
        &'d self,
        rendered: &gs_gpu::DeviceImage,
        gt: &gs_core::Image,
        guide: Option<&gs_losses::EdgeGuide>,
        slot: usize,
        cfg: &gs_losses::ImageLossConfig,
    ) -> gs_losses::Result<Deferred<'d, gs_losses::ImageLossOutput<gs_gpu::DeviceImage>, gs_losses::LossError>> {
        let Some(d) = &self.image else {
            return Err(gs_losses::LossError::Device("a rendered colour on the device but no L_I kernels there".into()));
        };
        let pending = d.borrow_mut().start_on_device(rendered, gt, guide, Some(view_key(slot, gt.width(), gt.height())), cfg)?;
        Ok(Deferred::later(move || d.borrow_mut().finish_on_device(pending)))
    }

    /// Whether L_I runs on the device, so that a render's colour may stay there
    /// ([`gs_raster::RenderRequest::color_on_device`]).
    pub fn image_on_device(&self) -> bool {
        #[cfg(feature = "wgpu")]
        return self.image.is_some();
        #[cfg(not(feature = "wgpu"))]
        false
    }

    /// L_nc and L_ns of a rendered view of training slot `slot`: started on the device when
    /// there is an executor for them (which keeps each slot's δ there, by `view_key`), else
    /// [`gs_losses::normal_losses`] (the reference), made at once.
    #[allow(clippy::too_many_arguments)]
    pub fn start_normal_losses<'d>(
        &'d self,
        plane_depth: &gs_core::Image,
        rendered_normal: &gs_core::Image,
        alpha: Option<&gs_core::Image>,
        guide: &gs_losses::EdgeGuide,
        intrinsics: &gs_core::Intrinsics,
        slot: usize,
        cfg: &gs_losses::NormalLossConfig,
    ) -> gs_losses::Result<Deferred<'d, gs_losses::NormalLossOutput, gs_losses::LossError>> {
        #[cfg(feature = "wgpu")]
        if let Some(d) = &self.normal {
            let key = view_key(slot, plane_depth.width(), plane_depth.height());
            let pending = d.borrow_mut().start(plane_depth, rendered_normal, alpha, guide, intrinsics, Some(key), cfg)?;
            return Ok(Deferred::later(move || d.borrow_mut().finish(pending)));
        }
        #[cfg(not(feature = "wgpu"))]
        let _ = slot;
        Ok(Deferred::ready(gs_losses::normal_losses(plane_depth, rendered_normal, alpha, guide, intrinsics, cfg)?))
    }

    /// [`LossDevices::start_normal_losses`] of a rendered surface kept on the device (the wgpu
    /// rasterizer's `SurfaceTexel`s; A counts when `with_alpha`): N̂ and the gradients stay there.
    #[cfg(feature = "wgpu")]
    pub fn start_normal_losses_on_device<'d>(
        &'d self,
        surface: &gs_gpu::DeviceImage,
        with_alpha: bool,
        guide: &gs_losses::EdgeGuide,
        intrinsics: &gs_core::Intrinsics,
        slot: usize,
        cfg: &gs_losses::NormalLossConfig,
    ) -> gs_losses::Result<Deferred<'d, gs_losses::NormalLossOutput<gs_gpu::DeviceImage>, gs_losses::LossError>> {
        let Some(d) = &self.normal else {
            return Err(gs_losses::LossError::Device("a rendered surface on the device but no L_nc/L_ns kernels there".into()));
        };
        let key = view_key(slot, surface.width(), surface.height());
        let pending = d.borrow_mut().start_on_device(surface, with_alpha, guide, intrinsics, Some(key), cfg)?;
        Ok(Deferred::later(move || d.borrow_mut().finish_on_device(pending)))
    }

    /// Whether L_nc and L_ns run on the device, so that a render's surface may stay there
    /// ([`gs_raster::RenderRequest::surface_on_device`]).
    pub fn normal_on_device(&self) -> bool {
        #[cfg(feature = "wgpu")]
        return self.normal.is_some();
        #[cfg(not(feature = "wgpu"))]
        false
    }

    /// L_p of `reference` over `sources` (`slots`: the reference's training slot, then each
    /// source's): the patches started on the device when there is an executor for them (which
    /// keeps each slot's grey image there, by `view_key`), else [`gs_mvs::photometric_loss`]
    /// (the reference), made at once.
    pub fn start_photometric_loss<'d>(
        &'d self,
        reference: &gs_mvs::PhotometricReference<'_, f32>,
        sources: &[gs_mvs::PhotometricSource<'_, f32>],
        slots: &[usize],
        config: &gs_mvs::PhotometricConfig,
    ) -> gs_mvs::Result<Deferred<'d, gs_mvs::PhotometricOutput<f32>, gs_mvs::MvsError>> {
        #[cfg(feature = "wgpu")]
        if let Some(d) = &self.photometric {
            let greys = std::iter::once(&reference.grey).chain(sources.iter().map(|s| &s.grey));
            let keys: Vec<u64> = slots.iter().zip(greys).map(|(&slot, g)| view_key(slot, g.width, g.height)).collect();
            let pending = d.borrow_mut().start(reference, sources, Some(&keys), config)?;
            return Ok(Deferred::later(move || d.borrow_mut().finish(pending)));
        }
        #[cfg(not(feature = "wgpu"))]
        let _ = slots;
        Ok(Deferred::ready(gs_mvs::photometric_loss(reference, sources, config)?))
    }

    /// [`LossDevices::start_photometric_loss`] of a reference whose rendered plane is on the
    /// device (the rasterizer's surface image), the gradient image kept there, υ/ω and the
    /// selection made there; each source's depth is kept there under its slot and `versions`
    /// (the iteration that rendered it), and with `keep` the reference's too, under that version
    /// (`gs_mvs::ViewKeys::keep_reference_depth`).
    #[cfg(feature = "wgpu")]
    pub fn start_photometric_loss_on_device<'d>(
        &'d self,
        reference: &gs_mvs::SurfaceReference<'_>,
        sources: &[gs_mvs::DeviceSource<'_>],
        (slots, versions, keep): (&[usize], &[u64], Option<u64>),
        config: &gs_mvs::PhotometricConfig,
    ) -> gs_mvs::Result<Deferred<'d, gs_mvs::PhotometricOnDevice, gs_mvs::MvsError>> {
        let Some(d) = &self.photometric else {
            return Err(gs_mvs::MvsError::InvalidInput("a reference surface on the device but no L_p kernels there".into()));
        };
        let greys = std::iter::once(&reference.grey).chain(sources.iter().map(|s| &s.grey));
        let keys: Vec<u64> = slots.iter().zip(greys).map(|(&slot, g)| view_key(slot, g.width, g.height)).collect();
        let keys = gs_mvs::ViewKeys { views: &keys, depth_versions: versions, keep_reference_depth: keep };
        let pending = d.borrow_mut().start_on_device(reference, sources, Some(keys), config)?;
        Ok(Deferred::later(move || d.borrow_mut().finish_on_device(pending)))
    }

    /// Whether the depth memo may keep depths on the device alone: L_p runs there and its
    /// arena holds the grey image and the depth of every one of `views` training views (each
    /// at most `floats` values) at once, so that none is ever evicted.
    pub fn memo_fits(&self, views: usize, floats: usize) -> bool {
        #[cfg(feature = "wgpu")]
        return self.photometric.as_ref().is_some_and(|d| d.borrow().holds_every_view(views, floats));
        #[cfg(not(feature = "wgpu"))]
        {
            let _ = (views, floats);
            false
        }
    }

    /// Keeps the plane depth of a render's `surface` (on the device) in L_p's arena as training
    /// slot `slot`'s at `version` (its grey image `grey` names its key); `false` where it was
    /// not kept (no L_p kernels, or no room).
    #[cfg(feature = "wgpu")]
    pub fn keep_depth(&self, slot: usize, grey: &gs_core::Image, surface: &gs_gpu::DeviceImage, version: u64) -> gs_mvs::Result<bool> {
        match &self.photometric {
            Some(d) => d.borrow_mut().keep_depth(surface, view_key(slot, grey.width(), grey.height()), version),
            None => Ok(false),
        }
    }

    /// Whether L_p's arena holds the plane depth of training slot `slot` (`pixels` values; its
    /// grey image `grey` names its key) at `version`.
    pub fn holds_depth(&self, slot: usize, grey: &gs_core::Image, pixels: usize, version: u64) -> bool {
        #[cfg(feature = "wgpu")]
        return self.photometric.as_ref().is_some_and(|d| d.borrow().holds_depth(view_key(slot, grey.width(), grey.height()), pixels, version));
        #[cfg(not(feature = "wgpu"))]
        {
            let _ = (slot, grey, pixels, version);
            false
        }
    }

    /// The plane depths each `(slot, grey image, pixels, version)` of `items` names in L_p's
    /// arena ([`LossDevices::holds_depth`]), read back at one wait; `None` where it is not held.
    pub fn held_depths(&self, items: &[(usize, &gs_core::Image, usize, u64)]) -> gs_mvs::Result<Vec<Option<Vec<f32>>>> {
        #[cfg(feature = "wgpu")]
        if let Some(d) = &self.photometric {
            let keys: Vec<_> = items.iter().map(|&(slot, g, pixels, version)| (view_key(slot, g.width(), g.height()), pixels, version)).collect();
            return d.borrow().held_depths(&keys);
        }
        Ok(vec![None; items.len()])
    }

    /// Whether L_p's patches run on the device, so that its gradient image may stay there.
    pub fn photometric_on_device(&self) -> bool {
        #[cfg(feature = "wgpu")]
        return self.photometric.is_some();
        #[cfg(not(feature = "wgpu"))]
        false
    }

    /// L_f of `reference` against `sources` (each view's key its training slot): the feature
    /// alignment on the device when there is an executor for it, else
    /// [`gs_mvs::feature_alignment::feature_loss`] (the reference).
    pub fn feature_loss(&self, reference: &gs_mvs::AlignView<'_>, sources: &[gs_mvs::AlignView<'_>]) -> gs_mvs::Result<gs_mvs::FeatureOutput<f32>> {
        #[cfg(feature = "wgpu")]
        if let Some(d) = &self.features {
            return d.borrow_mut().loss(reference, sources);
        }
        let sources: Vec<gs_mvs::FeatureSource<'_, f32>> = sources.iter().map(gs_mvs::AlignView::as_source).collect();
        gs_mvs::feature_loss(&reference.as_reference(), &sources)
    }

    /// L_f of a reference whose rendered surface is on the device (`reference`: its view, its
    /// surface and its grey image, which names L_p's key) against `sources` (each one's view and
    /// its depth and grey image as L_p takes them), weighed by υ/ω made on the device by L_p's
    /// executor: those its evaluation of this step lent, or made for L_f alone; `versions` are
    /// the sources' depth versions, and with `keep` the reference's depth stays in L_p's arena
    /// under that version (the depth memo), as L_p keeps it where L_p runs. The gradient stays
    /// on the device. `None` where that does not apply (no L_f or L_p kernels, or beyond their
    /// limits): the caller evaluates L_f from depths on the host.
    #[cfg(feature = "wgpu")]
    pub fn start_feature_loss_on_device<'d>(
        &'d self,
        reference: (&gs_mvs::DeviceAlignView<'_>, &gs_gpu::DeviceImage, &gs_core::Image),
        sources: (&[gs_mvs::DeviceAlignView<'_>], &[gs_mvs::DeviceSource<'_>]),
        (versions, keep): (&[u64], Option<u64>),
    ) -> gs_mvs::Result<Option<Deferred<'d, gs_mvs::FeaturesOnDevice, gs_mvs::MvsError>>> {
        let (Some(d), Some(lp)) = (&self.features, &self.photometric) else { return Ok(None) };
        let (view, surface, grey) = reference;
        let (views, depths) = sources;
        let mut keys = vec![view_key(view.key as usize, grey.width(), grey.height())];
        keys.extend(views.iter().zip(depths).map(|(v, s)| view_key(v.key as usize, s.grey.width, s.grey.height)));
        let lent = lp.borrow().visibility().filter(|v| v.is_of(surface, &keys, versions)).cloned();
        let visibility = match lent {
            Some(v) => v,
            None => {
                let on_surface = gs_mvs::SurfaceReference { camera: view.camera, surface, plane_depth: None, grey: grey.into() };
                let view_keys = gs_mvs::ViewKeys { views: &keys, depth_versions: versions, keep_reference_depth: None };
                // υ/ω do not depend on L_p's settings (its patch size only marks candidates).
                let made = lp.borrow_mut().visibility_on_device(&on_surface, depths, view_keys, &gs_mvs::PhotometricConfig::default())?;
                let Some(v) = made else { return Ok(None) };
                v
            }
        };
        let started = d.borrow_mut().start_on_device((view, surface), views, (&keys, versions), &visibility)?;
        // After L_f's submission, which reads the arena as it was.
        if let Some(version) = keep.filter(|_| started.is_some()) {
            let floats = surface.width() * surface.height();
            if !lp.borrow().holds_depth(keys[0], floats, version) {
                lp.borrow_mut().keep_depth(surface, keys[0], version)?;
            }
        }
        Ok(started.map(|pending| Deferred::later(move || d.borrow_mut().finish_on_device(pending))))
    }

    /// `target += weight · gradient` on the device: L_f's gradient image added into the
    /// plane-depth gradient the backward reads there.
    #[cfg(feature = "wgpu")]
    pub fn add_feature_gradient(&self, gradient: &gs_gpu::DeviceImage, weight: f32, target: &gs_gpu::DeviceImage) -> gs_mvs::Result<()> {
        match &self.features {
            Some(d) => d.borrow_mut().add_gradient(gradient, weight, target),
            None => Err(gs_mvs::MvsError::InvalidInput("an L_f gradient on the device but no L_f kernels there".into())),
        }
    }

    /// The values of `image`, kept on these executors' device, read back at one wait.
    #[cfg(feature = "wgpu")]
    pub fn read_image(&self, image: &gs_gpu::DeviceImage) -> gs_mvs::Result<Vec<f32>> {
        image.read(self.device()?).map_err(|e| gs_mvs::MvsError::Device(e.to_string()))
    }

    /// The plane depth (each texel's z) of a rendered surface on these executors' device, read
    /// back ([`gs_mvs::surface_depth`]).
    #[cfg(feature = "wgpu")]
    pub fn surface_depth(&self, surface: &gs_gpu::DeviceImage) -> gs_mvs::Result<Vec<f32>> {
        gs_mvs::surface_depth(self.device()?, surface)
    }

    /// Their device, or the error of a read without one.
    #[cfg(feature = "wgpu")]
    fn device(&self) -> gs_mvs::Result<&gs_gpu::GpuContext> {
        self.context.as_ref().ok_or_else(|| gs_mvs::MvsError::Device("an image on a device, read without one".into()))
    }

    /// Whether the exposure correction runs on the device, so that a render's colour may stay
    /// there with it on.
    pub fn exposure_on_device(&self) -> bool {
        #[cfg(feature = "wgpu")]
        return self.exposure.is_some();
        #[cfg(not(feature = "wgpu"))]
        false
    }

    /// c' = exp(a)·c + b of a rendered colour kept on the device, into a new image there.
    #[cfg(feature = "wgpu")]
    pub fn apply_exposure(&self, colour: &gs_gpu::DeviceImage, e: &gs_losses::ExposureParams) -> gs_losses::Result<gs_gpu::DeviceImage> {
        match &self.exposure {
            Some(d) => d.borrow_mut().apply(colour, e),
            None => Err(gs_losses::LossError::Device("a colour on the device but no exposure kernels there".into())),
        }
    }

    /// The exposure's backward on the device: ∂L/∂c from ∂L/∂c' (both there) and ∂L/∂(a, b).
    #[cfg(feature = "wgpu")]
    pub fn exposure_backward(&self, colour: &gs_gpu::DeviceImage, e: &gs_losses::ExposureParams, grad: &gs_gpu::DeviceImage) -> gs_losses::Result<(gs_gpu::DeviceImage, gs_losses::ExposureParams)> {
        match &self.exposure {
            Some(d) => d.borrow_mut().backward(colour, e, grad),
            None => Err(gs_losses::LossError::Device("a colour gradient on the device but no exposure kernels there".into())),
        }
    }

    /// Whether L_f runs on the device, where L_p's kernels make its υ/ω.
    pub fn features_on_device(&self) -> bool {
        #[cfg(feature = "wgpu")]
        return self.features.is_some() && self.photometric.is_some();
        #[cfg(not(feature = "wgpu"))]
        false
    }

    /// The VGG16 feature map of `photo` at `level` (L_f's F, once a view) made on the device
    /// when there is an extractor there; `None` when the caller makes it on the host.
    pub fn device_features(&self, photo: &gs_core::Image, level: gs_features::FeatureLevel) -> Option<gs_features::Result<gs_features::FeatureMap>> {
        #[cfg(feature = "wgpu")]
        if let Some(d) = &self.vgg {
            return Some(d.borrow_mut().extract(photo, level));
        }
        let _ = (photo, level);
        None
    }

    /// Each part of the loss terms and whether it runs on the device (the rest runs on the CPU),
    /// in the order the terms run.
    pub fn term_parts(&self) -> [(&'static str, bool); 7] {
        #[cfg(feature = "wgpu")]
        let (image, normal, photometric, features, vgg) =
            (self.image.is_some(), self.normal.is_some(), self.photometric.is_some(), self.features.is_some(), self.vgg.is_some());
        #[cfg(not(feature = "wgpu"))]
        let (image, normal, photometric, features, vgg) = (false, false, false, false, false);
        let exposure = self.exposure_on_device();
        [
            ("L_I (L1, D-SSIM, edge term)", image),
            ("L_nc and L_ns", normal),
            ("L_p: NCC of the patches", photometric),
            ("L_p: pixel selection, visibility υ and weight ω", photometric && normal),
            ("L_f: feature alignment", features),
            ("L_f: VGG16 features of each view (once a view)", vgg),
            ("exposure compensation", exposure),
        ]
    }

    /// Where each term runs, in words: `"L_p, L_I and L_nc/L_ns on wgpu (ADAPTER); the other
    /// terms on the CPU"`, or that every term runs on the CPU.
    pub fn describe(&self) -> String {
        #[allow(unused_mut)]
        let mut on: Vec<String> = Vec::new();
        #[cfg(feature = "wgpu")]
        {
            use crate::terms::term_name::{FEATURES, NORMAL_CONSISTENCY, NORMAL_SMOOTHING, PHOTOMETRIC};
            if self.photometric.is_some() {
                on.push(PHOTOMETRIC.into());
            }
            if self.features.is_some() {
                on.push(FEATURES.into());
            }
            if self.image.is_some() {
                on.push("L_I".into());
            }
            if self.normal.is_some() {
                on.push(format!("{NORMAL_CONSISTENCY}/{NORMAL_SMOOTHING}"));
            }
        }
        match (&self.adapter, on.split_last()) {
            (Some(a), Some((last, []))) => format!("{last} on wgpu ({a}); the other terms on the CPU"),
            (Some(a), Some((last, first))) => format!("{} and {last} on wgpu ({a}); the other terms on the CPU", first.join(", ")),
            _ => format!("every loss term on the CPU ({})", gs_raster::cpu_threads_in_words()),
        }
    }
}

/// A term's result made at once (on the CPU) or started on a device and read when asked:
/// the device executors' readbacks started before the first is read cost the host one wait.
pub struct Deferred<'d, T, E>(Box<dyn FnOnce() -> Result<T, E> + 'd>);

impl<'d, T: 'd, E: 'd> Deferred<'d, T, E> {
    /// A result already made.
    pub fn ready(value: T) -> Self {
        Self(Box::new(move || Ok(value)))
    }

    /// A result that `read` reads (waiting for the device if it has not answered).
    #[cfg(feature = "wgpu")]
    fn later(read: impl FnOnce() -> Result<T, E> + 'd) -> Self {
        Self(Box::new(read))
    }

    /// The result.
    pub fn wait(self) -> Result<T, E> {
        (self.0)()
    }
}

/// The key under which a device executor keeps the photo data of training slot `slot` at
/// `width` × `height` (a run's photo of one slot at one size never changes; the size is in the
/// key because the coarse-to-fine schedule trains a slot at several).
#[cfg(feature = "wgpu")]
pub(crate) fn view_key(slot: usize, width: usize, height: usize) -> u64 {
    ((slot as u64) << 40) ^ ((width as u64) << 20) ^ height as u64
}
