//! PlayCanvas / SuperSplat compressed PLY, as `splat-transform`'s `write-compressed-ply.ts` and
//! `compressed-chunk.ts` write it and its `decompress-ply.ts` reads it.
//!
//! Gaussians are sorted in Morton order (so a chunk is spatially compact) and cut into chunks of
//! 256. `element chunk` holds 18 floats per chunk: position, log-scale and colour bounds
//! (`min_x … max_b`; log-scale bounds clamped to [−20, 20]). `element vertex` holds four `uint`
//! per Gaussian: `packed_position` and `packed_scale` (11-10-11 bits, each value normalised
//! into its chunk's [min, max]), `packed_rotation` (2 bits for the largest component's index,
//! then the other three as `v·√2/2 + 0.5` in 10 bits, quaternion in PLY order `rot_0..3`, largest
//! made positive), `packed_color` (8-8-8-8: `0.5 + SH_C0·f_dc` normalised into the chunk's
//! colour bounds, then `sigmoid(opacity)`). With SH degree > 0, `element sh` holds the `f_rest`
//! coefficients of that degree as `uchar` (`trunc((v/8 + 0.5)·256)`, clamped), in the Inria
//! channel-major order. Values are rounded as `floor(v·(2^bits − 1) + 0.5)`.
//!
//! Round-trip bounds (asserted in the tests): positions and log-scales within
//! `(max − min)/(2·2047)` (x, z) or `(max − min)/(2·1023)` (y) of their chunk's range; colour
//! (`0.5 + SH_C0·f_dc`) within `(max − min)/510`; opacity within 0.5/255; quaternion components
//! within √2/2046 (+ the recomputed largest one, and up to sign); SH within 1/32 on [−4, 4].
//! The reader also accepts the older 12-float chunks without colour bounds.

use crate::error::{ExportError, Result};
use crate::quant::{f32_at, u32_at};
use gs_core::Gaussians;
use gs_core::gaussians::{MAX_GAUSSIANS, inverse_sigmoid, unit_quaternion};
use gs_core::sh::{MAX_SH_DEGREE, SH_C0, SH_COEFFS};
use gs_io::ply::{PlyEncoding, PlyHeader, PropertyKind, ScalarType, parse_header};
use std::path::Path;

/// Gaussians per chunk.
pub const CHUNK: usize = 256;
/// Chunk properties, in file order.
pub const CHUNK_PROPS: [&str; 18] = [
    "min_x", "min_y", "min_z", "max_x", "max_y", "max_z", "min_scale_x", "min_scale_y", "min_scale_z", "max_scale_x",
    "max_scale_y", "max_scale_z", "min_r", "min_g", "min_b", "max_r", "max_g", "max_b",
];
/// Vertex properties, in file order.
pub const VERTEX_PROPS: [&str; 4] = ["packed_position", "packed_rotation", "packed_scale", "packed_color"];

