//! gs-export: a trained vagsl model and its mesh in the formats other tools open.
//!
//! | format | what | writer | reader |
//! | --- | --- | --- | --- |
//! | `ply` | Inria 3DGS PLY (lossless) | gs-io | gs-io |
//! | `splat` | antimatter15/splat 32-byte records | [`splat`] | [`splat`] |
//! | `spz` | Niantic spz version 3 (gzip) | [`spz`] | [`spz`] (versions 2, 3) |
//! | `compressed-ply` | PlayCanvas / SuperSplat compressed PLY | [`compressed_ply`] | [`compressed_ply`] |
//! | `mesh-ply` | binary PLY with vertex colours | gs-io | gs-io |
//! | `obj` | Wavefront OBJ with vertex colours | [`obj`] | gs-io (`tobj`) |
//! | `glb` | glTF 2.0 binary | [`glb`] (`gltf`) | [`glb`] (`gltf`) |
//!
//! Every writer is atomic (a temporary file in the same folder, then a rename): a failed export
//! leaves nothing behind and an existing file untouched. Each format module states its
//! quantisation bounds, which the tests assert on real data.
//!
//! ```
//! use gs_export::{Format, read_gaussians, write_gaussians};
//! let dir = tempfile::tempdir().unwrap();
//! let mut g = gs_core::Gaussians::with_len(3).unwrap();
//! g.means[1] = [0.5, -1.0, 2.0];
//! let path = dir.path().join("model.spz");
//! let format = Format::from_path(&path).unwrap(); // Format::Spz
//! write_gaussians(format, &path, &g, false).unwrap(); // trained without opacity compensation
//! let back = read_gaussians(format, &path).unwrap();
//! assert!((back.means[1][1] + 1.0).abs() < 1e-5);
//! ```

pub mod compressed_ply;
pub mod error;
pub mod glb;
pub mod obj;
pub mod quant;
pub mod splat;
pub mod spz;

pub use error::{ExportError, Result};
use gs_core::{Gaussians, TriangleMesh};
use std::path::Path;

/// An export format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Format {
    /// Inria 3DGS PLY.
    Ply,
    /// antimatter15/splat `.splat`.
    Splat,
    /// Niantic `.spz`.
    Spz,
    /// PlayCanvas / SuperSplat compressed PLY.
    CompressedPly,
    /// Mesh as binary PLY.
    MeshPly,
    /// Mesh as Wavefront OBJ.
    Obj,
    /// Mesh as glTF 2.0 binary.
    Glb,
}

impl Format {
    /// Every format, Gaussian formats first.
    pub const ALL: [Format; 7] =
        [Format::Ply, Format::Splat, Format::Spz, Format::CompressedPly, Format::MeshPly, Format::Obj, Format::Glb];

    /// The name used by `--format`.
    pub fn name(self) -> &'static str {
        match self {
            Format::Ply => "ply",
            Format::Splat => "splat",
            Format::Spz => "spz",
            Format::CompressedPly => "compressed-ply",
            Format::MeshPly => "mesh-ply",
            Format::Obj => "obj",
            Format::Glb => "glb",
        }
    }

    /// The format called `name` (see [`Format::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.name() == name)
    }

    /// Whether the format records that a model was trained with opacity compensation (the
    /// `antialiased` argument of [`write_gaussians`]): only spz has a field for it. Viewers of
    /// the other formats render every model with the original 3DGS projection.
    pub fn records_antialiasing(self) -> bool {
        self == Format::Spz
    }

    /// Whether the format holds a mesh (else Gaussians).
    pub fn is_mesh(self) -> bool {
        matches!(self, Format::MeshPly | Format::Obj | Format::Glb)
    }

    /// The format of a file name's extension (case-insensitive): `.splat`, `.spz`, `.obj`,
    /// `.glb`. A `.ply` may hold three formats, so it is refused with a message listing them, as
    /// is an unknown or missing extension.
    pub fn from_path(path: &Path) -> Result<Self> {
        let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
        let names = Self::ALL.map(Format::name).join(", ");
        let message = match ext.as_deref() {
            Some("splat") => return Ok(Format::Splat),
            Some("spz") => return Ok(Format::Spz),
            Some("obj") => return Ok(Format::Obj),
            Some("glb") => return Ok(Format::Glb),
            Some("ply") => "a .ply file can be a 3DGS model (ply), a compressed model (compressed-ply) or a mesh (mesh-ply): give --format".to_string(),
            Some(e) => format!("unknown extension '.{e}': use .splat, .spz, .obj or .glb, or give --format ({names})"),
            None => format!("no extension to tell the format from: give --format ({names})"),
        };
        Err(ExportError::UnknownFormat { path: path.to_path_buf(), message })
    }
}

