//! The sparse voxel-block TSDF volume and depth-map integration.
//!
//! Semantics follow Open3D's `ScalableTSDFVolume` (the fusion PGSR, 2DGS and VA-GS use):
//! blocks of 8³ voxels are allocated around every back-projected depth sample (the box
//! `±sdf_trunc` around the point); each voxel of a touched block is projected into the view,
//! reads the depth of the pixel it falls into, and takes the signed distance along the pixel's
//! ray `sdf = (depth − z_voxel)·‖K⁻¹p̄‖` (positive in front of the surface). Voxels with
//! `sdf ≤ −sdf_trunc` are left untouched; the others receive `tsdf = min(1, sdf / sdf_trunc)`
//! with weight 1 into a running weighted average, and the pixel colour likewise.

use crate::error::{Result, TsdfError};
use crate::metrics::Aabb;
use crate::ray_depth::RayDepth;
use gs_core::glam::{DVec3, Vec3};
use gs_core::{Camera, Image};
use rayon::prelude::*;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// Voxels per block side.
pub const BLOCK: usize = 8;
/// Voxels per block.
pub const BLOCK_VOXELS: usize = BLOCK * BLOCK * BLOCK;

/// Which blocks (by key) a fusion piece holds: [`TsdfVolume::integrate_view`].
pub type BlockFilter<'a> = &'a (dyn Fn([i32; 3]) -> bool + Sync);

/// The world centre of the block with this key at this voxel size (block `k` spans
/// `[k, k + 1) × 8 × voxel` on each axis).
pub fn block_centre(key: [i32; 3], voxel_size: f64) -> DVec3 {
    (DVec3::new(key[0] as f64, key[1] as f64, key[2] as f64) + 0.5) * (BLOCK as f64 * voxel_size)
}

/// A small, fast, deterministic hasher for integer block keys.
#[derive(Default, Clone, Copy)]
pub(crate) struct KeyHasher(u64);

impl Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(b as u64);
        }
    }
    fn write_i32(&mut self, v: i32) {
        self.write_u64(v as u32 as u64);
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    fn write_usize(&mut self, v: usize) {
        self.write_u64(v as u64);
    }
}

pub(crate) type KeyMap<V> = HashMap<[i32; 3], V, BuildHasherDefault<KeyHasher>>;

/// Parameters of a TSDF volume (Open3D's `voxel_length`, `sdf_trunc`, `depth_trunc`).
#[derive(Debug, Clone, PartialEq)]
pub struct TsdfConfig {
    /// Edge length of a voxel in scene units.
    pub voxel_size: f64,
    /// Truncation distance of the signed distance; `None` = 4 × `voxel_size`.
    pub sdf_trunc: Option<f64>,
    /// Depths beyond this camera z are ignored (Open3D's `depth_trunc`).
    pub depth_trunc: f64,
    /// Maximum number of allocated 8³ blocks; exceeding it is a [`TsdfError::BlockCapExceeded`].
    pub max_blocks: usize,
    /// Drop depth samples whose surface (normal from neighbouring depths) is more than this many
    /// degrees from the viewing ray; `None` keeps every sample (Open3D's behaviour).
    pub max_normal_angle_deg: Option<f64>,
    /// Whether colours are stored and fused.
    pub with_color: bool,
    /// Region of interest: only the blocks meeting this box are allocated and fused (an
    /// object's box in a room: the memory and time of the object alone). `None`: everywhere.
    pub bounds: Option<Aabb>,
}

impl Default for TsdfConfig {
    fn default() -> Self {
        Self {
            voxel_size: 0.01,
            sdf_trunc: None,
            depth_trunc: f64::INFINITY,
            max_blocks: 2_000_000,
            max_normal_angle_deg: None,
            with_color: true,
            bounds: None,
        }
    }
}

impl TsdfConfig {
    /// A configuration with the given voxel size and the defaults for everything else.
    pub fn with_voxel_size(voxel_size: f64) -> Self {
        Self { voxel_size, ..Self::default() }
    }

    /// The truncation distance in use (`sdf_trunc` or 4 × voxel).
    pub fn truncation(&self) -> f64 {
        self.sdf_trunc.unwrap_or(4.0 * self.voxel_size)
    }

    fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(TsdfError::InvalidParameter(m));
        if !(self.voxel_size.is_finite() && self.voxel_size > 0.0) {
            return bad(format!("voxel_size must be finite and > 0, got {}", self.voxel_size));
        }
        let tr = self.truncation();
        if !(tr.is_finite() && tr > 0.0) {
            return bad(format!("sdf_trunc must be finite and > 0, got {tr}"));
        }
        if self.depth_trunc.is_nan() || self.depth_trunc <= 0.0 {
            return bad(format!("depth_trunc must be > 0, got {}", self.depth_trunc));
        }
        if self.max_blocks == 0 {
            return bad("max_blocks must be at least 1".into());
        }
        if let Some(b) = &self.bounds
            && !(0..3).all(|k| b.min[k].is_finite() && b.max[k].is_finite() && b.min[k] <= b.max[k])
        {
            let v = |p: [f64; 3]| format!("({}, {}, {})", p[0], p[1], p[2]);
            return bad(format!("bounds must be finite with min ≤ max on every axis, got {} to {}", v(b.min), v(b.max)));
        }
        if let Some(a) = self.max_normal_angle_deg
            && !(a.is_finite() && a > 0.0 && a <= 90.0)
        {
            return bad(format!("max_normal_angle_deg must be in (0, 90], got {a}"));
        }
        Ok(())
    }
}

/// One 8³ block: TSDF value, weight and (optionally) colour of each voxel, x fastest.
#[derive(Clone)]
pub(crate) struct Block {
    pub key: [i32; 3],
    pub tsdf: [f32; BLOCK_VOXELS],
    pub weight: [f32; BLOCK_VOXELS],
    /// Empty when the volume stores no colour.
    pub color: Vec<[f32; 3]>,
}

impl Block {
    fn new(key: [i32; 3], with_color: bool) -> Self {
        Self {
            key,
            tsdf: [0.0; BLOCK_VOXELS],
            weight: [0.0; BLOCK_VOXELS],
            color: if with_color { vec![[0.0; 3]; BLOCK_VOXELS] } else { Vec::new() },
        }
    }
}

/// Statistics of one [`TsdfVolume::integrate`] call.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct IntegrateStats {
    /// Depth samples that passed every filter.
    pub valid_pixels: usize,
    /// Median camera z of those samples (`None` when none passed): with the focal length it
    /// gives the world size of a pixel at the fused surface, which a voxel should not undercut.
    pub median_depth: Option<f32>,
    /// Blocks touched by this view.
    pub touched_blocks: usize,
    /// Blocks newly allocated by this view.
    pub new_blocks: usize,
    /// Blocks allocated in total afterwards.
    pub total_blocks: usize,
}

/// A sparse TSDF volume: a hash map of 8³ voxel blocks allocated only near observed surfaces.
pub struct TsdfVolume {
    config: TsdfConfig,
    pub(crate) blocks: Vec<Block>,
    pub(crate) index: KeyMap<u32>,
}

impl TsdfVolume {
    /// An empty volume; fails on a non-positive or non-finite voxel size / truncation.
    pub fn new(config: TsdfConfig) -> Result<Self> {
        config.validate()?;
        Ok(Self { config, blocks: Vec::new(), index: KeyMap::default() })
    }

    /// The configuration.
    pub fn config(&self) -> &TsdfConfig {
        &self.config
    }

    /// Number of allocated blocks.
    pub fn block_count(&self) -> usize {
        self.blocks.len()
    }

    /// Approximate memory held by the voxel data, bytes.
    pub fn memory_bytes(&self) -> usize {
        let per = std::mem::size_of::<Block>() + if self.config.with_color { BLOCK_VOXELS * 12 } else { 0 };
        self.blocks.len() * (per + 24)
    }

