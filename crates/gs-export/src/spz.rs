//! Niantic's `.spz` (github nianticlabs/spz), written as **version 3**: a gzip stream of a
//! 16-byte header (magic `0x5053474e` "NGSP", version, count, SH degree, fractional bits,
//! flags, reserved) followed by the attributes of all Gaussians, attribute by attribute:
//! positions (3 × 24-bit signed fixed point), alphas (u8), colours (3 × u8), log-scales
//! (3 × u8), rotations (v3: 4 bytes "smallest three"), SH coefficients (u8, coefficient-major,
//! colour innermost). Version 3 is the newest gzip version: Niantic's library (which now writes
//! ZSTD version 4 by default) and the web viewers that read spz all read it. The reader accepts
//! versions 2 and 3; version 1 (float16 positions, never released) and version 4 (ZSTD streams)
//! are refused with a message saying so.
//!
//! **Flags.** Bit [`FLAG_ANTIALIASED`] says the model was trained with Mip-Splatting's opacity
//! compensation (vagsl's `antialiased` projection, docs/method.md §Projection), so that viewers
//! that honour it (Niantic's library reads it as `antialiased`) render it as trained.
//!
//! **Coordinates.** spz stores RUB (x right, y up, z back: OpenGL / three.js); a 3DGS PLY, and
//! so a vagsl model, is RDF (COLMAP's x right, y down, z forward). The writer converts RDF → RUB
//! as Niantic's `coordinateConverter(RDF, RUB)` does: positions `(x, −y, −z)`, quaternion
//! `(w, x, −y, −z)`, and each SH coefficient multiplied by its sign under the flip (the table
//! `flipSh` of `splat-types.h`); the reader converts back. The flip is its own inverse.
//!
//! **Quantisation** (the reference encoder's, asserted in the tests): positions to
//! `2^−fb` with the largest `fb ≤ 20` that keeps every coordinate in 24 bits (error
//! `≤ 2^−(fb+1)`; the reference uses a fixed 12); alpha `sigmoid(opacity)·255` (error ≤ 0.5/255
//! in opacity); colour `f_dc·0.15·255 + 127.5` (error ≤ 0.5/38.25 = 0.0131 in `f_dc` for
//! `|f_dc| ≤ 3.33`, clamped beyond); log-scale `(s + 10)·16` (error ≤ 1/32 for s in
//! [−10, 5.94], clamped beyond); rotation: the three smallest components of the unit quaternion
//! in 10 bits (error ≤ 7e-4 each); SH `x·128 + 128` rounded to 5 bits for degree 1 and 4 bits
//! for degrees 2–3 (the reference defaults), error ≤ 4.5/128 and ≤ 8.5/128 for `x` in [−1, 1],
//! clamped beyond.

use crate::error::{ExportError, Result};
use crate::quant::{Cursor, to_u8};
use flate2::Compression;
use flate2::read::GzDecoder;
use flate2::write::GzEncoder;
use gs_core::Gaussians;
use gs_core::gaussians::{MAX_GAUSSIANS, inverse_sigmoid, sigmoid, unit_quaternion};
use gs_core::sh::{MAX_SH_DEGREE, SH_COEFFS};
use std::io::{Read, Write};
use std::path::Path;

/// The header magic, "NGSP" in file order.
pub const MAGIC: u32 = 0x5053_474e;
/// The version the writer produces.
pub const WRITE_VERSION: u32 = 3;
/// Header flag: the model was trained with opacity compensation (spz's `FlagAntialiased`).
pub const FLAG_ANTIALIASED: u8 = 0x1;
/// spz's DC colour scale (`colorScale` in `splat-utils.h`).
pub const COLOR_SCALE: f32 = 0.15;
/// Largest number of fractional position bits the writer uses.
pub const MAX_FRACTIONAL_BITS: u8 = 20;
/// Quantisation bits of the degree-1 SH coefficients (reference default).
pub const SH1_BITS: u32 = 5;
/// Quantisation bits of the degree-2 and 3 SH coefficients (reference default).
pub const SH_REST_BITS: u32 = 4;

/// Sign of SH coefficient `k` (1..16, 0 is DC) under the RDF ↔ RUB flip `(x, −y, −z)`: the
/// reference's `flipSh` table with x = 1, y = z = −1.
pub fn sh_flip(k: usize) -> f32 {
    const FLIP: [f32; SH_COEFFS - 1] = [-1., -1., 1., -1., 1., 1., -1., 1., -1., 1., -1., -1., 1., -1., 1.];
    if k == 0 { 1.0 } else { FLIP[k - 1] }
}

