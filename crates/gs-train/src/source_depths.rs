//! Source-view plane depths of L_p and L_f (docs/method.md §Visibility): the visibility υ_rs and weight ω
//! of a reference pixel need the source view's rendered plane depth D_s, which carries no
//! gradient. Rendering it for every source of every iteration costs N forward passes per
//! iteration (3 in `standard`, about a quarter of an L_p iteration at full resolution). Every
//! geometry-phase iteration already renders its reference view's D, so a view's depth from its
//! last render (as reference or as source) is reused while it is at most
//! [`crate::TrainConfig::source_depth_max_age`] iterations old; an older or missing one is
//! rendered. 0 renders every time (the paper). The memo is part of the training state and the
//! checkpoint, so a resumed run stays bit-identical.
//!
//! Where L_p runs on the device and its arena holds every view's grey image and depth at once
//! ([`memo_fits_on_device`]), a reference's depth stays there ([`StoredDepth::Device`]): it
//! neither comes back from the render nor goes up again as a source. The host reads such
//! depths back only where it reads them ([`bring_back`]): a checkpoint, L_f, a term made on the
//! host. The values are the same bits either way (the surface's z is the plane depth a render
//! reads back), so the memo's place changes no result.

use crate::caches::ViewCaches;
use crate::devices::LossDevices;
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

/// Where a memo's depth is.
#[derive(Debug, Clone, PartialEq)]
pub enum StoredDepth {
    /// On the host.
    Host(Image),
    /// On the device alone, `width × height` values in L_p's arena (kept there by the step that
    /// rendered the view as its reference: docs/architecture.md §GPU); the host reads it back
    /// when it needs it ([`crate::executor::StepExecutor::pull`], a step whose terms read it on
    /// the host).
    Device {
        /// Columns.
        width: usize,
        /// Rows.
        height: usize,
    },
}

impl StoredDepth {
    /// The depth on the host, if it is there.
    pub fn host(&self) -> Option<&Image> {
        match self {
            StoredDepth::Host(d) => Some(d),
            StoredDepth::Device { .. } => None,
        }
    }
}

/// The last rendered plane depth of each training slot and the iteration that rendered it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SourceDepths {
    entries: Vec<Option<(u64, StoredDepth)>>,
}

impl SourceDepths {
    /// An empty memo for `views` training slots.
    pub fn new(views: usize) -> Self {
        Self { entries: vec![None; views] }
    }

    /// The memo of stored entries on the host (one per training slot).
    pub fn from_entries(entries: Vec<Option<(u64, Image)>>) -> Self {
        Self { entries: entries.into_iter().map(|e| e.map(|(at, d)| (at, StoredDepth::Host(d)))).collect() }
    }

    /// The entries, one per training slot.
    pub fn entries(&self) -> &[Option<(u64, StoredDepth)>] {
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
    pub fn fresh(&self, slot: usize, iteration: u64, max_age: u64) -> Option<(&StoredDepth, u64)> {
        match self.entries.get(slot)? {
            Some((at, depth)) if max_age > 0 && iteration.saturating_sub(*at) <= max_age => Some((depth, *at)),
            _ => None,
        }
    }

    /// Records `depth` as rendered for `slot` at `iteration` (ignored for a slot out of range).
    pub fn store(&mut self, slot: usize, iteration: u64, depth: StoredDepth) {
        if let Some(e) = self.entries.get_mut(slot) {
            *e = Some((iteration, depth));
        }
    }

    /// Forgets the depth of `slot` (one the device no longer holds: it is rendered again).
    pub fn forget(&mut self, slot: usize) {
        if let Some(e) = self.entries.get_mut(slot) {
            *e = None;
        }
    }

    /// The slots whose depths are on the device alone, among `slots` (all when `None`).
    pub fn on_device(&self, slots: Option<&[usize]>) -> Vec<usize> {
        let held = |s: &usize| matches!(self.entries.get(*s), Some(Some((_, StoredDepth::Device { .. }))));
        match slots {
            Some(slots) => slots.iter().copied().filter(held).collect(),
            None => (0..self.entries.len()).filter(held).collect(),
        }
    }

    /// Bytes held on the host.
    pub fn bytes(&self) -> usize {
        self.entries.iter().flatten().filter_map(|(_, d)| d.host()).map(|d| d.data().len() * 4).sum()
    }
}

/// Whether the memo may keep depths on the device alone for this run: every training view has
/// one size, and L_p's arena on the device holds every view's grey image (at `ncc_scale`) and
/// depth at once, so that none is ever evicted.
pub(crate) fn memo_fits_on_device(run: &crate::executor::RunInputs<'_>, devices: &LossDevices) -> bool {
    let mut sizes = run.train_views.iter().map(|&v| (run.scene.views[v].camera.width as usize, run.scene.views[v].camera.height as usize));
    let Some((w, h)) = sizes.next() else { return false };
    let s = run.config.ncc_scale as usize;
    sizes.all(|size| size == (w, h)) && devices.memo_fits(run.train_views.len(), w * h * s * s)
}

/// A depth on the device alone: the grey image that names its key, its version and its size.
type DeviceEntry<'c> = (&'c Image, u64, usize, usize);

