//! The depth-consistency filter and the simplification on synth-bunny's exact depth maps
//! (release only: `cargo test -p gs-tsdf --release --test mesh_filters`).

mod common;

use gs_core::{Camera, Image, NeighbourRule, TriangleMesh, source_view_candidates};
use gs_tsdf::{
    Aabb, ConsistencyConfig, EvalOptions, SimplifyTarget, TsdfConfig, TsdfVolume, evaluate_meshes, filter_depths, metrics::nearest_distances,
    pixel_footprints, sample_surface, simplify_mesh, simplify_mesh_graded,
};

fn fuse(views: &[(Camera, Image)], voxel: f64, bounds: Option<Aabb>) -> TriangleMesh {
    let cfg = TsdfConfig { depth_trunc: 20.0, with_color: false, bounds, ..TsdfConfig::with_voxel_size(voxel) };
    let mut vol = TsdfVolume::new(cfg).unwrap();
    for (i, (cam, depth)) in views.iter().enumerate() {
        vol.integrate_view(i, cam, depth, None, None, None).unwrap();
    }
    vol.extract_mesh().unwrap()
}

/// The sheet planted in view `V`: pixels `X0..X1 × Y0..Y1` pulled to 60 % of their depth.
const V: usize = 5;
const SHEET: (usize, usize, usize, usize) = (200, 300, 120, 200);

#[test]
#[cfg_attr(debug_assertions, ignore = "release only: filters and fuses 40 views of 480x360")]
fn a_sheet_one_view_holds_is_dropped_and_the_surfaces_all_views_see_are_kept() {
    if !gs_testdata::needs!("data/synth-bunny") {
        return;
    }
    let mut views = common::bunny_views();
    assert_eq!(views.len(), 40);
    let (x0, x1, y0, y1) = SHEET;
    for y in y0..y1 {
        for x in x0..x1 {
            let d = views[V].1.get(x, y, 0);
            views[V].1.set(x, y, 0, 0.6 * d);
        }
    }
    let cameras: Vec<&Camera> = views.iter().map(|v| &v.0).collect();
    let neighbours = source_view_candidates(&cameras, &NeighbourRule::default());
    let mut depths: Vec<Image> = views.iter().map(|v| v.1.clone()).collect();
    let mut maps: Vec<&mut Image> = depths.iter_mut().collect();
    let t = std::time::Instant::now();
    let r = filter_depths(&cameras, &mut maps, &neighbours, &ConsistencyConfig::default()).unwrap();
    eprintln!("filter {:.2}s: {r:?}", t.elapsed().as_secs_f64());
    let sheet_kept = (y0..y1).flat_map(|y| (x0..x1).map(move |x| (x, y))).filter(|&(x, y)| depths[V].get(x, y, 0) > 0.0).count();
    assert_eq!(sheet_kept, 0, "pixels of the sheet kept");
    // Exact depths elsewhere: what is dropped lies where fewer than two neighbours' images
    // reach (the strips along a view's image border that the ring's neighbours do not cover)
    // and at depth edges. Measured 2026-11-26: 9.6 % of the 6.9 M exact depths.
    let sheet = ((x1 - x0) * (y1 - y0)) as u64;
    assert_eq!(r.pixels_checked, 40 * 480 * 360);
    let others = r.pixels_dropped - sheet;
    assert!((others as f64) < 0.11 * r.pixels_checked as f64, "{others} consistent pixels dropped");
    assert_eq!(r.views_without_neighbours, 0);

    // Fused, the sheet is a surface where nothing is; filtered, it is gone.
    let scene_gt = common::read_ply(&common::bunny_dir().join("gt_scene_mesh.ply"));
    let gt_points = sample_surface(&scene_gt, 2_000_000, 1).unwrap();
    let far = |mesh: &TriangleMesh| {
        let v: Vec<[f64; 3]> = mesh.positions.iter().map(|p| p.map(f64::from)).collect();
        nearest_distances(&v, &gt_points).unwrap().iter().filter(|d| **d > 0.05).count()
    };
    let clean = far(&fuse(&common::bunny_views(), 0.016, None));
    let raw = far(&fuse(&views, 0.016, None));
    let views_filtered: Vec<(Camera, Image)> = views.iter().map(|v| v.0.clone()).zip(depths).collect();
    let filtered = far(&fuse(&views_filtered, 0.016, None));
    eprintln!("vertices > 0.05 from the scene: {clean} without the sheet, {raw} with it, {filtered} filtered");
    assert!(raw > clean + 500, "the planted sheet left only {raw} stray vertices ({clean} without it)");
    assert!(filtered <= clean, "{filtered} stray vertices after the filter, {clean} without the sheet");
}