impl std::fmt::Display for Format {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Fails, naming the file, when `format` is a mesh format.
fn gaussian_format(format: Format, path: &Path) -> Result<()> {
    if format.is_mesh() {
        return Err(ExportError::unencodable(path, format.name(), "it is a mesh format, and Gaussians were given"));
    }
    Ok(())
}

/// Writes `g` at `path` in the Gaussian format `format`, atomically. `antialiased`: the model
/// was trained with Mip-Splatting's opacity compensation (docs/method.md §Projection), recorded
/// where the format can say so ([`Format::records_antialiasing`]). Fails, writing nothing, on
/// a model that does not validate or that the format cannot hold.
pub fn write_gaussians(format: Format, path: &Path, g: &Gaussians, antialiased: bool) -> Result<()> {
    gaussian_format(format, path)?;
    g.validate().map_err(|source| gs_io::IoError::Core { path: path.to_path_buf(), source })?;
    let bytes = match format {
        Format::Ply => return Ok(gs_io::write_gaussian_ply(path, g)?),
        Format::Splat => splat::encode_splat(g, path)?,
        Format::Spz => spz::encode_spz(g, antialiased, path)?,
        _ => compressed_ply::encode_compressed_ply(g),
    };
    Ok(gs_io::write_atomic(path, |w| w.write_all(&bytes))?)
}

/// Reads Gaussians in `format` from `path`.
pub fn read_gaussians(format: Format, path: &Path) -> Result<Gaussians> {
    gaussian_format(format, path)?;
    if format == Format::Ply {
        return Ok(gs_io::read_gaussian_ply(path)?);
    }
    let bytes = std::fs::read(path).map_err(|e| gs_io::IoError::io(path, e))?;
    match format {
        Format::Splat => splat::decode_splat(&bytes, path),
        Format::Spz => spz::decode_spz(&bytes, path).map(|(g, _)| g),
        _ => compressed_ply::decode_compressed_ply(&bytes, path),
    }
}

/// The position in `format`'s file of each Gaussian of `g`: `order[k]` is the index in `g` of
/// the `k`-th Gaussian written (the identity for `ply` and `spz`).
pub fn write_order(format: Format, g: &Gaussians) -> Vec<usize> {
    match format {
        Format::Splat => splat::splat_order(g),
        Format::CompressedPly => compressed_ply::morton_order(g),
        _ => (0..g.len()).collect(),
    }
}

/// Writes `mesh` at `path` in the mesh format `format`, atomically.
pub fn write_mesh(format: Format, path: &Path, mesh: &TriangleMesh) -> Result<()> {
    match format {
        Format::MeshPly => Ok(gs_io::write_mesh_ply(path, mesh)?),
        Format::Obj => obj::write_obj(path, mesh),
        Format::Glb => {
            mesh.validate().map_err(|source| gs_io::IoError::Core { path: path.to_path_buf(), source })?;
            let bytes = glb::encode_glb(mesh, path)?;
            Ok(gs_io::write_atomic(path, |w| w.write_all(&bytes))?)
        }
        _ => Err(ExportError::unencodable(path, format.name(), "it is a Gaussian format, and a mesh was given")),
    }
}

/// Reads a mesh in `format` from `path`.
pub fn read_mesh(format: Format, path: &Path) -> Result<TriangleMesh> {
    match format {
        Format::MeshPly => Ok(gs_io::read_mesh_ply(path)?),
        Format::Obj => Ok(gs_io::read_obj(path)?),
        Format::Glb => {
            let bytes = std::fs::read(path).map_err(|e| gs_io::IoError::io(path, e))?;
            glb::decode_glb(&bytes, path)
        }
        _ => Err(ExportError::unsupported(path, format!("{} holds Gaussians, not a mesh", format.name()))),
    }
}
