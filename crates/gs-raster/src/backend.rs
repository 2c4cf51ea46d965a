//! Backend selection: the CPU reference backend or the wgpu (WGSL compute) backend behind one
//! object with the same `render` / `backward` signatures.

use crate::{
    DeviceStep, GaussianGradients, OutputGradients, RasterConfig, RenderOutput, RenderRequest,
    Result, StepExtras,
};
use gs_core::{Adam, Camera, DensifyStats, Gaussians};

/// Which rasterizer backend to use (`"cpu" | "wgpu" | "auto"` via [`std::str::FromStr`], in any
/// letter case; `"gpu"` also names wgpu).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Backend {
    /// The CPU backend (rayon over tiles; the numerical reference).
    Cpu,
    /// The wgpu backend on the best adapter found, software adapters (lavapipe) included.
    Wgpu,
    /// wgpu when a hardware GPU adapter exists, else the CPU backend.
    #[default]
    Auto,
}

gs_core::named_choices!(Backend, "backend", {
    Backend::Cpu => "cpu",
    Backend::Wgpu => "wgpu",
    Backend::Auto => "auto",
}, ignore_case, aliases { "gpu" => Backend::Wgpu });

enum Inner {
    Cpu,
    #[cfg(feature = "wgpu")]
    Wgpu(Box<crate::gpu::WgpuRasterizer>),
}

/// A rasterizer of the chosen backend. Create it once and reuse it: the wgpu backend keeps its
/// device, pipelines and buffers across calls.
pub struct Rasterizer {
    inner: Inner,
}

impl std::fmt::Debug for Rasterizer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Rasterizer({})", self.description())
    }
}

impl Rasterizer {
    /// Creates the rasterizer. `Backend::Wgpu` fails with [`crate::RasterError::BackendUnavailable`]
    /// when there is no adapter or the crate was built without the `wgpu` feature;
    /// `Backend::Auto` picks wgpu on a hardware (non-CPU) adapter and the CPU otherwise.
    pub fn new(backend: Backend) -> Result<Self> {
        match backend {
            Backend::Cpu => Ok(Self { inner: Inner::Cpu }),
            #[cfg(feature = "wgpu")]
            Backend::Wgpu => Ok(Self {
                inner: Inner::Wgpu(Box::new(crate::gpu::WgpuRasterizer::new()?)),
            }),
            #[cfg(not(feature = "wgpu"))]
            Backend::Wgpu => Err(crate::RasterError::BackendUnavailable(
                "gs-raster was built without the `wgpu` feature".into(),
            )),
            #[cfg(feature = "wgpu")]
            Backend::Auto => {
                let opts = crate::gpu::WgpuOptions {
                    require_hardware: true,
                    ..Default::default()
                };
                match crate::gpu::WgpuRasterizer::with_options(opts) {
                    Ok(r) => Ok(Self {
                        inner: Inner::Wgpu(Box::new(r)),
                    }),
                    Err(_) => Ok(Self { inner: Inner::Cpu }),
                }
            }
            #[cfg(not(feature = "wgpu"))]
            Backend::Auto => Ok(Self { inner: Inner::Cpu }),
        }
    }

    /// A wgpu rasterizer with `options` (e.g. a hardware adapter only).
    #[cfg(feature = "wgpu")]
    pub fn with_wgpu_options(options: crate::gpu::WgpuOptions) -> Result<Self> {
        Ok(Self { inner: Inner::Wgpu(Box::new(crate::gpu::WgpuRasterizer::with_options(options)?)) })
    }

    /// The backend in use (`Cpu` or `Wgpu`, never `Auto`).
    pub fn backend(&self) -> Backend {
        match self.inner {
            Inner::Cpu => Backend::Cpu,
            #[cfg(feature = "wgpu")]
            Inner::Wgpu(_) => Backend::Wgpu,
        }
    }

