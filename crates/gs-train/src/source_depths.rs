//! Source-view plane depths of L_p and L_f (method-spec §6): the visibility υ_rs and weight ω
//! of a reference pixel need the source view's rendered plane depth D_s, which carries no
//! gradient. Rendering it for every source of every iteration costs N forward passes per
//! iteration (3 in `standard`, about a quarter of an L_p iteration at full resolution). Every
//! geometry-phase iteration already renders its reference view's D, so a view's depth from its
//! last render (as reference or as source) is reused while it is at most
//! [`crate::TrainConfig::source_depth_max_age`] iterations old; an older or missing one is
//! rendered. 0 renders every time (the paper). The memo is part of the training state and the
//! checkpoint, so a resumed run stays bit-identical.

use gs_core::Image;

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

    /// The depth of `slot` if it was rendered at most `max_age` iterations before `iteration`
    /// (never with `max_age` 0).
    pub fn fresh(&self, slot: usize, iteration: u64, max_age: u64) -> Option<&Image> {
        match self.entries.get(slot)? {
            Some((at, depth)) if max_age > 0 && iteration.saturating_sub(*at) <= max_age => Some(depth),
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
    fn a_depth_is_reused_until_it_is_too_old() {
        let mut m = SourceDepths::new(3);
        assert!(m.fresh(1, 10, 50).is_none(), "nothing stored yet");
        m.store(1, 10, Image::filled(2, 2, 1, 3.0).unwrap());
        assert_eq!(m.fresh(1, 60, 50).map(|d| d.get(0, 0, 0)), Some(3.0));
        assert!(m.fresh(1, 61, 50).is_none(), "51 iterations old");
        assert!(m.fresh(1, 10, 0).is_none(), "max age 0 renders every time");
        assert!(m.fresh(0, 10, 50).is_none() && m.fresh(7, 10, 50).is_none());
        m.store(9, 10, Image::filled(2, 2, 1, 1.0).unwrap());
        assert_eq!(m.bytes(), 16);
    }
}
