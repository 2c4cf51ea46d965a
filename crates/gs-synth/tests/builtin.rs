//! Integration tests of the built-in scene: determinism, GT conventions, masks, points,
//! texture and option validation. Small option sets keep them fast in the test profile.

use glam::DVec3;
use gs_core::{Camera, Image, TriangleMesh};
use gs_synth::{BuiltinOptions, BuiltinScene, Bvh, SynthError, generate};
use std::sync::OnceLock;

fn small() -> BuiltinOptions {
    BuiltinOptions {
        width: 64,
        height: 48,
        views: 8,
        supersample: 2,
        seed: 5,
        points: 600,
    }
}

fn small_scene() -> &'static BuiltinScene {
    static SCENE: OnceLock<BuiltinScene> = OnceLock::new();
    SCENE.get_or_init(|| generate(&small()).unwrap())
}

fn scene_bvh() -> &'static Bvh {
    static BVH: OnceLock<Bvh> = OnceLock::new();
    BVH.get_or_init(|| Bvh::new(&small_scene().scene_mesh).unwrap())
}

fn diagonal(mesh: &TriangleMesh) -> f64 {
    let (lo, hi) = mesh.bounds().unwrap();
    (DVec3::from_array(hi.map(f64::from)) - DVec3::from_array(lo.map(f64::from))).length()
}

/// The floor and walls only (the scene mesh after the object triangles).
fn background_mesh(b: &BuiltinScene) -> TriangleMesh {
    let n = b.object_mesh.triangles.len();
    TriangleMesh {
        positions: b.scene_mesh.positions.clone(),
        triangles: b.scene_mesh.triangles[n..].to_vec(),
        colors: None,
    }
}

fn same_scene(a: &BuiltinScene, b: &BuiltinScene) -> bool {
    let bits = |img: &Image| img.data().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    a.scene.views.len() == b.scene.views.len()
        && a.scene.views.iter().zip(&b.scene.views).all(|(x, y)| {
            x.name == y.name
                && x.camera == y.camera
                && bits(&x.image) == bits(&y.image)
                && bits(x.mask.as_ref().unwrap()) == bits(y.mask.as_ref().unwrap())
        })
        && a.gt_depth
            .iter()
            .zip(&b.gt_depth)
            .all(|(x, y)| bits(x) == bits(y))
        && a.gt_normals
            .iter()
            .zip(&b.gt_normals)
            .all(|(x, y)| bits(x) == bits(y))
        && a.scene.points == b.scene.points
        && a.point_sources == b.point_sources
        && a.scene_mesh == b.scene_mesh
        && a.object_mesh == b.object_mesh
}

#[test]
fn generation_is_deterministic_across_runs_and_thread_counts() {
    let opts = BuiltinOptions {
        width: 40,
        height: 30,
        views: 4,
        supersample: 2,
        seed: 11,
        points: 200,
    };
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let two = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    let a = one.install(|| generate(&opts)).unwrap();
    let b = two.install(|| generate(&opts)).unwrap();
    let c = two.install(|| generate(&opts)).unwrap();
    assert!(same_scene(&a, &b), "1 thread and 2 threads differ");
    assert!(same_scene(&b, &c), "two runs differ");
    // The seed matters (control: the comparison can fail).
    let d = generate(&BuiltinOptions { seed: 12, ..opts }).unwrap();
    assert!(!same_scene(&a, &d));
}

/// Back-projecting every GT depth pixel through its pixel centre lands on the scene mesh;
/// through the pixel's top-left corner it does not (control for the 0.5 convention).
#[test]
fn depth_back_projects_onto_the_scene_mesh_at_pixel_centres() {
    let b = small_scene();
    let bvh = scene_bvh();
    let tol = 1e-5 * diagonal(&b.scene_mesh);
    let (mut n, mut worst, mut corner_far, mut corner_sum, mut centre_sum) =
        (0usize, 0.0f64, 0usize, 0.0, 0.0);
    for (view, depth) in b.scene.views.iter().zip(&b.gt_depth) {
        let cam = &view.camera;
        for y in 0..depth.height() {
            for x in 0..depth.width() {
                let z = depth.get(x, y, 0) as f64;
                assert!(z > 0.0, "{} pixel ({x}, {y}) missed the scene", view.name);
                let p = cam.back_project(x as f64 + 0.5, y as f64 + 0.5, z);
                let d = bvh.closest_point(p).distance;
                worst = worst.max(d);
                centre_sum += d;
                let q = cam.back_project(x as f64, y as f64, z);
                let dc = bvh.closest_point(q).distance;
                corner_sum += dc;
                if dc > tol {
                    corner_far += 1;
                }
                n += 1;
            }
        }
    }
    assert!(worst < tol, "max distance {worst} (tolerance {tol})");
    assert!(
        corner_far as f64 > 0.5 * n as f64,
        "pixel corners: only {corner_far} of {n} off the mesh"
    );
    assert!(
        corner_sum > 100.0 * centre_sum.max(1e-12 * n as f64),
        "corners {corner_sum} vs centres {centre_sum}"
    );
}

