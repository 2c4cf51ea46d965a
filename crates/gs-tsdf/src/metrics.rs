//! Mesh metrics: area-weighted surface sampling, accuracy / completeness / Chamfer and
//! precision / recall / F1 at a distance threshold τ, with an optional distance clamp and an
//! axis-aligned crop of the prediction (the synth-bunny and DTU-style protocols).

use crate::error::{Result, TsdfError};
use gs_core::{Rng, TriangleMesh};
use kiddo::SquaredEuclidean;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use rayon::prelude::*;
use serde::Serialize;

/// An axis-aligned box.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Aabb {
    /// Lower corner.
    pub min: [f64; 3],
    /// Upper corner.
    pub max: [f64; 3],
}

impl Aabb {
    /// Whether `p` lies inside (bounds included).
    pub fn contains(&self, p: [f64; 3]) -> bool {
        (0..3).all(|k| p[k] >= self.min[k] && p[k] <= self.max[k])
    }

    /// The bounding box of a mesh's vertices; `None` when it has none.
    pub fn of_mesh(mesh: &TriangleMesh) -> Option<Self> {
        mesh.bounds().map(|(lo, hi)| Self { min: lo.map(|v| v as f64), max: hi.map(|v| v as f64) })
    }

    /// This box grown by `fraction` of its size per side, with everything below `min_z` cut
    /// off when given (the object protocols' crop of a prediction around a GT object).
    pub fn grown(&self, fraction: f64, min_z: Option<f64>) -> Self {
        let mut min: [f64; 3] = std::array::from_fn(|k| self.min[k] - fraction * (self.max[k] - self.min[k]));
        if let Some(z) = min_z {
            min[2] = z;
        }
        Self { min, max: std::array::from_fn(|k| self.max[k] + fraction * (self.max[k] - self.min[k])) }
    }

    /// Length of the diagonal.
    pub fn diagonal(&self) -> f64 {
        (0..3).map(|k| (self.max[k] - self.min[k]).powi(2)).sum::<f64>().sqrt()
    }
}

/// Options of [`evaluate_meshes`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EvalOptions {
    /// Points sampled on each mesh.
    pub samples: usize,
    /// Distance threshold τ of precision / recall / F1.
    pub tau: f64,
    /// Distances larger than this are clamped before averaging (DTU uses 20 mm).
    pub max_distance: Option<f64>,
    /// Crop of the prediction: triangles with a vertex outside are dropped before sampling.
    pub crop: Option<Aabb>,
    /// Seed of the surface sampling.
    pub seed: u64,
}

impl EvalOptions {
    /// Points sampled on each mesh by default.
    pub const DEFAULT_SAMPLES: usize = 200_000;

    /// The defaults against a GT whose bounding box is `gt`: [`Self::DEFAULT_SAMPLES`] samples,
    /// τ = 0.5 % of the box diagonal, no distance clamp, seed 0, and `crop` as given.
    pub fn for_gt(gt: &Aabb, crop: Option<Aabb>) -> Self {
        Self { samples: Self::DEFAULT_SAMPLES, tau: 0.005 * gt.diagonal(), max_distance: None, crop, seed: 0 }
    }

    /// The synth-bunny object protocol: crop the prediction to the GT's bounding box expanded by
    /// 5 % of its size per side with the floor (z < 0.005) removed, with [`Self::for_gt`]'s
    /// defaults.
    pub fn object_protocol(gt: &TriangleMesh) -> Result<Self> {
        let b = Aabb::of_mesh(gt).ok_or_else(|| TsdfError::InvalidMesh("ground-truth mesh has no vertices".into()))?;
        Ok(Self::for_gt(&b, Some(b.grown(0.05, Some(0.005)))))
    }
}

/// Accuracy, completeness, Chamfer and precision / recall / F1 of two point sets.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PointMetrics {
    /// Mean distance prediction → GT.
    pub accuracy: f64,
    /// Mean distance GT → prediction.
    pub completeness: f64,
    /// (accuracy + completeness) / 2.
    pub chamfer: f64,
    /// Fraction of prediction points closer than τ to the GT.
    pub precision: f64,
    /// Fraction of GT points closer than τ to the prediction.
    pub recall: f64,
    /// Harmonic mean of precision and recall (0 when both are 0).
    pub f1: f64,
    /// The threshold τ.
    pub tau: f64,
    /// Number of prediction points.
    pub pred_points: usize,
    /// Number of GT points.
    pub gt_points: usize,
}

/// The report of [`evaluate_meshes`] (what `vagsl eval-mesh --json` prints).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EvalReport {
    /// The metrics on the sampled points.
    #[serde(flatten)]
    pub metrics: PointMetrics,
    /// Triangles of the prediction after cropping.
    pub pred_triangles: usize,
    /// Surface area of the (cropped) prediction.
    pub pred_area: f64,
    /// Surface area of the GT.
    pub gt_area: f64,
    /// The options used.
    pub options: EvalOptions,
}

