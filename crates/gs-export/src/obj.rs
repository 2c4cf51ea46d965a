//! Wavefront OBJ writing for a [`TriangleMesh`] (reading is gs-io's `read_obj`, via `tobj`).
//!
//! `v x y z` per vertex, with `r g b` in [0, 1] appended when the mesh has colours (the common
//! "vertex colour" extension that MeshLab, Blender and `tobj` read), then `f a b c` (1-based).
//! Coordinates are printed in Rust's shortest round-trip form, so they read back bit-exactly;
//! colours with 6 decimals, which round back to the same bytes.

use crate::error::Result;
use gs_core::TriangleMesh;
use std::io::Write;
use std::path::Path;

/// Writes `mesh` as OBJ at `path` (atomically). Fails, writing nothing, when the mesh does not
/// validate.
pub fn write_obj(path: &Path, mesh: &TriangleMesh) -> Result<()> {
    mesh.validate().map_err(|source| gs_io::IoError::Core { path: path.to_path_buf(), source })?;
    gs_io::write_atomic(path, |w| write_obj_to(w, mesh))?;
    Ok(())
}

/// Streams the OBJ text of `mesh` into `w` (no validation).
pub fn write_obj_to(w: &mut dyn Write, mesh: &TriangleMesh) -> std::io::Result<()> {
    writeln!(w, "# vagsl mesh: {} vertices, {} triangles", mesh.positions.len(), mesh.triangles.len())?;
    let colors = mesh.colors.as_ref().filter(|c| c.len() == mesh.positions.len());
    for (i, p) in mesh.positions.iter().enumerate() {
        match colors {
            Some(c) => {
                let [r, g, b] = c[i].map(|v| v as f32 / 255.0);
                writeln!(w, "v {} {} {} {r:.6} {g:.6} {b:.6}", p[0], p[1], p[2])?
            }
            None => writeln!(w, "v {} {} {}", p[0], p[1], p[2])?,
        }
    }
    for t in &mesh.triangles {
        writeln!(w, "f {} {} {}", t[0] as u64 + 1, t[1] as u64 + 1, t[2] as u64 + 1)?;
    }
    Ok(())
}