/// The order the writer stores the Gaussians in: by 30-bit Morton code of the position in the
/// model's bounding box (10 bits per axis), ties by index.
pub fn morton_order(g: &Gaussians) -> Vec<usize> {
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for p in &g.means {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let spread = |v: u32| -> u64 {
        (0..10).fold(0u64, |acc, b| acc | ((((v >> b) & 1) as u64) << (3 * b)))
    };
    let code: Vec<u64> = g
        .means
        .iter()
        .map(|p| {
            let q = |k: usize| {
                let r = hi[k] - lo[k];
                if r > 0.0 { (((p[k] - lo[k]) / r) * 1023.0).clamp(0.0, 1023.0) as u32 } else { 0 }
            };
            spread(q(0)) << 2 | spread(q(1)) << 1 | spread(q(2))
        })
        .collect();
    let mut order: Vec<usize> = (0..g.len()).collect();
    order.sort_by(|&a, &b| code[a].cmp(&code[b]).then(a.cmp(&b)));
    order
}

/// `packUnorm`: `floor(v·(2^bits − 1) + 0.5)` clamped.
fn pack_unorm(v: f64, bits: u32) -> u32 {
    let t = ((1u32 << bits) - 1) as f64;
    (v * t + 0.5).floor().clamp(0.0, t) as u32
}

/// `normalize`: `v` in `[min, max]` as `[0, 1]` (0 for a range under 1e-5).
fn normalize(v: f64, min: f64, max: f64) -> f64 {
    if v <= min {
        0.0
    } else if v >= max {
        1.0
    } else if max - min < 1e-5 {
        0.0
    } else {
        (v - min) / (max - min)
    }
}

fn pack_11_10_11(v: [f64; 3]) -> u32 {
    pack_unorm(v[0], 11) << 21 | pack_unorm(v[1], 10) << 11 | pack_unorm(v[2], 11)
}

/// `packRot` on the quaternion in PLY order.
fn pack_rotation(q: [f32; 4]) -> u32 {
    let mut a = unit_quaternion(q).map(|v| v as f64);
    let largest = (1..4).fold(0, |m, i| if a[i].abs() > a[m].abs() { i } else { m });
    if a[largest] < 0.0 {
        a = a.map(|v| -v);
    }
    let norm = std::f64::consts::SQRT_2 * 0.5;
    (0..4).filter(|&i| i != largest).fold(largest as u32, |r, i| (r << 10) | pack_unorm(a[i] * norm + 0.5, 10))
}

/// Per-chunk bounds of the values `f(i)` for the chunk's members.
fn bounds(members: &[usize], f: impl Fn(usize) -> [f32; 3]) -> ([f32; 3], [f32; 3]) {
    members.iter().fold(([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]), |(mut lo, mut hi), &i| {
        let v = f(i);
        for k in 0..3 {
            lo[k] = lo[k].min(v[k]);
            hi[k] = hi[k].max(v[k]);
        }
        (lo, hi)
    })
}

/// The colour `0.5 + SH_C0·f_dc` of Gaussian `i`, rounded to f32 as the reference stores it.
fn color(g: &Gaussians, i: usize) -> [f32; 3] {
    g.sh[i][0].map(|c| c * SH_C0 + 0.5)
}

/// Encodes `g` as a compressed PLY.
pub fn encode_compressed_ply(g: &Gaussians) -> Vec<u8> {
    let n = g.len();
    let degree = g.sh_degree.min(MAX_SH_DEGREE) as usize;
    let rest = (degree + 1) * (degree + 1) - 1;
    let chunks = n.div_ceil(CHUNK);
    let mut header = String::from("ply\nformat binary_little_endian 1.0\ncomment Generated by vagsl (PlayCanvas compressed PLY)\n");
    header.push_str(&format!("element chunk {chunks}\n"));
    CHUNK_PROPS.iter().for_each(|p| header.push_str(&format!("property float {p}\n")));
    header.push_str(&format!("element vertex {n}\n"));
    VERTEX_PROPS.iter().for_each(|p| header.push_str(&format!("property uint {p}\n")));
    if rest > 0 {
        header.push_str(&format!("element sh {n}\n"));
        (0..3 * rest).for_each(|k| header.push_str(&format!("property uchar f_rest_{k}\n")));
    }
    header.push_str("end_header\n");
    let mut out = header.into_bytes();
    let order = morton_order(g);
    let mut packed = Vec::with_capacity(16 * n);
    for members in order.chunks(CHUNK) {
        let (plo, phi) = bounds(members, |i| g.means[i]);
        let (mut slo, mut shi) = bounds(members, |i| g.log_scales[i]);
        slo = slo.map(|v| v.clamp(-20.0, 20.0));
        shi = shi.map(|v| v.clamp(-20.0, 20.0));
        let (clo, chi) = bounds(members, |i| color(g, i));
        for v in plo.iter().chain(&phi).chain(&slo).chain(&shi).chain(&clo).chain(&chi) {
            out.extend_from_slice(&v.to_le_bytes());
        }
        let norm3 = |v: [f32; 3], lo: [f32; 3], hi: [f32; 3]| {
            [0, 1, 2].map(|k| normalize(v[k] as f64, lo[k] as f64, hi[k] as f64))
        };
        for &i in members {
            let c = norm3(color(g, i), clo, chi);
            let words = [
                pack_11_10_11(norm3(g.means[i], plo, phi)),
                pack_rotation(g.rotations[i]),
                pack_11_10_11(norm3(g.log_scales[i], slo, shi)),
                pack_unorm(c[0], 8) << 24
                    | pack_unorm(c[1], 8) << 16
                    | pack_unorm(c[2], 8) << 8
                    | pack_unorm(g.opacity(i) as f64, 8),
            ];
            words.iter().for_each(|w| packed.extend_from_slice(&w.to_le_bytes()));
        }
    }
    out.extend_from_slice(&packed);
    for &i in &order {
        for c in 0..3 {
            for k in 1..=rest {
                let v = g.sh[i][k][c] / 8.0 + 0.5;
                out.push(if v.is_nan() { 128 } else { (v * 256.0).trunc().clamp(0.0, 255.0) as u8 });
            }
        }
    }
    out
}

/// Where one element's records lie in the file.
struct Table<'a> {
    data: &'a [u8],
    stride: usize,
    /// Byte offset inside a record of each requested property.
    offsets: Vec<usize>,
}

