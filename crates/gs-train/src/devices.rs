//! The loss terms' device executors, passed to the terms explicitly through
//! [`crate::terms::TermInputs`] (docs/architecture.md §GPU). Today: L_p's patches
//! ([`gs_mvs::PhotometricGpu`]) on the adapter the wgpu rasterizer uses. Without the `wgpu`
//! feature the type is uninhabited, so the CPU reference is the only executor.

/// L_p's device executor (mutable behind a shared borrow: the terms see their inputs by `&`).
#[cfg(feature = "wgpu")]
pub type PhotometricDevice = std::cell::RefCell<gs_mvs::PhotometricGpu>;

/// L_p's device executor: none without the `wgpu` feature.
#[cfg(not(feature = "wgpu"))]
#[derive(Debug)]
pub enum PhotometricDevice {}

/// L_p's device executor on the best adapter, when the rasterizer runs on wgpu and the run uses
/// L_p; `Err` says why none could be made (the run then evaluates L_p on the CPU).
pub(crate) fn photometric_device(rasterizer: &gs_raster::Rasterizer, uses_photometric: bool) -> Option<Result<PhotometricDevice, String>> {
    if rasterizer.backend() != gs_raster::Backend::Wgpu || !uses_photometric {
        return None;
    }
    #[cfg(feature = "wgpu")]
    {
        Some(gs_mvs::PhotometricGpu::new(&Default::default()).map(std::cell::RefCell::new).map_err(|e| e.to_string()))
    }
    #[cfg(not(feature = "wgpu"))]
    {
        None
    }
}

/// Where L_p runs, in words.
pub(crate) fn describe(device: Option<&PhotometricDevice>) -> String {
    match device {
        #[cfg(feature = "wgpu")]
        Some(d) => format!("wgpu on {}", d.borrow().adapter_description()),
        #[cfg(not(feature = "wgpu"))]
        Some(d) => match *d {},
        None => format!("cpu ({} threads)", rayon::current_num_threads()),
    }
}
