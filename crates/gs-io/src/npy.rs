//! A minimal NumPy `.npy` reader (and f32 writer) for depth and normal maps.
//!
//! Reads `float32` (`<f4`) and `float16` (`<f2`) arrays in C order, 2-D `[H][W]` (→ a
//! 1-channel [`Image`]) or 3-D `[H][W][C]` (→ a C-channel image), format versions 1.0, 2.0 and
//! 3.0. Everything else (big-endian, other dtypes, Fortran order, other ranks) is rejected with
//! a clear [`IoError`]. Values are returned as stored (NaN and infinities included): the
//! synth-bunny ground truth uses 0 for "no surface".

use crate::atomic::write_atomic;
use crate::error::{IoError, Result};
use gs_core::Image;
use std::path::Path;

const MAGIC: &[u8] = b"\x93NUMPY";

/// Reads a `.npy` file into an [`Image`] (see the module docs for what is accepted).
pub fn read_npy(path: &Path) -> Result<Image> {
    let bytes = std::fs::read(path).map_err(|e| IoError::io(path, e))?;
    parse_npy(&bytes, path)
}

/// Parses a `.npy` file held in memory; `path` only names the file in errors.
pub fn parse_npy(bytes: &[u8], path: &Path) -> Result<Image> {
    let fmt = |m: String| IoError::format(path, m);
    if !bytes.starts_with(MAGIC) || bytes.len() < 10 {
        return Err(fmt("not a .npy file (missing the \\x93NUMPY magic)".into()));
    }
    let major = bytes[6];
    let (header_len, start) = match major {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10usize),
        2 | 3 => {
            if bytes.len() < 12 {
                return Err(fmt("truncated .npy preamble".into()));
            }
            (u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize, 12)
        }
        v => return Err(IoError::Unsupported { path: path.into(), message: format!(".npy format version {v}") }),
    };
    let end = start
        .checked_add(header_len)
        .filter(|&e| e <= bytes.len())
        .ok_or_else(|| fmt(format!("truncated .npy header ({header_len} bytes announced)")))?;
    let header = std::str::from_utf8(&bytes[start..end]).map_err(|_| fmt(".npy header is not valid UTF-8".into()))?;
    let descr = dict_value(header, "descr").ok_or_else(|| fmt(format!("no 'descr' in .npy header {header:?}")))?;
    let fortran = dict_value(header, "fortran_order").ok_or_else(|| fmt("no 'fortran_order' in .npy header".into()))?;
    let shape = dict_value(header, "shape").ok_or_else(|| fmt("no 'shape' in .npy header".into()))?;
    let unsupported = |m: String| IoError::Unsupported { path: path.into(), message: m };
    let descr = descr.trim_matches(|c| c == '\'' || c == '"');
    let item = match descr {
        "<f4" => 4,
        "<f2" => 2,
        other => return Err(unsupported(format!("dtype '{other}' (only little-endian float32 '<f4' and float16 '<f2')"))),
    };
    match fortran {
        "False" => {}
        "True" => return Err(unsupported("Fortran-ordered array (only C order)".into())),
        other => return Err(fmt(format!("bad fortran_order value '{other}'"))),
    }
    let dims: Vec<usize> = shape
        .trim_start_matches('(')
        .trim_end_matches(')')
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse::<usize>().map_err(|_| fmt(format!("bad shape entry '{s}'"))))
        .collect::<Result<_>>()?;
    let (h, w, c) = match dims[..] {
        [h, w] => (h, w, 1),
        [h, w, c] => (h, w, c),
        _ => return Err(unsupported(format!("shape {dims:?}: only 2-D [H][W] and 3-D [H][W][C] arrays"))),
    };
    let count = h
        .checked_mul(w)
        .and_then(|p| p.checked_mul(c))
        .ok_or_else(|| fmt(format!("shape {dims:?} overflows")))?;
    let data = &bytes[end..];
    if count.checked_mul(item).is_none_or(|need| need != data.len()) {
        return Err(fmt(format!(
            "shape {dims:?} of {descr} needs {} data bytes but the file has {} (truncated or wrong shape)",
            count.saturating_mul(item),
            data.len()
        )));
    }
    let values: Vec<f32> = if item == 4 {
        data.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
    } else {
        data.chunks_exact(2).map(|b| f16_to_f32(u16::from_le_bytes([b[0], b[1]]))).collect()
    };
    Image::from_vec(w, h, c, values).map_err(|source| IoError::Core { path: path.into(), source })
}

