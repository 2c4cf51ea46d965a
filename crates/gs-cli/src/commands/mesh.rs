//! `vagsl mesh`: TSDF fusion of a trained run's rendered plane depths (docs/method.md §TSDF).

use gs_run::run_config::{SceneSource, load_scene};
use gs_run::{OpenRun, write_json};
use anyhow::{Result, bail};
use gs_train::{DepthSource, FINE_VOXEL_FRACTION, MeshOptions, Simplify, extract_mesh, extract_mesh_in_pieces, fuse_mesh};
use std::path::{Path, PathBuf};

/// Options of `vagsl mesh`.
#[derive(Debug, Clone, clap::Args)]
pub struct MeshArgs {
    /// A `vagsl train` output folder (its rendered plane depths are fused), or with
    /// `--depth-dir` a scene folder whose depth maps are given.
    pub run: PathBuf,
    /// The run's scene folder, if it has moved since training (it must still be the scene the
    /// run was trained on).
    #[arg(long, conflicts_with = "depth_dir")]
    pub scene: Option<PathBuf>,
    /// Rasterizer backend: cpu, wgpu, or auto (wgpu on a hardware GPU, else the CPU).
    #[arg(long, default_value = "auto")]
    pub backend: gs_raster::Backend,
    /// Fuse a merged run (`vagsl merge`) in one TSDF volume instead of block by block (block
    /// by block, the volume of the largest block is the memory needed; the mesh is the same).
    #[arg(long, conflicts_with = "depth_dir")]
    pub whole: bool,
    /// Fuse these depth maps instead of rendering a run: one per view of the scene, named
    /// `<stem>.exr`, `<stem>_depth.exr`, `depth_<stem>.npy` or `<stem>.npy` (camera z, 0 = none).
    #[arg(long)]
    pub depth_dir: Option<PathBuf>,
    /// Output mesh (default RUN/mesh.ply).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Voxel size (default: the extent of all the scene's cameras / 512).
    #[arg(long)]
    pub voxel_size: Option<f64>,
    /// SDF truncation (default 4 × voxel).
    #[arg(long)]
    pub sdf_trunc: Option<f64>,
    /// Ignore depths beyond this (default 3 × the extent of all the scene's cameras).
    #[arg(long)]
    pub depth_trunc: Option<f64>,
    /// Drop depths whose depth normal is more than this many degrees from the ray (e.g. 80).
    #[arg(long)]
    pub max_normal_angle: Option<f64>,
    /// Fuse only pixels whose rendered opacity is at least this (default 0.5; 0 fuses every
    /// pixel with a depth).
    #[arg(long)]
    pub min_alpha: Option<f32>,
    /// Blend each pixel's rendered depth only until its transmittance falls to this (default
    /// 0.15): the front of the blend, nearer the true surface on curved objects; 0 blends every
    /// Gaussian the pixel sees (before stop 43's default).
    #[arg(long, conflicts_with = "depth_dir")]
    pub surface_cut: Option<f32>,
    /// Fuse only the depths that neighbouring views confirm (a multi-view depth consistency
    /// filter: a floating sheet that one view's depth holds and its neighbours see through is
    /// not fused). Off by default: on exact depths it drops the strips that fewer than two
    /// neighbours see (BENCHMARKS.md).
    #[arg(long)]
    pub depth_filter: bool,
    /// Neighbouring views that must confirm a depth under --depth-filter (default 2; a view
    /// with fewer neighbours needs all of them).
    #[arg(long, requires = "depth_filter")]
    pub depth_filter_views: Option<usize>,
    /// Keep only the largest connected component.
    #[arg(long)]
    pub largest: bool,
    /// Remove the connected components with fewer than this share of the mesh's triangles
    /// (default 0.001; 0 keeps every component of at least 50 triangles).
    #[arg(long, conflicts_with = "largest")]
    pub min_component_share: Option<f64>,
    /// Smooth the mesh with this many Taubin λ|μ step pairs before simplifying it (off by
    /// default): the fused surface's voxel-scale ripples go, so the simplifier removes more
    /// triangles within its error bound.
    #[arg(long, value_name = "STEPS")]
    pub smooth: Option<usize>,
    /// Simplify to at most this many triangles (instead of the error bound).
    #[arg(long, conflicts_with = "no_simplify")]
    pub triangles: Option<usize>,
    /// Simplify while each vertex moves at most this multiple of the pixel footprint at it
    /// (its nearest training view's depth / fx; never less than this multiple of the voxel)
    /// (default 0.3).
    #[arg(long, conflicts_with_all = ["no_simplify", "triangles"])]
    pub simplify_error: Option<f64>,
    /// Keep the mesh as marching cubes made it (no simplification).
    #[arg(long)]
    pub no_simplify: bool,
    /// Fuse only inside the views' masks.
    #[arg(long)]
    pub masks: bool,
    /// Fuse only inside this box, `XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX` in scene units (an object
    /// in a room: the memory and time of the object alone).
    #[arg(long, value_parser = parse_bounds, allow_hyphen_values = true)]
    pub bounds: Option<gs_tsdf::Aabb>,
    /// Refuse, before fusing, a mesh whose estimated memory exceeds this (e.g. 8GiB, 500MB;
    /// default 60 % of the available memory, or of 4 GiB when /proc/meminfo is unreadable).
    #[arg(long, value_parser = gs_run::budget_check::bytes_arg)]
    pub max_memory: Option<u64>,
}

