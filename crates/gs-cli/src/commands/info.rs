//! `vagsl info`: what is in a scene.

use crate::scene_path::images_dir;
use gs_io::SceneLayout;
use gs_io::colmap::ModelFormat;
use anyhow::Result;
use gs_core::{Camera, ExtentBasis, Intrinsics, NeighbourRule, ScenePoint, extent_report, source_view_candidates};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// Camera-model summary line: how many cameras use a model and their parameters (first one).
#[derive(Debug, Serialize)]
pub struct ModelCount {
    /// Model name (e.g. `OPENCV`).
    pub model: String,
    /// Cameras with this model.
    pub cameras: usize,
    /// Whether the model carries lens distortion that training will undistort.
    pub distorted: bool,
    /// Parameters of the first camera with this model.
    pub example_params: Vec<f64>,
}

/// Source-view neighbour statistics (the candidate rule of docs/method.md §Schedule).
#[derive(Debug, Serialize)]
pub struct NeighbourStats {
    /// Fewest candidates of a view.
    pub min: usize,
    /// Mean candidates per view.
    pub mean: f64,
    /// Most candidates of a view.
    pub max: usize,
    /// Views without any candidate (the multi-view losses skip them).
    pub views_without: usize,
}

/// Everything `info` reports.
#[derive(Debug, Serialize)]
pub struct Summary {
    /// The scene path, or `built-in`.
    pub source: String,
    /// `text`, `binary`, `transforms.json (FILE)` or `procedural`.
    pub format: String,
    /// How many views the scene's own files hold out for `--eval` (the frames of
    /// `transforms_test.json`); `None` when `--eval` holds out every 8th view.
    pub held_out_views: Option<usize>,
    /// Number of cameras.
    pub cameras: usize,
    /// Number of registered images.
    pub images: usize,
    /// How many image files exist on disk (None when there is no images folder).
    pub image_files_found: Option<usize>,
    /// Up to 5 names of missing image files.
    pub missing_images: Vec<String>,
    /// Number of 3D points.
    pub points: usize,
    /// Track entries in total.
    pub observations: usize,
    /// Mean track length.
    pub mean_track_length: f64,
    /// Mean reprojection error recomputed with the camera model including distortion, as
    /// COLMAP defines it: per point the mean over its track, then the mean over points (pixels).
    pub mean_reprojection_error_px: Option<f64>,
    /// Mean of the per-point errors stored in the model (COLMAP's `ERROR` column; the figure
    /// pycolmap and the scene READMEs quote). `None` when no point stores one.
    pub mean_stored_point_error_px: Option<f64>,
    /// Camera models in use.
    pub camera_models: Vec<ModelCount>,
    /// Image resolutions `WxH` → count.
    pub resolutions: BTreeMap<String, usize>,
    /// Scene extent r, as training computes it (`gs_core::extent_report`): 1.1 × the robust
    /// spread of the camera centres, or of the sparse points when the centres coincide.
    pub scene_extent: f64,
    /// What r comes from: "cameras", "sparse points" (coincident cameras) or "nothing" (no
    /// spread at all; training refuses such a scene).
    pub scene_extent_basis: String,
    /// Source-view candidates per view.
    pub neighbours: NeighbourStats,
}

fn neighbour_stats(cameras: &[Camera]) -> NeighbourStats {
    let refs: Vec<&Camera> = cameras.iter().collect();
    let nb = source_view_candidates(&refs, &NeighbourRule::default());
    let counts: Vec<usize> = nb.iter().map(Vec::len).collect();
    NeighbourStats {
        min: counts.iter().copied().min().unwrap_or(0),
        mean: if counts.is_empty() { 0.0 } else { counts.iter().sum::<usize>() as f64 / counts.len() as f64 },
        max: counts.iter().copied().max().unwrap_or(0),
        views_without: counts.iter().filter(|&&c| c == 0).count(),
    }
}

