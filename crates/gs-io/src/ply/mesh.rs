//! Triangle-mesh PLY read/write for [`TriangleMesh`].
//!
//! **Writing**: `binary_little_endian 1.0`, `element vertex` with `float x y z` and, when the
//! mesh has colours, `uchar red green blue`; `element face` with
//! `property list uchar int vertex_indices` (the layout of the synth-bunny ground truth and of
//! most tools).
//!
//! **Reading** accepts ASCII, binary little- and big-endian files; positions of any scalar
//! type (rounded to f32); colours from `red green blue` when all three exist (`uchar` as is,
//! floats in `[0, 1]` scaled by 255, other integers clamped to 0..255); faces from a list
//! property `vertex_indices` or `vertex_index` of any integer type, polygons triangulated as
//! fans `(v0, vk, vk+1)`; unknown properties and elements are skipped. A file without a `face`
//! element gives a mesh without triangles. Faces with fewer than 3 vertices, indices out of
//! range and non-finite positions are errors naming the record.

use super::{DataReader, PropertyKind, ScalarType, parse_header, read_file};
use crate::atomic::write_atomic;
use crate::error::{IoError, Result};
use gs_core::TriangleMesh;
use std::io::Write;
use std::path::Path;

/// Writes `mesh` as a binary PLY at `path` (atomically). Fails, writing nothing, when the mesh
/// does not validate (index out of range, non-finite position, colour count mismatch).
pub fn write_mesh_ply(path: &Path, mesh: &TriangleMesh) -> Result<()> {
    mesh.validate().map_err(|source| IoError::Core { path: path.to_path_buf(), source })?;
    if mesh.positions.len() > i32::MAX as usize {
        return Err(IoError::invalid(path, "mesh has more vertices than a PLY 'int' index can address"));
    }
    write_atomic(path, |w| write_mesh_ply_to(w, mesh))
}