/// `--bounds XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX`.
fn parse_bounds(s: &str) -> std::result::Result<gs_tsdf::Aabb, String> {
    let v: Vec<f64> = s.split(',').map(|x| x.trim().parse::<f64>()).collect::<std::result::Result<_, _>>().map_err(|e| format!("'{s}': {e}"))?;
    if v.len() != 6 || v.iter().any(|x| !x.is_finite()) {
        return Err(format!("'{s}': expected six finite numbers XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX"));
    }
    if (0..3).any(|k| v[k] > v[k + 3]) {
        return Err(format!("'{s}': each minimum must be at most its maximum"));
    }
    Ok(gs_tsdf::Aabb { min: [v[0], v[1], v[2]], max: [v[3], v[4], v[5]] })
}

/// The mesh options of `args`: [`MeshOptions::default`] with what the flags change.
fn options(args: &MeshArgs) -> Result<MeshOptions> {
    let d = MeshOptions::default();
    if let Some(a) = args.min_alpha
        && !(0.0..=1.0).contains(&a)
    {
        bail!("--min-alpha {a}: an opacity is between 0 and 1");
    }
    if let Some(c) = args.surface_cut
        && !(0.0..1.0).contains(&c)
    {
        bail!("--surface-cut {c}: a transmittance cut is at least 0 and below 1");
    }
    if let Some(s) = args.min_component_share
        && !(0.0..=1.0).contains(&s)
    {
        bail!("--min-component-share {s}: a share of the triangles is between 0 and 1");
    }
    if let Some(e) = args.simplify_error
        && !(e.is_finite() && e >= 0.0)
    {
        bail!("--simplify-error {e}: a multiple of the pixel footprint is a finite number ≥ 0");
    }
    let consistency = match (args.depth_filter, args.depth_filter_views) {
        (false, _) => d.consistency,
        (true, Some(0)) => bail!("--depth-filter-views 0: at least one view must confirm a depth"),
        (true, Some(k)) => Some(gs_tsdf::ConsistencyConfig { min_views: k, ..d.consistency.unwrap_or_default() }),
        (true, None) => Some(d.consistency.unwrap_or_default()),
    };
    let simplify = match (args.no_simplify, args.triangles, args.simplify_error) {
        (true, _, _) => Simplify::Off,
        (_, Some(n), _) => Simplify::Triangles(n),
        (_, _, Some(e)) => Simplify::FootprintError(e),
        _ => d.simplify,
    };
    Ok(MeshOptions {
        voxel_size: args.voxel_size,
        sdf_trunc: args.sdf_trunc,
        depth_trunc: args.depth_trunc,
        min_alpha: args.min_alpha.unwrap_or(d.min_alpha),
        surface_cut: args.surface_cut.unwrap_or(d.surface_cut),
        max_normal_angle_deg: args.max_normal_angle,
        consistency,
        largest_component_only: args.largest,
        min_component_share: args.min_component_share.unwrap_or(d.min_component_share),
        smoothing: args.smooth.filter(|&k| k > 0).map(gs_tsdf::Smoothing::taubin),
        simplify,
        use_masks: args.masks,
        bounds: args.bounds,
        max_memory: Some(gs_run::budget_check::limit(args.max_memory)),
        ..d
    })
}