    /// The TSDF value and weight of the voxel whose centre is nearest to `p` (world), if its
    /// block is allocated. TSDF values are normalised to [−1, 1] (units of `sdf_trunc`).
    pub fn voxel_at(&self, p: DVec3) -> Option<(f32, f32)> {
        let v = self.config.voxel_size;
        let g = (p / v).floor();
        if !g.is_finite() || g.abs().max_element() > i32::MAX as f64 / 2.0 {
            return None;
        }
        let g = [g.x as i64, g.y as i64, g.z as i64];
        let key = g.map(|c| c.div_euclid(BLOCK as i64) as i32);
        let l = g.map(|c| c.rem_euclid(BLOCK as i64) as usize);
        let b = &self.blocks[*self.index.get(&key)? as usize];
        let i = (l[2] * BLOCK + l[1]) * BLOCK + l[0];
        Some((b.tsdf[i], b.weight[i]))
    }

    /// Fuses one depth map (camera z, 1 channel, 0/NaN/inf = no depth) with optional colour
    /// (3 channels in [0, 1]) and mask (1 channel; pixels < 0.5 are ignored) seen by `camera`.
    /// Deterministic for any thread count. `view` only labels errors.
    pub fn integrate(
        &mut self,
        camera: &Camera,
        depth: &Image,
        color: Option<&Image>,
        mask: Option<&Image>,
    ) -> Result<IntegrateStats> {
        self.integrate_view(0, camera, depth, color, mask, None)
    }

    /// [`TsdfVolume::integrate`] with a label for errors (`view`), touching only the blocks
    /// `keep` accepts (by key, see [`block_centre`]; `None`: all) — one piece of a fusion split
    /// into pieces. A kept block receives exactly what it receives in a volume without the
    /// filter, so pieces fused from the same views in the same order agree voxel for voxel
    /// where they overlap.
    pub fn integrate_view(
        &mut self,
        view: usize,
        camera: &Camera,
        depth: &Image,
        color: Option<&Image>,
        mask: Option<&Image>,
        keep: Option<BlockFilter<'_>>,
    ) -> Result<IntegrateStats> {
        let (w, h) = (camera.width as usize, camera.height as usize);
        let bad = |problem: String| Err(TsdfError::InvalidInput { view, problem });
        if depth.width() != w || depth.height() != h || depth.channels() != 1 {
            return bad(format!(
                "depth map is {}x{}x{} but the camera is {w}x{h} (1 channel expected)",
                depth.width(),
                depth.height(),
                depth.channels()
            ));
        }
        if let Some(c) = color
            && (c.width() != w || c.height() != h || c.channels() != 3)
        {
            return bad(format!("colour image is {}x{}x{}, expected {w}x{h}x3", c.width(), c.height(), c.channels()));
        }
        if let Some(m) = mask
            && (m.width() != w || m.height() != h || m.channels() != 1)
        {
            return bad(format!("mask is {}x{}x{}, expected {w}x{h}x1", m.width(), m.height(), m.channels()));
        }
        let filtered = self.filter_depth(camera, depth, mask);
        let mut kept: Vec<f32> = filtered.iter().copied().filter(|&d| d > 0.0).collect();
        let valid_pixels = kept.len();
        let median_depth =
            (valid_pixels > 0).then(|| *kept.select_nth_unstable_by(valid_pixels / 2, f32::total_cmp).1);
        let mut stats =
            IntegrateStats { valid_pixels, median_depth, total_blocks: self.blocks.len(), ..Default::default() };
        if valid_pixels == 0 {
            return Ok(stats);
        }
        let keys = self.touched_blocks(camera, &filtered, keep)?;
        stats.touched_blocks = keys.len();
        // Allocate (keys are sorted, so block order is deterministic).
        let new: Vec<[i32; 3]> = keys.iter().filter(|k| !self.index.contains_key(*k)).copied().collect();
        if self.blocks.len() + new.len() > self.config.max_blocks {
            return Err(TsdfError::BlockCapExceeded {
                needed: self.blocks.len() + new.len(),
                cap: self.config.max_blocks,
                voxel_size: self.config.voxel_size,
            });
        }
        stats.new_blocks = new.len();
        // Exact growth (no doubling) and a clean error instead of an abort when memory is short.
        self.blocks.try_reserve_exact(new.len()).map_err(|_| TsdfError::OutOfMemory {
            blocks: self.blocks.len() + new.len(),
            bytes: ((self.blocks.len() + new.len()) * std::mem::size_of::<Block>()) as u64,
        })?;
        for k in new {
            self.index.insert(k, self.blocks.len() as u32);
            self.blocks.push(Block::new(k, self.config.with_color));
        }
        stats.total_blocks = self.blocks.len();
        let mut touched = vec![false; self.blocks.len()];
        for k in &keys {
            touched[self.index[k] as usize] = true;
        }
        let mut work: Vec<&mut Block> =
            self.blocks.iter_mut().zip(&touched).filter(|(_, t)| **t).map(|(b, _)| b).collect();
        let ctx = ViewContext::new(camera, &filtered, color, &self.config);
        work.par_iter_mut().with_min_len(16).for_each(|b| ctx.update_block(b));
        Ok(stats)
    }