/// Number of SH coefficients per channel above DC for `degree`.
fn sh_dim(degree: u32) -> usize {
    ((degree + 1) * (degree + 1) - 1) as usize
}

/// The largest fractional-bit count (≤ [`MAX_FRACTIONAL_BITS`]) that stores every coordinate of
/// `g` in a signed 24-bit integer, or `None` when even 0 bits do not.
pub fn fractional_bits(g: &Gaussians) -> Option<u8> {
    let max = g.means.iter().flatten().fold(0f64, |m, v| m.max(v.abs() as f64));
    (0..=MAX_FRACTIONAL_BITS).rev().find(|&fb| (max * (1u64 << fb) as f64).round() <= ((1 << 23) - 1) as f64)
}

/// Encodes `g` as spz version 3 (gzip), with [`FLAG_ANTIALIASED`] set when `antialiased`;
/// `path` only names the file in errors.
pub fn encode_spz(g: &Gaussians, antialiased: bool, path: &Path) -> Result<Vec<u8>> {
    let n = u32::try_from(g.len()).map_err(|_| ExportError::unencodable(path, "spz", "more than 2^32 Gaussians"))?;
    let fb = fractional_bits(g).ok_or_else(|| {
        ExportError::unencodable(path, "spz", "a coordinate exceeds ±8388607, the range of spz's 24-bit fixed-point positions")
    })?;
    let degree = g.sh_degree.min(MAX_SH_DEGREE);
    let dim = sh_dim(degree);
    let mut raw = Vec::with_capacity(16 + g.len() * (9 + 1 + 3 + 3 + 4 + 3 * dim));
    for v in [MAGIC, WRITE_VERSION, n] {
        raw.extend_from_slice(&v.to_le_bytes());
    }
    let flags = if antialiased { FLAG_ANTIALIASED } else { 0 };
    raw.extend_from_slice(&[degree as u8, fb, flags, 0]);
    let unit = (1u64 << fb) as f64;
    for p in &g.means {
        for (v, f) in p.iter().zip([1.0f32, -1.0, -1.0]) {
            let fixed = ((v * f) as f64 * unit).round() as i32;
            raw.extend_from_slice(&fixed.to_le_bytes()[..3]);
        }
    }
    raw.extend(g.opacity_logits.iter().map(|&o| to_u8(sigmoid(o) * 255.0)));
    for sh in &g.sh {
        raw.extend(sh[0].iter().map(|&c| to_u8(c * (COLOR_SCALE * 255.0) + 127.5)));
    }
    for s in &g.log_scales {
        raw.extend(s.iter().map(|&v| to_u8((v + 10.0) * 16.0)));
    }
    for q in &g.rotations {
        raw.extend_from_slice(&pack_smallest_three(rub_quaternion(*q)).to_le_bytes());
    }
    for sh in &g.sh {
        for (k, coeff) in sh.iter().enumerate().take(dim + 1).skip(1) {
            let bits = if k <= 3 { SH1_BITS } else { SH_REST_BITS };
            raw.extend(coeff.iter().map(|&v| quantize_sh(v * sh_flip(k), 1 << (8 - bits))));
        }
    }
    let mut enc = GzEncoder::new(Vec::with_capacity(raw.len() / 2), Compression::default());
    enc.write_all(&raw).and_then(|_| enc.finish()).map_err(|e| gs_io::IoError::io(path, e).into())
}

/// The unit quaternion `(w, x, y, z)` of vagsl (RDF) as spz's `(x, y, z, w)` in RUB.
fn rub_quaternion(q: [f32; 4]) -> [f32; 4] {
    let [w, x, y, z] = unit_quaternion(q);
    [x, -y, -z, w]
}

/// spz's `quantizeSH`: to 8 bits, then to the nearest multiple of `bucket` (clamped).
fn quantize_sh(x: f32, bucket: i32) -> u8 {
    let q = if x.is_nan() { 128 } else { ((x * 128.0).round() + 128.0).clamp(-1024.0, 1024.0) as i32 };
    let q = (q + bucket / 2).div_euclid(bucket) * bucket;
    q.clamp(0, 255) as u8
}

