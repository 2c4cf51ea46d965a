//! Integration tests of the validation suite's generator: determinism down to the written
//! bytes, GT depth on the mesh, masks that agree with depth, scenes that load with gs-io's
//! scene loader, and scenes that differ. Small images keep them fast.

mod common;

use glam::DVec3;
use gs_synth::{
    Bvh, SUITE_SIZE, SuiteOptions, SuiteScene, generate_suite_scene, write_suite_scene,
};
use std::sync::OnceLock;

fn tiny() -> SuiteOptions {
    SuiteOptions {
        width: 64,
        height: 48,
        supersample: 1,
        points: 300,
    }
}

fn all_tiny() -> &'static Vec<SuiteScene> {
    static SCENES: OnceLock<Vec<SuiteScene>> = OnceLock::new();
    SCENES.get_or_init(|| {
        (0..SUITE_SIZE)
            .map(|i| generate_suite_scene(i, 3, &tiny()).unwrap())
            .collect()
    })
}


#[test]
fn same_seed_same_bytes_whatever_the_threads_and_another_seed_differs() {
    common::assert_deterministic_writer(|dir, seed| write_suite_scene(dir, 1, seed, &tiny()).map(|_| ()), 20, &["images/0000.png", "sparse/0/images.txt"]);
}

#[test]
fn gt_depth_lies_on_the_mesh_and_masks_agree_with_depth() {
    for s in all_tiny() {
        let b = &s.built;
        let scene_bvh = Bvh::new(&b.scene_mesh).unwrap();
        let object_bvh = Bvh::new(&b.object_mesh).unwrap();
        let diag = gs_synth_diag(&b.object_mesh);
        let (mut on_object, mut misses) = (0usize, 0usize);
        for (i, view) in b.scene.views.iter().enumerate() {
            let cam = &view.camera;
            let mask = view.mask.as_ref().unwrap();
            // The GT maps are the ray caster's, pixel for pixel.
            let cast = scene_bvh.cast_view(cam).unwrap();
            assert_eq!(
                cast.depth.data(),
                b.gt_depth[i].data(),
                "{} view {i}",
                s.spec.name
            );
            for y in 0..cam.height as usize {
                for x in 0..cam.width as usize {
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
                        "{} view {i} ({x},{y})",
                        s.spec.name
                    );
                    let d_obj = object_bvh.closest_point(p).distance;
                    if m == 1.0 {
                        on_object += 1;
                        assert!(
                            d_obj < 1e-5 * z,
                            "{} view {i} ({x},{y}): masked pixel {d_obj} off the object",
                            s.spec.name
                        );
                    } else {
                        assert_eq!(m, 0.0);
                        assert!(
                            d_obj > 1e-6 * diag,
                            "{} view {i} ({x},{y}): object hit outside the mask",
                            s.spec.name
                        );
                    }
                    // Normals are unit and on the camera's side of the hit face (smooth normals
                    // may tilt past the silhouette; the face normal itself faces the camera).
                    let n = DVec3::new(
                        b.gt_normals[i].get(x, y, 0) as f64,
                        b.gt_normals[i].get(x, y, 1) as f64,
                        b.gt_normals[i].get(x, y, 2) as f64,
                    );
                    let f = DVec3::new(
                        cast.normal.get(x, y, 0) as f64,
                        cast.normal.get(x, y, 1) as f64,
                        cast.normal.get(x, y, 2) as f64,
                    );
                    assert!(
                        (n.length() - 1.0).abs() < 1e-4
                            && n.dot(f) > 0.0
                            && f.dot(p - cam.center()) < 0.0
                    );
                }
            }
            assert!(
                mask.data().iter().any(|&v| v == 1.0),
                "{} view {i}: the object is not in the image",
                s.spec.name
            );
        }
        let total = b.scene.views.len() * 64 * 48;
        assert!(
            on_object as f64 > 0.03 * total as f64,
            "{}: object on {on_object} of {total} pixels",
            s.spec.name
        );
        assert!(
            (misses as f64) < 0.02 * total as f64,
            "{}: {misses} rays of {total} miss everything",
            s.spec.name
        );
    }
}

fn gs_synth_diag(mesh: &gs_core::TriangleMesh) -> f64 {
    let (lo, hi) = mesh.bounds().unwrap();
    (DVec3::from_array(hi.map(f64::from)) - DVec3::from_array(lo.map(f64::from))).length()
}