/// The records of element `name` with the requested scalar properties of type `ty`.
fn table<'a>(bytes: &'a [u8], h: &PlyHeader, name: &str, props: &[String], ty: ScalarType, path: &Path) -> Result<Option<Table<'a>>> {
    let mut start = h.data_offset;
    for e in &h.elements {
        let stride = e.fixed_stride().ok_or_else(|| ExportError::format(path, format!("element '{}' has a list property", e.name)))?;
        let len = stride.checked_mul(e.count).filter(|l| start + l <= bytes.len());
        let len = len.ok_or_else(|| ExportError::format(path, format!("the file ends inside element '{}' (truncated)", e.name)))?;
        if e.name == name {
            let mut offsets = Vec::with_capacity(props.len());
            for p in props {
                let k = e.property_index(p).ok_or_else(|| ExportError::format(path, format!("element '{name}' lacks the property '{p}'")))?;
                if e.properties[k].kind != PropertyKind::Scalar(ty) {
                    return Err(ExportError::format(path, format!("property '{p}' of '{name}' is not '{}'", ty.name())));
                }
                offsets.push(e.properties[..k].iter().map(|q| if let PropertyKind::Scalar(t) = q.kind { t.size() } else { 0 }).sum());
            }
            return Ok(Some(Table { data: &bytes[start..start + len], stride, offsets }));
        }
        start += len;
    }
    Ok(None)
}

fn strings<const N: usize>(names: [&str; N]) -> Vec<String> {
    names.iter().map(|s| s.to_string()).collect()
}

fn lerp(lo: f32, hi: f32, t: f64) -> f32 {
    (lo as f64 * (1.0 - t) + hi as f64 * t) as f32
}

fn unorm(v: u32, bits: u32) -> f64 {
    let t = (1u32 << bits) - 1;
    (v & t) as f64 / t as f64
}

/// `unpackRot`, giving the quaternion in PLY order.
fn unpack_rotation(v: u32) -> [f32; 4] {
    let norm = std::f64::consts::SQRT_2;
    let abc = [20, 10, 0].map(|s| (unorm(v >> s, 10) - 0.5) * norm);
    let m = (1.0 - abc.iter().map(|x| x * x).sum::<f64>()).max(0.0).sqrt();
    let largest = (v >> 30) as usize;
    let mut q = [0f32; 4];
    let mut it = abc.iter();
    for (k, slot) in q.iter_mut().enumerate() {
        *slot = if k == largest { m as f32 } else { *it.next().unwrap_or(&0.0) as f32 };
    }
    q
}

