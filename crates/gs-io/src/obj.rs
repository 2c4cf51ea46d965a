//! Wavefront OBJ reading (via `tobj`) into a [`TriangleMesh`].
//!
//! All objects/groups of the file are merged into one mesh; polygons are triangulated as fans;
//! points and lines are ignored; normals, texture coordinates and materials (`.mtl`) are
//! ignored (no other file is opened). Vertex colours (`v x y z r g b`, floats in `[0, 1]`) are
//! kept when every object has them. Non-finite positions are an error naming the vertex.

use crate::error::{IoError, Result};
use gs_core::TriangleMesh;
use std::path::Path;

/// Reads an OBJ file into one triangle mesh (see the module docs).
pub fn read_obj(path: &Path) -> Result<TriangleMesh> {
    let bytes = crate::capped::OBJ.read(path)?;
    parse_obj(&bytes, path)
}

/// Parses an OBJ held in memory; `path` only names the file in errors.
pub fn parse_obj(bytes: &[u8], path: &Path) -> Result<TriangleMesh> {
    let options = tobj::LoadOptions { triangulate: true, single_index: false, ignore_points: true, ignore_lines: true, ..Default::default() };
    let kept = without_texcoords_and_normals(bytes);
    let mut reader = std::io::BufReader::new(&kept[..]);
    let (models, _materials) = tobj::load_obj_buf(&mut reader, &options, |_| Err(tobj::LoadError::OpenFileFailed))
        .map_err(|e| IoError::format(path, format!("OBJ parse error: {e}")))?;
    let mut mesh = TriangleMesh::default();
    let mut colors: Option<Vec<[u8; 3]>> = Some(Vec::new());
    for model in &models {
        let m = &model.mesh;
        if m.positions.len() % 3 != 0 || m.indices.len() % 3 != 0 {
            return Err(IoError::format(path, format!("OBJ object '{}' has incomplete vertices or faces", model.name)));
        }
        let base = mesh.positions.len();
        let nv = m.positions.len() / 3;
        for (i, p) in m.positions.chunks_exact(3).enumerate() {
            if !p.iter().all(|v| v.is_finite()) {
                return Err(IoError::format(path, format!("OBJ object '{}': vertex {i} is not finite: {p:?}", model.name)));
            }
            mesh.positions.push([p[0], p[1], p[2]]);
        }
        for t in m.indices.chunks_exact(3) {
            if t.iter().any(|&v| v as usize >= nv) {
                return Err(IoError::format(path, format!("OBJ object '{}': face index {t:?} out of range", model.name)));
            }
            let off = |v: u32| -> Result<u32> {
                u32::try_from(base + v as usize).map_err(|_| IoError::format(path, "OBJ has more than 2^32 vertices"))
            };
            mesh.triangles.push([off(t[0])?, off(t[1])?, off(t[2])?]);
        }
        match colors.as_mut() {
            Some(cs) if m.vertex_color.len() == m.positions.len() && !m.vertex_color.is_empty() => {
                cs.extend(m.vertex_color.chunks_exact(3).map(rgb8));
            }
            _ => colors = None,
        }
    }
    mesh.colors = colors.filter(|c| !c.is_empty() && c.len() == mesh.positions.len());
    Ok(mesh)
}

/// The OBJ without its `vt` and `vn` records. Texture coordinates and normals are ignored
/// (module docs), and tobj 4.0.5 indexes them with unchecked arithmetic: a face naming an
/// absurd normal index (`f 1/1/-3` with one normal, or `f 1//6148914691236517206`) overflows
/// inside it and, in a release build, panics on an index out of bounds (found by the `obj`
/// fuzz target). Without those records tobj never reads the indices. Lines split on `\n` and
/// are tokenised as tobj does; a line that is not UTF-8 is kept (tobj refuses it).
fn without_texcoords_and_normals(bytes: &[u8]) -> std::borrow::Cow<'_, [u8]> {
    let skipped = |line: &[u8]| {
        std::str::from_utf8(line).is_ok_and(|l| matches!(l.split_whitespace().next(), Some("vt" | "vn")))
    };
    if !bytes.split(|&b| b == b'\n').any(skipped) {
        return std::borrow::Cow::Borrowed(bytes);
    }
    let mut out = Vec::with_capacity(bytes.len());
    for line in bytes.split_inclusive(|&b| b == b'\n') {
        let body = line.strip_suffix(b"\n").unwrap_or(line);
        if !skipped(body) {
            out.extend_from_slice(line);
        }
    }
    std::borrow::Cow::Owned(out)
}

/// Converts one `[0, 1]` float colour to bytes (non-finite components become 0).
fn rgb8(c: &[f32]) -> [u8; 3] {
    let q = |v: f32| if v.is_finite() { (v.clamp(0.0, 1.0) * 255.0).round() as u8 } else { 0 };
    [q(c[0]), q(c[1]), q(c[2])]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quads_are_triangulated_and_objects_merged() {
        let text = b"# test\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\no a\nf 1 2 3 4\no b\nv 5 5 5\nf 1 2 5\n";
        let m = parse_obj(text, Path::new("t.obj")).unwrap();
        assert_eq!(m.triangles.len(), 3);
        m.validate().unwrap();
        let quad: f64 = m.triangles[..2].iter().map(|t| m.triangle_area(t)).sum();
        assert!((quad - 1.0).abs() < 1e-9, "{quad}");
        assert_eq!(m.positions[m.triangles[2][2] as usize], [5.0, 5.0, 5.0]);
        assert!(m.colors.is_none());
        let e = parse_obj(b"v 0 0 0\nf 1 2 3\n", Path::new("bad.obj")).unwrap_err().to_string();
        assert!(e.contains("bad.obj"), "{e}");
    }

    #[test]
    fn vertex_colours_are_kept() {
        let text = b"v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n";
        let m = parse_obj(text, Path::new("c.obj")).unwrap();
        assert_eq!(m.colors.unwrap(), vec![[255, 0, 0], [0, 255, 0], [0, 0, 255]]);
    }
}