/// Depth is camera z, not ray length: re-casting the pixel-centre ray gives the same value,
/// and the hit projects back to the pixel centre.
#[test]
fn depth_is_camera_z_and_projects_to_the_pixel_centre() {
    let b = small_scene();
    let cast = scene_bvh().cast_view(&b.scene.views[3].camera).unwrap();
    let cam = &b.scene.views[3].camera;
    for (k, (&z, &c)) in b.gt_depth[3]
        .data()
        .iter()
        .zip(cast.depth.data())
        .enumerate()
    {
        assert_eq!(z, c);
        let (x, y) = (k % cam.width as usize, k / cam.width as usize);
        let p = cam.back_project(x as f64 + 0.5, y as f64 + 0.5, z as f64);
        let (px, depth) = cam.project(p).unwrap();
        assert!((px.x - (x as f64 + 0.5)).abs() < 1e-6 && (px.y - (y as f64 + 0.5)).abs() < 1e-6);
        assert!((depth - z as f64).abs() < 1e-9 * depth.max(1.0));
    }
    // Off-axis pixels: ray length exceeds depth, so the two conventions differ measurably.
    let (o, d) = gs_synth::pixel_ray(cam, 0.5, 0.5);
    let hit = scene_bvh().intersect(o, d, 0.0, f64::INFINITY).unwrap();
    assert!((hit.t * d.length() - hit.t) > 1e-3);
}

/// Mask pixels lie on object triangles, the others on the floor/walls; both kinds occur.
#[test]
fn masks_agree_with_depth_and_meshes() {
    let b = small_scene();
    let tol = 1e-5 * diagonal(&b.scene_mesh);
    let objects = Bvh::new(&b.object_mesh).unwrap();
    let background = Bvh::new(&background_mesh(b)).unwrap();
    let (mut inside, mut outside) = (0usize, 0usize);
    for (view, depth) in b.scene.views.iter().zip(&b.gt_depth) {
        let mask = view.mask.as_ref().unwrap();
        let cast = scene_bvh().cast_view(&view.camera).unwrap();
        for y in 0..depth.height() {
            for x in 0..depth.width() {
                let p = view.camera.back_project(
                    x as f64 + 0.5,
                    y as f64 + 0.5,
                    depth.get(x, y, 0) as f64,
                );
                let m = mask.get(x, y, 0);
                assert!(m == 0.0 || m == 1.0);
                let tri = cast.triangle[y * depth.width() + x] as usize;
                if m == 1.0 {
                    inside += 1;
                    assert!(objects.closest_point(p).distance < tol);
                    assert!(tri < b.object_mesh.triangles.len());
                } else {
                    outside += 1;
                    assert!(background.closest_point(p).distance < tol);
                    assert!(tri >= b.object_mesh.triangles.len());
                }
            }
        }
    }
    let total = (inside + outside) as f64;
    assert!(
        inside as f64 > 0.05 * total && (outside as f64) > 0.3 * total,
        "mask {inside} / {outside}"
    );
}

/// GT normals are unit, face the camera, and match the face normals of the ray-cast mesh
/// on flat parts (and are close to them on the curved ones).
#[test]
fn normals_are_unit_and_face_the_camera() {
    let b = small_scene();
    for (view, normals) in b.scene.views.iter().zip(&b.gt_normals) {
        let cast = scene_bvh().cast_view(&view.camera).unwrap();
        for y in 0..normals.height() {
            for x in 0..normals.width() {
                let n = DVec3::new(
                    normals.get(x, y, 0) as f64,
                    normals.get(x, y, 1) as f64,
                    normals.get(x, y, 2) as f64,
                );
                let f = DVec3::new(
                    cast.normal.get(x, y, 0) as f64,
                    cast.normal.get(x, y, 1) as f64,
                    cast.normal.get(x, y, 2) as f64,
                );
                assert!((n.length() - 1.0).abs() < 1e-5);
                assert!(
                    n.dot(f) > 0.95,
                    "{} ({x},{y}): shading {n} vs face {f}",
                    view.name
                );
                let (_, d) = gs_synth::pixel_ray(&view.camera, x as f64 + 0.5, y as f64 + 0.5);
                assert!(f.dot(d) < 0.0);
            }
        }
    }
}

