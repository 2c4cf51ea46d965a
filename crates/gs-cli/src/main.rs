//! `vagsl`: posed photographs → surface mesh and Gaussian splats (VA-GS).
//!
//! A thin front end: every subcommand parses its arguments, calls the gs-* crates (run folders,
//! fingerprints and pairing checks live in gs-run) and prints a report. Errors are reported with their full cause chain and a non-zero exit status.

mod commands;
mod scene_path;
mod serve;
mod signals;

use clap::{Parser, Subcommand};
use std::path::PathBuf;

/// vagsl — view-aligned Gaussian splatting for accurate surface meshes.
#[derive(Debug, Parser)]
#[command(name = "vagsl", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Summarise a scene: cameras, images, points, resolutions, camera models, scene extent
    /// and source-view neighbour statistics.
    ///
    /// SCENE is a folder with `images/` and `sparse/0` (COLMAP text or binary), a model folder
    /// itself, or a folder with `transforms.json` (or `transforms_train.json` +
    /// `transforms_test.json`); COLMAP wins when both are there. Without SCENE the built-in
    /// procedural scene is described.
    Info {
        /// Scene folder (or COLMAP model folder). Omit for the built-in scene.
        scene: Option<PathBuf>,
        /// Print the summary as JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Convert a scene: COLMAP text ↔ binary (lossless), COLMAP → transforms.json, or
    /// transforms.json → COLMAP.
    ///
    /// `--to transforms` writes OUT/transforms.json and OUT/sparse_pc.ply (default OUT: the
    /// scene folder) naming the photos as `images/NAME` (OUT/images is linked to the scene's
    /// photos when OUT is elsewhere). From a transforms.json scene, `--to text|bin` writes a
    /// COLMAP model (default SCENE/sparse/0) without observations.
    Convert {
        /// Model folder (e.g. `SCENE/sparse/0`) or scene folder (COLMAP or transforms.json).
        model: PathBuf,
        /// Output format.
        #[arg(long, value_enum)]
        to: commands::convert::Format,
        /// Output folder (created if missing). Defaults to the input model folder (text/bin
        /// from COLMAP), the scene folder (transforms) or SCENE/sparse/0 (from transforms.json).
        #[arg(short, long)]
        output: Option<PathBuf>,
    },
    /// Train a VA-GS model: posed images → OUT/point_cloud.ply (3DGS layout).
    ///
    /// Without SCENE the built-in procedural scene is used. The schedule follows the paper
    /// (colour warm-up, then edge + L_nc + L_ns + L_p, then L_f); `--iterations` scales it.
    Train(Box<commands::train::TrainArgs>),
    /// Fuse a trained run's rendered plane depths into a mesh (TSDF + marching cubes).
    Mesh(commands::mesh::MeshArgs),
    /// Render a trained run's views: colour PNG, plane depth EXR, world normal PNG.
    Render(commands::render::RenderArgs),
    /// PSNR / SSIM / LPIPS of a trained run's held-out views.
    EvalImages(commands::eval_images::EvalImagesArgs),
    /// Accuracy / completeness / Chamfer / F1 of a mesh against a ground-truth mesh.
    EvalMesh(commands::eval_mesh::EvalMeshArgs),
    /// Export a run's model (ply, splat, spz, compressed-ply) or mesh (mesh-ply, obj, glb) for
    /// other viewers and tools.
    Export(commands::export::ExportArgs),
    /// Run the ablation ladder on a preset (only L_I, then one loss term at a time up to the
    /// preset; and the fast preset) and tabulate wall time, Gaussians, Chamfer / F1 and PSNR,
    /// with an SVG plot of accuracy against time.
    Tradeoff(commands::tradeoff::TradeoffArgs),
    /// Write the run's report page, RUN/report.html: an interactive view of the splats and the
    /// mesh, every view's photo, render, normal and depth maps with their scores, and the
    /// training curves (works offline; `--serve` serves it on 127.0.0.1).
    View(commands::view::ViewArgs),
    /// Write scenes of the validation suite: procedurally built objects in a room, ray-traced
    /// views in the COLMAP layout, exact GT depth, normals, masks and meshes (`scripts/suite.sh`
    /// trains and scores a preset on all of them).
    Synth(commands::synth::SynthArgs),
    /// Split a scene too large for one machine into blocks with overlapping views: each block
    /// a scene folder (photos linked) that `vagsl train` trains as its own job, with a block
    /// script, a Slurm job array and a Kubernetes Indexed Job to run them.
    Partition(commands::partition::PartitionArgs),
    /// Merge the trained blocks of a partition plan into one run of the whole scene (each
    /// block's Gaussians inside its core region), which mesh, render, eval-images and view open.
    Merge(commands::partition::MergeArgs),
}

