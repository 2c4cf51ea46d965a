//! Source-view plane depths of L_p and L_f (docs/method.md §Visibility): the visibility υ_rs and weight ω
//! of a reference pixel need the source view's rendered plane depth D_s, which carries no
//! gradient. Rendering it for every source of every iteration costs N forward passes per
//! iteration (3 in `standard`, about a quarter of an L_p iteration at full resolution). Every
//! geometry-phase iteration already renders its reference view's D, so a view's depth from its
//! last render (as reference or as source) is reused while it is at most
//! [`crate::TrainConfig::source_depth_max_age`] iterations old; an older or missing one is
//! rendered. 0 renders every time (the paper). The memo is part of the training state and the
//! checkpoint, so a resumed run stays bit-identical.

use crate::error::{Result, TrainError};
use gs_core::Image;

/// A plane depth rendered at a reduced size, brought back to `width × height` (pixel centres
/// mapped to the low-resolution grid, bilinear). Depth 0 means "no depth" (no surface, or a
/// grazing plane): where any of the four taps has none, the nearest tap is taken instead, so
/// no depth is ever blended with "none" into a depth that no surface has.
pub fn upsample_depth(low: &Image, width: usize, height: usize) -> Result<Image> {
    let (lw, lh) = (low.width(), low.height());
    if low.channels() != 1 || lw == 0 || lh == 0 || width == 0 || height == 0 {
        return Err(TrainError::InvalidConfig(format!(
            "source depth upsampling: a {lw}x{lh}x{} map to {width}x{height}",
            low.channels()
        )));
    }
    let d = low.data();
    let (sx, sy) = (lw as f32 / width as f32, lh as f32 / height as f32);
    let mut out = vec![0.0f32; width * height];
    for (y, row) in out.chunks_mut(width).enumerate() {
        for (x, px) in row.iter_mut().enumerate() {
            let ([x0, x1, y0, y1], [fx, fy]) = low.bilinear_taps((x as f32 + 0.5) * sx, (y as f32 + 0.5) * sy);
            let t = [d[y0 * lw + x0], d[y0 * lw + x1], d[y1 * lw + x0], d[y1 * lw + x1]];
            *px = if t.iter().all(|&z| z > 0.0) {
                let top = t[0] + (t[1] - t[0]) * fx;
                let bottom = t[2] + (t[3] - t[2]) * fx;
                top + (bottom - top) * fy
            } else {
                let (nx, ny) = ((fx >= 0.5) as usize, (fy >= 0.5) as usize);
                t[2 * ny + nx]
            };
        }
    }
    Image::from_vec(width, height, 1, out).map_err(|e| TrainError::InvalidConfig(e.to_string()))
}

/// The last rendered plane depth of each training slot and the iteration that rendered it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SourceDepths {
    entries: Vec<Option<(u64, Image)>>,
}

impl SourceDepths {
    /// An empty memo for `views` training slots.
    pub fn new(views: usize) -> Self {
        Self { entries: vec![None; views] }
    }

    /// The memo of stored entries (one per training slot).
    pub fn from_entries(entries: Vec<Option<(u64, Image)>>) -> Self {
        Self { entries }
    }

    /// The entries, one per training slot.
    pub fn entries(&self) -> &[Option<(u64, Image)>] {
        &self.entries
    }

    /// Number of training slots.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether there are no slots.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// The depth of `slot` and the iteration that rendered it (the version under which a device
    /// keeps it), if that was at most `max_age` iterations before `iteration` (never with
    /// `max_age` 0).
    pub fn fresh(&self, slot: usize, iteration: u64, max_age: u64) -> Option<(&Image, u64)> {
        match self.entries.get(slot)? {
            Some((at, depth)) if max_age > 0 && iteration.saturating_sub(*at) <= max_age => Some((depth, *at)),
            _ => None,
        }
    }

    /// Records `depth` as rendered for `slot` at `iteration` (ignored for a slot out of range).
    pub fn store(&mut self, slot: usize, iteration: u64, depth: Image) {
        if let Some(e) = self.entries.get_mut(slot) {
            *e = Some((iteration, depth));
        }
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.entries.iter().flatten().map(|(_, d)| d.data().len() * 4).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn upsampled_depth_interpolates_surfaces_and_never_blends_with_none() {
        // A ramp z = 2 + 0.1·x + 0.05·y on a 4×3 grid, upsampled ×2: inside, the values are
        // the ramp at the mapped centres (bilinear reproduces an affine field exactly).
        let low: Vec<f32> = (0..12).map(|i| 2.0 + 0.1 * (i % 4) as f32 + 0.05 * (i / 4) as f32).collect();
        let low = Image::from_vec(4, 3, 1, low).unwrap();
        let up = upsample_depth(&low, 8, 6).unwrap();
        for y in 1..5 {
            for x in 1..7 {
                let (u, v) = ((x as f32 + 0.5) / 2.0 - 0.5, (y as f32 + 0.5) / 2.0 - 0.5);
                let want = 2.0 + 0.1 * u + 0.05 * v;
                assert!((up.get(x, y, 0) - want).abs() < 1e-5, "({x}, {y}): {} vs {want}", up.get(x, y, 0));
            }
        }
        // Borders clamp to the grid.
        assert!((up.get(0, 0, 0) - 2.0).abs() < 1e-6);
        // A hole (depth 0 = none): outputs are 0 or a depth of the surface, never in between.
        let mut d = vec![5.0f32; 16];
        d[5] = 0.0;
        d[6] = 0.0;
        let up = upsample_depth(&Image::from_vec(4, 4, 1, d).unwrap(), 8, 8).unwrap();
        assert!(up.data().iter().all(|&z| z == 0.0 || z == 5.0), "{:?}", up.data());
        assert_eq!(up.get(3, 3, 0), 0.0, "the hole's own pixels stay empty");
        // Same size: a copy. Bad shapes: an error.
        let same = upsample_depth(&low, 4, 3).unwrap();
        assert_eq!(same.data(), low.data());
        assert!(upsample_depth(&Image::filled(2, 2, 3, 1.0).unwrap(), 4, 4).is_err());
        assert!(upsample_depth(&low, 0, 4).is_err());
    }

    #[test]
    fn a_depth_is_reused_until_it_is_too_old() {
        let mut m = SourceDepths::new(3);
        assert!(m.fresh(1, 10, 50).is_none(), "nothing stored yet");
        m.store(1, 10, Image::filled(2, 2, 1, 3.0).unwrap());
        assert_eq!(m.fresh(1, 60, 50).map(|(d, at)| (d.get(0, 0, 0), at)), Some((3.0, 10)));
        assert!(m.fresh(1, 61, 50).is_none(), "51 iterations old");
        assert!(m.fresh(1, 10, 0).is_none(), "max age 0 renders every time");
        assert!(m.fresh(0, 10, 50).is_none() && m.fresh(7, 10, 50).is_none());
        m.store(9, 10, Image::filled(2, 2, 1, 1.0).unwrap());
        assert_eq!(m.bytes(), 16);
    }
}