/// Writes `image` as a float32 `.npy` (shape `(H, W)` for one channel, `(H, W, C)` otherwise),
/// atomically.
pub fn write_npy(path: &Path, image: &Image) -> Result<()> {
    let shape = if image.channels() == 1 {
        format!("({}, {})", image.height(), image.width())
    } else {
        format!("({}, {}, {})", image.height(), image.width(), image.channels())
    };
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}, }}");
    // Pad with spaces so that magic + 4 + header + '\n' is a multiple of 64.
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    write_atomic(path, |w| {
        w.write_all(MAGIC)?;
        w.write_all(&[1, 0])?;
        w.write_all(&(header.len() as u16).to_le_bytes())?;
        w.write_all(header.as_bytes())?;
        let mut buf = Vec::with_capacity(image.data().len() * 4);
        for v in image.data() {
            buf.extend_from_slice(&v.to_le_bytes());
        }
        w.write_all(&buf)
    })
}

/// The text of the value of `key` in a Python dict literal (up to the next top-level comma).
fn dict_value<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let pat_a = format!("'{key}'");
    let pat_b = format!("\"{key}\"");
    let at = header.find(&pat_a).map(|i| i + pat_a.len()).or_else(|| header.find(&pat_b).map(|i| i + pat_b.len()))?;
    let rest = header[at..].trim_start().strip_prefix(':')?.trim_start();
    let mut depth = 0i32;
    for (i, ch) in rest.char_indices() {
        match ch {
            '(' | '[' => depth += 1,
            ')' | ']' => {
                depth -= 1;
                if depth == 0 {
                    return Some(rest[..=i].trim());
                }
            }
            ',' | '}' if depth == 0 => return Some(rest[..i].trim()),
            _ => {}
        }
    }
    None
}

/// IEEE 754 binary16 → f32 (exact, including subnormals, infinities and NaN).
pub fn f16_to_f32(h: u16) -> f32 {
    let sign = ((h as u32) & 0x8000) << 16;
    let exp = ((h >> 10) & 0x1f) as u32;
    let mant = (h & 0x3ff) as u32;
    let bits = match (exp, mant) {
        (0, 0) => sign,
        (0, m) => {
            // Subnormal: value = m · 2^-24.
            let v = m as f32 * (1.0 / 16_777_216.0);
            return if sign != 0 { -v } else { v };
        }
        (0x1f, 0) => sign | 0x7f80_0000,
        (0x1f, m) => sign | 0x7fc0_0000 | (m << 13),
        (e, m) => sign | ((e + 127 - 15) << 23) | (m << 13),
    };
    f32::from_bits(bits)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f16_conversion_matches_half_for_every_pattern() {
        for h in 0..=u16::MAX {
            let ours = f16_to_f32(h);
            let theirs = ::exr::prelude::f16::from_bits(h).to_f32();
            assert!(ours.to_bits() == theirs.to_bits() || (ours.is_nan() && theirs.is_nan()), "{h:#x}: {ours} vs {theirs}");
        }
    }

    #[test]
    fn dict_parsing() {
        let h = "{'descr': '<f2', 'fortran_order': False, 'shape': (360, 480, 3), }";
        assert_eq!(dict_value(h, "descr"), Some("'<f2'"));
        assert_eq!(dict_value(h, "fortran_order"), Some("False"));
        assert_eq!(dict_value(h, "shape"), Some("(360, 480, 3)"));
        assert_eq!(dict_value(h, "nope"), None);
    }
}
