//! glTF 2.0 binary (`.glb`) for a [`TriangleMesh`], through the `gltf` crate (its `gltf-json`
//! types write the JSON chunk, its GLB container writes the file, its reader reads one back).
//!
//! One scene, one node, one mesh with one indexed triangle primitive: `POSITION` (f32 VEC3,
//! with the `min`/`max` glTF requires), `COLOR_0` when the mesh has colours (f32 VEC3; glTF
//! vertex colours are linear, so the mesh's sRGB bytes are converted and converted back on
//! reading, exactly), indices as u32. No normals (viewers shade flat) and no material (the
//! default material shows the vertex colours). Positions are vagsl's world coordinates as they
//! are: glTF's "+Y up" is not imposed on a world whose up axis vagsl does not know.
//!
//! The reader merges the triangle primitives of every mesh in the file (node transforms are not
//! applied) and keeps colours only when every primitive has them.

use crate::error::{ExportError, Result};
use crate::quant::{linear_to_srgb, srgb_to_linear};
use gltf::json;
use gltf::json::validation::{Checked::Valid, USize64};
use gs_core::TriangleMesh;
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::Path;

/// A bufferView of `len` bytes at `offset` of buffer 0.
fn view(offset: usize, len: usize, target: json::buffer::Target) -> json::buffer::View {
    json::buffer::View {
        buffer: json::Index::new(0),
        byte_length: USize64::from(len),
        byte_offset: Some(USize64::from(offset)),
        byte_stride: None,
        name: None,
        target: Some(Valid(target)),
        extensions: None,
        extras: Default::default(),
    }
}

/// An accessor over the whole of bufferView `view`.
fn accessor(view: u32, count: usize, ty: json::accessor::Type, ct: json::accessor::ComponentType) -> json::Accessor {
    json::Accessor {
        buffer_view: Some(json::Index::new(view)),
        byte_offset: None,
        count: USize64::from(count),
        component_type: Valid(json::accessor::GenericComponentType(ct)),
        extensions: None,
        extras: Default::default(),
        type_: Valid(ty),
        min: None,
        max: None,
        name: None,
        normalized: false,
        sparse: None,
    }
}

/// Encodes `mesh` as GLB bytes; `path` only names the file in errors.
pub fn encode_glb(mesh: &TriangleMesh, path: &Path) -> Result<Vec<u8>> {
    use json::accessor::{ComponentType, Type};
    use json::buffer::Target;
    let n = mesh.positions.len();
    let Some((lo, hi)) = mesh.bounds().filter(|_| !mesh.triangles.is_empty()) else {
        return Err(ExportError::unencodable(path, "glb", "the mesh has no triangles (a glTF accessor needs at least one element)"));
    };
    let colors = mesh.colors.as_ref().filter(|c| c.len() == n);
    let mut bin: Vec<u8> = Vec::with_capacity(12 * n * 2 + 12 * mesh.triangles.len());
    mesh.positions.iter().flatten().for_each(|v| bin.extend_from_slice(&v.to_le_bytes()));
    let color_offset = bin.len();
    if let Some(c) = colors {
        c.iter().flatten().for_each(|&v| bin.extend_from_slice(&srgb_to_linear(v).to_le_bytes()));
    }
    let index_offset = bin.len();
    mesh.triangles.iter().flatten().for_each(|v| bin.extend_from_slice(&v.to_le_bytes()));
    if bin.len() > u32::MAX as usize - 1024 {
        return Err(ExportError::unencodable(path, "glb", "the mesh needs more than the 4 GiB a GLB file can hold"));
    }

    let mut root = json::Root::default();
    root.asset.generator = Some("vagsl".into());
    root.buffers.push(json::Buffer { byte_length: USize64::from(bin.len()), name: None, uri: None, extensions: None, extras: Default::default() });
    root.buffer_views.push(view(0, color_offset, Target::ArrayBuffer));
    let mut pos = accessor(0, n, Type::Vec3, ComponentType::F32);
    pos.min = Some(json::Value::from(lo.to_vec()));
    pos.max = Some(json::Value::from(hi.to_vec()));
    root.accessors.push(pos);
    let mut attributes = BTreeMap::new();
    attributes.insert(Valid(json::mesh::Semantic::Positions), json::Index::new(0));
    if colors.is_some() {
        root.buffer_views.push(view(color_offset, index_offset - color_offset, Target::ArrayBuffer));
        root.accessors.push(accessor(1, n, Type::Vec3, ComponentType::F32));
        attributes.insert(Valid(json::mesh::Semantic::Colors(0)), json::Index::new(1));
    }
    let k = root.buffer_views.len() as u32;
    root.buffer_views.push(view(index_offset, bin.len() - index_offset, Target::ElementArrayBuffer));
    root.accessors.push(accessor(k, 3 * mesh.triangles.len(), Type::Scalar, ComponentType::U32));
    let primitive = json::mesh::Primitive {
        attributes,
        extensions: None,
        extras: Default::default(),
        indices: Some(json::Index::new(k)),
        material: None,
        mode: Valid(json::mesh::Mode::Triangles),
        targets: None,
    };
    root.meshes.push(json::Mesh { extensions: None, extras: Default::default(), name: Some("mesh".into()), primitives: vec![primitive], weights: None });
    root.nodes.push(json::Node { mesh: Some(json::Index::new(0)), ..Default::default() });
    root.scenes.push(json::Scene { extensions: None, extras: Default::default(), name: None, nodes: vec![json::Index::new(0)] });
    root.scene = Some(json::Index::new(0));

    let text = root.to_vec().map_err(|e| ExportError::unencodable(path, "glb", format!("cannot serialise the glTF JSON: {e}")))?;
    let glb = gltf::binary::Glb {
        header: gltf::binary::Header { magic: *b"glTF", version: 2, length: 0 },
        json: Cow::Owned(text),
        bin: Some(Cow::Owned(bin)),
    };
    glb.to_vec().map_err(|e| ExportError::unencodable(path, "glb", format!("cannot assemble the GLB container: {e}")))
}

