//! The Inria 3DGS Gaussian PLY (what `gaussian_splatting/scene/gaussian_model.py::save_ply`
//! writes and every splat viewer opens).
//!
//! One `vertex` element, all properties `float`, in this order:
//! `x y z nx ny nz f_dc_0 f_dc_1 f_dc_2 f_rest_0 … f_rest_44 opacity scale_0 scale_1 scale_2
//! rot_0 rot_1 rot_2 rot_3`. Values are the raw parameters: opacity is the logit, scales are
//! log-scales, `rot` is the quaternion `(w, x, y, z)` as stored (not normalised), normals are 0.
//!
//! `f_rest` is channel-major: `f_rest_0..14` are the R coefficients 1..15, then G, then B.
//! In memory the SH are `[N][16][3]` (coefficient-major), so coefficient `k ≥ 1` of channel
//! `c` is `f_rest_{c·15 + k − 1}` (with `15` replaced by `(degree+1)² − 1` for files of lower
//! degree).
//!
//! **Writing** always stores all 45 `f_rest` fields (the exact Inria layout) and adds the
//! header line `comment vagsl sh_degree D` so the active degree survives a round trip
//! bit-exactly. **Reading** accepts 0, 9, 24 or 45 `f_rest` fields (degree 0..3, higher
//! coefficients set to 0), lowers the degree to a valid `vagsl sh_degree` comment when there
//! is one, skips unknown properties (and unknown elements), accepts `float` or `double`
//! properties and all three PLY encodings (ASCII and big-endian too), and rejects NaN or
//! infinite values naming the vertex and property.

use super::{DataReader, PlyEncoding, PropertyKind, ScalarType, parse_header, read_file};
use crate::atomic::write_atomic;
use crate::error::{IoError, Result};
use gs_core::Gaussians;
use gs_core::gaussians::MAX_GAUSSIANS;
use gs_core::sh::{MAX_SH_DEGREE, SH_COEFFS};
use rayon::prelude::*;
use std::io::Write;
use std::path::Path;

/// Number of `f_rest` properties the writer emits (degree 3: 15 coefficients × 3 channels).
pub const F_REST_COUNT: usize = 3 * (SH_COEFFS - 1);

/// Values per Gaussian in the in-memory record used while decoding: mean 3, log-scale 3,
/// rotation 4, opacity 1, SH 48.
const SLOTS: usize = 11 + 3 * SH_COEFFS;
const SLOT_MEAN: usize = 0;
const SLOT_SCALE: usize = 3;
const SLOT_ROT: usize = 6;
const SLOT_OPACITY: usize = 10;
const SLOT_SH: usize = 11;

/// The property names the writer emits, in order (the Inria layout).
pub fn gaussian_property_names() -> Vec<String> {
    let mut names: Vec<String> = ["x", "y", "z", "nx", "ny", "nz"].iter().map(|s| s.to_string()).collect();
    names.extend((0..3).map(|i| format!("f_dc_{i}")));
    names.extend((0..F_REST_COUNT).map(|i| format!("f_rest_{i}")));
    names.push("opacity".into());
    names.extend((0..3).map(|i| format!("scale_{i}")));
    names.extend((0..4).map(|i| format!("rot_{i}")));
    names
}

/// Writes `gaussians` as an Inria 3DGS PLY at `path` (atomically). Fails, writing nothing,
/// when the model does not validate (NaN, mismatched arrays, degree > 3).
pub fn write_gaussian_ply(path: &Path, gaussians: &Gaussians) -> Result<()> {
    gaussians.validate().map_err(|source| IoError::Core { path: path.to_path_buf(), source })?;
    write_atomic(path, |w| write_gaussian_ply_to(w, gaussians))
}