fn check_points(name: &str, pts: &[[f64; 3]]) -> Result<()> {
    if pts.is_empty() {
        return Err(TsdfError::InvalidMesh(format!("{name} point set is empty")));
    }
    if let Some(i) = pts.iter().position(|p| !p.iter().all(|v| v.is_finite())) {
        return Err(TsdfError::InvalidMesh(format!("{name} point {i} is not finite: {:?}", pts[i])));
    }
    Ok(())
}

/// Samples `n` points uniformly by area on the mesh's surface (deterministic for a seed and
/// independent of the thread count). Fails on a mesh with zero area or invalid indices.
pub fn sample_surface(mesh: &TriangleMesh, n: usize, seed: u64) -> Result<Vec<[f64; 3]>> {
    mesh.validate()?;
    let mut cum = Vec::with_capacity(mesh.triangles.len());
    let mut total = 0.0f64;
    for t in &mesh.triangles {
        total += mesh.triangle_area(t);
        cum.push(total);
    }
    if !(total > 0.0 && total.is_finite()) {
        return Err(TsdfError::InvalidMesh(format!(
            "cannot sample a mesh with surface area {total} ({} triangles)",
            mesh.triangles.len()
        )));
    }
    const CHUNK: usize = 4096;
    let rng = Rng::new(seed);
    let pos = |i: u32| mesh.positions[i as usize].map(|v| v as f64);
    let mut out = vec![[0.0; 3]; n];
    out.par_chunks_mut(CHUNK).enumerate().for_each(|(c, chunk)| {
        let mut r = rng.fork(c as u64);
        for p in chunk {
            let a = r.uniform_f64() * total;
            let ti = cum.partition_point(|&x| x <= a).min(cum.len() - 1);
            let t = mesh.triangles[ti];
            let (u1, u2) = (r.uniform_f64(), r.uniform_f64());
            let s = u1.sqrt();
            let (wa, wb, wc) = (1.0 - s, s * (1.0 - u2), s * u2);
            let (pa, pb, pc) = (pos(t[0]), pos(t[1]), pos(t[2]));
            *p = std::array::from_fn(|k| wa * pa[k] + wb * pb[k] + wc * pc[k]);
        }
    });
    Ok(out)
}

/// The prediction restricted to the box: triangles with all three vertices inside survive
/// (Open3D's `crop` semantics); unreferenced vertices are dropped.
pub fn crop_mesh(mesh: &TriangleMesh, aabb: &Aabb) -> TriangleMesh {
    let inside: Vec<bool> = mesh.positions.iter().map(|p| aabb.contains(p.map(|v| v as f64))).collect();
    let triangles = mesh
        .triangles
        .iter()
        .filter(|t| t.iter().all(|&v| inside.get(v as usize).copied().unwrap_or(false)))
        .copied()
        .collect();
    crate::clean::remove_unreferenced_vertices(&TriangleMesh { triangles, ..mesh.clone() })
}

/// Euclidean distance from each point of `from` to its nearest neighbour in `to` (kd-tree).
pub fn nearest_distances(from: &[[f64; 3]], to: &[[f64; 3]]) -> Result<Vec<f64>> {
    check_points("query", from)?;
    check_points("reference", to)?;
    let tree: ImmutableKdTree<f64, u32, 3, 32> = ImmutableKdTree::new_from_slice(to);
    Ok(from.par_iter().with_min_len(1024).map(|q| tree.nearest_one::<SquaredEuclidean>(q).distance.sqrt()).collect())
}

/// Metrics of a predicted point set against a GT point set at threshold `tau`; distances above
/// `max_distance` (if any) are clamped before averaging.
pub fn point_metrics(
    pred: &[[f64; 3]],
    gt: &[[f64; 3]],
    tau: f64,
    max_distance: Option<f64>,
) -> Result<PointMetrics> {
    if !(tau.is_finite() && tau > 0.0) {
        return Err(TsdfError::InvalidParameter(format!("tau must be finite and > 0, got {tau}")));
    }
    if let Some(m) = max_distance
        && !(m > 0.0)
    {
        return Err(TsdfError::InvalidParameter(format!("max_distance must be > 0, got {m}")));
    }
    let d_pg = nearest_distances(pred, gt)?;
    let d_gp = nearest_distances(gt, pred)?;
    let clamp = max_distance.unwrap_or(f64::INFINITY);
    let mean = |d: &[f64]| d.iter().map(|&x| x.min(clamp)).sum::<f64>() / d.len() as f64;
    let frac = |d: &[f64]| d.iter().filter(|&&x| x < tau).count() as f64 / d.len() as f64;
    let (accuracy, completeness) = (mean(&d_pg), mean(&d_gp));
    let (precision, recall) = (frac(&d_pg), frac(&d_gp));
    let f1 = if precision + recall > 0.0 { 2.0 * precision * recall / (precision + recall) } else { 0.0 };
    Ok(PointMetrics {
        accuracy,
        completeness,
        chamfer: 0.5 * (accuracy + completeness),
        precision,
        recall,
        f1,
        tau,
        pred_points: pred.len(),
        gt_points: gt.len(),
    })
}