/// spz's `packQuaternionSmallestThree` of a unit quaternion in `(x, y, z, w)` order: the index
/// of the largest component in the top 2 bits, then for each other component a sign bit
/// (relative to the largest's sign) and a 9-bit magnitude scaled by √2.
fn pack_smallest_three(q: [f32; 4]) -> u32 {
    let largest = (1..4).fold(0, |m, i| if q[i].abs() > q[m].abs() { i } else { m });
    let negate = q[largest] < 0.0;
    let mut comp = largest as u32;
    for (i, &v) in q.iter().enumerate() {
        if i != largest {
            let negbit = ((v < 0.0) ^ negate) as u32;
            let mag = ((511.0 * (v.abs() / std::f32::consts::FRAC_1_SQRT_2) + 0.5) as u32).min(511);
            comp = (comp << 10) | (negbit << 9) | mag;
        }
    }
    comp
}

/// spz's `unpackQuaternionSmallestThree`, giving `(x, y, z, w)`.
fn unpack_smallest_three(mut comp: u32) -> [f32; 4] {
    let largest = (comp >> 30) as usize;
    let mut q = [0f32; 4];
    let mut sum = 0.0;
    for i in (0..4).rev() {
        if i != largest {
            let mag = (comp & 511) as f32;
            let neg = (comp >> 9) & 1 == 1;
            comp >>= 10;
            let v = std::f32::consts::FRAC_1_SQRT_2 * mag / 511.0;
            q[i] = if neg { -v } else { v };
            sum += q[i] * q[i];
        }
    }
    q[largest] = (1.0 - sum).max(0.0).sqrt();
    q
}

