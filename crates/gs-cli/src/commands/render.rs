//! `vagsl render`: colour, plane depth (EXR) and world-space normal maps (PNG) of a run's views.

use gs_run::OpenRun;
use anyhow::{Context, Result};
use gs_core::Image;
use gs_raster::RenderRequest;
use std::path::PathBuf;

/// Which views to render.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Split {
    /// Training views.
    Train,
    /// Held-out views (`--eval` runs).
    Test,
    /// Every view.
    All,
}

impl Split {
    /// The split's name, as given to `--split` and used as the folder name under `renders/`.
    pub fn name(self) -> &'static str {
        match self {
            Split::Train => "train",
            Split::Test => "test",
            Split::All => "all",
        }
    }
}

/// Options of `vagsl render`.
#[derive(Debug, Clone, clap::Args)]
pub struct RenderArgs {
    /// A `vagsl train` output folder.
    pub run: PathBuf,
    /// The run's scene folder, if it has moved since training (it must still be the scene the
    /// run was trained on).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Rasterizer backend: cpu, wgpu, or auto (wgpu on a hardware GPU, else the CPU).
    #[arg(long, default_value = "auto")]
    pub backend: gs_raster::Backend,
    /// Which views.
    #[arg(long, value_enum, default_value = "test")]
    pub split: Split,
    /// Output folder (default RUN/renders/SPLIT).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Also ray-cast this mesh (PLY/OBJ, e.g. RUN/mesh.ply) from every view, shaded by the
    /// angle to the camera ("headlight"), as `<stem>_mesh.png`: a screenshot of the mesh from
    /// the photo's viewpoint, with no graphics driver needed.
    #[arg(long)]
    pub mesh: Option<PathBuf>,
}

/// Headlight shading of a ray-cast mesh: |n·ray| on a light grey, background black.
fn mesh_shaded(bvh: &gs_synth::Bvh, camera: &gs_core::Camera) -> Result<Image> {
    let cast = bvh.cast_view(camera)?;
    let (w, h) = (camera.width as usize, camera.height as usize);
    let mut out = Image::new(w, h, 3)?;
    for y in 0..h {
        for x in 0..w {
            if cast.depth.get(x, y, 0) <= 0.0 {
                continue;
            }
            let n = gs_core::glam::DVec3::new(
                cast.normal.get(x, y, 0) as f64,
                cast.normal.get(x, y, 1) as f64,
                cast.normal.get(x, y, 2) as f64,
            );
            let (_, d) = gs_synth::pixel_ray(camera, x as f64 + 0.5, y as f64 + 0.5);
            let shade = (0.15 + 0.8 * n.dot(-d.normalize()).abs()) as f32;
            for c in 0..3 {
                out.set(x, y, c, shade * [0.92, 0.9, 0.85][c]);
            }
        }
    }
    Ok(out)
}

/// World-space normal map encoded (n + 1)/2 (docs/architecture.md §Conventions), 0 where nothing was rendered.
pub(crate) fn world_normal_png(camera: &gs_core::Camera, normal: &Image) -> Result<Image> {
    let r_t = camera.rotation.transpose();
    let mut out = Image::new(normal.width(), normal.height(), 3)?;
    for (o, n) in out.data_mut().chunks_exact_mut(3).zip(normal.data().chunks_exact(3)) {
        let v = gs_core::glam::DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64);
        if v.length() > 1e-6 {
            let w = (r_t * v).normalize();
            o.copy_from_slice(&[(w.x as f32 + 1.0) / 2.0, (w.y as f32 + 1.0) / 2.0, (w.z as f32 + 1.0) / 2.0]);
        }
    }
    Ok(out)
}

