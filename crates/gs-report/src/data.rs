//! What the page's viewer draws, packed for WebGL2 textures and buffers: the splats
//! ([`SplatData`]), the mesh ([`MeshData`]) and the scene's cameras ([`CameraData`]).
//! Binary arrays travel as base64 little-endian f32 / u32 inside `report/data.js`.

use crate::error::{ReportError, Result};
use base64::Engine;
use gs_core::{Camera, Gaussians, TriangleMesh};
use serde::Serialize;
use std::collections::HashMap;

/// Texels per row of the viewer's data textures (WebGL2 guarantees 2048; every browser we
/// target gives at least 8192 rows of 4096).
pub const TEXTURE_WIDTH: usize = 4096;
/// The most texture rows the page relies on (WebGL2's guaranteed minimum of MAX_TEXTURE_SIZE
/// is 2048; 8192 holds on every desktop GPU and on SwiftShader).
pub const TEXTURE_ROWS: usize = 8192;
/// Geometry floats per Gaussian: mean (3), opacity (1), covariance Σ upper triangle (6), 2 pad.
pub const GEO_FLOATS: usize = 12;
/// Meshes above this many triangles are simplified for the page (vertex clustering); the
/// mesh file itself is untouched.
pub const MAX_MESH_TRIANGLES: usize = 2_000_000;

