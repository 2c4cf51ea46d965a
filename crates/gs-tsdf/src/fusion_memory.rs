//! Memory estimate of a fusion, made before the voxel data is allocated.
//!
//! The volume allocates the 8³ blocks within `sdf_trunc` of every back-projected depth sample
//! (see [`crate::volume`]), so its size depends on how the views' samples overlap — a voxel
//! below the pixel footprint gives every sample of every view its own blocks, a coarse one lets
//! all views share the same surface sheet. [`BlockCensus`] therefore counts, without allocating
//! voxels, the exact blocks a few evenly spaced probe views touch (the union of all probes and
//! of every other probe) and extrapolates to all views by the growth between the two unions:
//! `blocks ≈ U_all · (views / probes)^α` with `α = log(U_all / U_half) / log(probes / half)`
//! clamped to [0, 1] (α = 1: views share nothing; α = 0: the probes saw everything). With every
//! view probed the count is exact. [`MemoryEstimate`] turns a block count into bytes: the
//! blocks themselves plus marching cubes and the clean-up copies of its output.

use crate::error::{Result, TsdfError};
use crate::volume::{BLOCK_VOXELS, TsdfConfig, TsdfVolume};
use gs_core::{Camera, Image};

/// Bytes of one allocated block: the block (key, TSDF and weight of 512 voxels, colour vector
/// header), its colour payload when colour is fused, and its share of the key index.
pub fn block_bytes(with_color: bool) -> u64 {
    // 12 (key) + 2 × 2048 (tsdf, weight) + 24 (Vec header), 8-aligned; index entry with the
    // hash map's spare capacity and its rehash copy, plus the per-view key lists ≈ 128;
    // colour 512 × 12 plus the allocator's header.
    let base = 4136 + 128;
    base + if with_color { BLOCK_VOXELS as u64 * 12 + 16 } else { 0 }
}

/// Bytes marching cubes and the mesh clean-up hold per allocated block on top of the volume:
/// sort order, neighbour table and per-block vertex lists (≈ 100 B/block), the crossing-edge
/// masks of surface blocks (288 B), the vertices (15 B) and triangles (12 B) of a surface
/// crossing a block in growing vectors, held again while they are joined and again while the
/// clean-up copies the mesh. Measured on a fused sphere at ≈ 8 kB per block (tests/fusion_memory.rs);
/// this rounds that up by half.
pub const EXTRACT_BYTES_PER_BLOCK: u64 = 12 * 1024;

/// Bytes per pixel a view holds while it is integrated: its filtered depths and their copy for
/// the median (8), the inverse depths read on each voxel's ray (4) and the surface-join flags
/// (3; `ray_depth`). Added once, for the largest probed view, to the volume's bytes.
pub const VIEW_BYTES_PER_PIXEL: u64 = 15;

/// Peak memory of a fusion with a given number of blocks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MemoryEstimate {
    /// Blocks the volume will hold.
    pub blocks: u64,
    /// Bytes of the voxel blocks and their index.
    pub volume_bytes: u64,
    /// Bytes of marching cubes and the clean-up, held while the volume still exists.
    pub extract_bytes: u64,
}

impl MemoryEstimate {
    /// The estimate for `blocks` blocks (with or without colour).
    pub fn for_blocks(blocks: u64, with_color: bool) -> Self {
        Self {
            blocks,
            volume_bytes: blocks.saturating_mul(block_bytes(with_color)),
            extract_bytes: blocks.saturating_mul(EXTRACT_BYTES_PER_BLOCK),
        }
    }

    /// Bytes per block of the whole fusion (volume + extraction).
    pub fn bytes_per_block(with_color: bool) -> u64 {
        block_bytes(with_color) + EXTRACT_BYTES_PER_BLOCK
    }

    /// Peak bytes: the volume plus the extraction.
    pub fn peak_bytes(&self) -> u64 {
        self.volume_bytes.saturating_add(self.extract_bytes)
    }
}

/// Counts the blocks probe views would allocate, without allocating voxels (see the module
/// documentation). The key lists are capped by the configuration's `max_blocks`: a union
/// beyond it is a [`TsdfError::BlockCapExceeded`], so counting never holds more than
/// 12 bytes × `max_blocks` × 2.
pub struct BlockCensus {
    probe: TsdfVolume,
    all: Vec<[i32; 3]>,
    half: Vec<[i32; 3]>,
    probes: usize,
    half_probes: usize,
    max_pixels: u64,
}