#[test]
#[cfg_attr(debug_assertions, ignore = "release only: fuses 40 views of 480x360")]
fn the_simplified_bunny_keeps_its_accuracy_with_a_fraction_of_the_triangles() {
    if !gs_testdata::needs!("data/synth-bunny") {
        return;
    }
    let views = common::bunny_views();
    let gt = common::read_ply(&common::bunny_dir().join("gt_mesh.ply"));
    let protocol = EvalOptions::object_protocol(&gt).unwrap();
    // A fine voxel (about the pixel footprint at the bunny) inside the scoring box, to give
    // simplification work.
    let mesh = fuse(&views, 0.004, protocol.crop);
    let full = evaluate_meshes(&mesh, &gt, &protocol).unwrap().metrics;
    // Bound: a quarter of the pixel footprint (median depth / fx over the views).
    let mut fp: Vec<f64> = views
        .iter()
        .map(|(cam, d)| {
            let mut z: Vec<f32> = d.data().iter().copied().filter(|z| *z > 0.0).collect();
            let mid = z.len() / 2;
            *z.select_nth_unstable_by(mid, f32::total_cmp).1 as f64 / cam.intrinsics.fx
        })
        .collect();
    fp.sort_by(f64::total_cmp);
    let bound = 0.25 * fp[fp.len() / 2];
    let t = std::time::Instant::now();
    let (simple, r) = simplify_mesh(&mesh, SimplifyTarget::MaxError(bound)).unwrap();
    let s = evaluate_meshes(&simple, &gt, &protocol).unwrap().metrics;
    eprintln!(
        "bound {bound:.5}: {} -> {} triangles ({:.1} %) in {:.2}s; Chamfer {:.5} -> {:.5}, F1 {:.4} -> {:.4}",
        r.triangles_before,
        r.triangles_after,
        100.0 * r.triangles_after as f64 / r.triangles_before as f64,
        t.elapsed().as_secs_f64(),
        full.chamfer,
        s.chamfer,
        full.f1,
        s.f1
    );
    assert!(r.error <= bound);
    // Measured 2026-11-27: 389,124 -> 29,215 triangles (7.5 %), Chamfer 0.00553 -> 0.00558,
    // F1 0.9452 -> 0.9442, largest distance 0.0027.
    assert!(r.triangles_after * 10 < r.triangles_before, "{r:?}");
    assert!(s.chamfer <= full.chamfer * 1.02, "Chamfer {} vs {}", s.chamfer, full.chamfer);
    assert!(s.f1 >= full.f1 - 0.005, "F1 {} vs {}", s.f1, full.f1);
    // Every point of the simplified surface lies within the bound (plus the sampling spacing
    // of the dense surface it is measured against) of the unsimplified one, in the bunny box.
    let crop = protocol.crop.unwrap();
    let inside = |m: &TriangleMesh| -> Vec<[f64; 3]> {
        sample_surface(m, 4_000_000, 3).unwrap().into_iter().filter(|p| crop.contains(*p)).collect()
    };
    let dense = inside(&mesh);
    let d = nearest_distances(&inside(&simple), &dense).unwrap();
    let max = d.iter().copied().fold(0.0, f64::max);
    eprintln!("largest distance to the unsimplified surface {max:.5}, {} samples", d.len());
    assert!(max <= bound + 0.004, "{max}");
    // A triangle count is met exactly or below. 20,000 (the bound's count) keeps the scores;
    // 2,000 is a coarse bunny (measured: Chamfer 0.0076, F1 0.89, clustered).
    for (n, max_chamfer) in [(20_000, 1.05 * full.chamfer), (2_000, 1.6 * full.chamfer)] {
        let (m, r) = simplify_mesh(&mesh, SimplifyTarget::Triangles(n)).unwrap();
        assert!(m.triangles.len() <= n, "asked {n}, got {}", m.triangles.len());
        let e = evaluate_meshes(&m, &gt, &protocol).unwrap().metrics;
        eprintln!("{n} triangles: Chamfer {:.5}, F1 {:.4}, error {:.5}, sloppy {}", e.chamfer, e.f1, r.error, r.sloppy);
        assert!(e.chamfer < max_chamfer, "{n} triangles: Chamfer {}", e.chamfer);
    }
}

