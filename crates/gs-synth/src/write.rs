//! Writes a generated scene as a scene folder in synth-bunny's layout, which `vagsl train`
//! reads as a COLMAP text scene:
//!
//! `images/NNNN.png`, `masks/NNNN.png` (255 = the pixel-centre ray hits the object first),
//! `sparse/0/{cameras,images,points3D}.txt` (one PINHOLE camera, no observations),
//! `gt/depth_NNNN.npy` (float32 camera z, 0 = miss), `gt/normal_NNNN.npy` (float32 world
//! normals), `gt_mesh.ply` (object only), `gt_scene_mesh.ply` (object first, then the room),
//! `scene.json` (the parameters) and `README.md` (the description in words).
//!
//! The folder is written under a temporary name beside the target and renamed at the end, so
//! an interrupted run never leaves a half-written scene under the target's name.

use crate::BuiltinScene;
use crate::error::{Result, SynthError};
use gs_io::colmap::{
    CameraModel, ColmapCamera, ColmapImage, ColmapModel, ColmapPoint3D, write_text,
};
use std::collections::BTreeMap;
use std::path::Path;

/// Writes `built` to the new folder `dir` (which must not exist; its parent must), with
/// `meta` as `scene.json` and `readme` as `README.md`.
pub fn write_scene(
    dir: &Path,
    built: &BuiltinScene,
    meta: &serde_json::Value,
    readme: &str,
) -> Result<()> {
    if dir.exists() {
        return Err(SynthError::Write(format!(
            "{}: already exists; remove it or choose another folder",
            dir.display()
        )));
    }
    let name = dir
        .file_name()
        .ok_or_else(|| SynthError::Write(format!("{}: not a folder name", dir.display())))?;
    let tmp = dir.with_file_name(format!(
        ".{}.partial-{}",
        name.to_string_lossy(),
        std::process::id()
    ));
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp).map_err(|e| io(&tmp, e))?;
    }
    let result = write_into(&tmp, built, meta, readme)
        .and_then(|()| std::fs::rename(&tmp, dir).map_err(|e| io(dir, e)));
    if result.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    result
}

fn io(path: &Path, e: std::io::Error) -> SynthError {
    SynthError::Write(format!("{}: {e}", path.display()))
}

fn write_into(
    dir: &Path,
    built: &BuiltinScene,
    meta: &serde_json::Value,
    readme: &str,
) -> Result<()> {
    for sub in ["images", "masks", "gt", "sparse/0"] {
        std::fs::create_dir_all(dir.join(sub)).map_err(|e| io(&dir.join(sub), e))?;
    }
    let views = &built.scene.views;
    for (i, view) in views.iter().enumerate() {
        let stem = Path::new(&view.name)
            .file_stem()
            .map_or_else(|| format!("{i:04}"), |s| s.to_string_lossy().into_owned());
        gs_io::write_png(&dir.join("images").join(&view.name), &view.image)?;
        if let Some(mask) = &view.mask {
            gs_io::write_png(&dir.join("masks").join(format!("{stem}.png")), mask)?;
        }
        gs_io::write_npy(
            &dir.join("gt").join(format!("depth_{stem}.npy")),
            &built.gt_depth[i],
        )?;
        gs_io::write_npy(
            &dir.join("gt").join(format!("normal_{stem}.npy")),
            &built.gt_normals[i],
        )?;
    }
    write_text(&colmap_model(built)?, &dir.join("sparse/0"))?;
    gs_io::write_mesh_ply(&dir.join("gt_mesh.ply"), &built.object_mesh)?;
    gs_io::write_mesh_ply(&dir.join("gt_scene_mesh.ply"), &built.scene_mesh)?;
    let json = serde_json::to_string_pretty(meta)
        .map_err(|e| SynthError::Write(format!("scene.json: {e}")))?;
    gs_io::write_atomic(&dir.join("scene.json"), |w| w.write_all(json.as_bytes()))?;
    gs_io::write_atomic(&dir.join("README.md"), |w| w.write_all(readme.as_bytes()))?;
    Ok(())
}

/// The COLMAP model of a scene whose views share one PINHOLE camera: image ids from 1 in view
/// order, poses as quaternion + translation, the sparse points with empty tracks.
fn colmap_model(built: &BuiltinScene) -> Result<ColmapModel> {
    let first = &built
        .scene
        .views
        .first()
        .ok_or_else(|| SynthError::Write("a scene without views".into()))?
        .camera;
    let k = first.intrinsics;
    let camera = ColmapCamera {
        id: 1,
        model: CameraModel::Pinhole,
        width: first.width,
        height: first.height,
        params: vec![k.fx, k.fy, k.cx, k.cy],
    };
    let mut images = BTreeMap::new();
    for (i, view) in built.scene.views.iter().enumerate() {
        let c = &view.camera;
        if c.intrinsics != k || c.width != first.width || c.height != first.height {
            return Err(SynthError::Write(format!(
                "view {} has other intrinsics than view 0; one shared camera is written",
                view.name
            )));
        }
        let id = i as u32 + 1;
        images.insert(
            id,
            ColmapImage {
                id,
                qvec: c.quaternion(),
                tvec: c.translation.to_array(),
                camera_id: 1,
                name: view.name.clone(),
                points2d: vec![],
            },
        );
    }
    let points3d = built
        .scene
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let id = i as u64 + 1;
            let rgb = p.color.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8);
            (
                id,
                ColmapPoint3D {
                    id,
                    xyz: p.position.to_array(),
                    rgb,
                    error: 0.0,
                    track: vec![],
                },
            )
        })
        .collect();
    Ok(ColmapModel {
        cameras: BTreeMap::from([(1, camera)]),
        images,
        points3d,
    })
}