/// On a headless machine (no Wayland or X display) Mesa's Vulkan device-select layer, loaded
/// implicitly whenever wgpu probes for an adapter, tries to reach a Wayland compositor and
/// prints "error: XDG_RUNTIME_DIR is invalid or not set in the environment." twice. It is
/// harmless but reads like a failure of ours. The layer only re-orders devices, and `--backend`
/// picks the adapter itself, so it is switched off there (`NODEVICE_SELECT=1`) unless the user
/// set it or asked the layer for a device (`MESA_VK_DEVICE_SELECT`).
fn quiet_headless_vulkan_probe() {
    let unset = |k: &str| std::env::var_os(k).is_none();
    if unset("WAYLAND_DISPLAY") && unset("DISPLAY") && unset("MESA_VK_DEVICE_SELECT") && unset("NODEVICE_SELECT") {
        // SAFETY: called first thing in `main`, before any thread (rayon, wgpu) exists, so no
        // other thread can read the environment concurrently.
        unsafe { std::env::set_var("NODEVICE_SELECT", "1") };
    }
}

fn main() -> std::process::ExitCode {
    quiet_headless_vulkan_probe();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Info { scene, json } => commands::info::run(scene.as_deref(), json),
        Command::Convert { model, to, output } => commands::convert::run(&model, to, output.as_deref()),
        Command::Train(args) => commands::train::run(&args),
        Command::Mesh(args) => commands::mesh::run(&args),
        Command::Render(args) => commands::render::run(&args),
        Command::EvalImages(args) => commands::eval_images::run(&args),
        Command::EvalMesh(args) => commands::eval_mesh::run(&args),
        Command::Export(args) => commands::export::run(&args),
        Command::Tradeoff(args) => commands::tradeoff::run(&args),
        Command::View(args) => commands::view::run(&args),
        Command::Synth(args) => commands::synth::run(&args),
        Command::Partition(args) => commands::partition::run_partition(&args),
        Command::Merge(args) => commands::partition::run_merge(&args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", message(&e));
            match e.chain().find_map(|c| c.downcast_ref::<signals::Stopped>()) {
                Some(stopped) => std::process::ExitCode::from(stopped.exit_status()),
                None => std::process::ExitCode::FAILURE,
            }
        }
    }
}

/// The error and its causes joined by ": ", each cause left out when the text before it
/// already ends with it (library errors such as `{path}: {source}` print their source
/// themselves, and anyhow's `{:#}` would repeat it: "…: No such file or directory (os error
/// 2): No such file or directory (os error 2)").
fn message(e: &anyhow::Error) -> String {
    let mut text = e.to_string();
    for cause in e.chain().skip(1) {
        let c = cause.to_string();
        if !text.ends_with(&c) {
            text.push_str(": ");
            text.push_str(&c);
        }
    }
    text
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_cause_already_printed_is_not_repeated() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file or directory");
        let e = anyhow::Error::new(gs_io::IoError::io("/nope.ply", io));
        assert_eq!(super::message(&e), "/nope.ply: No such file or directory");
        let e = anyhow::anyhow!("inner problem").context("outer");
        assert_eq!(super::message(&e), "outer: inner problem");
    }
}