/// The whole synth-bunny scene (room and bunny) fused from exact depths at about the pixel
/// footprint, simplified with a tenth of the footprint at each vertex (never below a tenth of
/// the voxel; `vagsl mesh` uses 0.3): the flat room collapses, so the mesh keeps about a
/// twentieth of its triangles while the bunny keeps its scores. Measured 2026-11-27:
/// 5,012,106 -> 266,192 triangles (5.3 %; `vagsl mesh`, which also drops small components,
/// keeps 3.8 %), Chamfer 0.00560 -> 0.00560, F1 0.9448 -> 0.9450. Before the depth lookup on
/// each voxel's ray and the cell-wise simplification, the same bound kept 50 %.
#[test]
#[cfg_attr(debug_assertions, ignore = "release only: fuses 40 views of 480x360")]
fn the_whole_scene_keeps_a_twentieth_of_its_triangles_and_the_bunny_its_scores() {
    if !gs_testdata::needs!("data/synth-bunny") {
        return;
    }
    let views = common::bunny_views();
    let gt = common::read_ply(&common::bunny_dir().join("gt_mesh.ply"));
    let protocol = EvalOptions::object_protocol(&gt).unwrap();
    let voxel = 0.00614;
    let mesh = fuse(&views, voxel, None);
    let full = evaluate_meshes(&mesh, &gt, &protocol).unwrap().metrics;
    let cameras: Vec<&Camera> = views.iter().map(|v| &v.0).collect();
    let bounds: Vec<f64> = pixel_footprints(&mesh.positions, &cameras).into_iter().map(|f| 0.1 * f.unwrap_or(voxel).max(voxel)).collect();
    let t = std::time::Instant::now();
    let (simple, r) = simplify_mesh_graded(&mesh, &bounds).unwrap();
    let s = evaluate_meshes(&simple, &gt, &protocol).unwrap().metrics;
    let share = r.triangles_after as f64 / r.triangles_before as f64;
    eprintln!(
        "{} -> {} triangles ({:.1} %) in {:.1}s, bounds {:?}; Chamfer {:.5} -> {:.5}, F1 {:.4} -> {:.4}",
        r.triangles_before,
        r.triangles_after,
        100.0 * share,
        t.elapsed().as_secs_f64(),
        r.graded,
        full.chamfer,
        s.chamfer,
        full.f1,
        s.f1
    );
    simple.validate().unwrap();
    assert!(share < 0.06, "{share}");
    assert!(s.chamfer <= full.chamfer * 1.01, "Chamfer {} vs {}", s.chamfer, full.chamfer);
    assert!(s.f1 >= full.f1 - 0.003, "F1 {} vs {}", s.f1, full.f1);
}
