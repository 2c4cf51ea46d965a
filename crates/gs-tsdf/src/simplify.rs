//! Quadric-error mesh simplification (meshoptimizer, through the `meshopt` crate): a fused mesh
//! carries about two triangles per voxel face it crosses, far more than its accuracy needs;
//! edge collapses bounded by a world-space error (docs/method.md §meshing) keep the surface
//! within that distance with a fraction of the triangles. [`simplify_mesh_graded`] bounds each
//! vertex by its own distance ([`pixel_footprints`]: far surfaces, seen at a coarser footprint,
//! are simplified more than near ones).

use crate::clean::remove_unreferenced_vertices;
use crate::error::{Result, TsdfError};
use gs_core::{Camera, TriangleMesh};
use rayon::prelude::*;
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
    /// The per-vertex bounds of [`simplify_mesh_graded`] (`None` for one bound or a count).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub graded: Option<GradedBounds>,
    /// Whether a triangle count out of reach of topology-preserving collapses was met by
    /// meshoptimizer's topology-free ("sloppy") simplifier, clustering the whole mesh.
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
    } else if target_indices == 0 {
        let (out, e) = collapse_in_cells(indices.clone(), &mesh.positions, &vec![false; mesh.positions.len()], bound)?;
        error = e;
        out
    } else {
        meshopt::simplify_decoder(&indices, &mesh.positions, target_indices, bound, SimplifyOptions::ErrorAbsolute, Some(&mut error))
    };
    let mut sloppy = false;
    if let SimplifyTarget::Triangles(n) = target
        && out.len() > 3 * n
    {
        // Topology (holes, non-manifold edges) can stop edge collapses above the count; the
        // sloppy simplifier clusters vertices and always reaches it. Clustering the whole
        // mesh, not the stopped result, keeps it close: synth-bunny at 2,000 triangles,
        // Chamfer 0.0076 against 0.048. Its error is relative.
        let mut rel = 0.0f32;
        out = meshopt::simplify_sloppy_decoder(&indices, &mesh.positions, 3 * n, f32::MAX, Some(&mut rel));
        error = rel * meshopt::simplify_scale_decoder(&mesh.positions);
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
        graded: None,
        sloppy,
    };
    Ok((simplified, report))
}

/// The per-vertex error bounds of a [`simplify_mesh_graded`] run, world units.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GradedBounds {
    /// The smallest bound of a referenced vertex.
    pub smallest: f64,
    /// The largest bound of a referenced vertex (after the cap of [`GRADED_MAX_RATIO`]).
    pub largest: f64,
    /// meshoptimizer passes run (bound classes that hold vertices).
    pub passes: usize,
}

/// Ratio between consecutive bound classes of [`simplify_mesh_graded`]: a vertex's bound is
/// rounded down to `smallest · GRADED_CLASS_RATIO^c`, at most 1/√2 below the bound asked.
pub const GRADED_CLASS_RATIO: f64 = std::f64::consts::SQRT_2;

/// Bounds beyond this multiple of the smallest are capped (a background seen only from afar
/// still keeps a bound tied to the scene's resolution).
pub const GRADED_MAX_RATIO: f64 = 16.0;

