//! A bounding-volume hierarchy over the triangles of a [`TriangleMesh`], with exact f64
//! ray/triangle intersection, shadow (any-hit) queries and closest-point queries.
//!
//! The built-in scene is rendered with it, and it is public so that other crates and tests can
//! ray-cast any mesh: [`Bvh::cast_view`] gives the GT depth (camera-space z at the pixel-centre
//! rays, 0 = miss), face normals and hit triangles of a camera, e.g. for synth-bunny views that
//! ship without normal maps; [`Bvh::closest_point`] gives point-to-mesh distances for checks
//! and metrics.
//!
//! Vertices are read from the mesh's f32 positions and converted exactly to f64, so the
//! geometry that is intersected is exactly the mesh's geometry.

use crate::error::{Result, SynthError};
use glam::DVec3;
use gs_core::{Camera, Image, TriangleMesh};
use rayon::prelude::*;

/// Most triangles in one leaf.
const LEAF_SIZE: usize = 4;
/// Barycentric tolerance that closes the cracks between triangles sharing an edge.
const BARY_EPS: f64 = 1e-12;
/// Traversal stack size (the stack holds at most one entry per tree level plus one).
const STACK: usize = 128;
const _: () = assert!(STACK > MAX_SAH_DEPTH + 34);

/// A ray/triangle hit: `point = origin + t·direction = (1−u−v)·a + u·b + v·c`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Ray parameter (for [`pixel_ray`] rays this is the camera-space depth z).
    pub t: f64,
    /// Index of the hit triangle in the mesh the BVH was built from.
    pub triangle: u32,
    /// Barycentric weight of vertex b.
    pub u: f64,
    /// Barycentric weight of vertex c.
    pub v: f64,
}

/// The closest point of the mesh to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClosestPoint {
    /// Euclidean distance from the query point.
    pub distance: f64,
    /// The closest surface point.
    pub point: DVec3,
    /// Index of the triangle it lies on.
    pub triangle: u32,
}

/// Per-pixel results of casting one ray through every pixel centre of a camera.
#[derive(Debug, Clone)]
pub struct ViewCast {
    /// `[H][W][1]` camera-space z of the first hit, 0 where the ray misses.
    pub depth: Image,
    /// `[H][W][3]` world-space unit face normal of the hit triangle, oriented towards the
    /// camera (n·ray < 0); 0 where the ray misses.
    pub normal: Image,
    /// Row-major hit triangle index per pixel, `u32::MAX` where the ray misses.
    pub triangle: Vec<u32>,
}

#[derive(Debug, Clone, Copy)]
struct Node {
    lo: DVec3,
    hi: DVec3,
    /// Leaf: first triangle slot. Interior: index of the right child (left child = self + 1).
    start: u32,
    /// Leaf: triangle count (> 0). Interior: 0.
    count: u32,
}

#[derive(Debug, Clone, Copy)]
struct Tri {
    a: DVec3,
    e1: DVec3,
    e2: DVec3,
}

/// A BVH over a triangle mesh (binned surface-area-heuristic splits, small leaves). Deterministic: the same mesh always gives the same tree.
#[derive(Debug, Clone)]
pub struct Bvh {
    nodes: Vec<Node>,
    tris: Vec<Tri>,
    ids: Vec<u32>,
}