#[test]
fn written_scene_loads_with_the_scene_loader() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("scene");
    let s = write_suite_scene(&dir, 0, 3, &tiny()).unwrap();
    let opts = gs_io::LoadOptions {
        masks: gs_io::MaskPolicy::Require,
        ..Default::default()
    };
    let loaded = gs_io::load_scene(&dir, &opts).unwrap();
    assert_eq!(loaded.views.len(), s.spec.views);
    assert_eq!(loaded.points.len(), s.built.scene.points.len());
    for (a, b) in loaded.views.iter().zip(&s.built.scene.views) {
        assert_eq!(a.name, b.name);
        // The poses read back are the ones the GT was rendered with.
        assert!(a.camera.rotation.abs_diff_eq(b.camera.rotation, 1e-12));
        assert!(
            (a.camera.translation - b.camera.translation)
                .abs()
                .max_element()
                < 1e-12
        );
        assert_eq!(a.camera.intrinsics, b.camera.intrinsics);
        assert_eq!(a.image.data(), b.image.data(), "{}", a.name);
        assert_eq!(
            a.mask.as_ref().unwrap().data(),
            b.mask.as_ref().unwrap().data()
        );
    }
    let depth = gs_io::read_npy(&dir.join("gt/depth_0003.npy")).unwrap();
    assert_eq!(depth.data(), s.built.gt_depth[3].data());
    let gt = gs_io::read_mesh_ply(&dir.join("gt_mesh.ply")).unwrap();
    assert_eq!(gt.triangles, s.built.object_mesh.triangles);
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("scene.json")).unwrap()).unwrap();
    assert_eq!(meta["name"], "cup");
    assert_eq!(meta["views"], s.spec.views);
}

#[test]
fn the_scenes_differ_in_what_they_vary() {
    let scenes = all_tiny();
    assert!(scenes.len() >= 9);
    let views: Vec<usize> = scenes.iter().map(|s| s.spec.views).collect();
    assert!(views.iter().all(|v| (12..=60).contains(v)));
    // A sparse capture (10 training views under `--eval`) and a dense one.
    assert!(views.contains(&12) && views.contains(&60));
    for (i, a) in scenes.iter().enumerate() {
        for b in &scenes[i + 1..] {
            assert_ne!(
                a.built.object_mesh.positions, b.built.object_mesh.positions,
                "{} and {}",
                a.spec.name, b.spec.name
            );
            assert_ne!(a.spec.name, b.spec.name);
        }
    }
    let strengths: Vec<f64> = scenes
        .iter()
        .map(|s| s.spec.style.texture_strength)
        .collect();
    assert!(
        strengths.iter().cloned().fold(1.0, f64::min) <= 0.2
            && strengths.iter().cloned().fold(0.0, f64::max) >= 1.0
    );
    // Weak textures are weak: the object's pixel contrast grows with the texture strength.
    let contrast = |s: &SuiteScene| {
        let (mut sum, mut sum2, mut n) = (0.0, 0.0, 0.0);
        for v in &s.built.scene.views {
            let m = v.mask.as_ref().unwrap();
            for y in 1..v.image.height() {
                for x in 1..v.image.width() {
                    if m.get(x, y, 0) == 1.0 && m.get(x - 1, y, 0) == 1.0 {
                        let d = (v.image.get(x, y, 1) - v.image.get(x - 1, y, 1)) as f64;
                        sum += d;
                        sum2 += d * d;
                        n += 1.0;
                    }
                }
            }
        }
        (sum2 / n - (sum / n).powi(2)).sqrt()
    };
    let weakest = scenes
        .iter()
        .min_by(|a, b| {
            a.spec
                .style
                .texture_strength
                .total_cmp(&b.spec.style.texture_strength)
        })
        .unwrap();
    let strongest = scenes
        .iter()
        .max_by(|a, b| {
            a.spec
                .style
                .texture_strength
                .total_cmp(&b.spec.style.texture_strength)
        })
        .unwrap();
    assert!(
        contrast(weakest) < 0.6 * contrast(strongest),
        "{} vs {}",
        contrast(weakest),
        contrast(strongest)
    );
    // Some scenes put a wall close to the camera ring (within 0.6 of the farthest camera).
    let close = scenes.iter().filter(|s| {
        s.built.scene.views.iter().any(|v| {
            let c = v.camera.center();
            s.spec.room[0] - c.x.abs() < 0.6 || s.spec.room[1] - c.y.abs() < 0.6
        })
    });
    assert!(close.count() >= 3);
}
