//! Writing a COLMAP model as a nerfstudio-style `transforms.json` (+ `sparse_pc.ply`).

use super::convention::opengl_from_colmap;
use crate::atomic::write_atomic;
use crate::colmap::{CameraModel, ColmapCamera, ColmapModel};
use crate::error::{IoError, Result};
use gs_core::TriangleMesh;
use gs_core::glam::DVec3;
use serde_json::{Map, Value, json};
use std::path::Path;

/// The points file written beside `transforms.json` (the name nerfstudio's COLMAP processing
/// uses), referenced by `ply_file_path`.
pub const POINTS_FILE: &str = "sparse_pc.ply";

/// The transforms lens keys of a COLMAP camera: `camera_model` PINHOLE (SIMPLE_PINHOLE,
/// PINHOLE) or OPENCV (SIMPLE_RADIAL, RADIAL, OPENCV, and FULL_OPENCV without the rational
/// `k4 k5 k6`, whose `k3` is written), `fl_x fl_y cx cy w h` and the distortion coefficients.
/// A camera transforms.json cannot express is an error naming it.
fn lens_keys(cam: &ColmapCamera) -> std::result::Result<Map<String, Value>, String> {
    let [fx, fy, cx, cy] = cam.pinhole();
    let e = cam.extra_params();
    let (model, dist): (&str, Vec<(&str, f64)>) = match cam.model {
        CameraModel::SimplePinhole | CameraModel::Pinhole => ("PINHOLE", vec![]),
        CameraModel::SimpleRadial => ("OPENCV", vec![("k1", e[0]), ("k2", 0.0), ("p1", 0.0), ("p2", 0.0)]),
        CameraModel::Radial => ("OPENCV", vec![("k1", e[0]), ("k2", e[1]), ("p1", 0.0), ("p2", 0.0)]),
        CameraModel::OpenCv => ("OPENCV", vec![("k1", e[0]), ("k2", e[1]), ("p1", e[2]), ("p2", e[3])]),
        CameraModel::FullOpenCv => {
            if e[5..8].iter().any(|&k| k != 0.0) {
                return Err(format!(
                    "camera {}: FULL_OPENCV with rational terms k4 k5 k6 = {:?} has no transforms.json equivalent",
                    cam.id,
                    &e[5..8]
                ));
            }
            ("OPENCV", vec![("k1", e[0]), ("k2", e[1]), ("k3", e[4]), ("p1", e[2]), ("p2", e[3])])
        }
    };
    let mut m = Map::new();
    m.insert("camera_model".into(), json!(model));
    for (k, v) in [("fl_x", fx), ("fl_y", fy), ("cx", cx), ("cy", cy)] {
        m.insert(k.into(), json!(v));
    }
    m.insert("w".into(), json!(cam.width));
    m.insert("h".into(), json!(cam.height));
    for (k, v) in dist {
        m.insert(k.into(), json!(v));
    }
    Ok(m)
}

/// The `transforms.json` text of `model`: frames sorted by name with `file_path`
/// `image_prefix/NAME`, OpenGL camera→world `transform_matrix` ([`super::convention`]), the
/// intrinsics globally when every image shares one camera and per frame otherwise,
/// `colmap_im_id`, and `ply_file_path` when `points` is set. The message names a camera
/// transforms.json cannot express.
pub fn transforms_json(model: &ColmapModel, image_prefix: &str, points: bool) -> std::result::Result<String, String> {
    let mut root = Map::new();
    let shared = model.cameras.len() == 1;
    if let (true, Some(cam)) = (shared, model.cameras.values().next()) {
        root.extend(lens_keys(cam)?);
    }
    let mut images: Vec<_> = model.images.values().collect();
    images.sort_by(|a, b| a.name.cmp(&b.name));
    let mut frames = Vec::with_capacity(images.len());
    for img in images {
        let cam = model.cameras.get(&img.camera_id).ok_or_else(|| format!("image {} references missing camera {}", img.id, img.camera_id))?;
        let r = img.rotation().ok_or_else(|| format!("image {} ({}): quaternion has no usable norm", img.id, img.name))?;
        let c2w = opengl_from_colmap(r, DVec3::from_array(img.tvec));
        let mut f = if shared { Map::new() } else { lens_keys(cam)? };
        let prefix = image_prefix.trim_end_matches('/');
        let file_path = if prefix.is_empty() { img.name.clone() } else { format!("{prefix}/{}", img.name) };
        f.insert("file_path".into(), json!(file_path));
        f.insert("transform_matrix".into(), json!(c2w.rows()));
        f.insert("colmap_im_id".into(), json!(img.id));
        frames.push(Value::Object(f));
    }
    root.insert("frames".into(), Value::Array(frames));
    if points {
        root.insert("ply_file_path".into(), json!(POINTS_FILE));
    }
    serde_json::to_string_pretty(&Value::Object(root)).map_err(|e| format!("cannot encode JSON: {e}"))
}

/// Writes `out_dir/transforms.json` for `model` (see [`transforms_json`]) and, when the model
/// has points, `out_dir/sparse_pc.ply` (positions as float32, 8-bit colours); both atomically,
/// the points first so the JSON never names a missing file. Observations (tracks) are not
/// carried: the layout has no place for them.
pub fn write_transforms(model: &ColmapModel, out_dir: &Path, image_prefix: &str) -> Result<()> {
    let json_path = out_dir.join("transforms.json");
    let has_points = !model.points3d.is_empty();
    let text = transforms_json(model, image_prefix, has_points).map_err(|m| IoError::invalid(&json_path, m))?;
    if has_points {
        let cloud = TriangleMesh {
            positions: model.points3d.values().map(|p| p.xyz.map(|x| x as f32)).collect(),
            triangles: Vec::new(),
            colors: Some(model.points3d.values().map(|p| p.rgb).collect()),
        };
        crate::ply::mesh::write_mesh_ply(&out_dir.join(POINTS_FILE), &cloud)?;
    }
    write_atomic(&json_path, |w| w.write_all(text.as_bytes()))
}