/// Simplifies `mesh` so that no vertex moves further than its own bound `bounds[v]` (world
/// units, one per vertex; docs/method.md §meshing). The bounds are rounded down to classes
/// `b₀·r^c` ([`GRADED_CLASS_RATIO`], b₀ the smallest), and each class is simplified in a pass of
/// its own, coarsest first, with every other vertex locked: a vertex moves (or goes) only in its
/// class's pass, by at most `b₀·r^c ≤ bounds[v]`. A collapse onto a locked neighbour of a finer
/// class moves the surface within one ring of it by up to the coarser bound. The report's
/// `error` is the largest pass's estimate. Deterministic.
pub fn simplify_mesh_graded(mesh: &TriangleMesh, bounds: &[f64]) -> Result<(TriangleMesh, SimplifyReport)> {
    mesh.validate()?;
    if bounds.len() != mesh.positions.len() {
        return Err(TsdfError::InvalidParameter(format!(
            "{} simplification bounds for a mesh of {} vertices",
            bounds.len(),
            mesh.positions.len()
        )));
    }
    if let Some(b) = bounds.iter().find(|b| !(b.is_finite() && **b >= 0.0)) {
        return Err(TsdfError::InvalidParameter(format!("simplification error bound {b} is not a finite distance ≥ 0")));
    }
    let before = mesh.triangles.len();
    let mut indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    let smallest = indices.iter().map(|&i| bounds[i as usize]).fold(f64::INFINITY, f64::min);
    if indices.is_empty() || smallest <= 0.0 {
        // Nothing to simplify, or a vertex that may not move: one pass at the smallest bound.
        let b = if indices.is_empty() { 0.0 } else { smallest };
        return simplify_mesh(mesh, SimplifyTarget::MaxError(b));
    }
    let class_of = |b: f64| ((b / smallest).min(GRADED_MAX_RATIO).ln() / GRADED_CLASS_RATIO.ln() + 1e-9).floor() as usize;
    let classes: Vec<usize> = bounds.iter().map(|&b| if b > 0.0 { class_of(b) } else { 0 }).collect();
    let top = indices.iter().map(|&i| classes[i as usize]).max().unwrap_or(0);
    let mut present = vec![false; top + 1];
    for &i in &indices {
        present[classes[i as usize]] = true;
    }
    let mut moved = 0.0f64;
    let mut passes = 0;
    for class in (0..=top).rev().filter(|&c| present[c]) {
        let locks: Vec<bool> = classes.iter().map(|&c| c != class).collect();
        let bound = (smallest * GRADED_CLASS_RATIO.powi(class as i32)) as f32;
        let (out, err) = collapse_in_cells(indices, &mesh.positions, &locks, bound)?;
        indices = out;
        moved = moved.max(err as f64);
        passes += 1;
    }
    let triangles = indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
    let simplified = remove_unreferenced_vertices(&TriangleMesh { triangles, ..mesh.clone() });
    let largest = smallest * GRADED_CLASS_RATIO.powi(top as i32);
    let report = SimplifyReport {
        triangles_before: before,
        triangles_after: simplified.triangles.len(),
        error_bound: Some(smallest),
        error: moved,
        graded: Some(GradedBounds { smallest, largest, passes }),
        sloppy: false,
    };
    Ok((simplified, report))
}

/// Cell side of `collapse_in_cells`, in multiples of the error bound.
pub const CELL_BOUNDS: f64 = 256.0;

/// Share of the bound that `collapse_in_cells` spends in its first round (the rest in the
/// second, around the first round's seams).
pub const SEAM_SHARE_FIRST: f32 = 2.0 / 3.0;

/// Smallest cell side of `collapse_in_cells`, in mean edge lengths of the mesh.
pub const CELL_EDGES: f64 = 32.0;

