//! antimatter15/splat's `.splat`: headerless 32-byte records, one per Gaussian.
//!
//! Record (little-endian): position 3 × f32, scale 3 × f32 (linear, `exp` of the log-scale),
//! colour RGBA 4 × u8 (`RGB = clamp(0.5 + SH_C0·f_dc, 0, 1)·255`, `A = sigmoid(opacity)·255`),
//! rotation 4 × u8 (`q/‖q‖·128 + 128`, order w x y z). Bytes are rounded to nearest and clamped,
//! as the viewer's own PLY converter (`main.js`, a `Uint8ClampedArray` store) does. Records are
//! sorted by decreasing `exp(Σ log-scales)·sigmoid(opacity)` as in `convert.py` (ties by index).
//!
//! The format has no spherical harmonics beyond the DC colour: the reader returns degree 0.
//!
//! Round-trip bounds (asserted in the tests): positions exact; log-scales within f32 rounding of
//! `ln(exp(s))`; colour `|ĉ − clamp(c, 0, 1)| ≤ 0.5/255` with `c = 0.5 + SH_C0·f_dc`; opacity
//! `|σ̂ − σ| ≤ 0.5/255`; each component of the normalised quaternion within `1/128`
//! (0.5/128 from rounding, 1/128 at +1, which clamps to 255).

use crate::error::{ExportError, Result};
use crate::quant::{f32_at, to_u8};
use gs_core::Gaussians;
use gs_core::gaussians::{MAX_GAUSSIANS, inverse_sigmoid, unit_quaternion};
use gs_core::sh::{SH_C0, SH_COEFFS};
use std::path::Path;

/// Bytes per record.
pub const RECORD: usize = 32;

/// The order the writer stores the Gaussians in: decreasing `exp(Σ log-scales)·sigmoid(opacity)`
/// (the viewer draws big opaque splats first while the file streams in), ties by index.
pub fn splat_order(g: &Gaussians) -> Vec<usize> {
    let key: Vec<f64> = (0..g.len())
        .map(|i| {
            let s: f64 = g.log_scales[i].iter().map(|&v| v as f64).sum();
            s.exp() * g.opacity(i) as f64
        })
        .collect();
    let mut order: Vec<usize> = (0..g.len()).collect();
    order.sort_by(|&a, &b| key[b].total_cmp(&key[a]).then(a.cmp(&b)));
    order
}

/// Encodes `g` as `.splat` bytes; `path` only names the file in errors. Fails when a scale is
/// not a finite positive f32 (a log-scale beyond about ±87).
pub fn encode_splat(g: &Gaussians, path: &Path) -> Result<Vec<u8>> {
    let mut out = Vec::with_capacity(g.len() * RECORD);
    for i in splat_order(g) {
        let scale = g.scale(i);
        if !scale.iter().all(|s| s.is_finite() && *s > 0.0) {
            return Err(ExportError::unencodable(
                path,
                "splat",
                format!("Gaussian {i} has log-scales {:?}, whose exp is 0 or infinite in f32", g.log_scales[i]),
            ));
        }
        for v in g.means[i].iter().chain(scale.iter()) {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for c in 0..3 {
            out.push(to_u8((0.5 + SH_C0 * g.sh[i][0][c]).clamp(0.0, 1.0) * 255.0));
        }
        out.push(to_u8(g.opacity(i) * 255.0));
        for q in unit_quaternion(g.rotations[i]) {
            out.push(to_u8(q * 128.0 + 128.0));
        }
    }
    Ok(out)
}

/// Decodes `.splat` bytes (records in file order, SH degree 0); `path` only names the file.
pub fn decode_splat(bytes: &[u8], path: &Path) -> Result<Gaussians> {
    if bytes.len() % RECORD != 0 {
        return Err(ExportError::format(
            path,
            format!("not a .splat file: its {} bytes are not a whole number of {RECORD}-byte records", bytes.len()),
        ));
    }
    let n = bytes.len() / RECORD;
    if n > MAX_GAUSSIANS {
        return Err(ExportError::format(path, format!("{n} Gaussians exceed the cap of {MAX_GAUSSIANS}")));
    }
    let mut g = Gaussians::default();
    for (i, r) in bytes.chunks_exact(RECORD).enumerate() {
        let mean = [f32_at(&r[0..]), f32_at(&r[4..]), f32_at(&r[8..])];
        let scale = [f32_at(&r[12..]), f32_at(&r[16..]), f32_at(&r[20..])];
        if !mean.iter().all(|v| v.is_finite()) {
            return Err(ExportError::format(path, format!("record {i}: the position is not finite")));
        }
        if !scale.iter().all(|s| s.is_finite() && *s > 0.0) {
            return Err(ExportError::format(path, format!("record {i}: a scale is not a finite positive number")));
        }
        let mut sh = [[0f32; 3]; SH_COEFFS];
        for c in 0..3 {
            sh[0][c] = (r[24 + c] as f32 / 255.0 - 0.5) / SH_C0;
        }
        let logit = inverse_sigmoid(r[27] as f32 / 255.0);
        let rot = [0, 1, 2, 3].map(|k| (r[28 + k] as f32 - 128.0) / 128.0);
        g.push(mean, scale.map(f32::ln), rot, logit, sh);
    }
    Ok(g)
}
