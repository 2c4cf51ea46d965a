//! The loss-term contract (docs/method.md §Losses): every term of
//! L = L_I + λ1·L_nc + λ2·L_ns + λ3·L_p + λ4·L_f + λ_o·L_o + λ_s·L_s reads the rendered view (or,
//! L_o and L_s, the model), records its unweighted value(s) in [`LossValues`] and adds its weighted gradient into
//! [`GradientBuffers`]: the renderer's output-gradient buffers, or the parameter gradients that
//! join the rasterizer's.
//! The weights come from one place (the [`LossWeights`] of the step plan: the configuration's,
//! zero for the terms its phase leaves off), and so does the total ([`LossWeights::total`]).
//!
//! A term receives its weight rather than returning an unweighted gradient because some fold
//! it into their kernels (L_nc and L_ns share one back-propagation through the depth normal
//! N̂); the executor never scales a term's gradient itself.

use crate::config::LossWeights;
use crate::error::{Result, TrainError};
use crate::profile::Part;
use crate::devices::LossDevices;
use crate::source_depths::StoredDepth;
use gs_core::{Camera, Gaussians, Image};
use gs_features::FeatureMap;
use gs_losses::{EdgeGuide, ImageLossConfig, NormalLossConfig, opacity_entropy, smallest_scale_mean};
use gs_mvs::{PhotometricConfig, PhotometricReference, PhotometricSource};
use gs_raster::{OutputGradients, RenderOutput};
use serde::Serialize;

mod feature;
pub use feature::FeatureTerm;

/// The names of the optional terms in words, in the order of L (docs/method.md §Losses): the one
/// source for summaries, profiles and error messages.
pub mod term_name {
    /// The edge term β2·L1(∇Ĩ, ∇I) of L_I.
    pub const EDGE: &str = "edge";
    /// Normal consistency.
    pub const NORMAL_CONSISTENCY: &str = "L_nc";
    /// Normal smoothing.
    pub const NORMAL_SMOOTHING: &str = "L_ns";
    /// Multi-view photometric alignment.
    pub const PHOTOMETRIC: &str = "L_p";
    /// Multi-view feature alignment.
    pub const FEATURES: &str = "L_f";
    /// The opacity entropy.
    pub const OPACITY: &str = "L_o";
    /// The flattening term (the mean smallest scale).
    pub const FLATNESS: &str = "L_s";
    /// The edge weight of L_nc and L_ns.
    pub const DELTA: &str = "δ";
}

/// Loss values of one iteration (unweighted terms; `None` when the term was off).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct LossValues {
    /// L1(Ĩ, I).
    pub l1: f64,
    /// SSIM(Ĩ, I).
    pub ssim: f64,
    /// L1(∇Ĩ, ∇I).
    pub edge: Option<f64>,
    /// L_nc.
    pub normal_consistency: Option<f64>,
    /// L_ns.
    pub normal_smoothing: Option<f64>,
    /// L_p (summed over sources).
    pub photometric: Option<f64>,
    /// L_f (averaged over sources).
    pub features: Option<f64>,
    /// L_o, the mean opacity entropy.
    pub opacity_entropy: Option<f64>,
    /// L_s, the mean smallest scale.
    pub flatness: Option<f64>,
    /// The weighted total L.
    pub total: f64,
}

impl LossValues {
    /// The values in words, for an error message.
    pub fn in_words(&self) -> String {
        let mut s = format!("L1 {}, SSIM {}", self.l1, self.ssim);
        for (name, x) in self.optional_terms() {
            if let Some(x) = x {
                s.push_str(&format!(", {name} {x}"));
            }
        }
        s
    }

