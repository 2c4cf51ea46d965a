//! Marching cubes over the sparse block volume.
//!
//! Cubes join the centres of 2×2×2 neighbouring voxels, across block borders. A surface
//! vertex lives on a grid edge and is owned by the block holding the edge's lower end; its
//! global index is the block's vertex offset plus the edge's rank in the block's crossing-edge
//! bitmask, so every cube that uses the edge refers to the same vertex (no cracks, no
//! duplicates) and the output order is deterministic. A cube is polygonised only when all
//! eight corners have weight > `min_weight` (as Open3D does with weight ≠ 0).

use crate::error::Result;
use crate::mc_table::{EDGES, corner_offset, table};
use crate::volume::{BLOCK, BLOCK_VOXELS, TsdfVolume};
use gs_core::TriangleMesh;
use gs_core::glam::DVec3;
use rayon::prelude::*;

const G: usize = BLOCK + 1;
const EDGE_WORDS: usize = BLOCK_VOXELS * 3 / 64;

/// Options of [`TsdfVolume::extract_mesh_with`].
#[derive(Debug, Clone, PartialEq)]
pub struct ExtractOptions {
    /// A cube is polygonised only when the weight of each of its 8 voxels exceeds this.
    pub min_weight: f32,
    /// Skip cubes with an edge whose two TSDF values differ by more than this (in units of
    /// `sdf_trunc`); such jumps are not surfaces but the seam between the truncated free-space
    /// band of one view and the back side of another. `None` (Open3D's behaviour) keeps them.
    pub max_tsdf_jump: Option<f32>,
}

impl Default for ExtractOptions {
    fn default() -> Self {
        Self { min_weight: 0.0, max_tsdf_jump: None }
    }
}

/// The 9³ neighbourhood of a block (its voxels plus the +x/+y/+z neighbours' first layers).
struct Gathered {
    tsdf: [f32; G * G * G],
    weight: [f32; G * G * G],
}

#[inline]
fn gi(x: usize, y: usize, z: usize) -> usize {
    (z * G + y) * G + x
}

struct Edges {
    mask: [u64; EDGE_WORDS],
    prefix: [u32; EDGE_WORDS],
}

impl Edges {
    fn rank(&self, e: usize) -> u32 {
        let (w, b) = (e / 64, e % 64);
        self.prefix[w] + (self.mask[w] & ((1u64 << b) - 1)).count_ones()
    }
}

impl TsdfVolume {
    /// Marching cubes with default options: a coloured (if the volume has colour) triangle mesh
    /// whose normals point to the observed free space.
    pub fn extract_mesh(&self) -> Result<TriangleMesh> {
        self.extract_mesh_with(&ExtractOptions::default())
    }

