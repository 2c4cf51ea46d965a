//! Per-training-image feature cache: F = f(I) is computed once from the GT image and kept in
//! memory for the whole run (docs/method.md §L_f).
//!
//! Budget per 800×600 image: conv2_2 400·300·128·4 B = 61.4 MB in f32, 30.7 MB in f16;
//! conv3_3 200·150·256·4 B = 30.7 MB (f16 15.4 MB). [`ExtractOptions::bytes_per_image`] gives
//! the exact figure for any size and option set.

use crate::error::{FeatureError, Result};
use crate::map::FeatureMap;
use crate::net::{ExtractOptions, Vgg16};
use gs_core::Image;

/// Feature maps of the training views, indexed like the scene's views.
#[derive(Debug, Clone)]
pub struct FeatureCache {
    options: ExtractOptions,
    maps: Vec<Option<FeatureMap>>,
}

impl FeatureCache {
    /// An empty cache for `views` views (nothing computed until asked: a map is only built when
    /// L_f is active, docs/architecture.md §Economy).
    pub fn new(views: usize, options: ExtractOptions) -> Self {
        Self { options, maps: vec![None; views] }
    }

    /// A cache with every view's map computed now.
    pub fn build(net: &Vgg16, images: &[&Image], options: ExtractOptions) -> Result<Self> {
        let mut cache = Self::new(images.len(), options);
        for (i, img) in images.iter().enumerate() {
            cache.get_or_compute(net, i, img)?;
        }
        Ok(cache)
    }

    /// The options every map is computed with.
    pub fn options(&self) -> &ExtractOptions {
        &self.options
    }

    /// Number of view slots.
    pub fn len(&self) -> usize {
        self.maps.len()
    }

    /// Whether the cache has no view slots.
    pub fn is_empty(&self) -> bool {
        self.maps.is_empty()
    }

    /// The map of view `index`, computing it from `image` on first use.
    pub fn get_or_compute(&mut self, net: &Vgg16, index: usize, image: &Image) -> Result<&FeatureMap> {
        let n = self.maps.len();
        let slot = self.maps.get_mut(index).ok_or_else(|| {
            FeatureError::InvalidParameter(format!("view index {index} out of range (cache has {n} views)"))
        })?;
        if slot.is_none() {
            *slot = Some(net.extract_with(image, &self.options).map_err(|e| match e {
                FeatureError::InvalidImage(m) => FeatureError::InvalidImage(format!("view {index}: {m}")),
                other => other,
            })?);
        }
        Ok(slot.as_ref().expect("just filled"))
    }

    /// The map of view `index` if computed.
    pub fn get(&self, index: usize) -> Option<&FeatureMap> {
        self.maps.get(index).and_then(|m| m.as_ref())
    }

    /// Bytes held by all computed maps.
    pub fn memory_bytes(&self) -> usize {
        self.maps.iter().flatten().map(FeatureMap::memory_bytes).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{FeatureLevel, StoragePrecision};

    #[test]
    fn computes_once_and_reports_memory() {
        let net = Vgg16::bundled().unwrap();
        let a = Image::filled(16, 12, 3, 0.3).unwrap();
        let b = Image::filled(16, 12, 3, 0.7).unwrap();
        let opts = ExtractOptions { precision: StoragePrecision::F16, ..ExtractOptions::at(FeatureLevel::Conv2_2) };
        let mut cache = FeatureCache::new(3, opts.clone());
        assert_eq!(cache.memory_bytes(), 0);
        assert!(cache.get(0).is_none());
        let first = cache.get_or_compute(&net, 1, &a).unwrap().clone();
        // A second call returns the cached map, whatever image is passed.
        assert_eq!(cache.get_or_compute(&net, 1, &b).unwrap(), &first);
        assert_eq!(cache.memory_bytes(), 8 * 6 * 128 * 2);
        assert_eq!(cache.memory_bytes(), opts.bytes_per_image(16, 12));
        assert_eq!(cache.get(1).unwrap().channels(), 128);
        assert!(cache.get_or_compute(&net, 3, &a).unwrap_err().to_string().contains("out of range"));
        let tiny = Image::new(1, 1, 3).unwrap();
        assert!(cache.get_or_compute(&net, 0, &tiny).unwrap_err().to_string().contains("view 0"));
        let built = FeatureCache::build(&net, &[&a, &b], opts).unwrap();
        assert_eq!(built.get(0).unwrap(), &first);
        assert_eq!(built.len(), 2);
    }

    #[test]
    fn budget_at_800x600() {
        let f32_22 = ExtractOptions::at(FeatureLevel::Conv2_2);
        assert_eq!(f32_22.bytes_per_image(800, 600), 61_440_000);
        let f16_22 = ExtractOptions { precision: StoragePrecision::F16, ..f32_22 };
        assert_eq!(f16_22.bytes_per_image(800, 600), 30_720_000);
        assert_eq!(ExtractOptions::at(FeatureLevel::Conv3_3).bytes_per_image(800, 600), 30_720_000);
    }
}
