//! A fusion piece by piece makes the mesh of one volume: exact depth maps of three spheres and
//! a box, fused once whole and once as pieces cut across the scene at a slant, give the same
//! vertices and the same triangles, in less memory.

use gs_core::glam::DVec3;
use gs_core::{Image, Scene, View};
use gs_testdata::MeshShape;
use gs_train::{DepthSource, FusionPieces, MeshOptions, Simplify, fuse_mesh, fuse_mesh_in_pieces};
use gs_tsdf::analytic_depth::{Primitive, orbit_cameras, render_depth};

/// Pieces cut by parallel planes `p · normal = cut` (not aligned with the voxel grid).
struct Slabs {
    normal: DVec3,
    cuts: Vec<f64>,
}

impl FusionPieces for Slabs {
    fn count(&self) -> usize {
        self.cuts.len() + 1
    }
    fn owner(&self, p: DVec3) -> usize {
        let s = p.dot(self.normal);
        self.cuts.iter().filter(|&&c| s >= c).count()
    }
    fn near(&self, piece: usize, p: DVec3, reach: f64) -> bool {
        let s = p.dot(self.normal);
        let lo = if piece == 0 { f64::NEG_INFINITY } else { self.cuts[piece - 1] };
        let hi = self.cuts.get(piece).copied().unwrap_or(f64::INFINITY);
        s >= lo - reach && s < hi + reach
    }
    fn name(&self, piece: usize) -> String {
        format!("slab {piece}")
    }
}

fn world() -> (Scene, Vec<Primitive>) {
    let shapes = vec![
        Primitive::Sphere { center: DVec3::new(-0.9, 0.0, 0.1), radius: 0.5 },
        Primitive::Sphere { center: DVec3::new(0.2, 0.1, -0.2), radius: 0.6 },
        Primitive::Sphere { center: DVec3::new(1.1, -0.1, 0.3), radius: 0.4 },
        Primitive::Box { min: DVec3::new(-1.6, -0.9, -0.8), max: DVec3::new(1.7, -0.6, 0.9) },
    ];
    let views = orbit_cameras(24, 96, 72, DVec3::ZERO, 3.5)
        .into_iter()
        .enumerate()
        .map(|(i, camera)| View {
            name: format!("{i:03}.png"),
            image: Image::filled(camera.width as usize, camera.height as usize, 3, 0.5).unwrap(),
            camera,
            mask: None,
        })
        .collect();
    (Scene { views, ..Scene::default() }, shapes)
}

#[test]
fn pieces_join_into_the_mesh_of_one_volume() {
    let (scene, shapes) = world();
    let views: Vec<usize> = (0..scene.views.len()).collect();
    let opts = MeshOptions { voxel_size: Some(0.03), simplify: Simplify::Off, min_component_share: 0.0, ..MeshOptions::default() };
    let mut read = |v: &View| Ok(render_depth(&v.camera, &shapes));
    let (whole, whole_report) = fuse_mesh(&scene, &views, DepthSource::Given(&mut read), &opts).unwrap();
    let slabs = Slabs { normal: DVec3::new(1.0, 0.13, -0.21).normalize(), cuts: vec![-0.41, 0.57] };
    let (joined, report) = fuse_mesh_in_pieces(&scene, &views, DepthSource::Given(&mut read), &opts, &slabs).unwrap();
    // With a memory limit the survey's depth maps are kept for the pieces instead of read again.
    let mut reads = 0;
    let mut counted = |v: &View| {
        reads += 1;
        Ok(render_depth(&v.camera, &shapes))
    };
    let limited = MeshOptions { max_memory: Some(4 << 30), ..opts.clone() };
    let (kept, _) = fuse_mesh_in_pieces(&scene, &views, DepthSource::Given(&mut counted), &limited, &slabs).unwrap();
    assert_eq!(reads, views.len(), "each view read once (the probes of the memory estimate included)");
    assert!(MeshShape::of(&kept) == MeshShape::of(&joined));

    assert!(whole.triangles.len() > 5_000, "{} triangles", whole.triangles.len());
    assert_eq!(report.pieces.len(), 3);
    for piece in &report.pieces {
        assert!(piece.triangles > 500 && piece.views > 0, "{piece:?}");
        assert!(piece.tsdf_bytes < whole_report.tsdf_bytes, "{piece:?} against {} bytes whole", whole_report.tsdf_bytes);
    }
    // The pieces' triangles before the clean-up (degenerate ones, as one volume's) add up.
    let kept: usize = report.pieces.iter().map(|p| p.triangles).sum();
    assert_eq!(kept - report.components.result.triangles_removed, whole.triangles.len(), "{report:?}");
    assert_eq!(joined.triangles.len(), whole.triangles.len());
    let (w, j) = (MeshShape::of(&whole), MeshShape::of(&joined));
    assert_eq!(j.vertices.len(), w.vertices.len(), "vertices");
    assert!(j.vertices == w.vertices, "the joined mesh's vertices differ from one volume's");
    assert!(j.triangles == w.triangles, "the joined mesh's triangles differ from one volume's");
    // Shared seam vertices are one vertex, as in one volume's mesh.
    assert_eq!(joined.positions.len(), whole.positions.len());
    assert_eq!(report.pixel_footprint, whole_report.pixel_footprint);
}

#[test]
fn a_piece_over_the_memory_limit_is_refused_before_fusing() {
    let (scene, shapes) = world();
    let views: Vec<usize> = (0..scene.views.len()).collect();
    let opts = MeshOptions { voxel_size: Some(0.01), max_memory: Some(20 << 20), ..MeshOptions::default() };
    let mut read = |v: &View| Ok(render_depth(&v.camera, &shapes));
    let slabs = Slabs { normal: DVec3::X, cuts: vec![0.0] };
    let err = fuse_mesh_in_pieces(&scene, &views, DepthSource::Given(&mut read), &opts, &slabs).unwrap_err().to_string();
    assert!(err.contains("slab") && err.contains("memory limit") && err.contains("--voxel-size"), "{err}");
    let filtered = MeshOptions { consistency: Some(Default::default()), ..MeshOptions::default() };
    let err = fuse_mesh_in_pieces(&scene, &views, DepthSource::Given(&mut read), &filtered, &slabs).unwrap_err().to_string();
    assert!(err.contains("depth filter"), "{err}");
}
