//! One module per subcommand.

pub mod convert;
pub mod eval_images;
pub mod eval_mesh;
pub mod export;
pub mod info;
pub mod mesh;
pub mod partition;
pub mod render;
pub mod synth;
pub mod tradeoff;
pub mod train;
pub mod train_loop;
pub mod view;

/// The rasterizer of `--backend` (cpu, wgpu, or auto = wgpu on a hardware GPU, else the CPU),
/// announced on stderr so a user sees which one ran.
pub fn rasterizer(backend: gs_raster::Backend) -> anyhow::Result<gs_raster::Rasterizer> {
    let r = gs_raster::Rasterizer::new(backend)?;
    eprintln!("rasterizer: {} (--backend {backend})", r.description());
    Ok(r)
}