    /// `"cpu"` or `"wgpu"`.
    pub fn backend_name(&self) -> &'static str {
        match self.inner {
            Inner::Cpu => "cpu",
            #[cfg(feature = "wgpu")]
            Inner::Wgpu(_) => "wgpu",
        }
    }

    /// A human-readable description (the adapter for wgpu) for logs.
    pub fn description(&self) -> String {
        match &self.inner {
            Inner::Cpu => cpu_description(),
            #[cfg(feature = "wgpu")]
            Inner::Wgpu(r) => format!("wgpu on {}", r.adapter_description()),
        }
    }

    /// The wgpu device context when this rasterizer runs on wgpu (kernels of the loss terms
    /// share it), else `None`.
    #[cfg(feature = "wgpu")]
    pub fn gpu_context(&self) -> Option<&gs_gpu::GpuContext> {
        match &self.inner {
            Inner::Cpu => None,
            Inner::Wgpu(r) => Some(r.context()),
        }
    }

    /// Whether [`render_views`](Self::render_views) saves waits over renders one by one (a
    /// device backend; on the CPU it renders them one by one).
    pub fn renders_together(&self) -> bool {
        !matches!(self.inner, Inner::Cpu)
    }

    /// Whether a model is resident on this rasterizer's device (never on the CPU backend).
    pub fn is_resident(&self) -> bool {
        match &self.inner {
            Inner::Cpu => false,
            #[cfg(feature = "wgpu")]
            Inner::Wgpu(r) => r.is_resident(),
        }
    }

    /// Keeps `gaussians`, the moments of `adam` and the densification statistics `stats` on
    /// the device for training ([`crate::WgpuRasterizer::make_resident`]). The CPU backend has
    /// no device and refuses.
    pub fn make_resident(&mut self, gaussians: &Gaussians, adam: &Adam, stats: &DensifyStats) -> Result<()> {
        match &mut self.inner {
            Inner::Cpu => {
                let _ = (gaussians, adam, stats);
                Err(crate::RasterError::BackendUnavailable("the CPU backend keeps no model resident; it steps on the host (gs_raster::adam_step)".into()))
            }
            #[cfg(feature = "wgpu")]
            Inner::Wgpu(r) => r.make_resident(gaussians, adam, stats),
        }
    }

    /// Brings the resident model into `gaussians` (the host's copy, of the resident size and
    /// degree) and, when given, its moments and densification statistics into `optimiser`;
    /// the residency goes on ([`crate::WgpuRasterizer::read_resident`]). Nothing to do when no
    /// model is resident (always on the CPU backend, whose model is the host's).
    pub fn read_resident(&mut self, gaussians: &mut Gaussians, optimiser: Option<(&mut Adam, &mut DensifyStats)>) -> Result<()> {
        match &mut self.inner {
            #[cfg(feature = "wgpu")]
            Inner::Wgpu(r) if r.is_resident() => r.read_resident(gaussians, optimiser),
            _ => {
                let _ = (gaussians, optimiser);
                Ok(())
            }
        }
    }

    /// Brings the resident parameter records alone into `gaussians` (means, log-scales,
    /// rotations and opacity logits; its SH coefficients stay as they are), as
    /// [`Rasterizer::read_resident`] does: 44 bytes a Gaussian, for readers of the geometry.
    pub fn read_resident_records(&mut self, gaussians: &mut Gaussians) -> Result<()> {
        match &mut self.inner {
            #[cfg(feature = "wgpu")]
            Inner::Wgpu(r) if r.is_resident() => r.read_resident_records(gaussians),
            _ => {
                let _ = gaussians;
                Ok(())
            }
        }
    }

    /// Raises the resident model's SH degree to `degree`, the new bands' coefficients and
    /// moments zero ([`crate::WgpuRasterizer::raise_sh_degree_resident`]); `false`, with
    /// nothing changed, where the device does not take it. The CPU backend has no resident
    /// model and refuses.
    pub fn raise_sh_degree_resident(&mut self, gaussians: &Gaussians, degree: u32) -> Result<bool> {
        match &mut self.inner {
            #[cfg(feature = "wgpu")]
            Inner::Wgpu(r) => r.raise_sh_degree_resident(gaussians, degree),
            _ => {
                let _ = (gaussians, degree);
                Err(crate::RasterError::BackendUnavailable("the CPU backend keeps no model resident to raise the SH degree of".into()))
            }
        }
    }

    /// Clone, split and prune the resident model on its device by `rule`, each born row's
    /// position from `sample` in the host's order ([`crate::WgpuRasterizer::densify_resident`]); `None`,
    /// with nothing changed, where the device does not take the step (the host then runs it).
    /// The CPU backend has no resident model and refuses.
    pub fn densify_resident(&mut self, gaussians: &Gaussians, rule: &crate::DensifyRule, sample: &mut dyn FnMut(&crate::BornParent) -> [f32; 3]) -> Result<Option<crate::DensifyCounts>> {
        match &mut self.inner {
            #[cfg(feature = "wgpu")]
            Inner::Wgpu(r) => r.densify_resident(gaussians, rule, sample),
            _ => {
                let _ = (gaussians, rule, sample);
                Err(crate::RasterError::BackendUnavailable("the CPU backend keeps no model resident to densify".into()))
            }
        }
    }

    /// The opacity reset on the resident model ([`crate::WgpuRasterizer::reset_opacity_resident`]):
    /// opacities above `level` take the logit `logit`, the opacity moments start again at
    /// zero. The CPU backend has no resident model and refuses.
    pub fn reset_opacity_resident(&mut self, gaussians: &Gaussians, level: f32, logit: f32) -> Result<()> {
        match &mut self.inner {
            #[cfg(feature = "wgpu")]
            Inner::Wgpu(r) => r.reset_opacity_resident(gaussians, level, logit),
            _ => {
                let _ = (gaussians, level, logit);
                Err(crate::RasterError::BackendUnavailable("the CPU backend keeps no model resident to reset".into()))
            }
        }
    }

    /// Keeps the resident model's rows where `keep` is true, with their moments and statistics
    /// ([`crate::WgpuRasterizer::retain_resident`]); `None`, with nothing changed, where the
    /// device does not take it. The CPU backend has no resident model and refuses.
    pub fn retain_resident(&mut self, gaussians: &Gaussians, keep: &[bool]) -> Result<Option<usize>> {
        match &mut self.inner {
            #[cfg(feature = "wgpu")]
            Inner::Wgpu(r) => r.retain_resident(gaussians, keep),
            _ => {
                let _ = (gaussians, keep);
                Err(crate::RasterError::BackendUnavailable("the CPU backend keeps no model resident to remove Gaussians from".into()))
            }
        }
    }

    /// Counts, for each Gaussian of the resident model, the `cameras` that observe it, on the
    /// device ([`crate::WgpuRasterizer::count_views_resident`]), for
    /// [`Rasterizer::retain_observed_resident`]. The CPU backend has no resident model and
    /// refuses.
    pub fn count_views_resident(&mut self, gaussians: &Gaussians, cameras: &[&gs_core::Camera], config: &RasterConfig) -> Result<()> {
        match &mut self.inner {
            #[cfg(feature = "wgpu")]
            Inner::Wgpu(r) => r.count_views_resident(gaussians, cameras, config),
            _ => {
                let _ = (gaussians, cameras, config);
                Err(crate::RasterError::BackendUnavailable("the CPU backend keeps no model resident to count views of".into()))
            }
        }
    }

    /// The view counts of [`Rasterizer::count_views_resident`], read back.
    pub fn read_view_counts(&mut self) -> Result<Vec<u32>> {
        match &mut self.inner {
            #[cfg(feature = "wgpu")]
            Inner::Wgpu(r) => r.read_view_counts(),
            _ => Err(crate::RasterError::BackendUnavailable("the CPU backend keeps no view counts".into())),
        }
    }

    /// The multi-view trim of the resident model by the counted views
    /// ([`crate::WgpuRasterizer::retain_observed_resident`]); `None`, with nothing changed,
    /// where the device does not take it. The CPU backend refuses.
    pub fn retain_observed_resident(&mut self, gaussians: &Gaussians, min_views: u32) -> Result<Option<crate::TrimOnDevice>> {
        match &mut self.inner {
            #[cfg(feature = "wgpu")]
            Inner::Wgpu(r) => r.retain_observed_resident(gaussians, min_views),
            _ => {
                let _ = (gaussians, min_views);
                Err(crate::RasterError::BackendUnavailable("the CPU backend keeps no model resident to trim".into()))
            }
        }
    }

    /// Marks each Gaussian of the resident model inside or outside `capsules` on the device
    /// ([`crate::WgpuRasterizer::mark_capsules_resident`]) and returns the rows f32 could not
    /// settle, with their means, for the host's test; `None`, with nothing marked, where the
    /// device does not take it. The CPU backend refuses.
    pub fn mark_capsules_resident(&mut self, gaussians: &Gaussians, capsules: &[gs_core::Capsule]) -> Result<Option<crate::UnsureRows>> {
        match &mut self.inner {
            #[cfg(feature = "wgpu")]
            Inner::Wgpu(r) => r.mark_capsules_resident(gaussians, capsules),
            _ => {
                let _ = (gaussians, capsules);
                Err(crate::RasterError::BackendUnavailable("the CPU backend keeps no model resident to mark".into()))
            }
        }
    }

    /// Removes the resident rows marked inside the capsules, and the unsure rows listed in
    /// `inside` ([`crate::WgpuRasterizer::retain_outside_resident`]); `None`, with nothing
    /// changed, where the device does not take it. The CPU backend refuses.
    pub fn retain_outside_resident(&mut self, gaussians: &Gaussians, inside: &[usize]) -> Result<Option<crate::TrimOnDevice>> {
        match &mut self.inner {
            #[cfg(feature = "wgpu")]
            Inner::Wgpu(r) => r.retain_outside_resident(gaussians, inside),
            _ => {
                let _ = (gaussians, inside);
                Err(crate::RasterError::BackendUnavailable("the CPU backend keeps no model resident to remove rows from".into()))
            }
        }
    }

    /// Ends a residency: the device's parameters and moments are dropped (read them first,
    /// [`Rasterizer::read_resident`], to keep them) and the next render uploads again.
    /// Nothing to do when no model is resident.
    pub fn release_resident(&mut self) {
        #[cfg(feature = "wgpu")]
        if let Inner::Wgpu(r) = &mut self.inner {
            r.release_resident();
        }
    }

    /// The backward of `forward` and one Adam step on the resident model
    /// ([`crate::WgpuRasterizer::backward_and_step`]). The CPU backend has no resident model
    /// and refuses.
    #[allow(clippy::too_many_arguments)]
    pub fn backward_and_step(
        &mut self,
        gaussians: &Gaussians,
        camera: &Camera,
        config: &RasterConfig,
        forward: &RenderOutput,
        grads: &OutputGradients,
        adam: &mut Adam,
        extras: StepExtras<'_>,
    ) -> Result<DeviceStep> {
        let started = self.start_step(gaussians, camera, config, forward, grads, adam, extras)?;
        self.finish_step(started)
    }

    /// [`Rasterizer::backward_and_step`] submitted, its outcome read by
    /// [`Rasterizer::finish_step`] after later work whose wait for the device brings it
    /// ([`crate::WgpuRasterizer::start_step`]). The CPU backend refuses.
    #[allow(clippy::too_many_arguments)]
    pub fn start_step(
        &mut self,
        gaussians: &Gaussians,
        camera: &Camera,
        config: &RasterConfig,
        forward: &RenderOutput,
        grads: &OutputGradients,
        adam: &mut Adam,
        extras: StepExtras<'_>,
    ) -> Result<StartedStep> {
        match &mut self.inner {
            Inner::Cpu => {
                let _ = (gaussians, camera, config, forward, grads, adam, extras);
                Err(crate::RasterError::BackendUnavailable("the CPU backend keeps no model resident; use gs_raster::backward and gs_raster::adam_step".into()))
            }
            #[cfg(feature = "wgpu")]
            Inner::Wgpu(r) => Ok(StartedStep { pending: r.start_step(gaussians, camera, config, forward, grads, adam, extras)? }),
        }
    }

    /// The outcome of a step started by [`Rasterizer::start_step`] (waiting for the device if
    /// it has not answered).
    pub fn finish_step(&mut self, started: StartedStep) -> Result<DeviceStep> {
        match &mut self.inner {
            #[cfg(feature = "wgpu")]
            Inner::Wgpu(r) => r.finish_step(started.pending),
            _ => {
                let _ = started;
                Err(crate::RasterError::BackendUnavailable("a step is finished on the rasterizer that started it".into()))
            }
        }
    }

    /// Renders like [`crate::render`].
    pub fn render(
        &mut self,
        gaussians: &Gaussians,
        camera: &Camera,
        request: &RenderRequest,
        config: &RasterConfig,
    ) -> Result<RenderOutput> {
        match &mut self.inner {
            Inner::Cpu => crate::render(gaussians, camera, request, config),
            #[cfg(feature = "wgpu")]
            Inner::Wgpu(r) => r.render(gaussians, camera, request, config),
        }
    }

    /// Renders `views` in order, each like [`Rasterizer::render`] (the same outputs). On wgpu
    /// the renders of sizes rendered before are submitted one after another and read back
    /// with one wait; the last view's device state is the one a backward reuses.
    pub fn render_views(
        &mut self,
        gaussians: &Gaussians,
        views: &[(&Camera, RenderRequest)],
        config: &RasterConfig,
    ) -> Result<Vec<RenderOutput>> {
        match &mut self.inner {
            Inner::Cpu => views.iter().map(|(camera, request)| crate::render(gaussians, camera, request, config)).collect(),
            #[cfg(feature = "wgpu")]
            Inner::Wgpu(r) => r.render_views(gaussians, views, config),
        }
    }

    /// Backward like [`crate::backward`]; `forward` must come from this rasterizer (for wgpu,
    /// backward right after its render is fastest; an older render's device state is rebuilt).
    pub fn backward(
        &mut self,
        gaussians: &Gaussians,
        camera: &Camera,
        config: &RasterConfig,
        forward: &RenderOutput,
        grads: &OutputGradients,
    ) -> Result<GaussianGradients> {
        match &mut self.inner {
            Inner::Cpu => crate::backward(gaussians, camera, config, forward, grads),
            #[cfg(feature = "wgpu")]
            Inner::Wgpu(r) => r.backward(gaussians, camera, config, forward, grads),
        }
    }
}