    /// The optional terms' values by name ([`term_name`]), in the order of L.
    pub fn optional_terms(&self) -> [(&'static str, Option<f64>); 7] {
        [
            (term_name::EDGE, self.edge),
            (term_name::NORMAL_CONSISTENCY, self.normal_consistency),
            (term_name::NORMAL_SMOOTHING, self.normal_smoothing),
            (term_name::PHOTOMETRIC, self.photometric),
            (term_name::FEATURES, self.features),
            (term_name::OPACITY, self.opacity_entropy),
            (term_name::FLATNESS, self.flatness),
        ]
    }
}

impl LossWeights {
    /// L = (1 − β1)·L1 + β1·(1 − SSIM) + β2·L_edge + λ1·L_nc + λ2·L_ns + λ3·L_p + λ4·L_f + λ_o·L_o + λ_s·L_s of
    /// recorded values (absent terms count 0). The step plan's weights are zero for the terms
    /// its phase leaves off.
    pub fn total(&self, v: &LossValues) -> f64 {
        let w = |x: f32| x as f64;
        let b1 = w(self.beta1);
        (1.0 - b1) * v.l1
            + b1 * (1.0 - v.ssim)
            + w(self.beta2) * v.edge.unwrap_or(0.0)
            + w(self.lambda_nc) * v.normal_consistency.unwrap_or(0.0)
            + w(self.lambda_ns) * v.normal_smoothing.unwrap_or(0.0)
            + w(self.lambda_p) * v.photometric.unwrap_or(0.0)
            + w(self.lambda_f) * v.features.unwrap_or(0.0)
            + w(self.lambda_o) * v.opacity_entropy.unwrap_or(0.0)
            + w(self.lambda_s) * v.flatness.unwrap_or(0.0)
    }
}

/// Accumulated ∂L/∂(rendered channel), handed to the rasterizer's backward pass.
#[derive(Debug, Default)]
pub struct GradientBuffers {
    /// ∂L/∂colour (of the colour the loss saw: after exposure correction, if any).
    pub color: Option<Image>,
    /// ∂L/∂Ñ, the rendered normal.
    pub normal: Option<Image>,
    /// ∂L/∂D, the rendered plane distance.
    pub distance: Option<Image>,
    /// ∂L/∂z, the plane depth.
    pub plane_depth: Option<Image>,
    /// ∂L/∂opacity logit of the parameter-space terms (L_o), added to the rasterizer's.
    pub opacity_logits: Option<Vec<f32>>,
    /// ∂L/∂log-scale of the parameter-space terms (L_s), added to the rasterizer's.
    pub log_scales: Option<Vec<[f32; 3]>>,
    /// ∂L/∂colour kept on the device, when the rendered colour stayed there (L_I alone
    /// writes it; `color` is then `None`).
    #[cfg(feature = "wgpu")]
    pub device_color: Option<gs_gpu::DeviceImage>,
    /// ∂L/∂Ñ and ∂L/∂(plane depth) kept on the device, when the rendered surface stayed there
    /// (L_nc/L_ns alone write them, already weighted; `normal` and `plane_depth` hold the
    /// other terms').
    #[cfg(feature = "wgpu")]
    pub device_geometry: Option<(gs_gpu::DeviceImage, gs_gpu::DeviceImage)>,
    /// L_p's gradient of Ñ and D kept on the device (gs-gpu `PlaneGrad`s) with its weight λ3.
    #[cfg(feature = "wgpu")]
    pub device_plane: Option<(gs_gpu::DeviceImage, f32)>,
}

impl GradientBuffers {
    /// `buffer += weight·g` (the first contribution is taken as is when `weight` is 1).
    pub fn add(buffer: &mut Option<Image>, g: Image, weight: f32) {
        match buffer {
            Some(a) => {
                for (x, y) in a.data_mut().iter_mut().zip(g.data()) {
                    *x += weight * y;
                }
            }
            None => {
                let mut a = g;
                if weight != 1.0 {
                    a.data_mut().iter_mut().for_each(|x| *x *= weight);
                }
                *buffer = Some(a);
            }
        }
    }