/// Streams the PLY of `gaussians` into `w` (no validation; see [`write_gaussian_ply`]).
/// Records are encoded in parallel in blocks of 65,536.
pub fn write_gaussian_ply_to(w: &mut dyn Write, gaussians: &Gaussians) -> std::io::Result<()> {
    let n = gaussians.len();
    let mut header = String::with_capacity(2048);
    header.push_str("ply\nformat binary_little_endian 1.0\n");
    header.push_str(&format!("comment vagsl sh_degree {}\n", gaussians.sh_degree.min(MAX_SH_DEGREE)));
    header.push_str(&format!("element vertex {n}\n"));
    for name in gaussian_property_names() {
        header.push_str("property float ");
        header.push_str(&name);
        header.push('\n');
    }
    header.push_str("end_header\n");
    w.write_all(header.as_bytes())?;

    let fields = 6 + 3 + F_REST_COUNT + 1 + 3 + 4;
    let stride = fields * 4;
    const BLOCK: usize = 1 << 16;
    let mut buf = vec![0u8; BLOCK.min(n.max(1)) * stride];
    let mut start = 0;
    while start < n {
        let count = BLOCK.min(n - start);
        let out = &mut buf[..count * stride];
        out.par_chunks_mut(stride).enumerate().for_each(|(j, rec)| {
            let i = start + j;
            let mut vals = [0f32; 62];
            vals[0..3].copy_from_slice(&gaussians.means[i]);
            // vals[3..6]: normals, written as 0.
            let sh = &gaussians.sh[i];
            for c in 0..3 {
                vals[6 + c] = sh[0][c];
                for k in 1..SH_COEFFS {
                    vals[9 + c * (SH_COEFFS - 1) + (k - 1)] = sh[k][c];
                }
            }
            vals[54] = gaussians.opacity_logits[i];
            vals[55..58].copy_from_slice(&gaussians.log_scales[i]);
            vals[58..62].copy_from_slice(&gaussians.rotations[i]);
            for (dst, v) in rec.chunks_exact_mut(4).zip(vals.iter()) {
                dst.copy_from_slice(&v.to_le_bytes());
            }
        });
        w.write_all(out)?;
        start += count;
    }
    Ok(())
}

/// Reads an Inria 3DGS Gaussian PLY from `path` (see the module docs for what is accepted).
pub fn read_gaussian_ply(path: &Path) -> Result<Gaussians> {
    let bytes = read_file(path)?;
    parse_gaussian_ply(&bytes, path)
}

/// Where one vertex property goes: a slot of the decoding record, or nowhere (skipped).
#[derive(Clone, Copy)]
struct Field {
    kind: PropertyKind,
    slot: Option<usize>,
}

