//! The memory estimate against the real allocation, measured by a counting allocator.

use gs_core::glam::DVec3;
use gs_core::{Camera, Image};
use gs_tsdf::analytic_depth::{Primitive, orbit_cameras, render_depth};
use gs_tsdf::{BlockCensus, ComponentFilter, TsdfConfig, TsdfVolume, clean_mesh};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

/// The system allocator, counting live bytes and their peak.
struct Counting;
static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);
/// The tests measure the process-wide peak: one at a time.
static SERIAL: Mutex<()> = Mutex::new(());

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(l) };
        if !p.is_null() {
            let now = LIVE.fetch_add(l.size(), Ordering::Relaxed) + l.size();
            PEAK.fetch_max(now, Ordering::Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) };
        LIVE.fetch_sub(l.size(), Ordering::Relaxed);
    }
    /// Forwarded, as the system grows large blocks in place (mremap), counting the difference.
    unsafe fn realloc(&self, p: *mut u8, l: Layout, new_size: usize) -> *mut u8 {
        let q = unsafe { System.realloc(p, l, new_size) };
        if !q.is_null() {
            if new_size >= l.size() {
                let now = LIVE.fetch_add(new_size - l.size(), Ordering::Relaxed) + new_size - l.size();
                PEAK.fetch_max(now, Ordering::Relaxed);
            } else {
                LIVE.fetch_sub(l.size() - new_size, Ordering::Relaxed);
            }
        }
        q
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Peak live bytes above the level at the call, while `f` runs.
fn peak_of<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let base = LIVE.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    let out = f();
    (out, PEAK.load(Ordering::Relaxed) - base)
}

fn sphere() -> [Primitive; 1] {
    [Primitive::Sphere { center: DVec3::ZERO, radius: 1.0 }]
}

fn depths(cams: &[Camera]) -> Vec<Image> {
    cams.iter().map(|c| render_depth(c, &sphere())).collect()
}

/// Every view probed: the block count is exact, and the byte estimate brackets the measured
/// peak of fusion + marching cubes + clean-up within a factor 2 (stated bound: the measured
/// peak lies in [estimate / 2, estimate]).
#[test]
fn estimate_brackets_real_peak() {
    let _g = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let cams = orbit_cameras(12, 160, 120, DVec3::ZERO, 3.0);
    let maps = depths(&cams);
    let colors: Vec<Image> = cams.iter().map(|c| Image::new(c.width as usize, c.height as usize, 3).unwrap()).collect();
    let config = TsdfConfig::with_voxel_size(0.02);
    let mut census = BlockCensus::new(config.clone()).unwrap();
    for (c, d) in cams.iter().zip(&maps) {
        census.add(c, d, None).unwrap();
    }
    let est = census.estimate(cams.len());
    let ((blocks, volume_peak, _mesh), total_peak) = peak_of(|| {
        let (vol, volume_peak) = peak_of(|| {
            let mut vol = TsdfVolume::new(config.clone()).unwrap();
            for ((c, d), col) in cams.iter().zip(&maps).zip(&colors) {
                vol.integrate(c, d, Some(col), None).unwrap();
            }
            vol
        });
        let raw = vol.extract_mesh().unwrap();
        let (mesh, _) = clean_mesh(&raw, ComponentFilter::MinTriangles(50)).unwrap();
        (vol.block_count(), volume_peak, mesh)
    });
    assert_eq!(est.blocks, blocks as u64, "all views probed: the count is exact");
    let ratio_volume = volume_peak as f64 / est.volume_bytes as f64;
    let ratio_total = total_peak as f64 / est.peak_bytes() as f64;
    assert!((0.5..=1.0).contains(&ratio_volume), "volume: measured {volume_peak} vs estimate {}", est.volume_bytes);
    assert!((0.5..=1.0).contains(&ratio_total), "total: measured {total_peak} vs estimate {}", est.peak_bytes());
    eprintln!("volume {volume_peak} / {} B, total {total_peak} / {} B for {blocks} blocks", est.volume_bytes, est.peak_bytes());
}

/// Eight evenly spaced probes of 48 views extrapolate the block count within a factor 2 of
/// the exact union, both where the views share one surface sheet (coarse voxel) and where
/// every sample has its own blocks (a voxel far below the pixel footprint).
#[test]
fn probes_extrapolate_both_regimes() {
    let _g = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let cams = orbit_cameras(48, 64, 48, DVec3::ZERO, 3.0);
    let maps = depths(&cams);
    for voxel in [0.02, 1e-5] {
        let config = TsdfConfig { max_blocks: 50_000_000, ..TsdfConfig::with_voxel_size(voxel) };
        let mut exact = BlockCensus::new(config.clone()).unwrap();
        let mut probes = BlockCensus::new(config).unwrap();
        for (i, (c, d)) in cams.iter().zip(&maps).enumerate() {
            exact.add(c, d, None).unwrap();
            if i % 6 == 0 {
                probes.add(c, d, None).unwrap();
            }
        }
        let (truth, guess) = (exact.probed_blocks() as f64, probes.estimate_blocks(cams.len()) as f64);
        assert!((0.5..=2.0).contains(&(guess / truth)), "voxel {voxel}: estimated {guess} blocks, real {truth}");
    }
}

/// A census beyond its cap stops with the cap error instead of growing.
#[test]
fn census_respects_the_cap() {
    let _g = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let cams = orbit_cameras(2, 64, 48, DVec3::ZERO, 3.0);
    let mut census = BlockCensus::new(TsdfConfig { max_blocks: 1000, ..TsdfConfig::with_voxel_size(1e-6) }).unwrap();
    let e = census.add(&cams[0], &depths(&cams)[0], None).unwrap_err();
    assert!(matches!(e, gs_tsdf::TsdfError::BlockCapExceeded { cap: 1000, .. }), "{e}");
}