    /// The rasterizer's view of these buffers, with `color` standing in for the colour
    /// gradient (after the exposure backward, if any).
    pub fn as_output<'a>(&'a self, color: Option<&'a Image>) -> OutputGradients<'a> {
        OutputGradients {
            color,
            normal: self.normal.as_ref(),
            distance: self.distance.as_ref(),
            plane_depth: self.plane_depth.as_ref(),
            #[cfg(feature = "wgpu")]
            device_color: self.device_color.as_ref(),
            #[cfg(feature = "wgpu")]
            device_geometry: self.device_geometry.as_ref().map(|(normal, plane_depth)| gs_raster::DeviceGeometryGrads { normal, plane_depth }),
            #[cfg(feature = "wgpu")]
            device_plane: self.device_plane.as_ref().map(|(gradient, weight)| gs_raster::DevicePlaneGrads { gradient, weight: *weight }),
            ..Default::default()
        }
    }
}

/// A source view of L_p / L_f: its camera, rendered plane depth and cached photo data.
pub struct SourceInputs<'a> {
    /// Its training slot.
    pub slot: usize,
    /// Its camera.
    pub camera: &'a Camera,
    /// Its rendered plane depth (no gradient flows into sources): on the host, or on the
    /// device alone, where L_p reads it there (the executor reads it back for a term that
    /// needs it on the host).
    pub plane_depth: &'a StoredDepth,
    /// The iteration that rendered it: a device keeps the depth under this version.
    pub depth_version: u64,
    /// Its grey image (L_p).
    pub grey: Option<&'a Image>,
    /// Its feature map (L_f).
    pub features: Option<&'a FeatureMap>,
}

/// A source's plane depth for a term made on the host (the executor reads depths on the
/// device back before such a term runs).
fn on_host(depth: &StoredDepth) -> Result<&Image> {
    depth.host().ok_or_else(|| TrainError::InvalidConfig("a source plane depth on the device, read by a term on the host".into()))
}

/// The colour L_I compares with the photo: on the host (the render's, exposure-corrected when
/// that is on), or kept on the rasterizer's device.
#[derive(Clone, Copy)]
pub enum Colour<'a> {
    /// On the host.
    Host(&'a Image),
    /// On the device (`RenderRequest::color_on_device`).
    #[cfg(feature = "wgpu")]
    Device(&'a gs_gpu::DeviceImage),
}

/// What the terms read: the model, the reference view as rendered, its photo data and the sources.
pub struct TermInputs<'a> {
    /// The model the view was rendered from.
    pub gaussians: &'a Gaussians,
    /// The reference's training slot.
    pub slot: usize,
    /// The reference camera.
    pub camera: &'a Camera,
    /// The photograph I.
    pub photo: &'a Image,
    /// The rendered channels.
    pub render: &'a RenderOutput,
    /// The colour the loss compares (the render, exposure-corrected when that is on).
    pub color: Colour<'a>,
    /// ∇I and δ of the photograph (needed by the edge term, L_nc and L_ns).
    pub guide: Option<&'a EdgeGuide>,
    /// The reference grey image (L_p).
    pub grey: Option<&'a Image>,
    /// The reference feature map (L_f).
    pub features: Option<&'a FeatureMap>,
    /// The source views.
    pub sources: &'a [SourceInputs<'a>],
    /// The terms' device executors (a term without one runs on the CPU, the reference).
    pub devices: &'a LossDevices,
    /// The version under which L_p on the device keeps the reference's plane depth there for
    /// the depth memo (then the render did not bring it to the host); `None` keeps nothing.
    pub keep_depth: Option<u64>,
}

/// One term (or a group of terms that share their computation) of the loss.
pub trait LossTerm {
    /// Starts the term on `x`; its [`Fold`] records the unweighted value(s) in `values` and
    /// adds the gradient, weighted by `w`, into `grads`. A term with a device executor submits
    /// its work here and reads it in the fold, so that the terms started before the first fold
    /// cost the host one wait for the device; the others evaluate in the fold. The folds run
    /// in the terms' order.
    fn start<'a>(&'a self, x: &'a TermInputs<'a>, w: &'a LossWeights) -> Result<Fold<'a>>;