/// Decodes GLB bytes into one mesh (see the module docs); `path` only names the file.
pub fn decode_glb(bytes: &[u8], path: &Path) -> Result<TriangleMesh> {
    let gltf = gltf::Gltf::from_slice(bytes).map_err(|e| ExportError::format(path, format!("not a valid glTF binary: {e}")))?;
    let blob = gltf.blob.as_deref();
    let mut mesh = TriangleMesh::default();
    let mut colors: Option<Vec<[u8; 3]>> = Some(Vec::new());
    for m in gltf.meshes() {
        for p in m.primitives() {
            if p.mode() != gltf::mesh::Mode::Triangles {
                return Err(ExportError::unsupported(path, format!("mesh {} has a primitive of mode {:?}; only triangles are read", m.index(), p.mode())));
            }
            let reader = p.reader(|b| if b.index() == 0 { blob } else { None });
            let bad = |what: &str| ExportError::format(path, format!("mesh {}: {what} cannot be read (missing, external or out of the binary chunk)", m.index()));
            let base = mesh.positions.len();
            let positions: Vec<[f32; 3]> = reader.read_positions().ok_or_else(|| bad("POSITION"))?.collect();
            let nv = positions.len();
            if let Some(i) = positions.iter().position(|p| !p.iter().all(|v| v.is_finite())) {
                return Err(ExportError::format(path, format!("mesh {}: vertex {i} is not finite", m.index())));
            }
            mesh.positions.extend(positions);
            let indices: Vec<u32> = match reader.read_indices() {
                Some(ix) => ix.into_u32().collect(),
                None => (0..nv as u32).collect(),
            };
            if indices.len() % 3 != 0 {
                return Err(ExportError::format(path, format!("mesh {}: {} indices is not a whole number of triangles", m.index(), indices.len())));
            }
            for t in indices.chunks_exact(3) {
                if let Some(&v) = t.iter().find(|&&v| v as usize >= nv) {
                    return Err(ExportError::format(path, format!("mesh {}: index {v} is out of range ({nv} vertices)", m.index())));
                }
                let off = |v: u32| u32::try_from(base + v as usize).map_err(|_| ExportError::format(path, "more than 2^32 vertices"));
                mesh.triangles.push([off(t[0])?, off(t[1])?, off(t[2])?]);
            }
            match (colors.as_mut(), reader.read_colors(0)) {
                (Some(cs), Some(c)) => cs.extend(c.into_rgb_f32().map(|c| c.map(linear_to_srgb))),
                _ => colors = None,
            }
        }
    }
    mesh.colors = colors.filter(|c| !c.is_empty() && c.len() == mesh.positions.len());
    Ok(mesh)
}
