//! Quadric-error mesh simplification (meshoptimizer, through the `meshopt` crate): a fused mesh
//! carries about two triangles per voxel face it crosses, far more than its accuracy needs;
//! edge collapses bounded by a world-space error (docs/method.md §meshing) keep the surface
//! within that distance with a fraction of the triangles.

use crate::clean::remove_unreferenced_vertices;
use crate::error::{Result, TsdfError};
use gs_core::TriangleMesh;
use meshopt::SimplifyOptions;
use serde::Serialize;

/// How far [`simplify_mesh`] reduces a mesh.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SimplifyTarget {
    /// Collapse edges while meshoptimizer's error estimate (the largest distance a collapse
    /// moves the surface) stays at most this many world units.
    MaxError(f64),
    /// At most this many triangles, whatever the error.
    Triangles(usize),
}

/// What [`simplify_mesh`] did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SimplifyReport {
    /// Triangles before.
    pub triangles_before: usize,
    /// Triangles after.
    pub triangles_after: usize,
    /// The error bound, world units (`None` for a triangle count).
    pub error_bound: Option<f64>,
    /// meshoptimizer's estimate of the largest deviation of the result, world units.
    pub error: f64,
    /// Whether a triangle count out of reach of topology-preserving collapses was met by
    /// meshoptimizer's topology-free ("sloppy") simplifier on the result.
    pub sloppy: bool,
}

/// Simplifies `mesh` to `target`. Vertices keep their positions and colours (the result
/// references a subset of them); unreferenced vertices are dropped. Deterministic.
pub fn simplify_mesh(mesh: &TriangleMesh, target: SimplifyTarget) -> Result<(TriangleMesh, SimplifyReport)> {
    mesh.validate()?;
    let before = mesh.triangles.len();
    let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    let (target_indices, bound) = match target {
        SimplifyTarget::MaxError(e) if e.is_finite() && e >= 0.0 => (0, e as f32),
        SimplifyTarget::MaxError(e) => {
            return Err(TsdfError::InvalidParameter(format!("simplification error bound {e} is not a finite distance ≥ 0")));
        }
        SimplifyTarget::Triangles(n) => (3 * n, f32::MAX),
    };
    let mut error = 0.0f32;
    let mut out = if indices.is_empty() {
        Vec::new()
    } else {
        meshopt::simplify_decoder(&indices, &mesh.positions, target_indices, bound, SimplifyOptions::ErrorAbsolute, Some(&mut error))
    };
    let mut sloppy = false;
    if let SimplifyTarget::Triangles(n) = target
        && out.len() > 3 * n
    {
        // Topology (holes, non-manifold edges) can stop edge collapses above the count; the
        // sloppy simplifier clusters vertices and always reaches it. Its error is relative.
        let mut rel = 0.0f32;
        out = meshopt::simplify_sloppy_decoder(&out, &mesh.positions, 3 * n, f32::MAX, Some(&mut rel));
        error = error.max(rel * meshopt::simplify_scale_decoder(&mesh.positions));
        sloppy = true;
    }
    let triangles = out.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
    let simplified = remove_unreferenced_vertices(&TriangleMesh { triangles, ..mesh.clone() });
    let report = SimplifyReport {
        triangles_before: before,
        triangles_after: simplified.triangles.len(),
        error_bound: match target {
            SimplifyTarget::MaxError(e) => Some(e),
            SimplifyTarget::Triangles(_) => None,
        },
        error: error as f64,
        sloppy,
    };
    Ok((simplified, report))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat `n × n` grid of unit squares in z = 0 (2n² triangles), with colours.
    fn grid(n: u32) -> TriangleMesh {
        let mut positions = Vec::new();
        let mut colors = Vec::new();
        for y in 0..=n {
            for x in 0..=n {
                positions.push([x as f32, y as f32, 0.0]);
                colors.push([x as u8, y as u8, 7]);
            }
        }
        let id = |x: u32, y: u32| y * (n + 1) + x;
        let mut triangles = Vec::new();
        for y in 0..n {
            for x in 0..n {
                triangles.push([id(x, y), id(x + 1, y), id(x + 1, y + 1)]);
                triangles.push([id(x, y), id(x + 1, y + 1), id(x, y + 1)]);
            }
        }
        TriangleMesh { positions, triangles, colors: Some(colors) }
    }

    #[test]
    fn a_plane_collapses_to_few_triangles_within_the_bound_and_keeps_colours() {
        let m = grid(20);
        let (s, r) = simplify_mesh(&m, SimplifyTarget::MaxError(1e-3)).unwrap();
        assert_eq!(r.triangles_before, 800);
        assert!(r.triangles_after < 80, "{} triangles left of a flat grid", r.triangles_after);
        assert!(r.error <= 1e-3);
        assert!(s.positions.iter().all(|p| p[2] == 0.0));
        // Every kept vertex is an original one with its own colour.
        let c = s.colors.as_ref().unwrap();
        for (p, col) in s.positions.iter().zip(c) {
            assert_eq!(*col, [p[0] as u8, p[1] as u8, 7]);
        }
        // The four corners stay, so the simplified grid still spans the square.
        for corner in [[0.0, 0.0, 0.0], [20.0, 0.0, 0.0], [0.0, 20.0, 0.0], [20.0, 20.0, 0.0]] {
            assert!(s.positions.contains(&corner), "corner {corner:?} lost");
        }
    }

    #[test]
    fn a_bumpy_surface_keeps_its_bumps_under_a_tight_bound_and_meets_a_count() {
        let mut m = grid(30);
        for p in &mut m.positions {
            p[2] = ((p[0] * 0.7).sin() * (p[1] * 0.5).cos()) * 2.0;
        }
        let (tight, rt) = simplify_mesh(&m, SimplifyTarget::MaxError(1e-4)).unwrap();
        let (loose, rl) = simplify_mesh(&m, SimplifyTarget::MaxError(0.5)).unwrap();
        assert!(rt.triangles_after > rl.triangles_after, "{} vs {}", rt.triangles_after, rl.triangles_after);
        assert!(tight.triangles.len() > 1000, "a tight bound keeps the curvature: {}", tight.triangles.len());
        assert!(rl.error <= 0.5 && rt.error <= 1e-4);
        let _ = loose;
        for n in [100, 7, 0] {
            let (s, r) = simplify_mesh(&m, SimplifyTarget::Triangles(n)).unwrap();
            assert!(s.triangles.len() <= n, "asked {n}, got {}", s.triangles.len());
            assert_eq!(r.error_bound, None);
            s.validate().unwrap();
        }
    }

    #[test]
    fn empty_and_bad_inputs() {
        let (s, r) = simplify_mesh(&TriangleMesh::default(), SimplifyTarget::MaxError(0.1)).unwrap();
        assert!(s.triangles.is_empty() && r.triangles_after == 0);
        assert!(simplify_mesh(&grid(2), SimplifyTarget::MaxError(f64::NAN)).is_err());
        assert!(simplify_mesh(&grid(2), SimplifyTarget::MaxError(-1.0)).is_err());
        let bad = TriangleMesh { triangles: vec![[0, 1, 99]], ..grid(1) };
        assert!(simplify_mesh(&bad, SimplifyTarget::Triangles(1)).is_err());
    }
}
