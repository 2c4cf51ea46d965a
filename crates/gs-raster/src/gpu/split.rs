//! How the blend kernels share a 16×16 tile's 256 pixels among a workgroup's threads
//! (docs/architecture.md §GPU, "the blend kernels' tile split").
//!
//! A thread that owns several pixels reads each Gaussian of the tile's list once for all of
//! them, and the backward's workgroup reduction then runs over fewer threads and for several
//! Gaussians at a time (two barriers per round of [`TileSplit::backward_group`] Gaussians).
//! Software Vulkan runs a workgroup as a few SIMD lanes that switch at every barrier, so it
//! wants few threads with many pixels; a GPU wants enough threads to fill its lanes. The
//! split changes the order of no sum within a pixel, only which thread adds a pixel's part of
//! a Gaussian's gradient, so each split is reproducible bit for bit on its own.

use crate::{RasterError, Result};

/// Pixels in one tile (16 × 16).
const TILE_PIXELS: u32 = 256;
/// The backward's round values in workgroup memory: group × 16 components × threads floats
/// (8 KiB, half of WebGPU's default workgroup storage).
const ROUND_VALUES: u32 = 2048;
/// Gradient components per Gaussian in the backward's reduction.
const COMPONENTS: u32 = 16;
/// Software Vulkan (llvmpipe) ends an invocation after 65,535 loop iterations in all, counted
/// over every loop it runs: the blends walk long tile lists in windows (a dispatch each, with
/// the per-pixel state kept in buffers between them) sized to stay below it.
const LOOP_LIMIT: u32 = 65_535;
/// Tile-list positions per backward dispatch (the unit test `windows_stay_below_the_loop_limit`
/// keeps each split's walk of one window below [`LOOP_LIMIT`]).
pub(crate) const BWD_WINDOW: u32 = 256;

/// Threads per tile of the forward and the backward blend (powers of two).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TileSplit {
    /// `raster_fwd`'s threads per tile, 16..=256 (256 / threads pixels each).
    pub forward_threads: u32,
    /// `raster_bwd`'s threads per tile, 16..=128 (256 / threads pixels each).
    pub backward_threads: u32,
}

impl TileSplit {
    /// For a GPU: a thread per pixel in the forward (the layout measured on an H200), one
    /// 32-lane warp per tile in the backward (8 pixels per thread, 4 Gaussians per round).
    pub const HARDWARE: Self = Self { forward_threads: 256, backward_threads: 32 };
    /// For software Vulkan (lavapipe): 16 threads of 16 pixels in both blends. Measured on the
    /// 2-core VM (200×150, 30k Gaussians): forward 960 → 320 ms, backward 2,600 → 760 ms
    /// against a thread per pixel and 128 threads (BENCHMARKS.md, stop 64).
    pub const SOFTWARE: Self = Self { forward_threads: 16, backward_threads: 16 };

    /// The split for an adapter: [`Self::SOFTWARE`] on a CPU adapter, else [`Self::HARDWARE`].
    pub fn for_adapter(software: bool) -> Self {
        if software { Self::SOFTWARE } else { Self::HARDWARE }
    }

    /// Gaussians per reduction round of the backward.
    pub fn backward_group(&self) -> u32 {
        ROUND_VALUES / (COMPONENTS * self.backward_threads)
    }

    /// Tile-list positions per forward dispatch: a thread's walk takes a loop iteration per
    /// entry and one per entry and pixel (its pixel loop), and 26 per pixel before and after,
    /// so the window is the largest power of two that keeps that below [`LOOP_LIMIT`].
    pub(crate) fn forward_window(&self) -> u32 {
        let px = TILE_PIXELS / self.forward_threads;
        let room = (LOOP_LIMIT - 26 * px) / (px + 1);
        1 << room.ilog2()
    }

    /// Loop iterations of a backward thread's walk of one full window: per entry one, plus per
    /// pixel one and eight (the channels); per round of [`Self::backward_group`] entries the
    /// round's values written and zeroed, its sums, and the round itself; 24 per pixel before
    /// and after.
    #[cfg(test)]
    fn backward_loop_iterations(&self) -> u32 {
        let (px, group) = (TILE_PIXELS / self.backward_threads, self.backward_group());
        let sums = (group * COMPONENTS).div_ceil(self.backward_threads) * (1 + self.backward_threads);
        let round = 2 * group * COMPONENTS + sums + 1;
        BWD_WINDOW * (1 + 9 * px) + BWD_WINDOW.div_ceil(group) * round + 24 * px
    }

    /// Refuses thread counts the kernels cannot take.
    pub fn check(&self) -> Result<()> {
        let ok = |t: u32, max: u32| t.is_power_of_two() && (16..=max).contains(&t);
        if ok(self.forward_threads, TILE_PIXELS) && ok(self.backward_threads, ROUND_VALUES / COMPONENTS) {
            return Ok(());
        }
        Err(RasterError::InvalidConfig(format!(
            "tile split of {} forward and {} backward threads: each must be a power of two, from 16 to 256 (forward) and to 128 (backward)",
            self.forward_threads, self.backward_threads
        )))
    }

    /// The WGSL constants the blend kernels are compiled with.
    pub(crate) fn wgsl(&self) -> String {
        format!(
            "const FWD_THREADS: u32 = {}u;\nconst FWD_PIXELS: u32 = {}u;\nconst BWD_THREADS: u32 = {}u;\nconst PIXELS: u32 = {}u;\nconst GROUP: u32 = {}u;\n",
            self.forward_threads,
            TILE_PIXELS / self.forward_threads,
            self.backward_threads,
            TILE_PIXELS / self.backward_threads,
            self.backward_group()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every split the check accepts walks its windows below llvmpipe's loop limit.
    #[test]
    fn windows_stay_below_the_loop_limit() {
        for t in [16, 32, 64, 128] {
            let split = TileSplit { forward_threads: t, backward_threads: t };
            assert!(split.backward_loop_iterations() < LOOP_LIMIT, "{split:?}: {}", split.backward_loop_iterations());
        }
        let window = |t| TileSplit { forward_threads: t, backward_threads: 32 }.forward_window();
        assert_eq!([16, 32, 64, 128, 256].map(window), [2048, 4096, 8192, 16384, 16384]);
    }

    #[test]
    fn splits_are_checked() {
        assert!(TileSplit::HARDWARE.check().is_ok() && TileSplit::SOFTWARE.check().is_ok());
        assert_eq!((TileSplit::HARDWARE.backward_group(), TileSplit::SOFTWARE.backward_group()), (4, 8));
        for (f, b) in [(8, 32), (256, 256), (48, 32), (512, 32), (256, 0)] {
            assert!(TileSplit { forward_threads: f, backward_threads: b }.check().is_err(), "{f} {b}");
        }
    }
}
