//! Coarse-to-fine rendering (DashGaussian, issue #18): the colour warm-up renders and compares
//! at a fraction of the training resolution, rising to full. An early iteration then costs a
//! quarter or a sixteenth of a full one, while the model still only needs the coarse shape.

use serde::{Deserialize, Serialize};

/// The render-resolution schedule of the colour warm-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct CoarseToFine {
    /// The first iterations render at 1/2^levels of the training size; 0 = always full size.
    pub levels: u32,
    /// From this iteration on (and always in the geometry phases) the full size is used; the
    /// iterations before it are split evenly between 1/2^levels, …, 1/2 and 1.
    pub until: u64,
}

impl CoarseToFine {
    /// The downscale factor (1, 2, 4, 8) of 1-based iteration `it`.
    pub fn scale(&self, it: u64) -> u32 {
        if self.levels == 0 || it > self.until || self.until == 0 {
            return 1;
        }
        let stage = ((it - 1) * (self.levels as u64 + 1) / self.until) as u32;
        1 << self.levels.saturating_sub(stage)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scale_falls_to_full_size() {
        let c = CoarseToFine { levels: 2, until: 900 };
        assert_eq!([c.scale(1), c.scale(300), c.scale(301), c.scale(600), c.scale(601), c.scale(900), c.scale(901)], [4, 4, 2, 2, 1, 1, 1]);
        assert_eq!(CoarseToFine::default().scale(1), 1);
        assert_eq!(CoarseToFine { levels: 1, until: 10 }.scale(5), 2);
    }
}