/// Edge collapses of the triangles `indices` (over `positions`) within `bound`, leaving the
/// `locked` vertices in place, run cell by cell. meshoptimizer measures a collapse's error with
/// quadrics in f32 over coordinates normalised to the extent of what it is given; a bound a
/// ten-thousandth of that extent is below their rounding where the planes lie far from the
/// normalised origin, so a whole synth-bunny scene at a tenth of a voxel kept its exactly flat
/// far walls unsimplified (a wall alone collapsed to 0.6 % of its triangles). Cubes of
/// [`CELL_BOUNDS`] bounds (at least [`CELL_EDGES`] edges) keep the ratio at 1/256. Round 0
/// simplifies each cube's triangles with the vertices it shares with other cubes locked, within
/// [`SEAM_SHARE_FIRST`] of the bound; round 1 does the same on cubes offset by half a side with
/// only round 0's seam vertices free, within the rest, so the two add up to the bound.
/// Deterministic (cells in order). Returns the triangles and the sum over the rounds of the
/// largest error estimate.
fn collapse_in_cells(indices: Vec<u32>, positions: &[[f32; 3]], locked: &[bool], bound: f32) -> Result<(Vec<u32>, f32)> {
    // At least CELL_EDGES typical edges across, so that a coarse mesh under a tight bound is
    // not all seams.
    let at = |v: u32| gs_core::glam::Vec3::from(positions[v as usize]).as_dvec3();
    let edges: f64 = indices.chunks_exact(3).map(|t| at(t[0]).distance(at(t[1]))).sum();
    let mean_edge = edges / (indices.len() / 3).max(1) as f64;
    let side = (bound as f64 * CELL_BOUNDS).max(CELL_EDGES * mean_edge).max(f64::MIN_POSITIVE);
    let adapter = meshopt::VertexDataAdapter::new(meshopt::typed_to_bytes(positions), 12, 0)
        .map_err(|e| TsdfError::InvalidParameter(format!("mesh positions: {e}")))?;
    let mut tris = indices;
    let mut free: Vec<bool> = locked.iter().map(|l| !l).collect();
    let mut error = 0.0f32;
    for round in 0..2 {
        let offset = 0.5 * side * round as f64;
        // A seam vertex's surroundings are simplified in both rounds: the two shares sum to one.
        let share = if round == 0 { SEAM_SHARE_FIRST } else { 1.0 - SEAM_SHARE_FIRST };
        let cell = |t: &[u32]| -> [i64; 3] {
            std::array::from_fn(|a| {
                let c = t.iter().map(|&i| positions[i as usize][a] as f64).sum::<f64>() / 3.0;
                ((c + offset) / side).floor().clamp(-1e15, 1e15) as i64
            })
        };
        // Triangles with a free vertex, grouped by cell; the rest pass through.
        let mut work: Vec<([i64; 3], [u32; 3])> = Vec::new();
        let mut kept: Vec<[u32; 3]> = Vec::new();
        for t in tris.chunks_exact(3) {
            let t = [t[0], t[1], t[2]];
            if t.iter().any(|&i| free[i as usize]) {
                work.push((cell(&t), t));
            } else {
                kept.push(t);
            }
        }
        work.sort_by_key(|w| w.0);
        // A vertex in triangles of two cells is on a seam: locked this round, free the next.
        let mut first: Vec<Option<[i64; 3]>> = vec![None; positions.len()];
        let mut seam = vec![false; positions.len()];
        for (c, t) in &work {
            for &i in t {
                match first[i as usize] {
                    None => first[i as usize] = Some(*c),
                    Some(f) if f != *c => seam[i as usize] = true,
                    _ => {}
                }
            }
        }
        let locks: Vec<bool> = (0..positions.len()).map(|i| !free[i] || seam[i]).collect();
        let mut out: Vec<u32> = kept.into_iter().flatten().collect();
        let mut start = 0;
        let mut round_error = 0.0f32;
        while start < work.len() {
            let end = start + work[start..].iter().take_while(|w| w.0 == work[start].0).count();
            let group: Vec<u32> = work[start..end].iter().flat_map(|w| w.1).collect();
            let mut e = 0.0f32;
            let opts = SimplifyOptions::ErrorAbsolute | SimplifyOptions::Sparse;
            out.extend(meshopt::simplify_with_locks(&group, &adapter, &locks, 0, share * bound, opts, Some(&mut e)));
            round_error = round_error.max(e);
            start = end;
        }
        error += round_error;
        tris = out;
        free = seam.iter().zip(locked).map(|(s, l)| *s && !l).collect();
    }
    Ok((tris, error))
}