/// Summary of a scene folder in either layout (COLMAP, or transforms.json; see
/// [`gs_io::layout`]), or of a COLMAP model folder.
pub fn summarize_scene(scene: &Path) -> Result<Summary> {
    if !scene.exists() {
        anyhow::bail!("{}: no such file or folder", scene.display());
    }
    let sm = gs_io::read_scene_model(scene, None)?;
    let (model, dir) = (&sm.model, &sm.origin);
    let mut cameras = Vec::with_capacity(model.images.len());
    for img in model.images.values() {
        let cam = &model.cameras[&img.camera_id];
        let [fx, fy, cx, cy] = cam.pinhole();
        let camera = Camera::from_quaternion(cam.width, cam.height, Intrinsics::new(fx, fy, cx, cy), img.qvec, img.tvec)
            .map_err(|e| anyhow::anyhow!("{}: image {} ('{}'): {e}", dir.display(), img.id, img.name))?;
        cameras.push(camera);
    }
    let mut models: BTreeMap<String, ModelCount> = BTreeMap::new();
    let mut resolutions = BTreeMap::new();
    for cam in model.cameras.values() {
        let e = models.entry(cam.model.name().to_string()).or_insert_with(|| ModelCount {
            model: cam.model.name().to_string(),
            cameras: 0,
            distorted: !cam.is_undistorted(),
            example_params: cam.params.clone(),
        });
        e.cameras += 1;
        e.distorted |= !cam.is_undistorted();
    }
    for img in model.images.values() {
        let cam = &model.cameras[&img.camera_id];
        *resolutions.entry(format!("{}x{}", cam.width, cam.height)).or_insert(0) += 1;
    }
    let images = match &sm.layout {
        SceneLayout::Colmap { model_dir, .. } => images_dir(scene, model_dir),
        // The reader found every file (a missing one is an error naming its frame).
        SceneLayout::Transforms(_) => Some(scene.to_path_buf()),
    };
    let (image_files_found, missing_images) = match images {
        Some(_) => {
            let path = |i: &gs_io::colmap::ColmapImage| match (&sm.layout, &images) {
                (SceneLayout::Colmap { .. }, Some(d)) => d.join(&i.name),
                _ => sm.image_paths[&i.id].clone(),
            };
            let missing: Vec<String> =
                model.images.values().filter(|i| !path(i).is_file()).map(|i| i.name.clone()).collect();
            (Some(model.images.len() - missing.len()), missing.into_iter().take(5).collect())
        }
        None => (None, Vec::new()),
    };
    let refs: Vec<&Camera> = cameras.iter().collect();
    let points: Vec<ScenePoint> = model.points3d.values().map(gs_io::colmap::ColmapPoint3D::scene_point).collect();
    let extent = extent_report(&refs, &points);
    Ok(Summary {
        source: scene.display().to_string(),
        format: match &sm.layout {
            SceneLayout::Colmap { format: ModelFormat::Text, .. } => "text".into(),
            SceneLayout::Colmap { format: ModelFormat::Binary, .. } => "binary".into(),
            SceneLayout::Transforms(_) => format!("transforms.json ({})", sm.origin.display()),
        },
        held_out_views: sm.held_out.as_ref().map(Vec::len),
        cameras: model.cameras.len(),
        images: model.images.len(),
        image_files_found,
        missing_images,
        points: model.points3d.len(),
        observations: model.num_observations(),
        mean_track_length: model.mean_track_length(),
        mean_reprojection_error_px: model.mean_reprojection_error(),
        mean_stored_point_error_px: {
            let errs: Vec<f64> = model.points3d.values().map(|p| p.error).filter(|e| *e >= 0.0).collect();
            (!errs.is_empty()).then(|| errs.iter().sum::<f64>() / errs.len() as f64)
        },
        camera_models: models.into_values().collect(),
        resolutions,
        scene_extent: extent.radius,
        scene_extent_basis: basis_words(extent.basis).into(),
        neighbours: neighbour_stats(&cameras),
    })
}