impl BlockCensus {
    /// An empty census for fusions with `config`.
    pub fn new(config: TsdfConfig) -> Result<Self> {
        Ok(Self { probe: TsdfVolume::new(config)?, all: Vec::new(), half: Vec::new(), probes: 0, half_probes: 0, max_pixels: 0 })
    }

    /// Adds one probe view; the 1st, 3rd, 5th … probe also enter the half union (so probes
    /// added in view order give two nested, evenly spaced sets).
    pub fn add(&mut self, camera: &Camera, depth: &Image, mask: Option<&Image>) -> Result<()> {
        let keys = self.probe.probe_blocks(camera, depth, mask)?;
        let cap = self.probe.config().max_blocks;
        let voxel_size = self.probe.config().voxel_size;
        let merge = |a: &mut Vec<[i32; 3]>, b: &[[i32; 3]]| {
            let merged = crate::volume::merge_sorted_unique(std::mem::take(a), b.to_vec());
            if merged.len() > cap {
                return Err(TsdfError::BlockCapExceeded { needed: merged.len(), cap, voxel_size });
            }
            *a = merged;
            Ok(())
        };
        if self.probes % 2 == 0 {
            merge(&mut self.half, &keys)?;
            self.half_probes += 1;
        }
        merge(&mut self.all, &keys)?;
        self.probes += 1;
        self.max_pixels = self.max_pixels.max(camera.width as u64 * camera.height as u64);
        Ok(())
    }

    /// Probe views added so far.
    pub fn probes(&self) -> usize {
        self.probes
    }

    /// Blocks the probes touch together (exact).
    pub fn probed_blocks(&self) -> u64 {
        self.all.len() as u64
    }

    /// Estimated blocks of fusing `views` views (exact when every view was probed).
    pub fn estimate_blocks(&self, views: usize) -> u64 {
        extrapolate_blocks(self.half.len() as u64, self.half_probes, self.all.len() as u64, self.probes, views)
    }

    /// [`MemoryEstimate`] of fusing `views` views, the largest probed view's buffers
    /// ([`VIEW_BYTES_PER_PIXEL`]) included in the volume's bytes.
    pub fn estimate(&self, views: usize) -> MemoryEstimate {
        let mut e = MemoryEstimate::for_blocks(self.estimate_blocks(views), self.probe.config().with_color);
        e.volume_bytes = e.volume_bytes.saturating_add(self.max_pixels * VIEW_BYTES_PER_PIXEL);
        e
    }
}

/// The block count of `views` views from the union `all` of `probes` probes and the union
/// `half` of the nested `half_probes` (see the module documentation).
pub fn extrapolate_blocks(half: u64, half_probes: usize, all: u64, probes: usize, views: usize) -> u64 {
    if probes == 0 || all == 0 || views <= probes {
        return all;
    }
    let alpha = if half_probes == 0 || half_probes >= probes || half == 0 {
        1.0
    } else {
        ((all as f64 / half as f64).ln() / (probes as f64 / half_probes as f64).ln()).clamp(0.0, 1.0)
    };
    let est = all as f64 * (views as f64 / probes as f64).powf(alpha);
    if est >= u64::MAX as f64 { u64::MAX } else { est.ceil() as u64 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extrapolation_regimes() {
        // Disjoint views: the union doubles with the probes → linear in the views.
        assert_eq!(extrapolate_blocks(400, 4, 800, 8, 100), 10_000);
        // Saturated: the half already saw everything → no growth.
        assert_eq!(extrapolate_blocks(800, 4, 800, 8, 100), 800);
        // In between: growth by 1.5 per doubling → α = log2 1.5.
        let e = extrapolate_blocks(600, 4, 900, 8, 32);
        assert!((e as f64 - 900.0 * 1.5f64.powi(2)).abs() < 2.0, "{e}");
        // Every view probed: exact.
        assert_eq!(extrapolate_blocks(3, 2, 5, 3, 3), 5);
    }
}
