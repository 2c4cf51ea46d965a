//! A sparse 3D point of a scene (from SfM, or drawn at initialisation). Its own module so that
//! both [`crate::scene`] and [`crate::extent`] (which falls back to the points' spread) use it
//! without importing each other.

use glam::DVec3;

/// A sparse 3D point (from SfM) with its colour.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScenePoint {
    /// World position.
    pub position: DVec3,
    /// RGB colour in `[0, 1]`.
    pub color: [f32; 3],
}