    /// Sorted keys of the blocks [`TsdfVolume::integrate`] would touch for this view (after the
    /// same depth filters), without allocating anything: what [`crate::BlockCensus`] counts.
    pub fn probe_blocks(&self, camera: &Camera, depth: &Image, mask: Option<&Image>) -> Result<Vec<[i32; 3]>> {
        let (w, h) = (camera.width as usize, camera.height as usize);
        if depth.width() != w || depth.height() != h || depth.channels() != 1 {
            return Err(TsdfError::InvalidInput {
                view: 0,
                problem: format!("depth map is {}x{}x{} but the camera is {w}x{h}", depth.width(), depth.height(), depth.channels()),
            });
        }
        if let Some(m) = mask
            && (m.width() != w || m.height() != h || m.channels() != 1)
        {
            return Err(TsdfError::InvalidInput { view: 0, problem: format!("mask is {}x{}x{}, expected {w}x{h}x1", m.width(), m.height(), m.channels()) });
        }
        let filtered = self.filter_depth(camera, depth, mask);
        if filtered.iter().all(|&d| d <= 0.0) {
            return Ok(Vec::new());
        }
        self.touched_blocks(camera, &filtered, None)
    }

    /// The depth map after the validity, `depth_trunc`, mask and normal-angle filters
    /// (0 where dropped).
    fn filter_depth(&self, camera: &Camera, depth: &Image, mask: Option<&Image>) -> Vec<f32> {
        let (w, h) = (camera.width as usize, camera.height as usize);
        let dt = self.config.depth_trunc;
        let mut out: Vec<f32> = depth
            .data()
            .par_iter()
            .enumerate()
            .map(|(i, &d)| {
                let ok = d.is_finite() && d > 0.0 && (d as f64) <= dt && mask.is_none_or(|m| m.data()[i] >= 0.5);
                if ok { d } else { 0.0 }
            })
            .collect();
        if let Some(max_angle) = self.config.max_normal_angle_deg {
            let cos_min = max_angle.to_radians().cos() as f32;
            let k = camera.intrinsics;
            let (fx, fy, cx, cy) = (k.fx as f32, k.fy as f32, k.cx as f32, k.cy as f32);
            let src = out.clone();
            let point = |i: usize, j: usize| -> Option<Vec3> {
                let d = src[j * w + i];
                (d > 0.0).then(|| Vec3::new((i as f32 + 0.5 - cx) / fx * d, (j as f32 + 0.5 - cy) / fy * d, d))
            };
            out.par_chunks_mut(w).enumerate().for_each(|(j, row)| {
                for (i, d) in row.iter_mut().enumerate() {
                    let Some(p) = point(i, j) else { continue };
                    // Central differences where both neighbours exist, else one-sided.
                    let l = if i > 0 { point(i - 1, j) } else { None };
                    let r = if i + 1 < w { point(i + 1, j) } else { None };
                    let u = if j > 0 { point(i, j - 1) } else { None };
                    let dn = if j + 1 < h { point(i, j + 1) } else { None };
                    let dx = match (l, r) {
                        (Some(a), Some(b)) => b - a,
                        (None, Some(b)) => b - p,
                        (Some(a), None) => p - a,
                        (None, None) => continue,
                    };
                    let dy = match (u, dn) {
                        (Some(a), Some(b)) => b - a,
                        (None, Some(b)) => b - p,
                        (Some(a), None) => p - a,
                        (None, None) => continue,
                    };
                    let n = dx.cross(dy);
                    let nl = n.length() * p.length();
                    if nl > 0.0 && n.dot(p).abs() < cos_min * nl {
                        *d = 0.0;
                    }
                }
            });
        }
        out
    }

