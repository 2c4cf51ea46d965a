//! L_f, the multi-view alignment of deep (VGG16) features, behind the loss-term contract: on
//! the device where the reference's surface is there (υ/ω made by L_p's kernels, no depth
//! crossing, the gradient kept there), else from depths on the host (docs/method.md §L_f,
//! docs/architecture.md §GPU).

use super::{Fold, GradientBuffers, LossTerm, LossValues, TermInputs, needed, on_host};
use crate::config::LossWeights;
use crate::error::{Result, TrainError};
use crate::profile::Part;
use crate::source_depths::StoredDepth;
use gs_core::{Camera, Image};
use gs_features::FeatureMap;
use gs_mvs::AlignView;

/// L_f, the multi-view alignment of deep (VGG16) features.
pub struct FeatureTerm;

impl LossTerm for FeatureTerm {
    fn part(&self) -> Part {
        Part::Features
    }

    fn start<'a>(&'a self, x: &'a TermInputs<'a>, w: &'a LossWeights) -> Result<Fold<'a>> {
        #[cfg(feature = "wgpu")]
        if let Some(started) = Self::start_on_device(x)? {
            return Ok(Fold::new(move |grads, values| {
                let lf = started.wait()?;
                values.features = Some(lf.loss);
                match &grads.device_geometry {
                    Some((_, plane_depth)) => Ok(x.devices.add_feature_gradient(&lf.gradient, w.lambda_f, plane_depth)?),
                    None => {
                        let g = x.devices.read_image(&lf.gradient)?;
                        GradientBuffers::add(&mut grads.plane_depth, Image::from_vec(lf.gradient.width(), lf.gradient.height(), 1, g)?, w.lambda_f);
                        Ok(())
                    }
                }
            }));
        }
        Ok(Fold::new(move |grads, values| self.align(x, w, grads, values)))
    }
}

impl FeatureTerm {
    /// L_f started on the device where the reference's surface is there: υ/ω made there by
    /// L_p's kernels (lent by L_p's evaluation of this step, or made for L_f alone), no depth
    /// read back, and the gradient kept there, to be added into L_nc/L_ns's plane-depth
    /// gradient (read back where that is on the host). `None` elsewhere.
    #[cfg(feature = "wgpu")]
    fn start_on_device<'a>(x: &'a TermInputs<'a>) -> Result<Option<crate::devices::Deferred<'a, gs_mvs::FeaturesOnDevice, gs_mvs::MvsError>>> {
        let (Some(surface), Some(grey)) = (x.render.device_surface.as_ref(), x.grey) else { return Ok(None) };
        let view = |camera, features, slot: usize| gs_mvs::DeviceAlignView { camera, features, key: slot as u64 };
        let reference = view(x.camera, needed(x.features, "the reference feature map")?, x.slot);
        let mut views = Vec::with_capacity(x.sources.len());
        let mut depths = Vec::with_capacity(x.sources.len());
        for s in x.sources {
            let Some(grey) = s.grey else { return Ok(None) };
            views.push(view(s.camera, needed(s.features, "a source feature map")?, s.slot));
            let plane_depth = match s.plane_depth {
                StoredDepth::Host(d) => gs_mvs::SourceDepth::Host(d.into()),
                StoredDepth::Device { .. } => gs_mvs::SourceDepth::Held,
            };
            depths.push(gs_mvs::DeviceSource { camera: s.camera, plane_depth, grey: grey.into() });
        }
        let versions: Vec<u64> = x.sources.iter().map(|s| s.depth_version).collect();
        Ok(x.devices.start_feature_loss_on_device((&reference, surface, grey), (&views, &depths), (&versions, x.keep_depth))?)
    }

    /// L_f (on its device executor where there is one) from depths on the host, made when the
    /// term is folded: depths that stayed on the device (the reference's surface, the sources'
    /// in L_p's arena) are read back first.
    fn align(&self, x: &TermInputs<'_>, w: &LossWeights, grads: &mut GradientBuffers, values: &mut LossValues) -> Result<()> {
        let reference_depth = match &x.render.plane_depth {
            Some(d) => std::borrow::Cow::Borrowed(d),
            None => std::borrow::Cow::Owned(surface_depth(x)?),
        };
        let held = held_source_depths(x)?;
        fn view<'a>(camera: &'a Camera, plane_depth: &'a Image, features: &'a FeatureMap, slot: usize) -> AlignView<'a> {
            AlignView { camera, plane_depth: plane_depth.into(), features, key: slot as u64 }
        }
        let reference = view(x.camera, &reference_depth, needed(x.features, "the reference feature map")?, x.slot);
        let sources = x
            .sources
            .iter()
            .zip(&held)
            .map(|(s, h)| Ok(view(s.camera, h.as_ref().map_or_else(|| on_host(s.plane_depth), Ok)?, needed(s.features, "a source feature map")?, s.slot)))
            .collect::<Result<Vec<AlignView<'_>>>>()?;
        let lf = x.devices.feature_loss(&reference, &sources)?;
        values.features = Some(lf.loss);
        let g = Image::from_vec(lf.width, lf.height, 1, lf.grad_plane_depth)?;
        GradientBuffers::add(&mut grads.plane_depth, g, w.lambda_f);
        Ok(())
    }
}

/// The reference's plane depth where it stayed in the rendered surface on the device (its
/// z), read back.
fn surface_depth(x: &TermInputs<'_>) -> Result<Image> {
    #[cfg(feature = "wgpu")]
    if let Some(surface) = &x.render.device_surface {
        return Ok(Image::from_vec(surface.width(), surface.height(), 1, x.devices.surface_depth(surface)?)?);
    }
    let _ = x;
    Err(TrainError::InvalidConfig("the step plan did not request the plane depth channel".into()))
}

/// The sources' depths that are on the device alone (in L_p's arena), read back at one wait
/// (`None` for a depth on the host); an error names one the device no longer holds.
fn held_source_depths(x: &TermInputs<'_>) -> Result<Vec<Option<Image>>> {
    let items: Vec<_> = x
        .sources
        .iter()
        .filter_map(|s| match (s.plane_depth, s.grey) {
            (StoredDepth::Device { width, height }, Some(grey)) => Some((s.slot, grey, width * height, s.depth_version)),
            _ => None,
        })
        .collect();
    if items.is_empty() {
        return Ok(vec![None; x.sources.len()]);
    }
    let mut read = x.devices.held_depths(&items)?.into_iter();
    x.sources
        .iter()
        .map(|s| match s.plane_depth {
            StoredDepth::Device { width, height } if s.grey.is_some() => match read.next().flatten() {
                Some(v) => Ok(Some(Image::from_vec(*width, *height, 1, v)?)),
                None => Err(TrainError::InvalidConfig(format!("source view {}'s plane depth is no longer held on the device", s.slot))),
            },
            _ => Ok(None),
        })
        .collect()
}
