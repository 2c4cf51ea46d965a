//! Comparing meshes made in different orders: the same surface has the same [`MeshShape`].

use gs_core::TriangleMesh;

/// A mesh as sets: its distinct vertex positions (bit patterns, sorted) and its triangles as
/// position triples (each from its smallest vertex, keeping the winding; sorted).
#[derive(Debug, PartialEq, Eq)]
pub struct MeshShape {
    /// Distinct vertex positions.
    pub vertices: Vec<[u32; 3]>,
    /// Triangles by position.
    pub triangles: Vec<[[u32; 3]; 3]>,
}

impl MeshShape {
    /// The shape of `mesh`.
    pub fn of(mesh: &TriangleMesh) -> Self {
        let bits = |v: u32| mesh.positions[v as usize].map(f32::to_bits);
        let mut vertices: Vec<[u32; 3]> = mesh.positions.iter().map(|p| p.map(f32::to_bits)).collect();
        vertices.sort_unstable();
        vertices.dedup();
        let mut triangles: Vec<[[u32; 3]; 3]> = mesh
            .triangles
            .iter()
            .map(|t| {
                let p = t.map(bits);
                let r = (0..3).min_by_key(|&k| p[k]).unwrap_or(0);
                [p[r], p[(r + 1) % 3], p[(r + 2) % 3]]
            })
            .collect();
        triangles.sort_unstable();
        Self { vertices, triangles }
    }
}