/// The key of `slot`'s depth on the device and its version and size, if it is on the device
/// alone and the slot's grey image (which names the key) is cached.
fn device_entry<'c>(memo: &SourceDepths, caches: &'c ViewCaches, slot: usize) -> Option<DeviceEntry<'c>> {
    match memo.entries.get(slot)? {
        Some((at, StoredDepth::Device { width, height })) => Some((caches.grey(slot)?, *at, *width, *height)),
        _ => None,
    }
}

/// Forgets the depths of `slots` on the device alone that the device does not hold (rendered
/// again when needed): the arena is sized never to evict them, so this only guards.
pub(crate) fn drop_lost(memo: &mut SourceDepths, devices: &LossDevices, caches: &ViewCaches, slots: &[usize]) {
    for &s in &memo.on_device(Some(slots)) {
        let held = device_entry(memo, caches, s).is_some_and(|(grey, at, w, h)| devices.holds_depth(s, grey, w * h, at));
        if !held {
            memo.forget(s);
        }
    }
}

/// Reads the depths of `slots` (all when `None`) that are on the device alone back to the host,
/// at one wait; one the device no longer holds is forgotten (rendered again when needed).
pub(crate) fn bring_back(memo: &mut SourceDepths, devices: &LossDevices, caches: &ViewCaches, slots: Option<&[usize]>) -> Result<()> {
    let on_device = memo.on_device(slots);
    if on_device.is_empty() {
        return Ok(());
    }
    let found: Vec<(usize, Option<DeviceEntry<'_>>)> = on_device.iter().map(|&s| (s, device_entry(memo, caches, s))).collect();
    let items: Vec<_> = found.iter().filter_map(|&(s, e)| e.map(|(grey, at, w, h)| (s, grey, w * h, at))).collect();
    let mut read = devices.held_depths(&items)?.into_iter();
    for (s, entry) in found {
        let values = entry.and_then(|_| read.next().flatten());
        match (entry, values) {
            (Some((_, at, w, h)), Some(v)) => memo.store(s, at, StoredDepth::Host(Image::from_vec(w, h, 1, v)?)),
            _ => memo.forget(s),
        }
    }
    Ok(())
}

/// What keeps a source depth on the device: the loss terms' devices, the view caches and the
/// rasterizer whose render made it.
pub(crate) type Keepers<'a> = (&'a LossDevices, &'a ViewCaches, &'a gs_raster::Rasterizer);

/// The memo entry of source `slot`'s depth, rendered at `version` into `out`'s surface on the
/// device: kept there in L_p's arena, or (where the arena did not take it) read back.
#[cfg(feature = "wgpu")]
pub(crate) fn keep_source_depth((devices, caches, rasterizer): Keepers<'_>, slot: usize, out: &gs_raster::RenderOutput, version: u64) -> Result<StoredDepth> {
    let (Some(surface), Some(grey), Some(ctx)) = (out.device_surface.as_ref(), caches.grey(slot), rasterizer.gpu_context()) else {
        return Err(TrainError::InvalidConfig("a source depth kept on the device without its surface, grey image or device".into()));
    };
    let (width, height) = (surface.width(), surface.height());
    if devices.keep_depth(slot, grey, surface, version)? {
        return Ok(StoredDepth::Device { width, height });
    }
    Ok(StoredDepth::Host(Image::from_vec(width, height, 1, gs_mvs::surface_depth(ctx, surface)?)?))
}

/// Without the device: never asked (no depth stays on a device).
#[cfg(not(feature = "wgpu"))]
pub(crate) fn keep_source_depth(_: Keepers<'_>, _: usize, _: &gs_raster::RenderOutput, _: u64) -> Result<StoredDepth> {
    Err(TrainError::InvalidConfig("a source depth kept on a device in a build without wgpu".into()))
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
        m.store(1, 10, StoredDepth::Host(Image::filled(2, 2, 1, 3.0).unwrap()));
        assert_eq!(m.fresh(1, 60, 50).map(|(d, at)| (d.host().unwrap().get(0, 0, 0), at)), Some((3.0, 10)));
        assert!(m.fresh(1, 61, 50).is_none(), "51 iterations old");
        assert!(m.fresh(1, 10, 0).is_none(), "max age 0 renders every time");
        assert!(m.fresh(0, 10, 50).is_none() && m.fresh(7, 10, 50).is_none());
        m.store(9, 10, StoredDepth::Host(Image::filled(2, 2, 1, 1.0).unwrap()));
        assert_eq!(m.bytes(), 16);
        // A depth on the device is served like one on the host, costs the host nothing, and
        // is listed for its readback until forgotten.
        m.store(2, 20, StoredDepth::Device { width: 4, height: 3 });
        assert_eq!(m.fresh(2, 30, 50).map(|(d, at)| (d.clone(), at)), Some((StoredDepth::Device { width: 4, height: 3 }, 20)));
        assert_eq!((m.bytes(), m.on_device(None), m.on_device(Some(&[1, 2]))), (16, vec![2], vec![2]));
        assert!(m.on_device(Some(&[0, 1])).is_empty());
        m.forget(2);
        assert!(m.fresh(2, 30, 50).is_none() && m.on_device(None).is_empty());
    }
}
