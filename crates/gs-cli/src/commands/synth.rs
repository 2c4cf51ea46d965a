//! `vagsl synth`: writes scenes of the validation suite, or the street scene (gs-synth), as
//! scene folders that `vagsl train` reads, with their exact GT depth, normals, masks and meshes.

use anyhow::{Context, Result, bail};
use gs_synth::{GENERATOR_VERSION, SUITE_SIZE, StreetOptions, SuiteOptions, scene_spec, write_street, write_suite_scene};
use std::path::{Path, PathBuf};

/// Options of `vagsl synth`.
#[derive(Debug, Clone, clap::Args)]
pub struct SynthArgs {
    /// Output folder; scene N goes to OUT/NN-name (e.g. OUT/00-cup). A scene folder that
    /// already holds the same scene (same index, seed, size and generator version) is kept; one
    /// that holds anything else is an error. With --street: the new scene folder itself (an
    /// existing one is refused).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Write only this scene (0-based index into the suite).
    #[arg(long, conflicts_with = "suite")]
    pub scene: Option<usize>,
    /// Write every scene of the suite (the default when --scene is not given).
    #[arg(long)]
    pub suite: bool,
    /// Write the street scene instead: a 14 m street with objects along both sides and cameras
    /// walking its centre line, larger than one training block.
    #[arg(long, conflicts_with_all = ["scene", "suite"])]
    pub street: bool,
    /// Reduced resolution for trying an idea (200×150, 2×2 supersampling) instead of the
    /// record's 480×360, 3×3.
    #[arg(long)]
    pub quick: bool,
    /// Seed of the object sizes (and, for the street, their order and places), light, textures
    /// and cameras.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Runs `vagsl synth`.
pub fn run(args: &SynthArgs) -> Result<()> {
    if args.street {
        return run_street(args);
    }
    let opts = if args.quick { SuiteOptions::quick() } else { SuiteOptions::full() };
    let indices: Vec<usize> = match args.scene {
        Some(i) if i >= SUITE_SIZE => bail!("--scene {i}: the suite has scenes 0 to {}", SUITE_SIZE - 1),
        Some(i) => vec![i],
        None => (0..SUITE_SIZE).collect(),
    };
    std::fs::create_dir_all(&args.output).with_context(|| format!("{}: cannot create the output folder", args.output.display()))?;
    for i in indices {
        let spec = scene_spec(i, args.seed).expect("index checked above");
        let dir = args.output.join(spec.folder_name());
        if dir.exists() {
            check_same(&dir, i, args.seed, &opts)?;
            println!("{}: already written with the same parameters, kept", dir.display());
            continue;
        }
        let t0 = std::time::Instant::now();
        let scene = write_suite_scene(&dir, i, args.seed, &opts)?;
        println!(
            "{}: {} views of {}x{}, {} object triangles, {} ({:.1}s)",
            dir.display(),
            scene.spec.views,
            opts.width,
            opts.height,
            scene.built.object_mesh.triangles.len(),
            scene.spec.about,
            t0.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// Writes the street scene to the new folder `args.output`.
fn run_street(args: &SynthArgs) -> Result<()> {
    let opts = if args.quick { StreetOptions::quick() } else { StreetOptions::full() };
    let dir = &args.output;
    if let Some(parent) = dir.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).with_context(|| format!("{}: cannot create the parent folder", parent.display()))?;
    }
    let t0 = std::time::Instant::now();
    let scene = write_street(dir, args.seed, &opts)?;
    let b = &scene.built;
    println!(
        "{}: street scene, {} views of {}x{}, {} objects, {} scored triangles, {} sparse points ({:.1}s)",
        dir.display(),
        b.scene.views.len(),
        opts.width,
        opts.height,
        scene.spec.objects.len(),
        b.object_mesh.triangles.len(),
        b.scene.points.len(),
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Fails unless `dir/scene.json` records scene `index` made with `seed`, `opts` and this
/// generator version.
fn check_same(dir: &Path, index: usize, seed: u64, opts: &SuiteOptions) -> Result<()> {
    let path = dir.join("scene.json");
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("{}: exists but is not a suite scene folder (no readable scene.json); remove it or choose another output folder", dir.display()))?;
    let v: serde_json::Value = serde_json::from_str(&text).with_context(|| format!("{}: not valid JSON", path.display()))?;
    let want = [
        ("generator_version", u64::from(GENERATOR_VERSION)),
        ("index", index as u64),
        ("seed", seed),
        ("width", u64::from(opts.width)),
        ("height", u64::from(opts.height)),
        ("supersample", u64::from(opts.supersample)),
    ];
    for (key, value) in want {
        let got = v.get(key).and_then(serde_json::Value::as_u64);
        if got != Some(value) {
            let got = got.map_or("nothing".to_string(), |g| g.to_string());
            bail!("{}: holds a scene with {key} {got}, not {value}; remove it or choose another output folder", dir.display());
        }
    }
    Ok(())
}
