//! Indexed triangle meshes shared by the TSDF, the I/O and the metrics.

use crate::error::{CoreError, Result};

/// An indexed triangle mesh in world coordinates, optionally with per-vertex colours.
/// Triangles are wound counter-clockwise seen from the side their normal points to.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriangleMesh {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Vertex indices of each triangle.
    pub triangles: Vec<[u32; 3]>,
    /// Optional per-vertex RGB colours (same length as `positions`).
    pub colors: Option<Vec<[u8; 3]>>,
}

impl TriangleMesh {
    /// Checks that every index is in range, colours match the vertex count and every position
    /// is finite.
    pub fn validate(&self) -> Result<()> {
        let n = self.positions.len();
        if let Some(c) = &self.colors
            && c.len() != n
        {
            return Err(CoreError::InvalidParameter(format!(
                "mesh has {n} vertices but {} colours",
                c.len()
            )));
        }
        if let Some((i, _)) = self.positions.iter().enumerate().find(|(_, p)| !p.iter().all(|v| v.is_finite())) {
            return Err(CoreError::InvalidParameter(format!("mesh vertex {i} is not finite")));
        }
        if let Some((t, tri)) = self.triangles.iter().enumerate().find(|(_, t)| t.iter().any(|&v| v as usize >= n)) {
            return Err(CoreError::InvalidParameter(format!(
                "mesh triangle {t} references vertex {:?} but there are {n} vertices",
                tri
            )));
        }
        Ok(())
    }

    /// Total surface area.
    pub fn area(&self) -> f64 {
        self.triangles.iter().map(|t| self.triangle_area(t)).sum()
    }

    /// Area of one triangle.
    pub fn triangle_area(&self, t: &[u32; 3]) -> f64 {
        let p = |i: u32| {
            let v = self.positions[i as usize];
            glam::DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64)
        };
        let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
        0.5 * (b - a).cross(c - a).length()
    }

    /// Axis-aligned bounding box `(min, max)`; `None` for an empty mesh.
    pub fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        let mut it = self.positions.iter();
        let first = *it.next()?;
        Some(it.fold((first, first), |(mut lo, mut hi), p| {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
            (lo, hi)
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn area_and_validation() {
        let mut m = TriangleMesh {
            positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            triangles: vec![[0, 1, 2]],
            colors: None,
        };
        assert!((m.area() - 0.5).abs() < 1e-12);
        assert!(m.validate().is_ok());
        m.triangles.push([0, 1, 3]);
        assert!(m.validate().is_err());
    }
}