impl Bvh {
    /// Builds the BVH of `mesh`; an error when the mesh is invalid (see
    /// [`TriangleMesh::validate`]) or has no triangles.
    pub fn new(mesh: &TriangleMesh) -> Result<Self> {
        mesh.validate()
            .map_err(|e| SynthError::InvalidMesh(e.to_string()))?;
        if mesh.triangles.is_empty() {
            return Err(SynthError::InvalidMesh("mesh has no triangles".into()));
        }
        if mesh.triangles.len() >= u32::MAX as usize {
            return Err(SynthError::InvalidMesh(
                "mesh has too many triangles".into(),
            ));
        }
        let p = |i: u32| {
            let v = mesh.positions[i as usize];
            DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64)
        };
        let all: Vec<Tri> = mesh
            .triangles
            .iter()
            .map(|t| {
                let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
                Tri {
                    a,
                    e1: b - a,
                    e2: c - a,
                }
            })
            .collect();
        let centroids: Vec<DVec3> = all.iter().map(|t| t.a + (t.e1 + t.e2) / 3.0).collect();
        let mut order: Vec<u32> = (0..all.len() as u32).collect();
        let mut nodes = Vec::with_capacity(2 * all.len() / LEAF_SIZE + 1);
        build(&all, &centroids, &mut order, 0, 0, &mut nodes);
        let tris = order.iter().map(|&i| all[i as usize]).collect();
        Ok(Self {
            nodes,
            tris,
            ids: order,
        })
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    /// Axis-aligned bounds `(min, max)` of all triangles.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        (self.nodes[0].lo, self.nodes[0].hi)
    }

    /// The first hit of the ray `origin + t·direction` with `t_min < t < t_max` (both sides of
    /// every triangle count), or `None`. `direction` need not be normalised.
    pub fn intersect(
        &self,
        origin: DVec3,
        direction: DVec3,
        t_min: f64,
        t_max: f64,
    ) -> Option<Hit> {
        self.intersect_slot(origin, direction, t_min, t_max)
            .map(|(t, k, u, v)| Hit {
                t,
                triangle: self.ids[k],
                u,
                v,
            })
    }

    /// [`Bvh::intersect`] returning the internal triangle slot.
    fn intersect_slot(
        &self,
        origin: DVec3,
        direction: DVec3,
        t_min: f64,
        t_max: f64,
    ) -> Option<(f64, usize, f64, f64)> {
        let inv = direction.recip();
        let mut best: Option<(f64, usize, f64, f64)> = None;
        let mut t_far = t_max;
        // Node indices and their entry distances (a node is skipped when a closer hit was
        // found after it was pushed).
        let mut stack = [0u32; STACK];
        let mut entry = [0f64; STACK];
        let mut sp = 1usize;
        while sp > 0 {
            sp -= 1;
            if entry[sp] > t_far {
                continue;
            }
            let node = &self.nodes[stack[sp] as usize];
            if node.count > 0 {
                let s = node.start as usize;
                for k in s..s + node.count as usize {
                    if let Some((t, u, v)) =
                        intersect_tri(&self.tris[k], origin, direction, t_min, t_far)
                    {
                        t_far = t;
                        best = Some((t, k, u, v));
                    }
                }
                continue;
            }
            let left = stack[sp] as usize + 1;
            let right = node.start as usize;
            let tl = slab(&self.nodes[left], origin, inv, t_min, t_far);
            let tr = slab(&self.nodes[right], origin, inv, t_min, t_far);
            match (tl, tr) {
                (Some(a), Some(b)) => {
                    // Push the far child first so the near one is visited first.
                    let (near, far) = if a <= b { (left, right) } else { (right, left) };
                    stack[sp] = far as u32;
                    entry[sp] = a.max(b);
                    stack[sp + 1] = near as u32;
                    entry[sp + 1] = a.min(b);
                    sp += 2;
                }
                (Some(a), None) => {
                    stack[sp] = left as u32;
                    entry[sp] = a;
                    sp += 1;
                }
                (None, Some(b)) => {
                    stack[sp] = right as u32;
                    entry[sp] = b;
                    sp += 1;
                }
                (None, None) => {}
            }
        }
        best
    }

    /// Whether anything is hit with `t_min < t < t_max` (a shadow ray; stops at the first hit).
    pub fn occluded(&self, origin: DVec3, direction: DVec3, t_min: f64, t_max: f64) -> bool {
        let inv = direction.recip();
        let mut stack = [0u32; STACK];
        let mut sp = 1usize;
        while sp > 0 {
            sp -= 1;
            let idx = stack[sp] as usize;
            let node = &self.nodes[idx];
            if slab(node, origin, inv, t_min, t_max).is_none() {
                continue;
            }
            if node.count > 0 {
                let s = node.start as usize;
                if self.tris[s..s + node.count as usize]
                    .iter()
                    .any(|tri| intersect_tri(tri, origin, direction, t_min, t_max).is_some())
                {
                    return true;
                }
                continue;
            }
            stack[sp] = node.start;
            stack[sp + 1] = idx as u32 + 1;
            sp += 2;
        }
        false
    }

    /// The closest point of the mesh to `p` (exact point-triangle distance, branch and bound).
    pub fn closest_point(&self, p: DVec3) -> ClosestPoint {
        let mut best_d2 = f64::INFINITY;
        let mut best = (DVec3::ZERO, 0usize);
        let mut stack = [0u32; STACK];
        let mut sp = 1usize;
        while sp > 0 {
            sp -= 1;
            let idx = stack[sp] as usize;
            let node = &self.nodes[idx];
            if box_distance2(node, p) >= best_d2 {
                continue;
            }
            if node.count > 0 {
                let s = node.start as usize;
                for k in s..s + node.count as usize {
                    let q = closest_on_triangle(&self.tris[k], p);
                    let d2 = (q - p).length_squared();
                    if d2 < best_d2 {
                        best_d2 = d2;
                        best = (q, k);
                    }
                }
                continue;
            }
            let left = idx + 1;
            let right = node.start as usize;
            let dl = box_distance2(&self.nodes[left], p);
            let dr = box_distance2(&self.nodes[right], p);
            let (near, far) = if dl <= dr {
                (left, right)
            } else {
                (right, left)
            };
            stack[sp] = far as u32;
            stack[sp + 1] = near as u32;
            sp += 2;
        }
        ClosestPoint {
            distance: best_d2.sqrt(),
            point: best.0,
            triangle: self.ids[best.1],
        }
    }

    /// Casts the pixel-centre ray of every pixel of `camera` (see [`pixel_ray`]): GT depth
    /// (camera-space z, 0 = miss), camera-facing face normals and hit triangles. Rows run in
    /// parallel; the result does not depend on the thread count.
    pub fn cast_view(&self, camera: &Camera) -> Result<ViewCast> {
        let (w, h) = (camera.width as usize, camera.height as usize);
        let mut depth = Image::new(w, h, 1)?;
        let mut normal = Image::new(w, h, 3)?;
        let mut triangle = vec![u32::MAX; w * h];
        depth
            .data_mut()
            .par_chunks_mut(w)
            .zip(normal.data_mut().par_chunks_mut(3 * w))
            .zip(triangle.par_chunks_mut(w))
            .enumerate()
            .for_each(|(y, ((drow, nrow), trow))| {
                for x in 0..w {
                    let (o, d) = pixel_ray(camera, x as f64 + 0.5, y as f64 + 0.5);
                    if let Some((t, k, _, _)) = self.intersect_slot(o, d, 0.0, f64::INFINITY) {
                        drow[x] = t as f32;
                        let tri = &self.tris[k];
                        let mut n = tri.e1.cross(tri.e2).normalize_or_zero();
                        if n.dot(d) > 0.0 {
                            n = -n;
                        }
                        nrow[3 * x] = n.x as f32;
                        nrow[3 * x + 1] = n.y as f32;
                        nrow[3 * x + 2] = n.z as f32;
                        trow[x] = self.ids[k];
                    }
                }
            });
        Ok(ViewCast {
            depth,
            normal,
            triangle,
        })
    }
}