/// Evaluates a predicted mesh against a GT mesh: optional crop of the prediction, `samples`
/// area-weighted points on each (seeds `seed` and `seed + 1`), then [`point_metrics`].
pub fn evaluate_meshes(pred: &TriangleMesh, gt: &TriangleMesh, opts: &EvalOptions) -> Result<EvalReport> {
    if opts.samples == 0 {
        return Err(TsdfError::InvalidParameter("samples must be at least 1".into()));
    }
    pred.validate()?;
    gt.validate()?;
    let cropped = match &opts.crop {
        Some(b) => crop_mesh(pred, b),
        None => pred.clone(),
    };
    let p = sample_surface(&cropped, opts.samples, opts.seed)
        .map_err(|e| TsdfError::InvalidMesh(format!("prediction (after crop): {e}")))?;
    let g = sample_surface(gt, opts.samples, opts.seed.wrapping_add(1))
        .map_err(|e| TsdfError::InvalidMesh(format!("ground truth: {e}")))?;
    let metrics = point_metrics(&p, &g, opts.tau, opts.max_distance)?;
    Ok(EvalReport {
        metrics,
        pred_triangles: cropped.triangles.len(),
        pred_area: cropped.area(),
        gt_area: gt.area(),
        options: opts.clone(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(z: f32) -> TriangleMesh {
        TriangleMesh {
            positions: vec![[0.0, 0.0, z], [1.0, 0.0, z], [1.0, 1.0, z], [0.0, 1.0, z]],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            colors: None,
        }
    }

    #[test]
    fn sampling_is_uniform_deterministic_and_on_the_surface() {
        let mut m = square(0.0);
        // A large second triangle: three times the area of the square.
        m.positions.extend([[0.0, 0.0, 1.0], [3.0, 0.0, 1.0], [0.0, 2.0, 1.0]]);
        m.triangles.push([4, 5, 6]);
        let a = sample_surface(&m, 40_000, 7).unwrap();
        assert_eq!(a, sample_surface(&m, 40_000, 7).unwrap());
        assert_ne!(a, sample_surface(&m, 40_000, 8).unwrap());
        let top = a.iter().filter(|p| p[2] > 0.5).count() as f64 / a.len() as f64;
        assert!((top - 0.75).abs() < 0.01, "{top}");
        let mean_x = a.iter().filter(|p| p[2] == 0.0).map(|p| p[0]).sum::<f64>() / (a.len() as f64 * 0.25);
        assert!((mean_x - 0.5).abs() < 0.01, "{mean_x}");
        assert!(sample_surface(&TriangleMesh::default(), 10, 0).is_err());
    }

    #[test]
    fn metrics_of_offset_planes() {
        let g = sample_surface(&square(0.0), 20_000, 1).unwrap();
        let p = sample_surface(&square(0.01), 20_000, 2).unwrap();
        let m = point_metrics(&p, &g, 0.02, None).unwrap();
        assert!(m.accuracy >= 0.01 && m.accuracy < 0.0115, "{m:?}");
        assert!(m.completeness >= 0.01 && m.completeness < 0.0115);
        assert_eq!(m.precision, 1.0);
        assert_eq!(m.f1, 1.0);
        let tight = point_metrics(&p, &g, 0.005, Some(0.004)).unwrap();
        assert_eq!(tight.f1, 0.0);
        assert!((tight.accuracy - 0.004).abs() < 1e-12);
        assert!(point_metrics(&[], &g, 0.1, None).is_err());
        assert!(point_metrics(&p, &g, 0.0, None).is_err());
        assert!(point_metrics(&[[f64::NAN, 0.0, 0.0]], &g, 0.1, None).is_err());
    }

    #[test]
    fn crop_and_evaluate() {
        let mut pred = square(0.0);
        pred.positions.extend([[10.0, 10.0, 10.0], [11.0, 10.0, 10.0], [10.0, 11.0, 10.0]]);
        pred.triangles.push([4, 5, 6]);
        let gt = square(0.0);
        let opts = EvalOptions {
            samples: 5000,
            tau: 0.05,
            max_distance: None,
            crop: Some(Aabb { min: [-0.1; 3], max: [1.1; 3] }),
            seed: 3,
        };
        let r = evaluate_meshes(&pred, &gt, &opts).unwrap();
        assert_eq!(r.pred_triangles, 2);
        assert!(r.metrics.chamfer < 0.012 && r.metrics.f1 > 0.99, "{r:?}");
        let json = serde_json::to_string(&r).unwrap();
        assert!(json.contains("\"chamfer\""));
        let off = EvalOptions { crop: Some(Aabb { min: [5.0; 3], max: [6.0; 3] }), ..opts };
        assert!(evaluate_meshes(&pred, &gt, &off).is_err());
    }
}
