//! Per-view data derived once from the training photographs and reused every time a view is
//! the reference or a source: the edge guide (∇I, δ; docs/method.md §L_I, §L_nc, §L_ns), the grey image of
//! L_p (§L_p) and the VGG16 feature map F of L_f (§L_f). Built lazily, indexed by training slot.

use crate::devices::LossDevices;
use crate::error::{Result, TrainError};
use gs_core::{Image, Scene};
use gs_features::{FeatureLevel, FeatureMap, Vgg16};
use gs_losses::EdgeGuide;

/// The caches of one run's training views (slot k = `train_views[k]`).
pub struct ViewCaches {
    guides: Vec<Option<EdgeGuide>>,
    greys: Vec<Option<Image>>,
    vgg: Option<Vgg16>,
    features: Vec<Option<FeatureMap>>,
    /// Downscaled photographs of coarse-to-fine rendering: (scale, image) per slot.
    scaled: Vec<Vec<(u32, Image)>>,
}

/// The camera of an image `scale` times smaller (each side floored, at least 1 pixel).
pub fn downscaled_camera(camera: &gs_core::Camera, scale: u32) -> Result<gs_core::Camera> {
    if scale <= 1 {
        return Ok(camera.clone());
    }
    Ok(camera.resized((camera.width / scale).max(1), (camera.height / scale).max(1))?)
}

impl ViewCaches {
    /// Empty caches for `views` training views.
    pub fn new(views: usize) -> Self {
        Self {
            guides: (0..views).map(|_| None).collect(),
            greys: (0..views).map(|_| None).collect(),
            vgg: None,
            features: (0..views).map(|_| None).collect(),
            scaled: (0..views).map(|_| Vec::new()).collect(),
        }
    }

    /// Area-averages the photograph of slot `slot` to `camera`'s size (a downscaled camera of
    /// coarse-to-fine rendering) when not cached yet.
    pub fn ensure_scaled(&mut self, slot: usize, photo: &Image, scale: u32, camera: &gs_core::Camera) -> Result<()> {
        if scale > 1 && !self.scaled[slot].iter().any(|(s, _)| *s == scale) {
            let img = photo.resize_area(camera.width as usize, camera.height as usize)?;
            self.scaled[slot].push((scale, img));
        }
        Ok(())
    }

    /// The photograph of slot `slot` at 1/`scale` size if cached.
    pub fn scaled(&self, slot: usize, scale: u32) -> Option<&Image> {
        self.scaled[slot].iter().find(|(s, _)| *s == scale).map(|(_, i)| i)
    }

    /// Bytes held (guides, grey images, feature maps).
    pub fn bytes(&self) -> usize {
        let img = |i: &Image| i.data().len() * 4;
        self.guides.iter().flatten().map(|g| img(&g.gradient) + img(&g.delta)).sum::<usize>()
            + self.greys.iter().flatten().map(img).sum::<usize>()
            + self.features.iter().flatten().map(|f| f.memory_bytes()).sum::<usize>()
            + self.scaled.iter().flatten().map(|(_, i)| img(i)).sum::<usize>()
    }

    /// The edge guide of slot `slot`, built from `photo` on first use. Without `delta`
    /// (`--no-delta`) δ ≡ 1 inside and 0 on the border, where N̂ is undefined.
    pub fn guide(&mut self, slot: usize, photo: &Image, delta: bool) -> Result<&EdgeGuide> {
        if self.guides[slot].is_none() {
            let mut guide = EdgeGuide::from_gt(photo)?;
            if !delta {
                let (w, h) = (guide.delta.width(), guide.delta.height());
                for y in 0..h {
                    for x in 0..w {
                        let inside = x > 0 && y > 0 && x + 1 < w && y + 1 < h;
                        guide.delta.set(x, y, 0, if inside { 1.0 } else { 0.0 });
                    }
                }
            }
            self.guides[slot] = Some(guide);
        }
        Ok(self.guides[slot].as_ref().expect("set above"))
    }

    /// The edge guide of slot `slot` if built.
    pub fn guide_of(&self, slot: usize) -> Option<&EdgeGuide> {
        self.guides[slot].as_ref()
    }

    /// New caches holding this one's grey images alone (those supplied at a higher
    /// resolution need a copy; everything else is made again from the photographs).
    pub fn greys_copy(&self) -> Self {
        Self { greys: self.greys.clone(), ..Self::new(self.greys.len()) }
    }

    /// Supplies the grey images of L_p (one per slot, already checked for size).
    pub fn set_greys(&mut self, greys: Vec<Image>) {
        self.greys = greys.into_iter().map(Some).collect();
    }

    /// Builds the grey image of slot `slot` from `photo` when missing; with `ncc_scale` above 1
    /// they must have been supplied ([`ViewCaches::set_greys`]).
    pub fn ensure_grey(&mut self, slot: usize, photo: &Image, ncc_scale: u32) -> Result<()> {
        if self.greys[slot].is_none() {
            if ncc_scale != 1 {
                return Err(TrainError::InvalidConfig(format!(
                    "ncc_scale = {ncc_scale} needs the high-resolution grey images (Trainer::set_grey_images)"
                )));
            }
            self.greys[slot] = Some(photo.to_grey()?);
        }
        Ok(())
    }

    /// The grey image of slot `slot` if built.
    pub fn grey(&self, slot: usize) -> Option<&Image> {
        self.greys[slot].as_ref()
    }

    /// Extracts the feature map of slot `slot` from `photo` when missing: on the device where
    /// `devices` has an extractor, else on the host (loading the bundled VGG16 on first use).
    pub fn ensure_features(&mut self, slot: usize, photo: &Image, level: FeatureLevel, devices: &LossDevices) -> Result<()> {
        if self.features[slot].is_none() {
            let map = match devices.device_features(photo, level) {
                Some(map) => map?,
                None => {
                    if self.vgg.is_none() {
                        self.vgg = Some(Vgg16::bundled()?);
                    }
                    self.vgg.as_ref().expect("set above").extract(photo, level)?
                }
            };
            self.features[slot] = Some(map);
        }
        Ok(())
    }

    /// The feature map of slot `slot` if built.
    pub fn features(&self, slot: usize) -> Option<&FeatureMap> {
        self.features[slot].as_ref()
    }
}

/// The photograph of training slot `slot`.
pub(crate) fn photo<'s>(scene: &'s Scene, train_views: &[usize], slot: usize) -> &'s Image {
    &scene.views[train_views[slot]].image
}
