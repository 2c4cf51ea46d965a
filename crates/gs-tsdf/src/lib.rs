//! Sparse voxel-block TSDF fusion, marching cubes, mesh clean-up and mesh metrics.
//!
//! ```
//! use gs_tsdf::{TsdfConfig, TsdfVolume, analytic_depth::{Primitive, orbit_cameras, render_depth}};
//! use gs_core::glam::DVec3;
//!
//! // Fuse exact depth maps of a unit sphere seen from 30 cameras and extract its surface.
//! let sphere = [Primitive::Sphere { center: DVec3::ZERO, radius: 1.0 }];
//! let mut volume = TsdfVolume::new(TsdfConfig::with_voxel_size(0.05)).unwrap();
//! for camera in orbit_cameras(30, 160, 120, DVec3::ZERO, 3.0) {
//!     let depth = render_depth(&camera, &sphere);
//!     volume.integrate(&camera, &depth, None, None).unwrap();
//! }
//! let mesh = volume.extract_mesh().unwrap();
//! assert!(mesh.triangles.len() > 100);
//! // Every vertex lies within half a voxel of the sphere.
//! assert!(mesh.positions.iter().all(|p| (DVec3::from(p.map(f64::from)).length() - 1.0).abs() < 0.025));
//!
//! // Sample the surface uniformly by area: the mean distance to the true sphere is tiny.
//! let samples = gs_tsdf::sample_surface(&mesh, 10_000, 0).unwrap();
//! let mean = samples.iter().map(|p| (DVec3::from(*p).length() - 1.0).abs()).sum::<f64>() / 1e4;
//! assert!(mean < 0.01, "mean distance {mean}");
//! ```
//!
//! * [`TsdfVolume`]: a hash map of 8³ voxel blocks, allocated only within `sdf_trunc` of
//!   observed depth; [`TsdfVolume::integrate`] follows Open3D's `ScalableTSDFVolume`.
//! * [`TsdfVolume::extract_mesh`]: marching cubes across block borders with shared vertices.
//! * [`consistency`]: multi-view geometric depth consistency, before fusion.
//! * [`clean`]: connected components (absolute or relative size), degenerate / unreferenced
//!   elements, mask culling.
//! * [`smooth`]: Taubin λ|μ smoothing of the fused surface's voxel-scale ripples.
//! * [`simplify`]: quadric-error simplification to a world-space error bound (one, or one per
//!   vertex from the pixel footprint at it) or a count.
//! * [`fusion_memory`]: the peak-memory estimate of a fusion, made before allocating it.
//! * [`metrics`]: area-weighted sampling, accuracy / completeness / Chamfer / F1.

pub mod analytic_depth;
pub mod clean;
pub mod consistency;
mod ray_depth;
pub mod error;
pub mod extract;
pub mod fusion_memory;
mod mc_table;
pub mod metrics;
pub mod simplify;
pub mod smooth;
pub mod volume;

pub use clean::{ComponentFilter, ComponentReport, clean_mesh, cull_by_masks, filter_components, remove_degenerate_triangles, remove_unreferenced_vertices};
pub use consistency::{ConsistencyConfig, ConsistencyReport, filter_depths};
pub use error::{Result, TsdfError, format_bytes};
pub use extract::ExtractOptions;
pub use fusion_memory::{BlockCensus, MemoryEstimate};
pub use metrics::{Aabb, EvalOptions, EvalReport, PointMetrics, evaluate_meshes, point_metrics, sample_surface};
pub use simplify::{GradedBounds, SimplifyReport, SimplifyTarget, pixel_footprints, simplify_mesh, simplify_mesh_graded};
pub use smooth::{Smoothing, smooth_mesh};
pub use volume::{BlockFilter, IntegrateStats, TsdfConfig, TsdfVolume, block_centre};