/// The CPU backend in words, "cpu (2 threads)": what [`Rasterizer::description`] says of it
/// and what a run reports for its parts on the CPU.
pub fn cpu_description() -> String {
    format!("cpu ({})", cpu_threads_in_words())
}

/// The CPU's worker count in words ("1 thread", "16 threads"): the current rayon pool.
pub fn cpu_threads_in_words() -> String {
    match rayon::current_num_threads() {
        1 => "1 thread".into(),
        n => format!("{n} threads"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rasterizer_is_send() {
        fn send<T: Send>() {}
        send::<Rasterizer>();
    }

    #[test]
    fn backend_names_parse_and_print() {
        for b in [Backend::Cpu, Backend::Wgpu, Backend::Auto] {
            assert_eq!(b.to_string().parse::<Backend>().unwrap(), b);
        }
        assert_eq!(("WGPU".parse::<Backend>(), "Gpu".parse::<Backend>()), (Ok(Backend::Wgpu), Ok(Backend::Wgpu)));
        assert_eq!("metal".parse::<Backend>().unwrap_err(), "unknown backend 'metal' (one of: cpu, wgpu, auto)");
        let r = Rasterizer::new(Backend::Cpu).unwrap();
        assert_eq!((r.backend(), r.backend_name()), (Backend::Cpu, "cpu"));
    }

    #[cfg(not(feature = "wgpu"))]
    #[test]
    fn without_the_feature_wgpu_is_an_error_and_auto_is_cpu() {
        assert!(matches!(
            Rasterizer::new(Backend::Wgpu),
            Err(crate::RasterError::BackendUnavailable(_))
        ));
        assert_eq!(Rasterizer::new(Backend::Auto).unwrap().backend(), Backend::Cpu);
    }
}

/// A device step started by [`Rasterizer::start_step`], its outcome not read yet.
#[derive(Debug)]
pub struct StartedStep {
    #[cfg(feature = "wgpu")]
    pending: crate::PendingStep,
}
