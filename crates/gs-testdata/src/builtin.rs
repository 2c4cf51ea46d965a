//! The built-in procedural scene of gs-synth written as a scene folder, for tests that need a
//! scene on disk with exact ground truth but no particular one. The folder has the layout of
//! the shared synth-bunny scene:
//!
//! ```text
//! images/0000.png …      the views (8-bit, exactly the generated values)
//! masks/0000.png …       object masks (1 = sphere, box or torus)
//! sparse/0/*.txt         COLMAP text model: one PINHOLE camera, the poses, the sparse points
//! gt/depth_0000.npy …    camera-space z of each pixel centre's first hit (float32, 0 = miss)
//! gt/normal_0000.npy …   world-space unit normal there, facing the camera (float32, 0 = miss)
//! gt_mesh.ply            the objects' triangles (what the object protocol scores against)
//! gt_scene_mesh.ply      every rendered triangle (objects, floor and walls)
//! ```
//!
//! Folders are cached under the caller's `target/` temporary folder, keyed by the options, and
//! made atomically (written beside, then renamed), so tests running at once share one copy.

use gs_core::{Scene, View};
use gs_io::colmap::{CameraModel, ColmapCamera, ColmapImage, ColmapModel, ColmapPoint3D, write_text};
use gs_synth::{BuiltinOptions, BuiltinScene};
use std::hash::{Hash, Hasher};
use std::path::{Path, PathBuf};

/// Bumped whenever the written layout changes, so stale caches are not reused.
const LAYOUT_VERSION: u32 = 1;

/// Small options for tests: 12 views of 120 × 90, 1,500 sparse points (about a second to render).
pub fn small() -> BuiltinOptions {
    BuiltinOptions { width: 120, height: 90, views: 12, supersample: 1, points: 1500, ..Default::default() }
}

/// The scene folder of the built-in scene with `opts`, under `cache` (pass
/// `env!("CARGO_TARGET_TMPDIR")`): generated on first use, reused afterwards. Panics naming the
/// file and the problem where the scene cannot be generated or written (a test failure).
pub fn scene_dir(cache: &Path, opts: &BuiltinOptions) -> PathBuf {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    (LAYOUT_VERSION, format!("{opts:?}")).hash(&mut h);
    let dir = cache.join(format!("builtin-{}x{}-{}views-{:016x}", opts.width, opts.height, opts.views, h.finish()));
    if dir.is_dir() {
        return dir;
    }
    let tmp = cache.join(format!(".{}.tmp-{}-{:?}", dir.file_name().unwrap().to_string_lossy(), std::process::id(), std::thread::current().id()));
    let _ = std::fs::remove_dir_all(&tmp);
    let built = gs_synth::generate(opts).unwrap_or_else(|e| panic!("the built-in scene with {opts:?}: {e}"));
    write(&tmp, &built);
    // Another test may have finished the same folder first: then its copy stays.
    if std::fs::rename(&tmp, &dir).is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
        assert!(dir.is_dir(), "cannot move {} to {}", tmp.display(), dir.display());
    }
    dir
}

/// Writes `built` into the new folder `dir`.
fn write(dir: &Path, built: &BuiltinScene) {
    let mkdir = |p: &Path| std::fs::create_dir_all(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    for sub in ["images", "masks", "gt", "sparse/0"] {
        mkdir(&dir.join(sub));
    }
    let ok = |r: gs_io::Result<()>| r.unwrap_or_else(|e| panic!("{e}"));
    for (k, view) in built.scene.views.iter().enumerate() {
        ok(gs_io::write_png(&dir.join("images").join(&view.name), &view.image));
        if let Some(mask) = &view.mask {
            ok(gs_io::write_png(&dir.join("masks").join(&view.name), mask));
        }
        let stem = view.name.trim_end_matches(".png");
        ok(gs_io::write_npy(&dir.join(format!("gt/depth_{stem}.npy")), &built.gt_depth[k]));
        ok(gs_io::write_npy(&dir.join(format!("gt/normal_{stem}.npy")), &built.gt_normals[k]));
    }
    ok(write_text(&colmap_model(&built.scene), &dir.join("sparse/0")));
    ok(gs_io::write_mesh_ply(&dir.join("gt_mesh.ply"), &built.object_mesh));
    ok(gs_io::write_mesh_ply(&dir.join("gt_scene_mesh.ply"), &built.scene_mesh));
}

/// The scene's cameras, poses and sparse points as a COLMAP model (one PINHOLE camera per
/// image size and intrinsics; no 2D observations).
fn colmap_model(scene: &Scene) -> ColmapModel {
    let mut model = ColmapModel::default();
    for (k, view) in scene.views.iter().enumerate() {
        let camera_id = camera_id(&mut model, view);
        let c = &view.camera;
        let id = k as u32 + 1;
        let t = c.translation;
        model.images.insert(id, ColmapImage {
            id,
            qvec: c.quaternion(),
            tvec: [t.x, t.y, t.z],
            camera_id,
            name: view.name.clone(),
            points2d: vec![],
        });
    }
    for (k, p) in scene.points.iter().enumerate() {
        let id = k as u64 + 1;
        let rgb = p.color.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8);
        model.points3d.insert(id, ColmapPoint3D { id, xyz: p.position.to_array(), rgb, error: -1.0, track: vec![] });
    }
    model
}

/// The id of the model's camera matching `view`'s, added where new.
fn camera_id(model: &mut ColmapModel, view: &View) -> u32 {
    let c = &view.camera;
    let k = c.intrinsics;
    let params = vec![k.fx, k.fy, k.cx, k.cy];
    if let Some(cam) = model.cameras.values().find(|m| (m.width, m.height) == (c.width, c.height) && m.params == params) {
        return cam.id;
    }
    let id = model.cameras.len() as u32 + 1;
    model.cameras.insert(id, ColmapCamera { id, model: CameraModel::Pinhole, width: c.width, height: c.height, params });
    id
}