/// Every sparse point projects into the view it was sampled from, within a few noise
/// standard deviations of its pixel centre; colours are in [0, 1].
#[test]
fn sparse_points_project_into_their_source_views() {
    let b = small_scene();
    assert_eq!(b.scene.points.len(), 600);
    assert_eq!(b.point_sources.len(), 600);
    let on_objects = b.point_sources.iter().filter(|s| {
        let m = b.scene.views[s.view].mask.as_ref().unwrap();
        m.get(s.pixel[0] as usize, s.pixel[1] as usize, 0) == 1.0
    });
    assert_eq!(on_objects.count(), 400);
    let (mut max_px, mut inside): (f64, usize) = (0.0, 0);
    for (pt, src) in b.scene.points.iter().zip(&b.point_sources) {
        let cam: &Camera = &b.scene.views[src.view].camera;
        let (px, z) = cam
            .project(pt.position)
            .expect("point behind its source camera");
        // Points sampled at border pixels may be pushed just outside by the noise.
        inside += cam.contains(px) as usize;
        let err = ((px.x - (src.pixel[0] as f64 + 0.5)).powi(2)
            + (px.y - (src.pixel[1] as f64 + 0.5)).powi(2))
        .sqrt();
        // 6 σ of 3-D noise, seen at depth z.
        let bound = 6.0 * b.point_sigma * cam.intrinsics.fx / z;
        assert!(
            err <= bound,
            "point off its pixel by {err} px (bound {bound})"
        );
        max_px = max_px.max(err);
        assert!(pt.color.iter().all(|c| (0.0..=1.0).contains(c)));
    }
    assert!(
        inside as f64 > 0.97 * b.scene.points.len() as f64,
        "only {inside} project inside"
    );
    // The noise is really there (control).
    assert!(max_px > 0.01);
}

fn grey_stats(img: &Image) -> (f64, f64) {
    let g = img.to_grey().unwrap();
    let (w, h) = (g.width(), g.height());
    let mut grad = 0.0;
    for y in 0..h - 1 {
        for x in 0..w - 1 {
            grad += ((g.get(x + 1, y, 0) - g.get(x, y, 0)).abs()
                + (g.get(x, y + 1, 0) - g.get(x, y, 0)).abs()) as f64;
        }
    }
    // Fraction of 7×7 windows that are nearly flat (std < 0.02).
    let (mut flat, mut windows) = (0usize, 0usize);
    for y in (3..h - 3).step_by(2) {
        for x in (3..w - 3).step_by(2) {
            let vals: Vec<f64> = (0..49)
                .map(|k| g.get(x + k % 7 - 3, y + k / 7 - 3, 0) as f64)
                .collect();
            let mean = vals.iter().sum::<f64>() / 49.0;
            let var = vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / 49.0;
            windows += 1;
            if var.sqrt() < 0.02 {
                flat += 1;
            }
        }
    }
    (
        grad / ((w - 1) * (h - 1)) as f64,
        flat as f64 / windows as f64,
    )
}

/// Images are textured everywhere (high mean gradient, almost no flat 7×7 windows), neither
/// saturated nor dark, and already quantised to /255.
#[test]
fn images_are_textured_and_not_saturated() {
    let b = small_scene();
    for view in &b.scene.views {
        let img = &view.image;
        let (grad, flat) = grey_stats(img);
        assert!(grad > 0.04, "{}: mean gradient {grad}", view.name);
        assert!(
            flat < 0.05,
            "{}: {:.1} % flat windows",
            view.name,
            100.0 * flat
        );
        let n = img.data().len() as f64;
        let clipped = img.data().iter().filter(|&&v| v <= 0.0 || v >= 1.0).count() as f64;
        assert!(
            clipped / n < 0.01,
            "{}: {:.2} % clipped",
            view.name,
            100.0 * clipped / n
        );
        let mean = img.data().iter().map(|&v| v as f64).sum::<f64>() / n;
        assert!((0.2..0.8).contains(&mean), "{}: mean {mean}", view.name);
        assert!(img.data().iter().all(|&v| (v * 255.0).round() / 255.0 == v));
    }
    // Control: a constant image fails the texture criterion.
    let flat_img = Image::filled(64, 48, 3, 0.5).unwrap();
    assert!(grey_stats(&flat_img).0 < 0.04 && grey_stats(&flat_img).1 > 0.05);
}