    /// The part of the iteration its time counts to ([`crate::profile`]).
    fn part(&self) -> Part;

    /// Evaluates the term on `x`: [`LossTerm::start`], then its fold.
    fn evaluate(&self, x: &TermInputs<'_>, w: &LossWeights, grads: &mut GradientBuffers, values: &mut LossValues) -> Result<()> {
        self.start(x, w)?.apply(grads, values)
    }
}

/// What a started term does to the gradients and values when its result is read.
pub struct Fold<'a>(Box<FoldFn<'a>>);

/// The body of a [`Fold`].
type FoldFn<'a> = dyn FnOnce(&mut GradientBuffers, &mut LossValues) -> Result<()> + 'a;

impl<'a> Fold<'a> {
    /// A fold that runs `f`.
    pub fn new(f: impl FnOnce(&mut GradientBuffers, &mut LossValues) -> Result<()> + 'a) -> Self {
        Self(Box::new(f))
    }

    /// Reads the term's result into `grads` and `values`.
    pub fn apply(self, grads: &mut GradientBuffers, values: &mut LossValues) -> Result<()> {
        (self.0)(grads, values)
    }
}

/// Stores a term's gradient kept on the device in its one slot of the step (`what` names the
/// slot): a second term writing the same slot is an error, not a silent overwrite.
#[cfg(feature = "wgpu")]
fn put_once<T>(slot: &mut Option<T>, gradient: T, what: &str) -> Result<()> {
    match slot.replace(gradient) {
        Some(_) => Err(crate::TrainError::InvalidConfig(format!("two {what} gradients on the device in one step"))),
        None => Ok(()),
    }
}

fn channel<'a>(c: &'a Option<Image>, name: &str) -> Result<&'a Image> {
    c.as_ref().ok_or_else(|| crate::TrainError::InvalidConfig(format!("the step plan did not request the {name} channel")))
}

fn needed<'a, T>(v: Option<&'a T>, what: &str) -> Result<&'a T> {
    v.ok_or_else(|| crate::TrainError::InvalidConfig(format!("{what} missing from the term inputs")))
}

/// L_I: (1 − β1)·L1 + β1·D-SSIM (+ β2·edge when β2 > 0 … and the phase has it).
pub struct ImageTerm {
    /// Whether the edge term is on.
    pub edge: bool,
}

impl LossTerm for ImageTerm {
    fn part(&self) -> Part {
        Part::ImageLoss
    }

    fn start<'a>(&'a self, x: &'a TermInputs<'a>, w: &'a LossWeights) -> Result<Fold<'a>> {
        let cfg = ImageLossConfig { beta1: w.beta1, beta2: w.beta2, edge: self.edge };
        match x.color {
            Colour::Host(color) => {
                let started = x.devices.start_image_loss(color, x.photo, x.guide, x.slot, &cfg)?;
                Ok(Fold::new(move |grads, values| {
                    let li = started.wait()?;
                    (values.l1, values.ssim, values.edge) = (li.l1, li.ssim, li.edge);
                    GradientBuffers::add(&mut grads.color, li.grad_rendered, 1.0);
                    Ok(())
                }))
            }
            #[cfg(feature = "wgpu")]
            Colour::Device(color) => {
                let started = x.devices.start_image_loss_on_device(color, x.photo, x.guide, x.slot, &cfg)?;
                Ok(Fold::new(move |grads, values| {
                    let li = started.wait()?;
                    (values.l1, values.ssim, values.edge) = (li.l1, li.ssim, li.edge);
                    put_once(&mut grads.device_color, li.grad_rendered, "colour")
                }))
            }
        }
    }
}

/// L_nc and L_ns, evaluated together (they share N̂ and its backward pass); λ1 and λ2 are
/// folded into that pass.
pub struct NormalTerms {
    /// Whether L_nc is on.
    pub consistency: bool,
    /// Whether L_ns is on.
    pub smoothing: bool,
    /// τ and the gate of L_ns.
    pub config: NormalLossConfig,
    /// Whether the rendered A counts (the plan renders it with these terms): on the device
    /// the surface carries A, so the render need not bring it to the host.
    pub with_alpha: bool,
}