    /// Marching cubes with explicit options.
    pub fn extract_mesh_with(&self, opts: &ExtractOptions) -> Result<TriangleMesh> {
        let n = self.blocks.len();
        let v = self.config().voxel_size;
        let with_color = self.config().with_color;
        // Block order by key: deterministic regardless of integration history.
        let mut order: Vec<u32> = (0..n as u32).collect();
        order.par_sort_unstable_by_key(|&i| self.blocks[i as usize].key);
        let mut rank_of = vec![0u32; n];
        for (r, &b) in order.iter().enumerate() {
            rank_of[b as usize] = r as u32;
        }
        // Neighbour table: for each block (in sorted order), the sorted ranks of the 8 blocks at
        // offsets {0,1}³ (index = dx + 2dy + 4dz), u32::MAX when absent.
        let neigh: Vec<[u32; 8]> = order
            .par_iter()
            .map(|&b| {
                let k = self.blocks[b as usize].key;
                let mut out = [u32::MAX; 8];
                for (c, o) in out.iter_mut().enumerate() {
                    let d = corner_offset(c);
                    let key = [k[0].wrapping_add(d[0] as i32), k[1].wrapping_add(d[1] as i32), k[2].wrapping_add(d[2] as i32)];
                    if let Some(&i) = self.index.get(&key) {
                        *o = rank_of[i as usize];
                    }
                }
                out
            })
            .collect();
        let gather = |r: usize| -> Gathered {
            let mut g = Gathered { tsdf: [0.0; G * G * G], weight: [0.0; G * G * G] };
            for c in 0..8 {
                let nb = neigh[r][c];
                if nb == u32::MAX {
                    continue;
                }
                let blk = &self.blocks[order[nb as usize] as usize];
                let d = corner_offset(c);
                let range = |dd: usize| if dd == 0 { 0..BLOCK } else { 0..1 };
                for z in range(d[2]) {
                    for y in range(d[1]) {
                        for x in range(d[0]) {
                            let src = (z * BLOCK + y) * BLOCK + x;
                            let dst = gi(x + d[0] * BLOCK, y + d[1] * BLOCK, z + d[2] * BLOCK);
                            g.tsdf[dst] = blk.tsdf[src];
                            g.weight[dst] = blk.weight[src];
                        }
                    }
                }
            }
            g
        };
        let min_w = opts.min_weight;
        let color_at = |r: usize, x: usize, y: usize, z: usize| -> [f32; 3] {
            // (x, y, z) in 0..=8 relative to block r.
            let c = (x / BLOCK) | ((y / BLOCK) << 1) | ((z / BLOCK) << 2);
            let nb = neigh[r][c];
            let blk = &self.blocks[order[nb as usize] as usize];
            blk.color[((z % BLOCK) * BLOCK + (y % BLOCK)) * BLOCK + (x % BLOCK)]
        };
        // Phase 1: vertices on crossing edges owned by each block.
        struct BlockVerts {
            edges: Option<Box<Edges>>,
            pos: Vec<[f32; 3]>,
            col: Vec<[u8; 3]>,
        }
        let phase1: Vec<BlockVerts> = (0..n)
            .into_par_iter()
            .with_min_len(8)
            .map(|r| {
                let g = gather(r);
                let key = self.blocks[order[r] as usize].key;
                let origin = DVec3::new(key[0] as f64, key[1] as f64, key[2] as f64) * (BLOCK as f64 * v)
                    + DVec3::splat(0.5 * v);
                let mut edges = Edges { mask: [0; EDGE_WORDS], prefix: [0; EDGE_WORDS] };
                let mut pos = Vec::new();
                let mut col = Vec::new();
                for z in 0..BLOCK {
                    for y in 0..BLOCK {
                        for x in 0..BLOCK {
                            let a = gi(x, y, z);
                            if g.weight[a] <= min_w {
                                continue;
                            }
                            let fa = g.tsdf[a];
                            for axis in 0..3 {
                                let (bx, by, bz) = match axis {
                                    0 => (x + 1, y, z),
                                    1 => (x, y + 1, z),
                                    _ => (x, y, z + 1),
                                };
                                let b = gi(bx, by, bz);
                                if g.weight[b] <= min_w {
                                    continue;
                                }
                                let fb = g.tsdf[b];
                                if (fa < 0.0) == (fb < 0.0) {
                                    continue;
                                }
                                let e = ((z * BLOCK + y) * BLOCK + x) * 3 + axis;
                                edges.mask[e / 64] |= 1 << (e % 64);
                                let t = (fa / (fa - fb)) as f64;
                                let mut p = origin + DVec3::new(x as f64, y as f64, z as f64) * v;
                                p[axis] += t * v;
                                pos.push(p.as_vec3().to_array());
                                if with_color {
                                    let ca = color_at(r, x, y, z);
                                    let cb = color_at(r, bx, by, bz);
                                    let t = t as f32;
                                    col.push(std::array::from_fn(|k| {
                                        ((ca[k] + (cb[k] - ca[k]) * t).clamp(0.0, 1.0) * 255.0).round() as u8
                                    }));
                                }
                            }
                        }
                    }
                }
                if pos.is_empty() {
                    return BlockVerts { edges: None, pos, col };
                }
                let mut acc = 0;
                for w in 0..EDGE_WORDS {
                    edges.prefix[w] = acc;
                    acc += edges.mask[w].count_ones();
                }
                BlockVerts { edges: Some(Box::new(edges)), pos, col }
            })
            .collect();
        let mut offsets = Vec::with_capacity(n + 1);
        let mut total = 0u64;
        for b in &phase1 {
            offsets.push(total as u32);
            total += b.pos.len() as u64;
        }
        if total >= u32::MAX as u64 {
            return Err(crate::TsdfError::InvalidParameter(format!(
                "marching cubes would create {total} vertices, more than a mesh can index"
            )));
        }
        let tab = table();
        let jump = opts.max_tsdf_jump.unwrap_or(f32::INFINITY);
        // Phase 2: triangles of the cubes whose lower corner lies in each block.
        let tris: Vec<Vec<[u32; 3]>> = (0..n)
            .into_par_iter()
            .with_min_len(8)
            .map(|r| {
                let mut out = Vec::new();
                // Only blocks whose own or +neighbours' edges carry vertices can emit triangles.
                if (0..8).all(|c| {
                    let nb = neigh[r][c];
                    nb == u32::MAX || phase1[nb as usize].edges.is_none()
                }) {
                    return out;
                }
                let g = gather(r);
                for z in 0..BLOCK {
                    for y in 0..BLOCK {
                        for x in 0..BLOCK {
                            let mut config = 0usize;
                            let mut vals = [0f32; 8];
                            let mut ok = true;
                            for c in 0..8 {
                                let o = corner_offset(c);
                                let i = gi(x + o[0], y + o[1], z + o[2]);
                                if g.weight[i] <= min_w {
                                    ok = false;
                                    break;
                                }
                                vals[c] = g.tsdf[i];
                                if vals[c] < 0.0 {
                                    config |= 1 << c;
                                }
                            }
                            if !ok || config == 0 || config == 255 {
                                continue;
                            }
                            let mut ids = [u32::MAX; 12];
                            let mut skip = false;
                            for (e, &(c, axis)) in EDGES.iter().enumerate() {
                                let (a, b) = (c, c | (1 << axis));
                                if (config >> a) & 1 == (config >> b) & 1 {
                                    continue;
                                }
                                if (vals[a] - vals[b]).abs() > jump {
                                    skip = true;
                                    break;
                                }
                                let o = corner_offset(c);
                                let (lx, ly, lz) = (x + o[0], y + o[1], z + o[2]);
                                let owner = (lx / BLOCK) | ((ly / BLOCK) << 1) | ((lz / BLOCK) << 2);
                                let nb = neigh[r][owner] as usize;
                                let edge =
                                    (((lz % BLOCK) * BLOCK + (ly % BLOCK)) * BLOCK + (lx % BLOCK)) * 3 + axis;
                                let bv = phase1[nb].edges.as_ref().expect("crossing edge has a vertex");
                                ids[e] = offsets[nb] + bv.rank(edge);
                            }
                            if skip {
                                continue;
                            }
                            for t in &tab.tris[config][..tab.count[config] as usize] {
                                out.push([ids[t[0] as usize], ids[t[1] as usize], ids[t[2] as usize]]);
                            }
                        }
                    }
                }
                out
            })
            .collect();
        let mut positions = Vec::with_capacity(total as usize);
        let mut colors = Vec::with_capacity(if with_color { total as usize } else { 0 });
        for b in phase1 {
            positions.extend(b.pos);
            colors.extend(b.col);
        }
        let triangles: Vec<[u32; 3]> = tris.into_iter().flatten().collect();
        let mesh = TriangleMesh { positions, triangles, colors: with_color.then_some(colors) };
        Ok(crate::clean::remove_unreferenced_vertices(&mesh))
    }
}
