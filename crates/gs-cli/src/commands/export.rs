//! `vagsl export`: a run's model or mesh in another format (gs-export does the encoding).

use gs_run::read_run_model;
use anyhow::{Context, Result, bail};
use gs_export::Format;
use std::path::PathBuf;

/// Options of `vagsl export`.
#[derive(Debug, Clone, clap::Args)]
pub struct ExportArgs {
    /// A `vagsl train` output folder (RUN/point_cloud.ply; RUN/mesh.ply for the mesh formats).
    pub run: PathBuf,
    /// Output format: ply, splat, spz, compressed-ply (Gaussians) or mesh-ply, obj, glb (mesh).
    /// Default: from the extension of -o (.splat, .spz, .obj, .glb; a .ply needs --format).
    #[arg(long, value_parser = parse_format)]
    pub format: Option<Format>,
    /// Output file.
    #[arg(short, long)]
    pub output: PathBuf,
}

/// `--format` values, with the list of names in the error.
fn parse_format(s: &str) -> std::result::Result<Format, String> {
    Format::from_name(s).ok_or_else(|| format!("unknown format '{s}' (use one of {})", Format::ALL.map(Format::name).join(", ")))
}

/// Runs `vagsl export`.
pub fn run(args: &ExportArgs) -> Result<()> {
    let format = match args.format {
        Some(f) => f,
        None => Format::from_path(&args.output)?,
    };
    if !args.run.is_dir() {
        bail!("{}: no such run folder (give a `vagsl train` output folder)", args.run.display());
    }
    // Never one of a run's own files: a compressed copy must not replace the model or mesh.
    gs_run::run_folder::check_output_file(&args.output, &format!("the {format} file"), &[])?;
    let src = args.run.join("mesh.ply");
    if format.is_mesh() && !src.is_file() {
        bail!("{}: the run has no mesh.ply; make it first with `vagsl mesh {}`", args.run.display(), args.run.display());
    }
    let (config, gaussians) = read_run_model(&args.run)?;
    let current = gs_run::MadeFrom::of(&config, &gaussians);
    let summary = if format.is_mesh() {
        gs_run::provenance::check(&src, &args.run.join("mesh.json"), &current, &format!("vagsl mesh {}", args.run.display()))?;
        let mesh = gs_io::read_mesh_ply(&src)?;
        if mesh.triangles.is_empty() {
            bail!("{}: the mesh has no triangles (an empty mesh); nothing to export", src.display());
        }
        gs_export::write_mesh(format, &args.output, &mesh)?;
        let colours = if mesh.colors.is_some() { "with vertex colours" } else { "without colours" };
        format!("{} vertices, {} triangles {colours}", mesh.positions.len(), mesh.triangles.len())
    } else {
        let antialiased = config.train.antialiased;
        gs_export::write_gaussians(format, &args.output, &gaussians, antialiased)?;
        let degree = if matches!(format, Format::Splat) { 0 } else { gaussians.sh_degree };
        if antialiased && !format.records_antialiasing() {
            eprintln!(
                "note: the model was trained with opacity compensation (the Mip filter of the standard and fast \
                 presets); {format} has no field for it, so viewers render it without: small splats look a \
                 little more opaque than in training. spz records it."
            );
        }
        let aa = if antialiased && format.records_antialiasing() { ", antialiased" } else { "" };
        format!("{} Gaussians, SH degree {degree}{aa}", gaussians.len())
    };
    record(&args.run, &args.output, format, &current);
    let size = std::fs::metadata(&args.output).with_context(|| format!("{}: written but cannot be read back", args.output.display()))?.len();
    println!("export: {format}: {summary} → {} ({size} bytes)", args.output.display());
    Ok(())
}

/// Records the export in the run's index `RUN/exports.json` with the model it was made from
/// (docs/architecture.md §Provenance). The export itself is written by then, so an index that
/// cannot be written (a read-only run, a link in its place) is a warning, not a failure.
fn record(run: &std::path::Path, output: &std::path::Path, format: Format, made_from: &gs_run::MadeFrom) {
    let index = run.join(gs_run::provenance::EXPORTS_INDEX);
    let recorded = gs_run::run_folder::check_output_file(&index, "the run's index of exports", std::slice::from_ref(&index))
        .and_then(|()| gs_run::provenance::record_export(run, output, format.name(), made_from));
    if let Err(e) = recorded {
        eprintln!("warning: the export was written, but not recorded in {}: {e}", index.display());
    }
}