/// Runs `vagsl mesh`: a run's rendered plane depths, or with `--depth-dir` given depth maps of
/// every view of a scene (e.g. ground truth, or another method's output), through the one
/// fusion path of [`fuse_mesh`].
pub fn run(args: &MeshArgs) -> Result<()> {
    let opts = options(args)?;
    // Both outputs are checked before any rendering or fusing.
    let home = args.depth_dir.as_deref().unwrap_or(&args.run);
    let own = [home.join("mesh.ply"), home.join("mesh.json")];
    let path = args.output.clone().unwrap_or_else(|| own[0].clone());
    gs_run::run_folder::check_output_file(&path, "the mesh", &own)?;
    gs_run::run_folder::check_output_file(&report_path(&path), "the mesh's report", &own)?;
    let (mesh, report, made_from) = match &args.depth_dir {
        Some(dir) => {
            let scene = load_scene(&SceneSource { path: Some(args.run.clone()), resolution_factor: None, width: None, eval: false })?;
            let views: Vec<usize> = (0..scene.views.len()).collect();
            let mut read = |v: &gs_core::View| Ok(gs_io::read_view_depth(dir, &v.name)?);
            let (mesh, report) = fuse_mesh(&scene, &views, DepthSource::Given(&mut read), &opts)?;
            (mesh, report, None)
        }
        None => {
            let run = OpenRun::open(&args.run, args.scene.as_deref())?;
            let mut rasterizer = super::rasterizer(args.backend)?;
            let blocks = if args.whole { None } else { gs_partition::BlockPieces::of_merged_run(&args.run)? };
            let (mesh, report) = match &blocks {
                Some(_) if args.depth_filter => {
                    bail!("--depth-filter holds every view's depth map at once, so a merged run is then fused whole: add --whole")
                }
                Some(pieces) => extract_mesh_in_pieces(&run.model(), &mut rasterizer, &opts, pieces)?,
                None => extract_mesh(&run.model(), &mut rasterizer, &opts)?,
            };
            (mesh, report, Some(run.made_from))
        }
    };
    if mesh.triangles.is_empty() {
        bail!(
            "the fused mesh is empty (0 triangles from {} TSDF blocks at voxel size {}): no surface crossed the volume; nothing written. Check --voxel-size (the default follows the scene), --bounds and --depth-trunc, or the run (a model of a few Gaussians renders no surface)",
            report.blocks,
            gs_train::length_text(report.voxel_size)
        );
    }
    gs_io::write_mesh_ply(&path, &mesh)?;
    match &made_from {
        Some(m) => write_json(&report_path(&path), &gs_run::provenance::with_made_from(&report, m)?)?,
        None => write_json(&report_path(&path), &report)?,
    }
    let source = match args.depth_dir {
        Some(_) => format!("{} depth maps read in {:.1}s", report.views, report.render_seconds),
        None => format!("{} views rendered in {:.1}s", report.views, report.render_seconds),
    };
    println!(
        "mesh: {} vertices, {} triangles (voxel {}, {} blocks; {source}, fused in {:.1}s) → {}",
        report.vertices,
        report.triangles,
        gs_train::length_text(report.voxel_size),
        report.blocks,
        report.fuse_seconds,
        path.display()
    );
    if let Some(largest) = report.pieces.iter().max_by_key(|p| p.tsdf_bytes) {
        println!(
            "  fused block by block: {} blocks, the largest volume {} ({}, {} views); --whole fuses at once",
            report.pieces.len(),
            gs_tsdf::format_bytes(largest.tsdf_bytes as u64),
            largest.name,
            largest.views
        );
    }
    println!("{}", cleanup_line(&report));
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

/// One line on what the filters and the simplification removed.
fn cleanup_line(r: &gs_train::MeshReport) -> String {
    let mut parts = Vec::new();
    if r.pixels_below_min_alpha > 0 {
        parts.push(format!("{} pixels below opacity {}", r.pixels_below_min_alpha, r.min_alpha.unwrap_or(0.0)));
    }
    if let Some(f) = &r.depth_filter {
        let share = 100.0 * f.result.pixels_dropped as f64 / f.result.pixels_checked.max(1) as f64;
        parts.push(format!("{} depths ({share:.1} %) not confirmed by {} neighbouring views", f.result.pixels_dropped, f.settings.min_views));
    }
    let c = &r.components.result;
    parts.push(format!("{} of {} components ({} triangles)", c.removed, c.components, c.triangles_removed));
    let mut line = format!("  removed: {}", parts.join("; "));
    if let Some(s) = &r.simplification {
        line.push_str(&format!(
            "\n  simplified: {} → {} triangles (error {:.2e}{})",
            s.result.triangles_before,
            s.result.triangles_after,
            s.result.error,
            match (s.result.graded, s.result.error_bound) {
                (Some(g), _) => format!(", bounds {:.2e} to {:.2e} by the pixel footprint at each vertex", g.smallest, g.largest),
                (None, Some(b)) => format!(", bound {b:.2e}"),
                (None, None) => String::new(),
            }
        ));
    }
    line
}

fn report_path(mesh: &Path) -> PathBuf {
    mesh.with_extension("json")
}
