//! Shared parts of the wgpu parity tests.

pub mod compare;
pub mod scenes;
