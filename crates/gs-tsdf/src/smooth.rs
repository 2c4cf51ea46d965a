//! Taubin λ|μ smoothing of a fused mesh (docs/method.md §TSDF): marching cubes on a TSDF of
//! noisy depths leaves voxel-scale ripples that quadric simplification must keep (each collapse
//! may move the surface only by its error bound), so smoothing them first lets the simplifier
//! remove more triangles for the same error. Alternating a shrinking step (λ > 0) and an
//! inflating one (μ < −λ) removes the ripples without the shrinkage of plain Laplacian
//! smoothing (G. Taubin, "A signal processing approach to fair surface design", SIGGRAPH 1995).
//! Boundary vertices (on an edge of one triangle) stay where they are.
//!
//! Hand-written rather than taken from a mesh crate: it is a uniform Laplacian over
//! [`TriangleMesh`]'s own arrays (a crate would convert to and from its mesh type, which costs
//! more than the smoothing), and a per-vertex pure function of the previous positions, so it is
//! identical at any thread count.

use crate::error::{Result, TsdfError};
use gs_core::TriangleMesh;
use rayon::prelude::*;

/// Taubin's pass-band parameters (λ = 0.5, μ = −0.53: k_PB ≈ 0.1).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Smoothing {
    /// λ|μ step pairs.
    pub iterations: usize,
    /// Shrinking step λ, in (0, 1).
    pub lambda: f32,
    /// Inflating step μ, with μ < −λ.
    pub mu: f32,
}

impl Smoothing {
    /// `iterations` step pairs with Taubin's λ = 0.5, μ = −0.53.
    pub fn taubin(iterations: usize) -> Self {
        Self { iterations, lambda: 0.5, mu: -0.53 }
    }

    fn validate(&self) -> Result<()> {
        if !(self.lambda > 0.0 && self.lambda < 1.0 && self.mu < -self.lambda && self.mu > -1.0) {
            return Err(TsdfError::InvalidParameter(format!(
                "smoothing steps λ = {}, μ = {}: need 0 < λ < 1 and −1 < μ < −λ",
                self.lambda, self.mu
            )));
        }
        Ok(())
    }
}

/// The vertex neighbourhoods of `mesh` in compressed rows (sorted, each neighbour once) and
/// whether each vertex lies on the boundary.
fn neighbourhoods(mesh: &TriangleMesh) -> (Vec<usize>, Vec<u32>, Vec<bool>) {
    let n = mesh.positions.len();
    let mut edges: Vec<(u32, u32)> = Vec::with_capacity(mesh.triangles.len() * 3);
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if a != b {
                edges.push((a.min(b), a.max(b)));
            }
        }
    }
    edges.par_sort_unstable();
    let mut boundary = vec![false; n];
    let mut unique: Vec<(u32, u32)> = Vec::with_capacity(edges.len() / 2 + 1);
    let mut i = 0;
    while i < edges.len() {
        let mut j = i + 1;
        while j < edges.len() && edges[j] == edges[i] {
            j += 1;
        }
        if j - i == 1 {
            boundary[edges[i].0 as usize] = true;
            boundary[edges[i].1 as usize] = true;
        }
        unique.push(edges[i]);
        i = j;
    }
    let mut start = vec![0usize; n + 1];
    for &(a, b) in &unique {
        start[a as usize + 1] += 1;
        start[b as usize + 1] += 1;
    }
    for v in 0..n {
        start[v + 1] += start[v];
    }
    let mut fill = start.clone();
    let mut adj = vec![0u32; start[n]];
    for &(a, b) in &unique {
        adj[fill[a as usize]] = b;
        fill[a as usize] += 1;
        adj[fill[b as usize]] = a;
        fill[b as usize] += 1;
    }
    (start, adj, boundary)
}

/// One uniform-Laplacian step of size `step` from `from` into `to`.
fn laplacian_step(from: &[[f32; 3]], to: &mut [[f32; 3]], start: &[usize], adj: &[u32], boundary: &[bool], step: f32) {
    to.par_iter_mut().enumerate().for_each(|(v, out)| {
        let p = from[v];
        let ring = &adj[start[v]..start[v + 1]];
        if boundary[v] || ring.is_empty() {
            *out = p;
            return;
        }
        let mut mean = [0.0f64; 3];
        for &u in ring {
            let q = from[u as usize];
            for c in 0..3 {
                mean[c] += q[c] as f64;
            }
        }
        let k = ring.len() as f64;
        for c in 0..3 {
            out[c] = p[c] + step * ((mean[c] / k) as f32 - p[c]);
        }
    });
}

