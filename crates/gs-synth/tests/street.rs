//! Integration tests of the street scene: determinism down to the written bytes, a capture
//! where every object is seen by enough views and no view sees the whole street, GT depth on
//! the mesh, masks on the scored surfaces (objects and facades), and a folder the scene loader
//! reads. Small images keep them fast.

mod common;

use glam::DVec3;
use gs_synth::street::{STREET_HALF_WIDTH, STREET_LENGTH};
use gs_synth::{Bvh, StreetOptions, StreetScene, generate_street, write_street};
use std::sync::OnceLock;

fn tiny() -> StreetOptions {
    StreetOptions {
        width: 64,
        height: 48,
        supersample: 1,
        points: 400,
    }
}

fn tiny_street() -> &'static StreetScene {
    static SCENE: OnceLock<StreetScene> = OnceLock::new();
    SCENE.get_or_init(|| generate_street(3, &tiny()).unwrap())
}


#[test]
fn same_seed_same_bytes_whatever_the_threads_and_another_seed_differs() {
    common::assert_deterministic_writer(|dir, seed| write_street(dir, seed, &tiny()).map(|_| ()), 4 * 60, &["images/0000.png", "gt_mesh.ply", "sparse/0/images.txt"]);
}

/// Views in which the centre of an object's box projects inside the image, in front of the
/// camera, with nothing else in front of it: the GT depth there is sky or at least the camera
/// z of the centre minus the box's half diagonal.
fn views_seeing(s: &StreetScene, lo: [f64; 3], hi: [f64; 3]) -> usize {
    let (lo, hi) = (DVec3::from_array(lo), DVec3::from_array(hi));
    let (centre, r) = ((lo + hi) * 0.5, (hi - lo).length() * 0.5);
    let b = &s.built;
    (0..b.scene.views.len())
        .filter(|&i| {
            let cam = &b.scene.views[i].camera;
            let Some((px, z)) = cam.project(centre) else {
                return false;
            };
            if z <= 0.0 || !cam.contains(px) {
                return false;
            }
            let d = b.gt_depth[i].get(px.x as usize, px.y as usize, 0) as f64;
            d == 0.0 || d >= z - r
        })
        .count()
}

#[test]
fn every_object_is_seen_by_enough_views_and_no_view_sees_the_whole_street() {
    let s = tiny_street();
    let b = &s.built;
    let views = b.scene.views.len();
    assert!((60..=96).contains(&views), "{views} views");
    let counts: Vec<(&str, usize)> = s
        .spec
        .objects
        .iter()
        .map(|o| (o.name, views_seeing(s, o.bbox.0, o.bbox.1)))
        .collect();
    eprintln!("views seeing each object: {counts:?}");
    for &(name, n) in &counts {
        assert!((8..=40).contains(&n), "{name}: seen by {n} views");
    }
    // The x range of what each view hits in the street (between the facades, between its
    // ends) is at most half its length.
    let mut widest: f64 = 0.0;
    for (i, v) in b.scene.views.iter().enumerate() {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for y in 0..v.camera.height as usize {
            for x in 0..v.camera.width as usize {
                let z = b.gt_depth[i].get(x, y, 0) as f64;
                if z > 0.0 {
                    let p = v.camera.back_project(x as f64 + 0.5, y as f64 + 0.5, z);
                    if p.y.abs() < STREET_HALF_WIDTH + 1e-3 && (0.0..=STREET_LENGTH).contains(&p.x)
                    {
                        (lo, hi) = (lo.min(p.x), hi.max(p.x));
                    }
                }
            }
        }
        widest = widest.max(hi - lo);
    }
    eprintln!("widest view: {widest:.2} m of {STREET_LENGTH} m");
    assert!(
        widest < 0.5 * STREET_LENGTH,
        "a view sees {widest} m of the street"
    );
}

#[test]
fn gt_depth_lies_on_the_mesh_and_masks_mark_objects_and_facades() {
    let s = tiny_street();
    let b = &s.built;
    let scene_bvh = Bvh::new(&b.scene_mesh).unwrap();
    let scored_bvh = Bvh::new(&b.object_mesh).unwrap();
    let (mut scored, mut misses, mut total) = (0usize, 0usize, 0usize);
    for (i, view) in b.scene.views.iter().enumerate() {
        let cam = &view.camera;
        let mask = view.mask.as_ref().unwrap();
        // The GT maps are the ray caster's, pixel for pixel.
        let cast = scene_bvh.cast_view(cam).unwrap();
        assert_eq!(cast.depth.data(), b.gt_depth[i].data(), "view {i}");
        for y in 0..cam.height as usize {
            for x in 0..cam.width as usize {
                total += 1;
                let z = b.gt_depth[i].get(x, y, 0) as f64;
                let m = mask.get(x, y, 0);
                if z == 0.0 {
                    misses += 1;
                    assert_eq!(m, 0.0);
                    continue;
                }
                let p = cam.back_project(x as f64 + 0.5, y as f64 + 0.5, z);
                assert!(
                    scene_bvh.closest_point(p).distance < 1e-5 * z,
                    "view {i} ({x},{y})"
                );
                let d_scored = scored_bvh.closest_point(p).distance;
                if m == 1.0 {
                    scored += 1;
                    assert!(
                        d_scored < 1e-5 * z,
                        "view {i} ({x},{y}): masked pixel off the scored mesh"
                    );
                } else {
                    assert_eq!(m, 0.0);
                    // Unmasked hits are on the ground (facades start at z = 0, so allow it).
                    assert!(
                        p.z.abs() < 1e-4 * z,
                        "view {i} ({x},{y}): unmasked hit at z {}",
                        p.z
                    );
                }
            }
        }
    }
    let (fs, fm) = (scored as f64 / total as f64, misses as f64 / total as f64);
    eprintln!("scored {fs:.3}, sky {fm:.3} of {total} pixels");
    assert!(fs > 0.3 && fs < 0.9, "scored fraction {fs}");
    assert!(fm < 0.1, "sky fraction {fm}");
    // Scored and scene meshes share their first triangles; the rest is one ground rectangle.
    assert_eq!(
        b.scene_mesh.triangles[..b.object_mesh.triangles.len()],
        b.object_mesh.triangles[..]
    );
    assert_eq!(
        b.scene_mesh.triangles.len(),
        b.object_mesh.triangles.len() + 2
    );
    let (lo, hi) = b.object_mesh.bounds().unwrap();
    assert!(lo[0] < 0.0 && hi[0] > STREET_LENGTH as f32);
    assert!(
        (lo[1] + STREET_HALF_WIDTH as f32).abs() < 1e-6
            && (hi[1] - STREET_HALF_WIDTH as f32).abs() < 1e-6
    );
}

