//! The shared float trait of the kernels (f32 for training, f64 for gradient checks and
//! reference conformance), defined in gs-core.

pub use gs_core::real::Real;