impl LossTerm for NormalTerms {
    fn part(&self) -> Part {
        Part::NormalLosses
    }

    fn start<'a>(&'a self, x: &'a TermInputs<'a>, w: &'a LossWeights) -> Result<Fold<'a>> {
        let cfg = NormalLossConfig {
            lambda_nc: if self.consistency { w.lambda_nc } else { 0.0 },
            lambda_ns: if self.smoothing { w.lambda_ns } else { 0.0 },
            ..self.config
        };
        let r = x.render;
        let guide = needed(x.guide, "the edge guide")?;
        #[cfg(feature = "wgpu")]
        if let Some(surface) = &r.device_surface {
            let started = x.devices.start_normal_losses_on_device(surface, self.with_alpha, guide, &x.camera.intrinsics, x.slot, &cfg)?;
            return Ok(Fold::new(move |grads, values| {
                let nl = started.wait()?;
                values.normal_consistency = self.consistency.then_some(nl.l_nc);
                values.normal_smoothing = self.smoothing.then_some(nl.l_ns);
                put_once(&mut grads.device_geometry, (nl.grad_normal, nl.grad_plane_depth), "geometry")
            }));
        }
        let started = x.devices.start_normal_losses(
            channel(&r.plane_depth, "plane depth")?,
            channel(&r.normal, "normal")?,
            r.alpha.as_ref(),
            guide,
            &x.camera.intrinsics,
            x.slot,
            &cfg,
        )?;
        Ok(Fold::new(move |grads, values| {
            let nl = started.wait()?;
            values.normal_consistency = self.consistency.then_some(nl.l_nc);
            values.normal_smoothing = self.smoothing.then_some(nl.l_ns);
            GradientBuffers::add(&mut grads.normal, nl.grad_normal, 1.0);
            GradientBuffers::add(&mut grads.plane_depth, nl.grad_plane_depth, 1.0);
            Ok(())
        }))
    }
}

/// L_p, the multi-view photometric alignment (NCC of homography-warped patches).
pub struct PhotometricTerm {
    /// Patch size, NCC reading, pixel cap and sampling seed.
    pub config: PhotometricConfig,
}

impl LossTerm for PhotometricTerm {
    fn part(&self) -> Part {
        Part::Photometric
    }

    fn start<'a>(&'a self, x: &'a TermInputs<'a>, w: &'a LossWeights) -> Result<Fold<'a>> {
        #[cfg(feature = "wgpu")]
        if let Some(surface) = x.render.device_surface.as_ref().filter(|_| x.devices.photometric_on_device()) {
            return self.start_on_device(x, w, surface);
        }
        let r = x.render;
        let reference = PhotometricReference {
            camera: x.camera,
            normal: channel(&r.normal, "normal")?.into(),
            distance: channel(&r.distance, "distance")?.into(),
            plane_depth: channel(&r.plane_depth, "plane depth")?.into(),
            grey: needed(x.grey, "the reference grey image")?.into(),
        };
        let sources = Self::sources(x)?;
        let slots: Vec<usize> = std::iter::once(x.slot).chain(x.sources.iter().map(|s| s.slot)).collect();
        let started = x.devices.start_photometric_loss(&reference, &sources, &slots, &self.config)?;
        Ok(Fold::new(move |grads, values| {
            Self::fold_host(started.wait()?, w, grads, values);
            Ok(())
        }))
    }
}

impl PhotometricTerm {
    /// The sources' inputs of L_p.
    fn sources<'a>(x: &'a TermInputs<'a>) -> Result<Vec<PhotometricSource<'a, f32>>> {
        x.sources
            .iter()
            .map(|s| {
                let grey = needed(s.grey, "a source grey image")?;
                Ok(PhotometricSource { camera: s.camera, plane_depth: on_host(s.plane_depth)?.into(), grey: grey.into() })
            })
            .collect()
    }

