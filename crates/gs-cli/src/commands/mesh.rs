//! `vagsl mesh`: TSDF fusion of a trained run's rendered plane depths (method-spec §8).

use crate::run_dir::{OpenRun, SceneSource, load_scene, write_json};
use anyhow::{Context, Result, bail};
use gs_tsdf::{ComponentFilter, TsdfConfig, TsdfVolume, clean_mesh};
use gs_train::{FINE_VOXEL_FRACTION, MeshOptions, extract_mesh};
use std::path::{Path, PathBuf};

/// Options of `vagsl mesh`.
#[derive(Debug, Clone, clap::Args)]
pub struct MeshArgs {
    /// A `vagsl train` output folder (its rendered plane depths are fused), or with
    /// `--depth-dir` a scene folder whose depth maps are given.
    pub run: PathBuf,
    /// Rasterizer backend: cpu, wgpu, or auto (wgpu on a hardware GPU, else the CPU).
    #[arg(long, default_value = "auto")]
    pub backend: gs_raster::Backend,
    /// Fuse these depth maps instead of rendering a run: one per view of the scene, named
    /// `<stem>.exr`, `<stem>_depth.exr`, `depth_<stem>.npy` or `<stem>.npy` (camera z, 0 = none).
    #[arg(long)]
    pub depth_dir: Option<PathBuf>,
    /// Output mesh (default RUN/mesh.ply).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Voxel size (default: scene extent / 512).
    #[arg(long)]
    pub voxel_size: Option<f64>,
    /// SDF truncation (default 4 × voxel).
    #[arg(long)]
    pub sdf_trunc: Option<f64>,
    /// Ignore depths beyond this (default 3 × scene extent).
    #[arg(long)]
    pub depth_trunc: Option<f64>,
    /// Drop depths whose depth normal is more than this many degrees from the ray (e.g. 80).
    #[arg(long)]
    pub max_normal_angle: Option<f64>,
    /// Keep only the largest connected component.
    #[arg(long)]
    pub largest: bool,
    /// Fuse only inside the views' masks.
    #[arg(long)]
    pub masks: bool,
}

/// The depth map of view `name` in `dir` (see [`MeshArgs::depth_dir`]).
fn read_depth(dir: &Path, name: &str) -> Result<gs_core::Image> {
    let stem = Path::new(name).file_stem().map_or(name.to_string(), |s| s.to_string_lossy().into_owned());
    for cand in [format!("{stem}.exr"), format!("{stem}_depth.exr"), format!("depth_{stem}.npy"), format!("{stem}.npy")] {
        let p = dir.join(&cand);
        if p.is_file() {
            let img = if cand.ends_with(".exr") { gs_io::read_exr(&p)? } else { gs_io::read_npy(&p)? };
            if img.channels() != 1 {
                bail!("{}: a depth map has 1 channel, this one has {}", p.display(), img.channels());
            }
            return Ok(img);
        }
    }
    bail!("{}: no depth map for view '{name}' (looked for {stem}.exr, {stem}_depth.exr, depth_{stem}.npy, {stem}.npy)", dir.display())
}

/// Fuses given depth maps of a scene's views (e.g. ground truth, or another method's output).
fn fuse_depth_dir(args: &MeshArgs, depth_dir: &Path) -> Result<()> {
    let scene = load_scene(&SceneSource { path: Some(args.run.clone()), resolution_factor: None, width: None, eval: false })?;
    let extent = scene.extent();
    let voxel = args.voxel_size.unwrap_or(extent / 512.0);
    let mut volume = TsdfVolume::new(TsdfConfig {
        voxel_size: voxel,
        sdf_trunc: args.sdf_trunc,
        depth_trunc: args.depth_trunc.unwrap_or(3.0 * extent),
        max_normal_angle_deg: args.max_normal_angle,
        with_color: true,
        ..Default::default()
    })?;
    for (i, view) in scene.views.iter().enumerate() {
        let depth = read_depth(depth_dir, &view.name)?;
        let mask = if args.masks { view.mask.as_ref() } else { None };
        volume.integrate_view(i, &view.camera, &depth, Some(&view.image), mask).with_context(|| format!("view '{}'", view.name))?;
    }
    let raw = volume.extract_mesh()?;
    let filter = if args.largest { ComponentFilter::Largest } else { ComponentFilter::MinTriangles(50) };
    let mesh = clean_mesh(&raw, filter)?;
    let path = args.output.clone().unwrap_or_else(|| depth_dir.join("mesh.ply"));
    gs_io::write_mesh_ply(&path, &mesh)?;
    println!(
        "mesh: {} vertices, {} triangles from {} depth maps (voxel {voxel:.5}, {} blocks) → {}",
        mesh.positions.len(),
        mesh.triangles.len(),
        scene.views.len(),
        volume.block_count(),
        path.display()
    );
    Ok(())
}

/// Runs `vagsl mesh`.
pub fn run(args: &MeshArgs) -> Result<()> {
    if let Some(dir) = &args.depth_dir {
        return fuse_depth_dir(args, dir);
    }
    let run = OpenRun::open(&args.run)?;
    let opts = MeshOptions {
        voxel_size: args.voxel_size,
        sdf_trunc: args.sdf_trunc,
        depth_trunc: args.depth_trunc,
        max_normal_angle_deg: args.max_normal_angle,
        largest_component_only: args.largest,
        use_masks: args.masks,
        ..Default::default()
    };
    let mut rasterizer = super::rasterizer(args.backend)?;
    let (mesh, report) = extract_mesh(&run.gaussians, &run.scene, &run.train, &mut rasterizer, &run.raster(), run.extent(), &opts)?;
    let path = args.output.clone().unwrap_or_else(|| run.dir.join("mesh.ply"));
    gs_io::write_mesh_ply(&path, &mesh)?;
    write_json(&report_path(&path), &report)?;
    println!(
        "mesh: {} vertices, {} triangles (voxel {:.5}, {} views, {} blocks; render {:.1}s, fuse {:.1}s) → {}",
        report.vertices,
        report.triangles,
        report.voxel_size,
        report.views,
        report.blocks,
        report.render_seconds,
        report.fuse_seconds,
        path.display()
    );
    if let Some(footprint) = report.pixel_footprint
        && report.voxel_size < FINE_VOXEL_FRACTION * footprint
    {
        eprintln!(
            "note: the voxel ({:.5}) is finer than a training pixel at the surface ({footprint:.5}); the mesh will carry per-pixel depth noise. --voxel-size {footprint:.4} fuses at the images' resolution",
            report.voxel_size
        );
    }
    Ok(())
}

fn report_path(mesh: &Path) -> PathBuf {
    mesh.with_extension("json")
}