/// `mesh` smoothed by `smoothing` (same triangles and colours; boundary vertices fixed).
pub fn smooth_mesh(mesh: &TriangleMesh, smoothing: Smoothing) -> Result<TriangleMesh> {
    smoothing.validate()?;
    mesh.validate()?;
    let (start, adj, boundary) = neighbourhoods(mesh);
    let mut a = mesh.positions.clone();
    let mut b = a.clone();
    for _ in 0..smoothing.iterations {
        laplacian_step(&a, &mut b, &start, &adj, &boundary, smoothing.lambda);
        laplacian_step(&b, &mut a, &start, &adj, &boundary, smoothing.mu);
    }
    Ok(TriangleMesh { positions: a, ..mesh.clone() })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit sphere from a subdivided octahedron, with radial noise of amplitude `noise`.
    fn noisy_sphere(levels: u32, noise: f32) -> TriangleMesh {
        let mut pos: Vec<[f32; 3]> = vec![[1., 0., 0.], [-1., 0., 0.], [0., 1., 0.], [0., -1., 0.], [0., 0., 1.], [0., 0., -1.]];
        let mut tris: Vec<[u32; 3]> =
            vec![[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]];
        for _ in 0..levels {
            let mut mid = std::collections::HashMap::new();
            let mut next = Vec::new();
            let mut m = |a: u32, b: u32, pos: &mut Vec<[f32; 3]>| {
                *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    let (p, q) = (pos[a as usize], pos[b as usize]);
                    let c = [(p[0] + q[0]) / 2., (p[1] + q[1]) / 2., (p[2] + q[2]) / 2.];
                    let l = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
                    pos.push([c[0] / l, c[1] / l, c[2] / l]);
                    pos.len() as u32 - 1
                })
            };
            for t in &tris {
                let (ab, bc, ca) = (m(t[0], t[1], &mut pos), m(t[1], t[2], &mut pos), m(t[2], t[0], &mut pos));
                next.extend([[t[0], ab, ca], [ab, t[1], bc], [ca, bc, t[2]], [ab, bc, ca]]);
            }
            tris = next;
        }
        let mut rng = gs_core::Rng::new(3);
        for p in &mut pos {
            let s = 1.0 + noise * rng.uniform_range(-1.0, 1.0);
            *p = [p[0] * s, p[1] * s, p[2] * s];
        }
        TriangleMesh { positions: pos, triangles: tris, colors: None }
    }

    fn radius_error(m: &TriangleMesh) -> (f64, f64) {
        let r: Vec<f64> = m.positions.iter().map(|p| ((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) as f64).sqrt()).collect();
        let mean = r.iter().sum::<f64>() / r.len() as f64;
        let rms = (r.iter().map(|x| (x - 1.0).powi(2)).sum::<f64>() / r.len() as f64).sqrt();
        (mean, rms)
    }

    #[test]
    fn smoothing_removes_ripples_without_shrinking() {
        let noisy = noisy_sphere(5, 0.02);
        let (_, rms0) = radius_error(&noisy);
        let smooth = smooth_mesh(&noisy, Smoothing::taubin(10)).unwrap();
        let (mean, rms) = radius_error(&smooth);
        assert!(rms < 0.5 * rms0, "rms {rms0} -> {rms}");
        // Plain Laplacian smoothing (λ steps only) shrinks the sphere by far more than this.
        assert!((mean - 1.0).abs() < 2e-3, "mean radius {mean}");
        assert_eq!(smooth.triangles, noisy.triangles);
        // The same result at any thread count: each vertex is a pure function of the last step.
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        assert_eq!(one.install(|| smooth_mesh(&noisy, Smoothing::taubin(10)).unwrap()).positions, smooth.positions);
    }

    #[test]
    fn boundary_vertices_stay_and_bad_steps_are_refused() {
        // A single triangle: every vertex is on the boundary.
        let m = TriangleMesh { positions: vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]], triangles: vec![[0, 1, 2]], colors: None };
        assert_eq!(smooth_mesh(&m, Smoothing::taubin(5)).unwrap().positions, m.positions);
        for (lambda, mu) in [(0.0, -0.5), (0.5, -0.4), (1.2, -1.3), (f32::NAN, -0.5)] {
            assert!(smooth_mesh(&m, Smoothing { iterations: 1, lambda, mu }).is_err(), "λ {lambda} μ {mu}");
        }
        let empty = TriangleMesh { positions: vec![], triangles: vec![], colors: None };
        assert!(smooth_mesh(&empty, Smoothing::taubin(3)).unwrap().positions.is_empty());
    }
}