/// The pixel footprint at each of `positions` (world units): the smallest camera depth / fx
/// over the `cameras` whose image contains the point, occluded or not (so never coarser than
/// the finest view of it). `None` for a point no camera's image contains.
pub fn pixel_footprints(positions: &[[f32; 3]], cameras: &[&Camera]) -> Vec<Option<f64>> {
    positions
        .par_iter()
        .map(|p| {
            let p = gs_core::glam::DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            cameras
                .iter()
                .filter_map(|c| c.project(p).filter(|(px, _)| c.contains(*px)).map(|(_, z)| z / c.intrinsics.fx))
                .reduce(f64::min)
        })
        .collect()
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
        assert!(r.triangles_after < 100, "{} triangles left of a flat grid", r.triangles_after);
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

    /// The height of the simplified height-field `s` above (x, y): barycentric interpolation
    /// in the triangle whose xy-projection holds the point.
    fn height_at(s: &TriangleMesh, x: f32, y: f32) -> Option<f32> {
        s.triangles.iter().find_map(|t| {
            let [a, b, c] = t.map(|i| s.positions[i as usize]);
            let d = (b[1] - c[1]) * (a[0] - c[0]) + (c[0] - b[0]) * (a[1] - c[1]);
            let l0 = ((b[1] - c[1]) * (x - c[0]) + (c[0] - b[0]) * (y - c[1])) / d;
            let l1 = ((c[1] - a[1]) * (x - c[0]) + (a[0] - c[0]) * (y - c[1])) / d;
            let l2 = 1.0 - l0 - l1;
            (l0 >= -1e-5 && l1 >= -1e-5 && l2 >= -1e-5).then(|| l0 * a[2] + l1 * b[2] + l2 * c[2])
        })
    }

    /// A bumpy height field whose right half may move 8× further than its left half: each half
    /// keeps about as many triangles as its own bound leaves of the whole grid, every original
    /// vertex stays within its own bound of the result (checked on the height field), and the
    /// result lies between the uniform simplifications at the two bounds.
    #[test]
    fn graded_bounds_simplify_each_vertex_to_its_own_distance() {
        let mut m = grid(40);
        for p in &mut m.positions {
            p[2] = (p[0] * 0.45).sin() * (p[1] * 0.35).cos() * 1.5;
        }
        let (fine, coarse) = (0.01, 0.08);
        let bounds: Vec<f64> = m.positions.iter().map(|p| if p[0] < 20.0 { fine } else { coarse }).collect();
        let (s, r) = simplify_mesh_graded(&m, &bounds).unwrap();
        s.validate().unwrap();
        let g = r.graded.unwrap();
        assert_eq!((g.smallest, g.passes), (fine, 2), "classes 0 and 6 (8 = √2⁶)");
        assert!((g.largest - coarse).abs() < 1e-12 && r.error <= coarse + 1e-6, "{r:?}");
        let left = |t: &[u32; 3]| t.iter().all(|&i| s.positions[i as usize][0] < 20.0);
        let right = |t: &[u32; 3]| t.iter().all(|&i| s.positions[i as usize][0] > 20.0);
        let (nl, nr) = (s.triangles.iter().filter(|t| left(t)).count(), s.triangles.iter().filter(|t| right(t)).count());
        let (u_fine, _) = simplify_mesh(&m, SimplifyTarget::MaxError(fine)).unwrap();
        let (u_coarse, _) = simplify_mesh(&m, SimplifyTarget::MaxError(coarse)).unwrap();
        // Each half is simplified about as its own bound simplifies the whole grid.
        let (uf, uc) = (u_fine.triangles.len() as f64 / 2.0, u_coarse.triangles.len() as f64 / 2.0);
        assert!(nl as f64 > 0.85 * uf && (nr as f64) < 1.1 * uc, "{nl} left ({uf} at the fine bound), {nr} right ({uc} at the coarse)");
        let mut worst = [0f32; 2];
        for (p, b) in m.positions.iter().zip(&bounds) {
            let h = height_at(&s, p[0], p[1]).expect("the result covers the grid");
            let k = usize::from(*b == coarse);
            worst[k] = worst[k].max((h - p[2]).abs());
        }
        assert!(worst[0] <= fine as f32 * 1.5 && worst[1] <= coarse as f32 * 1.5, "deviation {worst:?}");
        let n = s.triangles.len();
        assert!(u_coarse.triangles.len() < n && n < u_fine.triangles.len(), "{} < {n} < {}", u_coarse.triangles.len(), u_fine.triangles.len());
        eprintln!("graded: {n} triangles ({nl} left, {nr} right), deviation {worst:?}");
        // One bound for every vertex is one pass, as the uniform simplification.
        let (one, r1) = simplify_mesh_graded(&m, &vec![coarse; bounds.len()]).unwrap();
        assert_eq!((one.triangles.len(), r1.graded.unwrap().passes), (u_coarse.triangles.len(), 1));
        // Bad bounds are errors.
        assert!(simplify_mesh_graded(&m, &bounds[1..]).is_err());
        assert!(simplify_mesh_graded(&m, &[f64::NAN].repeat(bounds.len())).is_err());
    }

    /// A point's footprint is its depth / fx in the nearest camera that images it: on a ring
    /// of eight cameras (radius 3, height 1, fx 60, all looking at the origin) the origin is
    /// √10 deep in every view; halfway to camera 0 it is √10/2 deep there.
    #[test]
    fn footprints_come_from_the_nearest_camera_that_sees_the_point() {
        let cams = gs_core::camera::camera_ring(8);
        let refs: Vec<&Camera> = cams.iter().collect();
        let f = pixel_footprints(&[[0.0, 0.0, 0.0], [1.5, 0.0, 0.5], [1e4, 1e4, 1e4]], &refs);
        let expect = [10f64.sqrt() / 60.0, 10f64.sqrt() / 120.0];
        for k in 0..2 {
            assert!((f[k].unwrap() - expect[k]).abs() < 1e-9, "{k}: {:?} vs {}", f[k], expect[k]);
        }
        assert_eq!(f[2], None, "no camera images a point far off");
        assert_eq!(pixel_footprints(&[[0.0; 3]], &[]), vec![None]);
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