/// Decodes a compressed PLY (Gaussians in file order); `path` only names the file in errors.
pub fn decode_compressed_ply(bytes: &[u8], path: &Path) -> Result<Gaussians> {
    let h = parse_header(bytes, path)?;
    if h.encoding != PlyEncoding::BinaryLittleEndian {
        return Err(ExportError::unsupported(path, "a compressed PLY that is not binary_little_endian"));
    }
    let (_, vertex) = h.element("vertex").ok_or_else(|| ExportError::format(path, "PLY has no 'vertex' element"))?;
    let (_, chunk_el) = h.element("chunk").ok_or_else(|| ExportError::format(path, "not a compressed PLY: no 'chunk' element"))?;
    let n = vertex.count;
    if n > MAX_GAUSSIANS {
        return Err(ExportError::format(path, format!("{n} Gaussians exceed the cap of {MAX_GAUSSIANS}")));
    }
    if chunk_el.count != n.div_ceil(CHUNK) {
        return Err(ExportError::format(path, format!("{} chunks for {n} Gaussians, expected {}", chunk_el.count, n.div_ceil(CHUNK))));
    }
    let colors = chunk_el.property_index("min_r").is_some();
    let chunk_props = if colors { strings(CHUNK_PROPS) } else { strings(CHUNK_PROPS)[..12].to_vec() };
    let missing = |e: &str| ExportError::format(path, format!("PLY has no '{e}' element"));
    let ct = table(bytes, &h, "chunk", &chunk_props, ScalarType::F32, path)?.ok_or_else(|| missing("chunk"))?;
    let vt = table(bytes, &h, "vertex", &strings(VERTEX_PROPS), ScalarType::U32, path)?.ok_or_else(|| missing("vertex"))?;
    let rest = match h.element("sh").map(|(_, e)| (e.count, e.properties.len())) {
        None => 0,
        Some((c, _)) if c != n => return Err(ExportError::format(path, format!("'sh' has {c} records for {n} Gaussians"))),
        Some((_, 9)) => 3,
        Some((_, 24)) => 8,
        Some((_, 45)) => 15,
        Some((_, k)) => return Err(ExportError::format(path, format!("'sh' has {k} properties; expected 9, 24 or 45"))),
    };
    let sh_names: Vec<String> = (0..3 * rest).map(|k| format!("f_rest_{k}")).collect();
    let st = if rest > 0 { table(bytes, &h, "sh", &sh_names, ScalarType::U8, path)? } else { None };
    let mut g = Gaussians::default();
    for i in 0..n {
        let c = &ct.data[(i / CHUNK) * ct.stride..];
        let cf = |k: usize| f32_at(&c[ct.offsets[k]..]);
        let v = &vt.data[i * vt.stride..];
        let [pp, pr, ps, pc] = [0, 1, 2, 3].map(|k| u32_at(&v[vt.offsets[k]..]));
        let t3 = |w: u32| [unorm(w >> 21, 11), unorm(w >> 11, 10), unorm(w, 11)];
        let (tp, ts) = (t3(pp), t3(ps));
        let mean = [0, 1, 2].map(|k| lerp(cf(k), cf(3 + k), tp[k]));
        let log_scale = [0, 1, 2].map(|k| lerp(cf(6 + k), cf(9 + k), ts[k]));
        let tc = [24, 16, 8].map(|s| unorm(pc >> s, 8));
        let mut sh = [[0f32; 3]; SH_COEFFS];
        for k in 0..3 {
            let rgb = if colors { lerp(cf(12 + k), cf(15 + k), tc[k]) } else { tc[k] as f32 };
            sh[0][k] = (rgb - 0.5) / SH_C0;
        }
        if let Some(st) = &st {
            let r = &st.data[i * st.stride..];
            for ch in 0..3 {
                for k in 1..=rest {
                    let b = r[st.offsets[ch * rest + k - 1]];
                    let t = match b { 0 => 0.0, 255 => 1.0, b => (b as f32 + 0.5) / 256.0 };
                    sh[k][ch] = (t - 0.5) * 8.0;
                }
            }
        }
        let logit = inverse_sigmoid(unorm(pc, 8) as f32);
        g.push(mean, log_scale, unpack_rotation(pr), logit, sh);
    }
    if let Some(bad) = g.means.iter().chain(&g.log_scales).position(|p| !p.iter().all(|v| v.is_finite())) {
        return Err(ExportError::format(path, format!("Gaussian {}: its chunk bounds are not finite", bad % n.max(1))));
    }
    g.sh_degree = match rest { 0 => 0, 3 => 1, 8 => 2, _ => 3 };
    Ok(g)
}