fn b64_f32(v: &[f32]) -> String {
    let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

fn b64_u32(v: &[u32]) -> String {
    let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

/// The splats as the viewer reads them: per Gaussian the mean, activated opacity and world
/// covariance Σ = R S Sᵀ Rᵀ (docs/method.md §Rendering), and the SH coefficients up to the model's degree.
#[derive(Debug, Clone, Serialize)]
pub struct SplatData {
    /// Number of Gaussians.
    pub count: usize,
    /// SH degree used for colour (0–3).
    pub sh_degree: u32,
    /// SH coefficients per colour channel, `(degree + 1)²`.
    pub sh_coeffs: usize,
    /// `count × GEO_FLOATS` f32, base64.
    pub geo: String,
    /// `count × 4⌈3K/4⌉` f32 (coefficient-major RGB triples, padded to whole texels), base64.
    pub sh: String,
    /// How the run projects its splats (its own `RasterConfig`), so the page draws what
    /// `vagsl render` draws (docs/method.md §Projection).
    pub projection: Projection,
}

/// The projection settings of a run that the viewer's shader applies.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Projection {
    /// Near plane: splats with camera z ≤ near are culled.
    pub near: f32,
    /// Screen-space low-pass filter added to Σ' (px²).
    pub low_pass: f32,
    /// Mip-Splatting's opacity compensation √(det Σ'_raw / det Σ'), floored at `min_compensation`.
    pub antialiased: bool,
    /// Floor of the compensation (`gs_raster::MIN_COMPENSATION`).
    pub min_compensation: f32,
    /// t_x/t_z and t_y/t_z are clamped to ±this·tan(fov/2) (`gs_raster::JACOBIAN_CLAMP`).
    pub jacobian_clamp: f32,
}

impl From<&gs_raster::RasterConfig> for Projection {
    fn from(c: &gs_raster::RasterConfig) -> Self {
        Self {
            near: c.near,
            low_pass: c.low_pass,
            antialiased: c.antialiased,
            min_compensation: gs_raster::MIN_COMPENSATION,
            jacobian_clamp: gs_raster::JACOBIAN_CLAMP,
        }
    }
}

impl SplatData {
    /// Packs `g`, drawn as `raster` projects it, for the viewer; refuses a model too large for
    /// the page's textures.
    pub fn from_gaussians(g: &Gaussians, raster: &gs_raster::RasterConfig) -> Result<Self> {
        let k = gs_core::sh::coeffs_for_degree(g.sh_degree);
        let sh_floats = (3 * k).div_ceil(4) * 4;
        let texels = g.len() * (GEO_FLOATS / 4).max(sh_floats / 4);
        if texels > TEXTURE_WIDTH * TEXTURE_ROWS {
            return Err(ReportError::Invalid(format!(
                "{} Gaussians at SH degree {} do not fit the viewer's textures ({} texels at most); the page can show at most {} Gaussians",
                g.len(),
                g.sh_degree,
                TEXTURE_WIDTH * TEXTURE_ROWS,
                TEXTURE_WIDTH * TEXTURE_ROWS / (sh_floats / 4).max(GEO_FLOATS / 4)
            )));
        }
        let mut geo = Vec::with_capacity(g.len() * GEO_FLOATS);
        let mut sh = Vec::with_capacity(g.len() * sh_floats);
        for i in 0..g.len() {
            let c = g.covariance(i);
            geo.extend_from_slice(&g.means[i]);
            geo.push(g.opacity(i));
            geo.extend_from_slice(&[c.x_axis.x, c.y_axis.x, c.z_axis.x, c.y_axis.y, c.z_axis.y, c.z_axis.z, 0.0, 0.0]);
            let start = sh.len();
            sh.extend(g.sh[i][..k].iter().flatten());
            sh.resize(start + sh_floats, 0.0);
        }
        Ok(Self {
            count: g.len(),
            sh_degree: g.sh_degree,
            sh_coeffs: k,
            geo: b64_f32(&geo),
            sh: b64_f32(&sh),
            projection: Projection::from(raster),
        })
    }
}

/// A mesh for the viewer: positions, area-weighted vertex normals and triangles.
#[derive(Debug, Clone, Serialize)]
pub struct MeshData {
    /// Vertices.
    pub vertices: usize,
    /// Triangles.
    pub triangles: usize,
    /// Triangles of the mesh file (more than `triangles` when it was simplified for the page).
    pub source_triangles: usize,
    /// `vertices × 3` f32, base64.
    pub positions: String,
    /// `vertices × 3` f32, base64.
    pub normals: String,
    /// `triangles × 3` u32, base64.
    pub indices: String,
}

impl MeshData {
    /// Packs `mesh` for the viewer, simplified by vertex clustering when it has more than
    /// `MAX_MESH_TRIANGLES` triangles (a browser draws a few million smoothly).
    pub fn from_mesh(mesh: &TriangleMesh) -> Result<Self> {
        mesh.validate().map_err(|e| ReportError::Invalid(format!("the mesh cannot be shown: {e}")))?;
        let source_triangles = mesh.triangles.len();
        let simplified;
        let m = if source_triangles > MAX_MESH_TRIANGLES {
            simplified = simplify(mesh, MAX_MESH_TRIANGLES);
            &simplified
        } else {
            mesh
        };
        let normals = vertex_normals(m);
        let positions: Vec<f32> = m.positions.iter().flatten().copied().collect();
        let indices: Vec<u32> = m.triangles.iter().flatten().copied().collect();
        Ok(Self {
            vertices: m.positions.len(),
            triangles: m.triangles.len(),
            source_triangles,
            positions: b64_f32(&positions),
            normals: b64_f32(&normals.iter().flatten().copied().collect::<Vec<_>>()),
            indices: b64_u32(&indices),
        })
    }
}

/// Area-weighted vertex normals (unit length; zero for isolated vertices).
fn vertex_normals(m: &TriangleMesh) -> Vec<[f32; 3]> {
    let mut n = vec![[0.0f64; 3]; m.positions.len()];
    for t in &m.triangles {
        let p = t.map(|i| m.positions[i as usize].map(f64::from));
        let (a, b) = ([0, 1, 2].map(|k| p[1][k] - p[0][k]), [0, 1, 2].map(|k| p[2][k] - p[0][k]));
        let c = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
        for &i in t {
            (0..3).for_each(|k| n[i as usize][k] += c[k]);
        }
    }
    n.iter()
        .map(|v| {
            let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if l > 0.0 { v.map(|x| (x / l) as f32) } else { [0.0; 3] }
        })
        .collect()
}

/// Vertex clustering on a grid whose cell doubles until at most `max_triangles` remain: each
/// cell's vertices merge into their mean, and triangles that collapse are dropped.
fn simplify(mesh: &TriangleMesh, max_triangles: usize) -> TriangleMesh {
    let (lo, hi) = mesh.bounds().unwrap_or(([0.0; 3], [1.0; 3]));
    let diag = ((0..3).map(|k| ((hi[k] - lo[k]) as f64).powi(2)).sum::<f64>()).sqrt().max(1e-12);
    let mut cell = diag / 2048.0;
    loop {
        let mut ids: HashMap<[i64; 3], u32> = HashMap::new();
        let mut sums: Vec<([f64; 3], u32)> = Vec::new();
        let remap: Vec<u32> = mesh
            .positions
            .iter()
            .map(|p| {
                let key = [0, 1, 2].map(|k| ((p[k] - lo[k]) as f64 / cell).floor() as i64);
                let id = *ids.entry(key).or_insert_with(|| {
                    sums.push(([0.0; 3], 0));
                    (sums.len() - 1) as u32
                });
                let s = &mut sums[id as usize];
                (0..3).for_each(|k| s.0[k] += p[k] as f64);
                s.1 += 1;
                id
            })
            .collect();
        let triangles: Vec<[u32; 3]> = mesh
            .triangles
            .iter()
            .map(|t| t.map(|i| remap[i as usize]))
            .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
            .collect();
        if triangles.len() <= max_triangles {
            let positions = sums.iter().map(|(s, n)| s.map(|x| (x / *n as f64) as f32)).collect();
            return TriangleMesh { positions, triangles, colors: None };
        }
        cell *= 2.0;
    }
}

/// One scene camera as the viewer uses it: a pinhole with the photo's intrinsics and the
/// world-to-camera pose x_c = R x_w + t (COLMAP convention: x right, y down, z forward).
#[derive(Debug, Clone, Serialize)]
pub struct CameraData {
    /// Image name.
    pub name: String,
    /// `train` or `test`.
    pub split: &'static str,
    /// Image width, px.
    pub width: u32,
    /// Image height, px.
    pub height: u32,
    /// Focal lengths and principal point, px.
    pub fx: f64,
    /// See `fx`.
    pub fy: f64,
    /// See `fx`.
    pub cx: f64,
    /// See `fx`.
    pub cy: f64,
    /// R, row-major.
    pub r: [f64; 9],
    /// t.
    pub t: [f64; 3],
}

impl CameraData {
    /// The camera of view `name` in split `split`.
    pub fn new(name: &str, split: &'static str, camera: &Camera) -> Self {
        let k = &camera.intrinsics;
        let r = camera.rotation;
        Self {
            name: name.to_string(),
            split,
            width: camera.width,
            height: camera.height,
            fx: k.fx,
            fy: k.fy,
            cx: k.cx,
            cy: k.cy,
            r: [r.x_axis.x, r.y_axis.x, r.z_axis.x, r.x_axis.y, r.y_axis.y, r.z_axis.y, r.x_axis.z, r.y_axis.z, r.z_axis.z],
            t: camera.translation.to_array(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode_f32(s: &str) -> Vec<f32> {
        let b = base64::engine::general_purpose::STANDARD.decode(s).unwrap();
        b.chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect()
    }

    #[test]
    fn splats_pack_mean_opacity_covariance_and_sh() {
        let mut g = Gaussians::default();
        let mut sh = [[0.0f32; 3]; 16];
        sh[0] = [0.1, 0.2, 0.3];
        sh[3] = [0.4, 0.5, 0.6];
        g.push([1.0, 2.0, 3.0], [0.0, (2.0f32).ln(), (3.0f32).ln()], [1.0, 0.0, 0.0, 0.0], 0.0, sh);
        g.sh_degree = 1;
        let d = SplatData::from_gaussians(&g, &gs_raster::RasterConfig::default()).unwrap();
        assert_eq!((d.count, d.sh_coeffs), (1, 4));
        let geo = decode_f32(&d.geo);
        assert_eq!(&geo[..4], &[1.0, 2.0, 3.0, 0.5]);
        // Σ = diag(1, 4, 9) for the identity rotation.
        let want = [1.0, 0.0, 0.0, 4.0, 0.0, 9.0];
        geo[4..10].iter().zip(want).for_each(|(a, b)| assert!((a - b).abs() < 1e-5, "{a} vs {b}"));
        let shd = decode_f32(&d.sh);
        assert_eq!(shd.len(), 12);
        assert_eq!(&shd[..3], &[0.1, 0.2, 0.3]);
        assert_eq!(&shd[9..12], &[0.4, 0.5, 0.6]);
        // The page draws with the run's projection, not the rasterizer's defaults.
        let mip = gs_raster::RasterConfig { antialiased: true, low_pass: 0.1, near: 0.2, ..Default::default() };
        let p = serde_json::to_value(SplatData::from_gaussians(&g, &mip).unwrap()).unwrap()["projection"].clone();
        assert_eq!((p["antialiased"].as_bool(), p["low_pass"].as_f64(), p["near"].as_f64()), (Some(true), Some(0.1f32 as f64), Some(0.2f32 as f64)));
        assert_eq!(p["min_compensation"].as_f64(), Some(gs_raster::MIN_COMPENSATION as f64));
    }

    #[test]
    fn a_large_mesh_is_clustered_below_the_cap_and_keeps_its_extent() {
        let n = 60usize;
        let mut m = TriangleMesh::default();
        for y in 0..=n {
            for x in 0..=n {
                m.positions.push([x as f32 / n as f32, y as f32 / n as f32, 0.0]);
            }
        }
        let id = |x: usize, y: usize| (y * (n + 1) + x) as u32;
        for y in 0..n {
            for x in 0..n {
                m.triangles.push([id(x, y), id(x + 1, y), id(x + 1, y + 1)]);
                m.triangles.push([id(x, y), id(x + 1, y + 1), id(x, y + 1)]);
            }
        }
        let s = simplify(&m, 2000);
        assert!(s.triangles.len() <= 2000 && s.triangles.len() > 200, "{}", s.triangles.len());
        let (lo, hi) = s.bounds().unwrap();
        assert!(lo[0] < 0.05 && hi[0] > 0.95, "{lo:?} {hi:?}");
        let normals = vertex_normals(&s);
        assert!(normals.iter().filter(|v| v[2].abs() > 0.99).count() > normals.len() / 2);
    }
}