/// Streams the binary PLY of `mesh` into `w` (no validation; see [`write_mesh_ply`]).
pub fn write_mesh_ply_to(w: &mut dyn Write, mesh: &TriangleMesh) -> std::io::Result<()> {
    let colors = mesh.colors.as_ref().filter(|c| c.len() == mesh.positions.len());
    let mut header = format!("ply\nformat binary_little_endian 1.0\nelement vertex {}\n", mesh.positions.len());
    header.push_str("property float x\nproperty float y\nproperty float z\n");
    if colors.is_some() {
        header.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    header.push_str(&format!("element face {}\nproperty list uchar int vertex_indices\nend_header\n", mesh.triangles.len()));
    w.write_all(header.as_bytes())?;
    let vstride = if colors.is_some() { 15 } else { 12 };
    let mut buf = Vec::with_capacity(vstride * mesh.positions.len().min(1 << 16));
    for (i, p) in mesh.positions.iter().enumerate() {
        for v in p {
            buf.extend_from_slice(&v.to_le_bytes());
        }
        if let Some(c) = colors {
            buf.extend_from_slice(&c[i]);
        }
        if buf.len() >= 1 << 20 {
            w.write_all(&buf)?;
            buf.clear();
        }
    }
    for t in &mesh.triangles {
        buf.push(3);
        for &v in t {
            buf.extend_from_slice(&(v as i32).to_le_bytes());
        }
        if buf.len() >= 1 << 20 {
            w.write_all(&buf)?;
            buf.clear();
        }
    }
    w.write_all(&buf)
}

/// Reads a mesh PLY from `path` (see the module docs for what is accepted).
pub fn read_mesh_ply(path: &Path) -> Result<TriangleMesh> {
    let bytes = read_file(path)?;
    parse_mesh_ply(&bytes, path)
}

/// How a vertex property is used.
#[derive(Clone, Copy)]
enum VertexUse {
    Position(usize),
    Color(usize),
    Skip,
}

/// Parses a mesh PLY held in memory; `path` only names the file in errors. This is the
/// function the fuzz target drives.
pub fn parse_mesh_ply(bytes: &[u8], path: &Path) -> Result<TriangleMesh> {
    let header = parse_header(bytes, path)?;
    let (_, vertex) = header.element("vertex").ok_or_else(|| IoError::format(path, "PLY has no 'vertex' element"))?;
    let mut uses = vec![VertexUse::Skip; vertex.properties.len()];
    for (k, axis) in ["x", "y", "z"].iter().enumerate() {
        let idx = vertex
            .property_index(axis)
            .ok_or_else(|| IoError::format(path, format!("vertex element lacks the property '{axis}'")))?;
        if !matches!(vertex.properties[idx].kind, PropertyKind::Scalar(_)) {
            return Err(IoError::format(path, format!("vertex property '{axis}' is a list, expected a scalar")));
        }
        uses[idx] = VertexUse::Position(k);
    }
    let color_idx: Vec<usize> = ["red", "green", "blue"]
        .iter()
        .filter_map(|c| vertex.property_index(c))
        .filter(|&i| matches!(vertex.properties[i].kind, PropertyKind::Scalar(_)))
        .collect();
    let has_colors = color_idx.len() == 3;
    if has_colors {
        for (k, &i) in color_idx.iter().enumerate() {
            uses[i] = VertexUse::Color(k);
        }
    }

    let face = header.element("face").map(|(_, e)| e);
    let face_list = match face {
        Some(f) => {
            let idx = f
                .property_index("vertex_indices")
                .or_else(|| f.property_index("vertex_index"))
                .ok_or_else(|| IoError::format(path, "face element lacks a 'vertex_indices' (or 'vertex_index') list"))?;
            match f.properties[idx].kind {
                PropertyKind::List { item, .. } if item.is_integer() => Some(idx),
                _ => {
                    return Err(IoError::format(
                        path,
                        format!("face property '{}' must be a list of integers", f.properties[idx].name),
                    ));
                }
            }
        }
        None => None,
    };

    let n = vertex.count;
    let mut positions = Vec::with_capacity(n);
    let mut colors = if has_colors { Some(Vec::with_capacity(n)) } else { None };
    let mut triangles = Vec::with_capacity(face.map_or(0, |f| f.count));
    let mut reader = DataReader::new(bytes, &header);
    for e in &header.elements {
        if e.name == "vertex" && std::ptr::eq(e, vertex) {
            for i in 0..n {
                let mut p = [0f32; 3];
                let mut c = [0u8; 3];
                for (prop, u) in e.properties.iter().zip(&uses) {
                    let r = match (*u, prop.kind) {
                        (VertexUse::Position(k), PropertyKind::Scalar(t)) => reader.read_f32(t).map(|v| p[k] = v),
                        (VertexUse::Color(k), PropertyKind::Scalar(t)) => reader.read_f64(t).map(|v| c[k] = to_u8(v, t)),
                        (_, kind) => reader.skip(kind),
                    };
                    r.map_err(|m| IoError::format(path, format!("vertex {i}, property '{}': {m}", prop.name)))?;
                }
                if let Some(k) = p.iter().position(|v| !v.is_finite()) {
                    return Err(IoError::format(path, format!("vertex {i}: coordinate {} is {}", ["x", "y", "z"][k], p[k])));
                }
                positions.push(p);
                if let Some(cs) = colors.as_mut() {
                    cs.push(c);
                }
            }
        } else if face.is_some_and(|f| std::ptr::eq(e, f)) {
            let list = face_list.unwrap_or(usize::MAX);
            let mut poly: Vec<u32> = Vec::with_capacity(8);
            for i in 0..e.count {
                for (j, prop) in e.properties.iter().enumerate() {
                    let r = match prop.kind {
                        PropertyKind::List { count, item } if j == list => {
                            read_polygon(&mut reader, count, item, n, &mut poly)
                        }
                        kind => reader.skip(kind),
                    };
                    r.map_err(|m| IoError::format(path, format!("face {i}, property '{}': {m}", prop.name)))?;
                }
                for k in 1..poly.len().saturating_sub(1) {
                    triangles.push([poly[0], poly[k], poly[k + 1]]);
                }
            }
        } else {
            reader.skip_element(e).map_err(|m| IoError::format(path, m))?;
        }
    }
    Ok(TriangleMesh { positions, triangles, colors })
}

/// Reads one face's index list into `poly`, checking length ≥ 3 and every index < `n`.
fn read_polygon(
    reader: &mut DataReader<'_>,
    count: ScalarType,
    item: ScalarType,
    n: usize,
    poly: &mut Vec<u32>,
) -> std::result::Result<(), String> {
    let len = reader.read_int(count)?;
    if len < 3 {
        return Err(format!("a face needs at least 3 vertices, this one has {len}"));
    }
    poly.clear();
    for _ in 0..len {
        let v = reader.read_int(item)?;
        if v < 0 || v as u64 >= n as u64 {
            return Err(format!("vertex index {v} is out of range (the mesh has {n} vertices)"));
        }
        poly.push(v as u32);
    }
    Ok(())
}

/// A colour component of type `t` as u8 (floats are in `[0, 1]`).
fn to_u8(v: f64, t: ScalarType) -> u8 {
    match t {
        ScalarType::F32 | ScalarType::F64 => (v.clamp(0.0, 1.0) * 255.0).round() as u8,
        _ => v.clamp(0.0, 255.0) as u8,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ascii_polygons_are_fan_triangulated() {
        let text = b"ply\nformat ascii 1.0\ncomment quad + pentagon\nelement vertex 6\nproperty double x\nproperty double y\nproperty double z\nproperty float red\nproperty float green\nproperty float blue\nproperty float alpha\nelement face 2\nproperty uchar flags\nproperty list uchar uint vertex_index\nend_header\n\
0 0 0 1 0 0 1\n1 0 0 0 1 0 1\n1 1 0 0 0 1 1\n0 1 0 0.5 0.5 0.5 1\n2 2 0 0 0 0 1\n3 3 0 1 1 1 1\n\
7 4 0 1 2 3\n0 5 0 1 4 5 2\n";
        let m = parse_mesh_ply(text, Path::new("q.ply")).unwrap();
        assert_eq!(m.positions.len(), 6);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 4], [0, 4, 5], [0, 5, 2]]);
        let c = m.colors.unwrap();
        assert_eq!(c[0], [255, 0, 0]);
        assert_eq!(c[3], [128, 128, 128]);
    }

    #[test]
    fn bad_faces_are_rejected() {
        let base = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n";
        for (face, expect) in [("3 0 1 3\n", "out of range"), ("2 0 1\n", "at least 3"), ("3 0 1 -1\n", "out of range"), ("3 0 1\n", "truncated")] {
            let text = format!("{base}{face}");
            let e = parse_mesh_ply(text.as_bytes(), Path::new("f.ply")).unwrap_err().to_string();
            assert!(e.contains(expect) && e.contains("face 0") && e.contains("f.ply"), "{e}");
        }
    }
}