/// Parses a Gaussian PLY held in memory; `path` only names the file in errors. This is the
/// function the fuzz target drives.
pub fn parse_gaussian_ply(bytes: &[u8], path: &Path) -> Result<Gaussians> {
    let header = parse_header(bytes, path)?;
    let (vertex_index, vertex) =
        header.element("vertex").ok_or_else(|| IoError::format(path, "PLY has no 'vertex' element"))?;
    let n = vertex.count;
    if n > MAX_GAUSSIANS {
        return Err(IoError::format(path, format!("{n} Gaussians exceed the cap of {MAX_GAUSSIANS}")));
    }

    // f_rest fields: they must be exactly f_rest_0 .. f_rest_{K-1} with K ∈ {0, 9, 24, 45}.
    let rest_count = vertex.properties.iter().filter(|p| p.name.starts_with("f_rest_")).count();
    let degree = match rest_count {
        0 => 0,
        9 => 1,
        24 => 2,
        45 => 3,
        k => {
            return Err(IoError::format(
                path,
                format!("vertex has {k} f_rest properties; expected 0, 9, 24 or 45 (SH degree 0..3)"),
            ));
        }
    };
    let per_channel = rest_count / 3;

    let mut names: Vec<String> = Vec::with_capacity(SLOTS);
    let mut required: Vec<(String, usize)> = Vec::with_capacity(14 + rest_count);
    // In the Inria order, so that the first missing one is reported.
    for (i, axis) in ["x", "y", "z"].iter().enumerate() {
        required.push((axis.to_string(), SLOT_MEAN + i));
    }
    for i in 0..3 {
        required.push((format!("f_dc_{i}"), SLOT_SH + i));
    }
    for j in 0..rest_count {
        let (c, k) = (j / per_channel, 1 + j % per_channel);
        required.push((format!("f_rest_{j}"), SLOT_SH + 3 * k + c));
    }
    required.push(("opacity".into(), SLOT_OPACITY));
    for i in 0..3 {
        required.push((format!("scale_{i}"), SLOT_SCALE + i));
    }
    for i in 0..4 {
        required.push((format!("rot_{i}"), SLOT_ROT + i));
    }
    names.resize(SLOTS, String::new());
    let mut fields: Vec<Field> = vertex.properties.iter().map(|p| Field { kind: p.kind, slot: None }).collect();
    for (name, slot) in &required {
        let idx = vertex.property_index(name).ok_or_else(|| {
            IoError::format(path, format!("vertex element lacks the property '{name}' of the 3DGS layout"))
        })?;
        match vertex.properties[idx].kind {
            PropertyKind::Scalar(ScalarType::F32 | ScalarType::F64) => {}
            other => {
                return Err(IoError::format(
                    path,
                    format!("property '{name}' has type {other:?}; 3DGS properties must be float or double"),
                ));
            }
        }
        fields[idx].slot = Some(*slot);
        names[*slot] = name.clone();
    }

    let mut g = Gaussians::with_len(n).map_err(|source| IoError::Core { path: path.to_path_buf(), source })?;
    g.sh_degree = degree;
    // Our writer records the active degree; honour it when it is not above what the fields hold.
    for c in &header.comments {
        if let Some(d) = c.strip_prefix("vagsl sh_degree ").and_then(|d| d.trim().parse::<u32>().ok())
            && d <= degree
        {
            g.sh_degree = d;
        }
    }

    // Skip the elements before the vertex element.
    let mut reader = DataReader::new(bytes, &header);
    for e in &header.elements[..vertex_index] {
        reader.skip_element(e).map_err(|m| IoError::format(path, m))?;
    }
    let check = |i: usize, rec: &[f32; SLOTS]| -> Result<()> {
        if let Some(s) = rec.iter().position(|v| !v.is_finite()) {
            return Err(IoError::format(
                path,
                format!("vertex {i}: property '{}' is {} (NaN or infinite values are rejected)", names[s], rec[s]),
            ));
        }
        Ok(())
    };

    let fast = header.encoding != PlyEncoding::Ascii && vertex.fixed_stride().is_some();
    if fast {
        // Fixed-size records: decode in parallel straight from the byte slice.
        let stride = vertex.fixed_stride().unwrap_or(0);
        let start = reader.position();
        let total = n.saturating_mul(stride); // fits: parse_header checked it against the file size
        let data = bytes.get(start..start.saturating_add(total)).ok_or_else(|| {
            IoError::format(path, format!("truncated data: {n} vertices need {total} bytes from byte {start}"))
        })?;
        let big = header.encoding == PlyEncoding::BinaryBigEndian;
        let mut plan: Vec<(usize, ScalarType, usize)> = Vec::with_capacity(SLOTS);
        let mut offset = 0;
        for f in &fields {
            if let PropertyKind::Scalar(t) = f.kind {
                if let Some(slot) = f.slot {
                    plan.push((offset, t, slot));
                }
                offset += t.size();
            }
        }
        const CHUNK: usize = 4096;
        let Gaussians { means, log_scales, rotations, opacity_logits, sh, .. } = &mut g;
        means
            .par_chunks_mut(CHUNK)
            .zip(log_scales.par_chunks_mut(CHUNK))
            .zip(rotations.par_chunks_mut(CHUNK))
            .zip(opacity_logits.par_chunks_mut(CHUNK))
            .zip(sh.par_chunks_mut(CHUNK))
            .enumerate()
            .try_for_each(|(ci, ((((m, s), r), o), sh))| -> Result<()> {
                for j in 0..m.len() {
                    let i = ci * CHUNK + j;
                    let raw = &data[i * stride..(i + 1) * stride];
                    let mut rec = [0f32; SLOTS];
                    for &(off, t, slot) in &plan {
                        rec[slot] = if t == ScalarType::F32 && !big {
                            f32::from_le_bytes([raw[off], raw[off + 1], raw[off + 2], raw[off + 3]])
                        } else {
                            super::decode_binary(&raw[off..off + t.size()], t, big) as f32
                        };
                    }
                    check(i, &rec)?;
                    store(&rec, &mut m[j], &mut s[j], &mut r[j], &mut o[j], &mut sh[j]);
                }
                Ok(())
            })?;
    } else {
        for i in 0..n {
            let mut rec = [0f32; SLOTS];
            for (f, p) in fields.iter().zip(&vertex.properties) {
                let r = match (f.slot, f.kind) {
                    (Some(slot), PropertyKind::Scalar(t)) => reader.read_f32(t).map(|v| rec[slot] = v),
                    (_, kind) => reader.skip(kind),
                };
                r.map_err(|m| IoError::format(path, format!("vertex {i}, property '{}': {m}", p.name)))?;
            }
            check(i, &rec)?;
            store(&rec, &mut g.means[i], &mut g.log_scales[i], &mut g.rotations[i], &mut g.opacity_logits[i], &mut g.sh[i]);
        }
    }
    Ok(g)
}