#[test]
fn written_street_loads_with_the_scene_loader_and_records_its_path() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("street");
    let s = write_street(&dir, 3, &tiny()).unwrap();
    let opts = gs_io::LoadOptions {
        masks: gs_io::MaskPolicy::Require,
        ..Default::default()
    };
    let loaded = gs_io::load_scene(&dir, &opts).unwrap();
    assert_eq!(loaded.views.len(), s.built.scene.views.len());
    assert_eq!(loaded.points.len(), s.built.scene.points.len());
    for (a, b) in loaded.views.iter().zip(&s.built.scene.views) {
        assert_eq!(a.name, b.name);
        assert!(a.camera.rotation.abs_diff_eq(b.camera.rotation, 1e-12));
        assert!(
            (a.camera.translation - b.camera.translation)
                .abs()
                .max_element()
                < 1e-12
        );
        assert_eq!(a.image.data(), b.image.data(), "{}", a.name);
        assert_eq!(
            a.mask.as_ref().unwrap().data(),
            b.mask.as_ref().unwrap().data()
        );
    }
    let gt = gs_io::read_mesh_ply(&dir.join("gt_mesh.ply")).unwrap();
    assert_eq!(gt.triangles, s.built.object_mesh.triangles);
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("scene.json")).unwrap()).unwrap();
    assert_eq!(meta["generator"], "gs-synth street");
    assert_eq!(meta["street"]["axis"], serde_json::json!([1.0, 0.0, 0.0]));
    assert_eq!(meta["street"]["length"], STREET_LENGTH);
    let path = meta["cameras"]["path"].as_array().unwrap();
    assert_eq!(path.len(), loaded.views.len());
    // The recorded eyes are the loaded camera centres, in image order.
    for (p, v) in path.iter().zip(&loaded.views) {
        assert_eq!(p["image"], v.name.as_str());
        let eye: Vec<f64> = p["eye"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e.as_f64().unwrap())
            .collect();
        assert!((DVec3::new(eye[0], eye[1], eye[2]) - v.camera.center()).length() < 1e-9);
    }
    assert_eq!(
        meta["objects"].as_array().unwrap().len(),
        s.spec.objects.len()
    );
    let readme = std::fs::read_to_string(dir.join("README.md")).unwrap();
    assert!(readme.contains("larger than one block") && readme.contains("gt_mesh.ply"));
}

/// `n` points uniform by area on `mesh` (seeded).
fn surface_samples(mesh: &gs_core::TriangleMesh, n: usize, seed: u64) -> Vec<DVec3> {
    let p = |i: u32| DVec3::from_array(mesh.positions[i as usize].map(f64::from));
    let mut cum = Vec::with_capacity(mesh.triangles.len());
    let mut total = 0.0;
    for t in &mesh.triangles {
        total += 0.5 * (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0])).length();
        cum.push(total);
    }
    let mut rng = gs_core::Rng::new(seed);
    (0..n)
        .map(|_| {
            let k = cum
                .partition_point(|&c| c < rng.uniform_f64() * total)
                .min(cum.len() - 1);
            let t = mesh.triangles[k];
            let (mut u, mut v) = (rng.uniform_f64(), rng.uniform_f64());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            p(t[0]) + u * (p(t[1]) - p(t[0])) + v * (p(t[2]) - p(t[0]))
        })
        .collect()
}

#[test]
fn most_of_the_scored_surface_is_seen() {
    let s = tiny_street();
    let b = &s.built;
    let samples = surface_samples(&b.object_mesh, 20_000, 9);
    let seen_by = |q: DVec3| {
        b.scene
            .views
            .iter()
            .enumerate()
            .filter(|(i, v)| {
                let Some((px, z)) = v.camera.project(q) else {
                    return false;
                };
                if z <= 0.0 || !v.camera.contains(px) {
                    return false;
                }
                let d = b.gt_depth[*i].get(px.x as usize, px.y as usize, 0) as f64;
                (d - z).abs() < 0.03 * z
            })
            .count()
    };
    let counts: Vec<usize> = samples.iter().map(|&q| seen_by(q)).collect();
    let frac = |k: usize| counts.iter().filter(|&&c| c >= k).count() as f64 / counts.len() as f64;
    eprintln!(
        "scored surface seen by >= 1 view: {:.3}, >= 3 views: {:.3}",
        frac(1),
        frac(3)
    );
    assert!(frac(1) > 0.8 && frac(3) > 0.6, "{} {}", frac(1), frac(3));
}