    /// L_p of a reference whose rendered plane is the device's `surface`: its gradient image
    /// stays there for the backward (made on the host where the device cannot hold it).
    #[cfg(feature = "wgpu")]
    fn start_on_device<'a>(&'a self, x: &'a TermInputs<'a>, w: &'a LossWeights, surface: &'a gs_gpu::DeviceImage) -> Result<Fold<'a>> {
        let reference = gs_mvs::SurfaceReference {
            camera: x.camera,
            surface,
            plane_depth: x.render.plane_depth.as_ref().map(Into::into),
            grey: needed(x.grey, "the reference grey image")?.into(),
        };
        let slots: Vec<usize> = std::iter::once(x.slot).chain(x.sources.iter().map(|s| s.slot)).collect();
        let versions: Vec<u64> = x.sources.iter().map(|s| s.depth_version).collect();
        let sources = x
            .sources
            .iter()
            .map(|s| {
                let plane_depth = match s.plane_depth {
                    StoredDepth::Host(d) => gs_mvs::SourceDepth::Host(d.into()),
                    StoredDepth::Device { .. } => gs_mvs::SourceDepth::Held,
                };
                Ok(gs_mvs::DeviceSource { camera: s.camera, plane_depth, grey: needed(s.grey, "a source grey image")?.into() })
            })
            .collect::<Result<Vec<_>>>()?;
        let started = x.devices.start_photometric_loss_on_device(&reference, &sources, (&slots, &versions, x.keep_depth), &self.config)?;
        Ok(Fold::new(move |grads, values| {
            match started.wait()? {
                gs_mvs::PhotometricOnDevice::Device { loss, gradient, .. } => {
                    values.photometric = Some(loss);
                    put_once(&mut grads.device_plane, (gradient, w.lambda_p), "plane")?;
                }
                gs_mvs::PhotometricOnDevice::Host(lp) => Self::fold_host(lp, w, grads, values),
            }
            Ok(())
        }))
    }

    /// L_p made on the host: its value, and its gradient weighted into the host's buffers.
    fn fold_host(lp: gs_mvs::PhotometricOutput<f32>, w: &LossWeights, grads: &mut GradientBuffers, values: &mut LossValues) {
        values.photometric = Some(lp.loss);
        let (gn, gd) = lp.grad_images();
        GradientBuffers::add(&mut grads.normal, gn, w.lambda_p);
        GradientBuffers::add(&mut grads.distance, gd, w.lambda_p);
    }
}

/// L_o, the opacity entropy of the model (a parameter-space term; docs/method.md §L_o).
pub struct OpacityTerm;

impl LossTerm for OpacityTerm {
    fn part(&self) -> Part {
        Part::Optimizer
    }

    fn start<'a>(&'a self, x: &'a TermInputs<'a>, w: &'a LossWeights) -> Result<Fold<'a>> {
        Ok(Fold::new(move |grads, values| {
            let logits = &x.gaussians.opacity_logits;
            let g = grads.opacity_logits.get_or_insert_with(|| vec![0.0; logits.len()]);
            values.opacity_entropy = Some(opacity_entropy(logits, w.lambda_o, g)?);
            Ok(())
        }))
    }
}

/// L_s, PGSR's flattening term: the mean smallest scale of the model (a parameter-space term;
/// docs/method.md §L_s).
pub struct FlatnessTerm;

impl LossTerm for FlatnessTerm {
    fn part(&self) -> Part {
        Part::Optimizer
    }

    fn start<'a>(&'a self, x: &'a TermInputs<'a>, w: &'a LossWeights) -> Result<Fold<'a>> {
        Ok(Fold::new(move |grads, values| {
            let rows = &x.gaussians.log_scales;
            let g = grads.log_scales.get_or_insert_with(|| vec![[0.0; 3]; rows.len()]);
            values.flatness = Some(smallest_scale_mean(rows, w.lambda_s, g)?);
            Ok(())
        }))
    }
}