/// The file stem each view is written under: its image name without the extension, folders
/// joined with `_` (`cam1/0001.jpg` → `cam1_0001`). Two views that would share a stem (`a.jpg`
/// and `a.png`) are refused before anything is rendered, naming both, rather than one
/// silently overwriting the other.
fn output_stems<'a>(names: impl Iterator<Item = &'a str>, dir: &std::path::Path) -> Result<Vec<String>> {
    let mut seen = std::collections::HashMap::new();
    let mut stems = Vec::new();
    for name in names {
        let p = std::path::Path::new(name);
        let file = p.file_stem().map_or(name.into(), |s| s.to_string_lossy().into_owned());
        let stem = match p.parent().map(|d| d.to_string_lossy().replace(['/', '\\'], "_")) {
            Some(d) if !d.is_empty() => format!("{d}_{file}"),
            _ => file,
        };
        if let Some(other) = seen.insert(stem.clone(), name) {
            anyhow::bail!("views '{other}' and '{name}' would both be written as {stem}.png in {}; rename one of the photos", dir.display());
        }
        stems.push(stem);
    }
    Ok(stems)
}

/// Runs `vagsl render`.
pub fn run(args: &RenderArgs) -> Result<()> {
    let run = OpenRun::open(&args.run, args.scene.as_deref())?;
    let model = run.model();
    let views: Vec<usize> = match args.split {
        Split::Train => model.train.to_vec(),
        Split::Test => model.test.to_vec(),
        Split::All => (0..run.scene.views.len()).collect(),
    };
    let name = args.split.name();
    if views.is_empty() {
        anyhow::bail!("no views in the {name} split (held-out views exist only for runs trained with --eval)");
    }
    let dir = args.output.clone().unwrap_or_else(|| run.dir.join("renders").join(name));
    let stems = output_stems(views.iter().map(|&i| run.scene.views[i].name.as_str()), &dir)?;
    std::fs::create_dir_all(&dir).with_context(|| format!("{}: cannot create folder", dir.display()))?;
    // Every file checked before the first render (never a link, device, folder or run file).
    for stem in &stems {
        let kinds: &[&str] = if args.mesh.is_some() { &[".png", "_depth.exr", "_normal.png", "_mesh.png"] } else { &[".png", "_depth.exr", "_normal.png"] };
        for kind in kinds {
            gs_run::run_folder::check_output_file(&dir.join(format!("{stem}{kind}")), "a render", &[])?;
        }
    }
    // The folder's record of the model its renders come from (docs/architecture.md §Provenance).
    let record = dir.join(gs_run::provenance::RENDERS_RECORD);
    gs_run::run_folder::check_output_file(&record, "the renders' record", &[])?;
    let req = RenderRequest { color: true, alpha: true, normal: true, distance: true, plane_depth: true, ..Default::default() };
    let mut rasterizer = super::rasterizer(args.backend)?;
    let bvh = match &args.mesh {
        Some(p) => {
            let mesh = super::eval_mesh::read_mesh(p)?;
            Some(gs_synth::Bvh::new(&mesh).with_context(|| format!("{}: cannot build a BVH of the mesh", p.display()))?)
        }
        None => None,
    };
    for (&i, stem) in views.iter().zip(&stems) {
        let view = &run.scene.views[i];
        let out = model.render(&mut rasterizer, i, &req)?;
        gs_io::write_png(&dir.join(format!("{stem}.png")), out.color.as_ref().expect("requested"))?;
        gs_io::write_depth_exr(&dir.join(format!("{stem}_depth.exr")), out.plane_depth.as_ref().expect("requested"))?;
        let normal = world_normal_png(&view.camera, out.normal.as_ref().expect("requested"))?;
        gs_io::write_png(&dir.join(format!("{stem}_normal.png")), &normal)?;
        if let Some(bvh) = &bvh {
            gs_io::write_png(&dir.join(format!("{stem}_mesh.png")), &mesh_shaded(bvh, &view.camera)?)?;
        }
    }
    let names: Vec<String> = views.iter().map(|&i| run.scene.views[i].name.clone()).collect();
    gs_run::provenance::write_renders_record(&dir, name, &names, &run.made_from)?;
    println!(
        "rendered {} views (colour PNG, plane depth EXR, world normal PNG{}) → {}",
        views.len(),
        if bvh.is_some() { ", shaded mesh PNG" } else { "" },
        dir.display()
    );
    Ok(())
}