#[test]
fn meshes_and_description() {
    let b = small_scene();
    b.scene_mesh.validate().unwrap();
    b.object_mesh.validate().unwrap();
    let n = b.object_mesh.triangles.len();
    assert_eq!(&b.scene_mesh.triangles[..n], &b.object_mesh.triangles[..]);
    assert_eq!(b.scene_mesh.triangles.len(), n + 10);
    let (lo, hi) = b.object_mesh.bounds().unwrap();
    assert!(lo[2] >= 0.0 && hi[2] < 1.0);
    assert!(b.description.contains("8 views of 64x48"));
    assert!((b.scene.extent() - 3.3).abs() < 0.3);
}

#[test]
fn invalid_options_are_errors() {
    let base = small();
    let cases = [
        BuiltinOptions {
            views: 0,
            ..base.clone()
        },
        BuiltinOptions {
            width: 0,
            ..base.clone()
        },
        BuiltinOptions {
            height: 0,
            ..base.clone()
        },
        BuiltinOptions {
            width: 100_000,
            height: 100_000,
            ..base.clone()
        },
        BuiltinOptions {
            width: 8000,
            height: 8000,
            views: 100,
            ..base.clone()
        },
        BuiltinOptions {
            supersample: 0,
            ..base.clone()
        },
        BuiltinOptions {
            supersample: 1000,
            ..base.clone()
        },
        BuiltinOptions {
            views: usize::MAX,
            ..base.clone()
        },
        BuiltinOptions {
            points: usize::MAX,
            ..base.clone()
        },
    ];
    for opts in cases {
        match generate(&opts) {
            Err(SynthError::InvalidOptions(msg)) => assert!(!msg.is_empty()),
            other => panic!("{opts:?} gave {:?}", other.map(|_| ())),
        }
    }
    // Tiny but valid sizes work, including 1×1 images and one view.
    let tiny = generate(&BuiltinOptions {
        width: 1,
        height: 1,
        views: 1,
        supersample: 1,
        seed: 0,
        points: 3,
    })
    .unwrap();
    assert_eq!(tiny.scene.views[0].image.data().len(), 3);
    // Portrait images see the sky at the top: depth 0 there, never negative.
    let tall = generate(&BuiltinOptions {
        width: 24,
        height: 64,
        views: 2,
        supersample: 1,
        seed: 0,
        points: 10,
    })
    .unwrap();
    assert!(
        tall.gt_depth
            .iter()
            .all(|d| d.data().iter().all(|&z| z >= 0.0 && z.is_finite()))
    );
}

#[test]
fn bvh_rejects_bad_meshes() {
    assert!(matches!(
        Bvh::new(&TriangleMesh::default()),
        Err(SynthError::InvalidMesh(_))
    ));
    let bad = TriangleMesh {
        positions: vec![[0.0; 3]; 2],
        triangles: vec![[0, 1, 2]],
        colors: None,
    };
    assert!(matches!(Bvh::new(&bad), Err(SynthError::InvalidMesh(_))));
    let nan = TriangleMesh {
        positions: vec![[f32::NAN, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        triangles: vec![[0, 1, 2]],
        colors: None,
    };
    assert!(matches!(Bvh::new(&nan), Err(SynthError::InvalidMesh(_))));
}

/// The default scene (32 views of 200×150, 2×2 supersampling): every pixel-centre ray hits,
/// objects cover a reasonable share of every image. Release only (a few seconds).
#[test]
#[cfg_attr(debug_assertions, ignore = "release-only: default-size scene")]
fn default_scene_statistics() {
    let t = std::time::Instant::now();
    let b = generate(&BuiltinOptions::default()).unwrap();
    eprintln!(
        "default scene generated in {:.2} s: {}",
        t.elapsed().as_secs_f64(),
        b.description
    );
    assert_eq!(b.scene.views.len(), 32);
    assert_eq!(b.scene.points.len(), 3000);
    for (view, depth) in b.scene.views.iter().zip(&b.gt_depth) {
        assert_eq!((view.image.width(), view.image.height()), (200, 150));
        assert!(
            depth.data().iter().all(|&z| z > 0.0),
            "{}: a pixel-centre ray missed",
            view.name
        );
        let m = view.mask.as_ref().unwrap();
        let frac = m.data().iter().filter(|&&v| v == 1.0).count() as f64 / m.data().len() as f64;
        assert!(
            (0.08..0.5).contains(&frac),
            "{}: objects cover {frac}",
            view.name
        );
        // The objects do not touch the image border.
        let (w, h) = (m.width(), m.height());
        for x in 0..w {
            assert!(
                m.get(x, 0, 0) == 0.0 && m.get(x, h - 1, 0) == 0.0,
                "{}: object on border",
                view.name
            );
        }
        for y in 0..h {
            assert!(
                m.get(0, y, 0) == 0.0 && m.get(w - 1, y, 0) == 0.0,
                "{}: object on border",
                view.name
            );
        }
    }
}