/// Number of SAH bins per axis.
const BINS: usize = 16;
/// Depth after which the build switches from SAH to median splits.
const MAX_SAH_DEPTH: usize = 64;

fn tri_bounds(t: &Tri) -> (DVec3, DVec3) {
    let (b, c) = (t.a + t.e1, t.a + t.e2);
    (t.a.min(b).min(c), t.a.max(b).max(c))
}

fn half_area(lo: DVec3, hi: DVec3) -> f64 {
    let e = (hi - lo).max(DVec3::ZERO);
    e.x * e.y + e.y * e.z + e.z * e.x
}

/// Recursive binned-SAH build over `order` (triangle indices), which it permutes; nodes are
/// appended depth-first (left child right after its parent).
fn build(
    all: &[Tri],
    centroids: &[DVec3],
    order: &mut [u32],
    offset: usize,
    depth: usize,
    nodes: &mut Vec<Node>,
) {
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    let (mut clo, mut chi) = (lo, hi);
    for &i in order.iter() {
        let (a, b) = tri_bounds(&all[i as usize]);
        lo = lo.min(a);
        hi = hi.max(b);
        let c = centroids[i as usize];
        clo = clo.min(c);
        chi = chi.max(c);
    }
    let me = nodes.len();
    let n = order.len();
    nodes.push(Node {
        lo,
        hi,
        start: offset as u32,
        count: n as u32,
    });
    if n <= 2 {
        return;
    }
    // Best SAH split over all axes: cost = A_L·N_L + A_R·N_R (in units of one intersection).
    let mut best: Option<(f64, usize, usize)> = None; // (cost, axis, bins on the left)
    for axis in 0..3 {
        let ext = chi[axis] - clo[axis];
        if ext <= 0.0 {
            continue;
        }
        let scale = BINS as f64 / ext;
        let mut count = [0usize; BINS];
        let mut blo = [DVec3::splat(f64::INFINITY); BINS];
        let mut bhi = [DVec3::splat(f64::NEG_INFINITY); BINS];
        for &i in order.iter() {
            let b = (((centroids[i as usize][axis] - clo[axis]) * scale) as usize).min(BINS - 1);
            let (a, c) = tri_bounds(&all[i as usize]);
            count[b] += 1;
            blo[b] = blo[b].min(a);
            bhi[b] = bhi[b].max(c);
        }
        // Sweep from the right to get the right-side areas, then from the left.
        let mut right_area = [0.0; BINS];
        let mut right_count = [0usize; BINS];
        let (mut rlo, mut rhi, mut rc) = (
            DVec3::splat(f64::INFINITY),
            DVec3::splat(f64::NEG_INFINITY),
            0,
        );
        for b in (1..BINS).rev() {
            rlo = rlo.min(blo[b]);
            rhi = rhi.max(bhi[b]);
            rc += count[b];
            right_area[b] = half_area(rlo, rhi);
            right_count[b] = rc;
        }
        let (mut llo, mut lhi, mut lc) = (
            DVec3::splat(f64::INFINITY),
            DVec3::splat(f64::NEG_INFINITY),
            0,
        );
        for b in 0..BINS - 1 {
            llo = llo.min(blo[b]);
            lhi = lhi.max(bhi[b]);
            lc += count[b];
            if lc == 0 || right_count[b + 1] == 0 {
                continue;
            }
            let cost =
                half_area(llo, lhi) * lc as f64 + right_area[b + 1] * right_count[b + 1] as f64;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, b + 1));
            }
        }
    }
    let leaf_cost = half_area(lo, hi) * n as f64;
    if depth > MAX_SAH_DEPTH {
        // Pathological input: fall back to median splits, which halve the count, so the depth
        // (and the traversal stack) stays bounded by MAX_SAH_DEPTH + 32.
        let axis = (chi - clo).max_position();
        let mid = n / 2;
        order.select_nth_unstable_by(mid, |&a, &b| {
            centroids[a as usize][axis]
                .total_cmp(&centroids[b as usize][axis])
                .then(a.cmp(&b))
        });
        if n <= LEAF_SIZE {
            return;
        }
        return split(all, centroids, order, offset, depth, nodes, me, mid);
    }
    let mid = match best {
        // Traversal costs about one intersection per node visit.
        Some((cost, _, _)) if n <= LEAF_SIZE && cost + half_area(lo, hi) >= leaf_cost => return,
        Some((_, axis, left_bins)) => {
            let scale = BINS as f64 / (chi[axis] - clo[axis]);
            let goes_left = |i: u32| {
                (((centroids[i as usize][axis] - clo[axis]) * scale) as usize).min(BINS - 1)
                    < left_bins
            };
            // Stable in-place partition (deterministic).
            let mut k = 0;
            for j in 0..n {
                if goes_left(order[j]) {
                    order.swap(k, j);
                    k += 1;
                }
            }
            k
        }
        // All centroids coincide: split by index (or stay a leaf when small).
        None if n <= LEAF_SIZE => return,
        None => n / 2,
    };
    split(all, centroids, order, offset, depth, nodes, me, mid);
}