/// Scatters one decoded record into the Gaussian's parameters.
#[inline]
fn store(
    rec: &[f32; SLOTS],
    mean: &mut [f32; 3],
    log_scale: &mut [f32; 3],
    rot: &mut [f32; 4],
    opacity: &mut f32,
    sh: &mut [[f32; 3]; SH_COEFFS],
) {
    mean.copy_from_slice(&rec[SLOT_MEAN..SLOT_MEAN + 3]);
    log_scale.copy_from_slice(&rec[SLOT_SCALE..SLOT_SCALE + 3]);
    rot.copy_from_slice(&rec[SLOT_ROT..SLOT_ROT + 4]);
    *opacity = rec[SLOT_OPACITY];
    for (k, coeff) in sh.iter_mut().enumerate() {
        coeff.copy_from_slice(&rec[SLOT_SH + 3 * k..SLOT_SH + 3 * k + 3]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(n: usize, degree: u32) -> Gaussians {
        let mut rng = gs_core::Rng::new(7 + degree as u64);
        let mut g = Gaussians::default();
        for _ in 0..n {
            let mut sh = [[0f32; 3]; SH_COEFFS];
            for (k, c) in sh.iter_mut().enumerate() {
                if k < gs_core::sh::coeffs_for_degree(degree) {
                    *c = [rng.normal(), rng.normal(), rng.normal()];
                }
            }
            g.push(
                [rng.normal(), rng.normal(), rng.normal()],
                [rng.normal(), rng.normal(), rng.normal()],
                [rng.normal(), rng.normal(), rng.normal(), rng.normal()],
                rng.normal(),
                sh,
            );
        }
        g.sh_degree = degree;
        g
    }

    #[test]
    fn f_rest_is_channel_major() {
        let mut g = sample(1, 3);
        for k in 0..SH_COEFFS {
            for c in 0..3 {
                g.sh[0][k][c] = (100 * c + k) as f32;
            }
        }
        let mut buf = Vec::new();
        write_gaussian_ply_to(&mut buf, &g).unwrap();
        let h = parse_header(&buf, Path::new("m")).unwrap();
        let data = &buf[h.data_offset..];
        let val = |field: usize| f32::from_le_bytes(data[field * 4..field * 4 + 4].try_into().unwrap());
        // f_rest_0 = R coeff 1, f_rest_14 = R coeff 15, f_rest_15 = G coeff 1, f_rest_44 = B coeff 15.
        assert_eq!(val(9), 1.0);
        assert_eq!(val(9 + 14), 15.0);
        assert_eq!(val(9 + 15), 101.0);
        assert_eq!(val(9 + 44), 215.0);
        assert_eq!(val(6), 0.0);
        assert_eq!(val(7), 100.0);
        assert_eq!(val(3), 0.0); // nx
        assert_eq!(parse_gaussian_ply(&buf, Path::new("m")).unwrap(), g);
    }

    #[test]
    fn lower_degree_files_and_unknown_properties() {
        // A degree-1 ASCII file with an extra double property and an extra element first.
        let mut text = String::from("ply\nformat ascii 1.0\nelement camera 1\nproperty list uchar float k\nelement vertex 1\n");
        let props = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2"];
        for p in props {
            text.push_str(&format!("property float {p}\n"));
        }
        text.push_str("property double extra\n");
        for j in 0..9 {
            text.push_str(&format!("property float f_rest_{j}\n"));
        }
        for p in ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"] {
            text.push_str(&format!("property double {p}\n"));
        }
        text.push_str("end_header\n2 0.5 0.25\n1 2 3 0.1 0.2 0.3 99.5 10 11 12 20 21 22 30 31 32 -1 -2 -3 -4 1 0 0 0\n");
        let g = parse_gaussian_ply(text.as_bytes(), Path::new("a.ply")).unwrap();
        assert_eq!(g.sh_degree, 1);
        assert_eq!(g.means[0], [1.0, 2.0, 3.0]);
        assert_eq!(g.sh[0][0], [0.1, 0.2, 0.3]);
        // per channel 3 coefficients: R = 10 11 12, G = 20 21 22, B = 30 31 32.
        assert_eq!(g.sh[0][1], [10.0, 20.0, 30.0]);
        assert_eq!(g.sh[0][3], [12.0, 22.0, 32.0]);
        assert_eq!(g.sh[0][4], [0.0; 3]);
        assert_eq!(g.opacity_logits[0], -1.0);
        assert_eq!(g.log_scales[0], [-2.0, -3.0, -4.0]);
        assert_eq!(g.rotations[0], [1.0, 0.0, 0.0, 0.0]);
    }

    #[test]
    fn degree_comment_round_trips() {
        for d in 0..=3 {
            let mut g = sample(5, 3);
            g.sh_degree = d;
            let mut buf = Vec::new();
            write_gaussian_ply_to(&mut buf, &g).unwrap();
            assert_eq!(parse_gaussian_ply(&buf, Path::new("m")).unwrap(), g);
        }
    }
}