/// Summary of the built-in procedural scene (generated with its default options).
pub fn summarize_builtin() -> Result<Summary> {
    let opts = gs_synth::BuiltinOptions::default();
    let built = gs_synth::generate(&opts)?;
    let scene = &built.scene;
    let cameras: Vec<Camera> = scene.views.iter().map(|v| v.camera.clone()).collect();
    let mut resolutions = BTreeMap::new();
    for v in &scene.views {
        *resolutions.entry(format!("{}x{}", v.camera.width, v.camera.height)).or_insert(0) += 1;
    }
    let k = &cameras[0].intrinsics;
    Ok(Summary {
        source: format!("built-in (seed {}, {} triangles of exact ground truth)", opts.seed, built.scene_mesh.triangles.len()),
        format: "procedural".into(),
        held_out_views: None,
        cameras: cameras.len(),
        images: scene.views.len(),
        image_files_found: None,
        missing_images: Vec::new(),
        points: scene.points.len(),
        observations: 0,
        mean_track_length: 0.0,
        mean_reprojection_error_px: None,
        mean_stored_point_error_px: None,
        camera_models: vec![ModelCount {
            model: "PINHOLE".into(),
            cameras: cameras.len(),
            distorted: false,
            example_params: vec![k.fx, k.fy, k.cx, k.cy],
        }],
        resolutions,
        scene_extent: scene.extent(),
        scene_extent_basis: basis_words(scene.extent_report().basis).into(),
        neighbours: neighbour_stats(&cameras),
    })
}

/// What an extent was computed from, in words.
fn basis_words(basis: ExtentBasis) -> &'static str {
    match basis {
        ExtentBasis::Cameras => "cameras",
        ExtentBasis::SparsePoints => "sparse points",
        ExtentBasis::Unscaled => "nothing",
    }
}

/// Prints a summary as aligned text.
pub fn print_text(s: &Summary) {
    println!("scene            {}", s.source);
    println!("format           {}", s.format);
    println!("cameras          {}", s.cameras);
    match s.image_files_found {
        Some(found) if found == s.images => println!("images           {} (all files present)", s.images),
        Some(found) => println!(
            "images           {} ({} files missing, e.g. {})",
            s.images,
            s.images - found,
            s.missing_images.join(", ")
        ),
        None if s.format == "procedural" => println!("images           {} (generated in memory)", s.images),
        None => println!("images           {} (no images folder found)", s.images),
    }
    if let Some(n) = s.held_out_views {
        println!("held out         {n} views for --eval (the scene's own test split)");
    }
    println!("points           {}", s.points);
    if s.observations > 0 {
        println!("observations     {} (mean track length {:.2})", s.observations, s.mean_track_length);
    }
    if let Some(e) = s.mean_reprojection_error_px {
        print!("reprojection     {e:.3} px mean over points (recomputed with the camera model)");
        match s.mean_stored_point_error_px {
            Some(p) => println!("; {p:.3} px mean of the stored per-point errors"),
            None => println!(),
        }
    }
    for m in &s.camera_models {
        println!(
            "camera model     {} × {}{}  params {}",
            m.model,
            m.cameras,
            if m.distorted { " (distorted: undistorted to PINHOLE on load)" } else { "" },
            m.example_params.iter().map(|p| p.to_string()).collect::<Vec<_>>().join(", ")
        );
    }
    for (res, n) in &s.resolutions {
        println!("resolution       {res} × {n}");
    }
    match s.scene_extent_basis.as_str() {
        "cameras" => println!("scene extent r   {:.6}", s.scene_extent),
        "sparse points" => println!("scene extent r   {:.6} (from the sparse points: the camera centres coincide)", s.scene_extent),
        _ => println!("scene extent r   {:.6} (nothing sets the scale: the camera centres coincide and the sparse points have no spread)", s.scene_extent),
    }
    println!(
        "neighbours       min {} / mean {:.2} / max {} source-view candidates; {} views without",
        s.neighbours.min, s.neighbours.mean, s.neighbours.max, s.neighbours.views_without
    );
}

/// Runs `vagsl info`.
pub fn run(scene: Option<&Path>, json: bool) -> Result<()> {
    let summary = match scene {
        Some(path) => summarize_scene(path)?,
        None => summarize_builtin()?,
    };
    if json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print_text(&summary);
    }
    Ok(())
}