    /// Sorted keys of the blocks within `sdf_trunc` (box) of any back-projected sample.
    fn touched_blocks(&self, camera: &Camera, depth: &[f32], keep: Option<BlockFilter<'_>>) -> Result<Vec<[i32; 3]>> {
        let w = camera.width as usize;
        let block_len = self.config.voxel_size * BLOCK as f64;
        let tr = self.config.truncation();
        let lim = (i32::MAX / 2) as f64;
        let cap = self.config.max_blocks;
        let v = self.config.voxel_size;
        // Block range of the region of interest (blocks meeting the box).
        let roi = self.config.bounds.map(|b| {
            let lo = DVec3::from_array(b.min) / block_len;
            let hi = DVec3::from_array(b.max) / block_len;
            let f = |x: f64| x.floor().clamp(-lim, lim) as i64;
            ([f(lo.x), f(lo.y), f(lo.z)], [f(hi.x), f(hi.y), f(hi.z)])
        });
        let all = depth
            .par_chunks(w)
            .enumerate()
            .map(|(j, row)| {
                let mut keys = Vec::new();
                let mut next_dedup = 4096;
                let mut last: Option<([i64; 3], [i64; 3])> = None;
                for (i, &d) in row.iter().enumerate() {
                    if d <= 0.0 {
                        continue;
                    }
                    let p = camera.back_project(i as f64 + 0.5, j as f64 + 0.5, d as f64);
                    let lo = ((p - DVec3::splat(tr)) / block_len).floor();
                    let hi = ((p + DVec3::splat(tr)) / block_len).floor();
                    if !(lo.is_finite() && hi.is_finite()) || lo.min_element() < -lim || hi.max_element() > lim {
                        return Err(TsdfError::OutOfRange { point: p.to_array(), voxel_size: v });
                    }
                    let mut lo = [lo.x as i64, lo.y as i64, lo.z as i64];
                    let mut hi = [hi.x as i64, hi.y as i64, hi.z as i64];
                    if let Some((rlo, rhi)) = roi {
                        for k in 0..3 {
                            lo[k] = lo[k].max(rlo[k]);
                            hi[k] = hi[k].min(rhi[k]);
                        }
                        if (0..3).any(|k| lo[k] > hi[k]) {
                            continue;
                        }
                    }
                    if last == Some((lo, hi)) {
                        continue;
                    }
                    last = Some((lo, hi));
                    let boxed: i64 = (0..3).map(|k| hi[k] - lo[k] + 1).product();
                    if boxed as usize > cap {
                        return Err(TsdfError::BlockCapExceeded { needed: boxed as usize, cap, voxel_size: v });
                    }
                    for z in lo[2]..=hi[2] {
                        for y in lo[1]..=hi[1] {
                            for x in lo[0]..=hi[0] {
                                let key = [x as i32, y as i32, z as i32];
                                if keep.is_none_or(|f| f(key)) {
                                    keys.push(key);
                                }
                            }
                        }
                    }
                    if keys.len() > next_dedup {
                        keys.sort_unstable();
                        keys.dedup();
                        if keys.len() > cap {
                            return Err(TsdfError::BlockCapExceeded { needed: keys.len(), cap, voxel_size: v });
                        }
                        next_dedup = 2 * keys.len() + 4096;
                    }
                }
                keys.sort_unstable();
                keys.dedup();
                Ok(keys)
            })
            .try_reduce(Vec::new, |a, b| {
                let merged = merge_sorted_unique(a, b);
                if merged.len() > cap {
                    return Err(TsdfError::BlockCapExceeded { needed: merged.len(), cap, voxel_size: v });
                }
                Ok(merged)
            })?;
        Ok(all)
    }
}