/// Decodes an spz file (version 2 or 3): the Gaussians and whether [`FLAG_ANTIALIASED`] is set;
/// `path` only names the file in errors.
pub fn decode_spz(bytes: &[u8], path: &Path) -> Result<(Gaussians, bool)> {
    if bytes.starts_with(b"NGSP") {
        return Err(ExportError::unsupported(path, "spz version 4 (ZSTD streams); vagsl reads versions 2 and 3 (gzip)"));
    }
    if !bytes.starts_with(&[0x1f, 0x8b]) {
        return Err(ExportError::format(path, "not an spz file: it is neither gzip-compressed nor starts with 'NGSP'"));
    }
    let mut dec = GzDecoder::new(bytes);
    let mut head = [0u8; 16];
    dec.read_exact(&mut head).map_err(|e| ExportError::format(path, format!("cannot decompress the spz header: {e}")))?;
    let word = |k: usize| u32::from_le_bytes([head[4 * k], head[4 * k + 1], head[4 * k + 2], head[4 * k + 3]]);
    if word(0) != MAGIC {
        return Err(ExportError::format(path, format!("not an spz file: magic {:#010x}, expected {MAGIC:#010x}", word(0))));
    }
    let (version, n, degree, fb) = (word(1), word(2) as usize, head[12] as u32, head[13]);
    let antialiased = head[14] & FLAG_ANTIALIASED != 0;
    match version {
        2 | 3 => {}
        1 => return Err(ExportError::unsupported(path, "spz version 1 (float16 positions); vagsl reads versions 2 and 3")),
        v => return Err(ExportError::unsupported(path, format!("spz version {v}; vagsl reads versions 2 and 3"))),
    }
    if n > MAX_GAUSSIANS {
        return Err(ExportError::format(path, format!("{n} Gaussians exceed the cap of {MAX_GAUSSIANS}")));
    }
    if degree > MAX_SH_DEGREE {
        return Err(ExportError::unsupported(path, format!("SH degree {degree}; vagsl models go up to {MAX_SH_DEGREE}")));
    }
    if fb > 23 {
        return Err(ExportError::format(path, format!("{fb} fractional bits exceed the 24-bit positions")));
    }
    let (rot_bytes, dim) = (if version >= 3 { 4 } else { 3 }, sh_dim(degree));
    let expected = n * (9 + 1 + 3 + 3 + rot_bytes + 3 * dim);
    // Read at most what the header announces, so a small file cannot inflate without bound.
    let mut body = Vec::with_capacity(expected.min(1 << 26));
    (&mut dec).take(expected as u64)
        .read_to_end(&mut body)
        .map_err(|e| ExportError::format(path, format!("cannot decompress the spz data: {e}")))?;
    // Drain what follows (extensions), up to a bound, so a damaged or truncated stream (CRC,
    // length) is reported rather than silently accepted.
    std::io::copy(&mut dec.take(1 << 26), &mut std::io::sink())
        .map_err(|e| ExportError::format(path, format!("the spz stream is damaged: {e}")))?;
    let mut cur = Cursor::new(&body, path);
    let positions = cur.take(9 * n, "positions")?;
    let alphas = cur.take(n, "alphas")?;
    let colors = cur.take(3 * n, "colours")?;
    let scales = cur.take(3 * n, "scales")?;
    let rotations = cur.take(rot_bytes * n, "rotations")?;
    let shs = cur.take(3 * dim * n, "spherical harmonics")?;

    let mut g = Gaussians::default();
    let unit = 1.0 / (1u64 << fb) as f64;
    for i in 0..n {
        let mut mean = [0f32; 3];
        for (k, f) in [1.0f32, -1.0, -1.0].into_iter().enumerate() {
            let b = &positions[9 * i + 3 * k..];
            let fixed = i32::from_le_bytes([b[0], b[1], b[2], if b[2] & 0x80 != 0 { 0xff } else { 0 }]);
            mean[k] = (fixed as f64 * unit) as f32 * f;
        }
        let log_scale = [0, 1, 2].map(|k| scales[3 * i + k] as f32 / 16.0 - 10.0);
        let [x, y, z, w] = if version >= 3 {
            let b = &rotations[4 * i..];
            unpack_smallest_three(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        } else {
            let v = [0, 1, 2].map(|k| rotations[3 * i + k] as f32 / 127.5 - 1.0);
            [v[0], v[1], v[2], (1.0 - v.iter().map(|a| a * a).sum::<f32>()).max(0.0).sqrt()]
        };
        let mut sh = [[0f32; 3]; SH_COEFFS];
        for c in 0..3 {
            sh[0][c] = (colors[3 * i + c] as f32 / 255.0 - 0.5) / COLOR_SCALE;
        }
        for k in 1..=dim {
            for c in 0..3 {
                sh[k][c] = (shs[3 * (i * dim + k - 1) + c] as f32 - 128.0) / 128.0 * sh_flip(k);
            }
        }
        g.push(mean, log_scale, [w, x, -y, -z], inverse_sigmoid(alphas[i] as f32 / 255.0), sh);
    }
    g.sh_degree = degree;
    Ok((g, antialiased))
}

#[cfg(test)]
mod tests {
    use super::*;
    use gs_core::sh::eval_sh;

    /// The flip table is the SH symmetry of the flip: the RUB coefficients evaluated at the
    /// flipped direction give the RDF colour at the direction.
    #[test]
    fn sh_flip_matches_the_reflection() {
        let mut rng = gs_core::Rng::new(5);
        let mut sh = [[0f32; 3]; SH_COEFFS];
        for c in sh.iter_mut() {
            *c = [rng.normal(), rng.normal(), rng.normal()];
        }
        let flipped: [[f32; 3]; SH_COEFFS] = std::array::from_fn(|k| sh[k].map(|v| v * sh_flip(k)));
        for _ in 0..20 {
            let d = gs_core::glam::Vec3::new(rng.normal(), rng.normal(), rng.normal()).normalize().to_array();
            let a = eval_sh(3, &sh, d);
            let b = eval_sh(3, &flipped, [d[0], -d[1], -d[2]]);
            for c in 0..3 {
                assert!((a[c] - b[c]).abs() < 1e-4, "{a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn smallest_three_round_trips() {
        for q in [[0.0, 0.0, 0.0, 1.0], [0.5, -0.5, 0.5, -0.5], [0.1, 0.9, -0.3, 0.2]] {
            let n = unit_quaternion(q);
            let back = unpack_smallest_three(pack_smallest_three(n));
            let dot: f32 = n.iter().zip(back).map(|(a, b)| a * b).sum();
            assert!(dot.abs() > 1.0 - 1e-5, "{n:?} → {back:?}");
        }
    }

    #[test]
    fn sh_quantisation_matches_the_reference() {
        assert_eq!(quantize_sh(0.0, 16), 128);
        assert_eq!(quantize_sh(1.0, 8), 255);
        assert_eq!(quantize_sh(-1.0, 16), 0);
        assert_eq!(quantize_sh(-5.0, 16), 0);
    }
}