#[allow(clippy::too_many_arguments)]
fn split(
    all: &[Tri],
    centroids: &[DVec3],
    order: &mut [u32],
    offset: usize,
    depth: usize,
    nodes: &mut Vec<Node>,
    me: usize,
    mid: usize,
) {
    let (left, right) = order.split_at_mut(mid);
    build(all, centroids, left, offset, depth + 1, nodes);
    let right_index = nodes.len() as u32;
    build(all, centroids, right, offset + mid, depth + 1, nodes);
    nodes[me].start = right_index;
    nodes[me].count = 0;
}

/// Entry distance of the ray into the node's box within `(t_min, t_max)`, or `None`.
#[inline]
fn slab(node: &Node, o: DVec3, inv: DVec3, t_min: f64, t_max: f64) -> Option<f64> {
    let t1 = (node.lo - o) * inv;
    let t2 = (node.hi - o) * inv;
    let tn = t1.min(t2);
    let tf = t1.max(t2);
    let enter = tn.x.max(tn.y).max(tn.z).max(t_min);
    let exit = tf.x.min(tf.y).min(tf.z).min(t_max);
    // NaN (0·∞ on a slab plane) compares false: treat as a (conservative) hit.
    if enter <= exit || enter.is_nan() || exit.is_nan() {
        Some(enter)
    } else {
        None
    }
}