/// Union of two sorted, duplicate-free key lists (sorted, duplicate-free).
pub(crate) fn merge_sorted_unique(a: Vec<[i32; 3]>, b: Vec<[i32; 3]>) -> Vec<[i32; 3]> {
    if a.is_empty() {
        return b;
    }
    if b.is_empty() {
        return a;
    }
    let mut out = Vec::with_capacity(a.len() + b.len());
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Less => {
                out.push(a[i]);
                i += 1;
            }
            std::cmp::Ordering::Greater => {
                out.push(b[j]);
                j += 1;
            }
            std::cmp::Ordering::Equal => {
                out.push(a[i]);
                i += 1;
                j += 1;
            }
        }
    }
    out.extend_from_slice(&a[i..]);
    out.extend_from_slice(&b[j..]);
    out
}

/// Per-view constants for the voxel update.
struct ViewContext<'a> {
    rot: [DVec3; 3],
    trans: DVec3,
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    w: usize,
    h: usize,
    /// The view's depths, read on each voxel's ray.
    depth: RayDepth<'a>,
    color: Option<&'a Image>,
    voxel: f64,
    trunc: f32,
}

impl<'a> ViewContext<'a> {
    fn new(camera: &Camera, depth: &'a [f32], color: Option<&'a Image>, config: &TsdfConfig) -> Self {
        let k = camera.intrinsics;
        let trunc = config.truncation() as f32;
        Self {
            rot: [camera.rotation.col(0), camera.rotation.col(1), camera.rotation.col(2)],
            trans: camera.translation,
            fx: k.fx as f32,
            fy: k.fy as f32,
            cx: k.cx as f32,
            cy: k.cy as f32,
            w: camera.width as usize,
            h: camera.height as usize,
            depth: RayDepth::new(depth, camera.width as usize, camera.height as usize, trunc),
            color: if config.with_color { color } else { None },
            voxel: config.voxel_size,
            trunc,
        }
    }

    fn update_block(&self, b: &mut Block) {
        let v = self.voxel;
        let bl = (BLOCK as f64) * v;
        // Centre of voxel (0,0,0) of the block, in camera coordinates (f64, then f32 offsets).
        let origin = DVec3::new(b.key[0] as f64, b.key[1] as f64, b.key[2] as f64) * bl + DVec3::splat(0.5 * v);
        let o = (self.rot[0] * origin.x + self.rot[1] * origin.y + self.rot[2] * origin.z + self.trans).as_vec3();
        let sx = (self.rot[0] * v).as_vec3();
        let sy = (self.rot[1] * v).as_vec3();
        let sz = (self.rot[2] * v).as_vec3();
        let inv_trunc = 1.0 / self.trunc;
        let (wf, hf) = (self.w as f32, self.h as f32);
        let mut idx = 0;
        for z in 0..BLOCK {
            let pz = o + sz * z as f32;
            for y in 0..BLOCK {
                let py = pz + sy * y as f32;
                for x in 0..BLOCK {
                    let p = py + sx * x as f32;
                    let i = idx;
                    idx += 1;
                    if p.z <= 0.0 {
                        continue;
                    }
                    let inv_z = 1.0 / p.z;
                    let rx = p.x * inv_z;
                    let ry = p.y * inv_z;
                    let u = self.fx * rx + self.cx;
                    let vv = self.fy * ry + self.cy;
                    if !(u >= 0.0 && vv >= 0.0 && u < wf && vv < hf) {
                        continue;
                    }
                    let pix = (vv as usize) * self.w + u as usize;
                    let d = self.depth.at(u, vv, pix);
                    if d <= 0.0 {
                        continue;
                    }
                    // Distance along the pixel's ray (Open3D's depth-to-camera-distance multiplier).
                    let sdf = (d - p.z) * (1.0 + rx * rx + ry * ry).sqrt();
                    if sdf <= -self.trunc {
                        continue;
                    }
                    let t = (sdf * inv_trunc).min(1.0);
                    let w0 = b.weight[i];
                    let w1 = w0 + 1.0;
                    b.tsdf[i] = (b.tsdf[i] * w0 + t) / w1;
                    b.weight[i] = w1;
                    if let Some(c) = self.color {
                        let px = &c.data()[pix * 3..pix * 3 + 3];
                        let bc = &mut b.color[i];
                        for k in 0..3 {
                            bc[k] = (bc[k] * w0 + px[k]) / w1;
                        }
                    }
                }
            }
        }
    }
}
