//! `vagsl mesh`: TSDF fusion of a trained run's rendered plane depths (method-spec §8).

use crate::run_dir::{OpenRun, write_json};
use anyhow::Result;
use gs_train::{MeshOptions, extract_mesh};
use std::path::{Path, PathBuf};

/// Options of `vagsl mesh`.
#[derive(Debug, Clone, clap::Args)]
pub struct MeshArgs {
    /// A `vagsl train` output folder.
    pub run: PathBuf,
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

/// Runs `vagsl mesh`.
pub fn run(args: &MeshArgs) -> Result<()> {
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
    let (mesh, report) = extract_mesh(&run.gaussians, &run.scene, &run.train, &run.raster(), run.extent(), &opts)?;
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
    Ok(())
}

fn report_path(mesh: &Path) -> PathBuf {
    mesh.with_extension("json")
}