/// Möller–Trumbore in f64; `(t, u, v)` with `t_min < t < t_max`.
#[inline]
fn intersect_tri(tri: &Tri, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Option<(f64, f64, f64)> {
    let p = d.cross(tri.e2);
    let det = tri.e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - tri.a;
    let u = s.dot(p) * inv;
    if !(-BARY_EPS..=1.0 + BARY_EPS).contains(&u) {
        return None;
    }
    let q = s.cross(tri.e1);
    let v = d.dot(q) * inv;
    if v < -BARY_EPS || u + v > 1.0 + BARY_EPS {
        return None;
    }
    let t = tri.e2.dot(q) * inv;
    (t > t_min && t < t_max).then_some((t, u, v))
}

fn box_distance2(node: &Node, p: DVec3) -> f64 {
    let d = (node.lo - p).max(p - node.hi).max(DVec3::ZERO);
    d.length_squared()
}

/// Closest point on a triangle (Ericson, Real-Time Collision Detection §5.1.5), with a
/// segment fallback for degenerate triangles.
fn closest_on_triangle(tri: &Tri, p: DVec3) -> DVec3 {
    let a = tri.a;
    let b = a + tri.e1;
    let c = a + tri.e2;
    let ab = tri.e1;
    let ac = tri.e2;
    if ab.cross(ac).length_squared() == 0.0 {
        let cands = [
            closest_on_segment(a, b, p),
            closest_on_segment(b, c, p),
            closest_on_segment(c, a, p),
        ];
        return cands
            .into_iter()
            .min_by(|x, y| {
                (*x - p)
                    .length_squared()
                    .total_cmp(&(*y - p).length_squared())
            })
            .unwrap_or(a);
    }
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

fn closest_on_segment(a: DVec3, b: DVec3, p: DVec3) -> DVec3 {
    let ab = b - a;
    let l2 = ab.length_squared();
    if l2 == 0.0 {
        return a;
    }
    a + ab * ((p - a).dot(ab) / l2).clamp(0.0, 1.0)
}

/// The world-space ray through continuous pixel coordinates `(u, v)` of `camera`:
/// `(origin = C, direction = Rᵀ K⁻¹ (u, v, 1)ᵀ)`. The direction's camera-space z is 1, so the
/// ray parameter of a hit is its camera-space depth z (docs/architecture.md §Conventions).
pub fn pixel_ray(camera: &Camera, u: f64, v: f64) -> (DVec3, DVec3) {
    (
        camera.center(),
        camera.rotation.transpose() * camera.ray(u, v),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use gs_core::Rng;

    /// A random triangle soup: small triangles plus a few huge ones (like floor and walls).
    fn soup(seed: u64, n: usize) -> TriangleMesh {
        let mut rng = Rng::new(seed);
        let mut m = TriangleMesh::default();
        for k in 0..n {
            let size = if k % 50 == 0 { 6.0 } else { 0.3 };
            let c = [
                rng.uniform_range(-2.0, 2.0),
                rng.uniform_range(-2.0, 2.0),
                rng.uniform_range(-2.0, 2.0),
            ];
            for _ in 0..3 {
                m.positions
                    .push([0, 1, 2].map(|i| c[i] + size * rng.uniform_range(-0.5, 0.5)));
            }
            let b = 3 * k as u32;
            m.triangles.push([b, b + 1, b + 2]);
        }
        m
    }

    fn brute_intersect(m: &TriangleMesh, o: DVec3, d: DVec3) -> Option<(f64, u32)> {
        let mut best: Option<(f64, u32)> = None;
        for (k, t) in m.triangles.iter().enumerate() {
            let p = |i: u32| DVec3::from_array(m.positions[i as usize].map(f64::from));
            let tri = Tri {
                a: p(t[0]),
                e1: p(t[1]) - p(t[0]),
                e2: p(t[2]) - p(t[0]),
            };
            let far = best.map_or(f64::INFINITY, |b| b.0);
            if let Some((t, _, _)) = intersect_tri(&tri, o, d, 0.0, far) {
                best = Some((t, k as u32));
            }
        }
        best
    }

    #[test]
    fn bvh_matches_brute_force() {
        let m = soup(3, 600);
        let bvh = Bvh::new(&m).unwrap();
        assert_eq!(bvh.triangle_count(), 600);
        let mut rng = Rng::new(9);
        let mut hits = 0;
        for _ in 0..2000 {
            let o = DVec3::new(
                rng.uniform_f64() * 8.0 - 4.0,
                rng.uniform_f64() * 8.0 - 4.0,
                rng.uniform_f64() * 8.0 - 4.0,
            );
            let d = DVec3::new(
                rng.normal() as f64,
                rng.normal() as f64,
                rng.normal() as f64,
            );
            let got = bvh
                .intersect(o, d, 0.0, f64::INFINITY)
                .map(|h| (h.t, h.triangle));
            let want = brute_intersect(&m, o, d);
            assert_eq!(got.map(|g| g.0), want.map(|w| w.0));
            assert_eq!(bvh.occluded(o, d, 0.0, f64::INFINITY), want.is_some());
            if let Some((t, _)) = want {
                hits += 1;
                // Nothing lies before the nearest hit.
                assert!(!bvh.occluded(o, d, 0.0, t * (1.0 - 1e-9)));
            }
            // Closest point vs brute force over all triangles.
            let cp = bvh.closest_point(o);
            let brute = bvh
                .tris
                .iter()
                .map(|t| (closest_on_triangle(t, o) - o).length())
                .fold(f64::INFINITY, f64::min);
            assert!(
                (cp.distance - brute).abs() < 1e-12,
                "{} vs {brute}",
                cp.distance
            );
            assert!(((cp.point - o).length() - cp.distance).abs() < 1e-12);
        }
        assert!(hits > 200, "only {hits} hits");
    }

    #[test]
    fn closest_point_on_a_triangle_regions() {
        let tri = Tri {
            a: DVec3::ZERO,
            e1: DVec3::X,
            e2: DVec3::Y,
        };
        let near = |p: DVec3, q: DVec3| (p - q).length() < 1e-14;
        // Face, vertex, vertex, edge, hypotenuse regions.
        assert!(near(
            closest_on_triangle(&tri, DVec3::new(0.2, 0.2, 3.0)),
            DVec3::new(0.2, 0.2, 0.0)
        ));
        assert!(near(
            closest_on_triangle(&tri, DVec3::new(-1.0, -1.0, 0.0)),
            DVec3::ZERO
        ));
        assert!(near(
            closest_on_triangle(&tri, DVec3::new(2.0, -1.0, 0.0)),
            DVec3::X
        ));
        assert!(near(
            closest_on_triangle(&tri, DVec3::new(0.5, -1.0, 0.0)),
            DVec3::new(0.5, 0.0, 0.0)
        ));
        assert!(near(
            closest_on_triangle(&tri, DVec3::new(1.0, 1.0, 0.0)),
            DVec3::new(0.5, 0.5, 0.0)
        ));
        // Degenerate (collinear) triangle.
        let line = Tri {
            a: DVec3::ZERO,
            e1: DVec3::X,
            e2: 2.0 * DVec3::X,
        };
        assert!(near(
            closest_on_triangle(&line, DVec3::new(1.5, 1.0, 0.0)),
            DVec3::new(1.5, 0.0, 0.0)
        ));
    }

    #[test]
    fn deep_degenerate_inputs_build_and_cast() {
        // Many triangles with identical centroids (SAH cannot split) and a long thin fan.
        let mut m = TriangleMesh::default();
        for k in 0..300u32 {
            let s = 1.0 + k as f32 * 0.01;
            m.positions
                .extend([[-s, -s, 0.0], [s, -s, 0.0], [0.0, 2.0 * s, 0.0]]);
            m.triangles.push([3 * k, 3 * k + 1, 3 * k + 2]);
        }
        let bvh = Bvh::new(&m).unwrap();
        let h = bvh
            .intersect(DVec3::new(0.0, 0.0, 5.0), -DVec3::Z, 0.0, f64::INFINITY)
            .unwrap();
        assert!((h.t - 5.0).abs() < 1e-12);
        let mut fan = TriangleMesh::default();
        for k in 0..5000u32 {
            let x = (k as f32).powi(2) * 1e-3;
            fan.positions
                .extend([[x, 0.0, 0.0], [x + 1e-4, 0.0, 0.0], [x, 1.0, 0.0]]);
            fan.triangles.push([3 * k, 3 * k + 1, 3 * k + 2]);
        }
        let bvh = Bvh::new(&fan).unwrap();
        assert!(bvh.occluded(DVec3::new(1e-5, 0.5, 1.0), -DVec3::Z, 0.0, 2.0));
        assert!(
            bvh.closest_point(DVec3::new(1e9, 0.0, 0.0))
                .distance
                .is_finite()
        );
    }
}
