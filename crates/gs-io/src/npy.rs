//! A minimal NumPy `.npy` / `.npz` reader (and f32 `.npy` writer) for depth and normal maps
//! and for pretrained weights.
//!
//! Reads `float32` (`<f4`) and `float16` (`<f2`) arrays in C order, format versions 1.0, 2.0
//! and 3.0: any rank as an [`NpyArray`], 2-D `[H][W]` (→ a 1-channel [`Image`]) or 3-D
//! `[H][W][C]` (→ a C-channel image) through [`read_npy`]; `.npz` archives written by
//! `numpy.savez` (uncompressed zip) through [`read_npz`]. Everything else (big-endian, other dtypes, Fortran order, other ranks) is rejected with
//! a clear [`IoError`]. Values are returned as stored (NaN and infinities included): the
//! synth-bunny ground truth uses 0 for "no surface".

use crate::atomic::write_atomic;
use crate::error::{IoError, Result};
use gs_core::Image;
pub use gs_core::half::f16_to_f32;
use std::path::Path;

const MAGIC: &[u8] = b"\x93NUMPY";

/// Reads a `.npy` file of any rank (see the module docs for what is accepted).
pub fn read_npy_array(path: &Path) -> Result<NpyArray> {
    let bytes = crate::capped::NPY.read(path)?;
    parse_npy_array(&bytes, path)
}

/// Reads a `.npy` file into an [`Image`] (see the module docs for what is accepted).
pub fn read_npy(path: &Path) -> Result<Image> {
    let bytes = crate::capped::NPY.read(path)?;
    parse_npy(&bytes, path)
}

/// An array of any rank read from a `.npy` file: C-order shape and values (f16 widened to f32).
#[derive(Debug, Clone, PartialEq)]
pub struct NpyArray {
    /// Shape, C order (empty for a scalar).
    pub shape: Vec<usize>,
    /// Values in C order.
    pub data: Vec<f32>,
}

/// Parses a `.npy` file held in memory into an [`Image`] (2-D or 3-D arrays only); `path` only
/// names the file in errors.
pub fn parse_npy(bytes: &[u8], path: &Path) -> Result<Image> {
    let array = parse_npy_array(bytes, path)?;
    let dims = &array.shape;
    let (h, w, c) = match dims[..] {
        [h, w] => (h, w, 1),
        [h, w, c] => (h, w, c),
        _ => {
            return Err(IoError::Unsupported {
                path: path.into(),
                message: format!("shape {dims:?}: only 2-D [H][W] and 3-D [H][W][C] arrays are images"),
            });
        }
    };
    Image::from_vec(w, h, c, array.data).map_err(|source| IoError::Core { path: path.into(), source })
}

/// Parses a `.npy` file of any rank held in memory; `path` only names the file in errors.
pub fn parse_npy_array(bytes: &[u8], path: &Path) -> Result<NpyArray> {
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
    let cap = crate::capped::NPY;
    let count = dims.iter().try_fold(1u64, |p, &d| p.checked_mul(d as u64)).ok_or_else(|| {
        fmt(format!("shape {dims:?} declares more than 2^64 values; the cap for {} is {}", cap.what, crate::capped::bytes(cap.bytes)))
    })?;
    let data = &bytes[end..];
    cap.check_declared(path, &format!("shape {dims:?} of {descr}"), (count, "values"), item as u64, data.len() as u64)?;
    if count * item as u64 != data.len() as u64 {
        return Err(fmt(format!(
            "shape {dims:?} of {descr} needs {} data bytes but the file has {} (truncated or wrong shape)",
            count * item as u64,
            data.len()
        )));
    }
    let values: Vec<f32> = if item == 4 {
        data.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
    } else {
        data.chunks_exact(2).map(|b| f16_to_f32(u16::from_le_bytes([b[0], b[1]]))).collect()
    };
    Ok(NpyArray { shape: dims, data: values })
}

/// Reads every array of an `.npz` archive (as written by `numpy.savez`: an uncompressed zip
/// of `.npy` members), in archive order, as `(name without ".npy", array)`. Compressed
/// members (`numpy.savez_compressed`) are rejected with a clear error.
pub fn read_npz(path: &Path) -> Result<Vec<(String, NpyArray)>> {
    let bytes = crate::capped::NPY.read(path)?;
    parse_npz(&bytes, path)
}

/// Parses an `.npz` archive held in memory (see [`read_npz`]).
pub fn parse_npz(bytes: &[u8], path: &Path) -> Result<Vec<(String, NpyArray)>> {
    let fmt = |m: String| IoError::format(path, m);
    let u16_at = |o: usize| -> Result<u16> {
        bytes.get(o..o + 2).map(|b| u16::from_le_bytes([b[0], b[1]])).ok_or_else(|| fmt(format!("truncated zip at byte {o}")))
    };
    let u32_at = |o: usize| -> Result<u32> {
        bytes
            .get(o..o + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .ok_or_else(|| fmt(format!("truncated zip at byte {o}")))
    };
    let mut out = Vec::new();
    let mut at = 0usize;
    // Local file headers follow each other; the central directory (PK\x01\x02) ends them.
    while at + 4 <= bytes.len() && u32_at(at)? == 0x0403_4b50 {
        let flags = u16_at(at + 6)?;
        let method = u16_at(at + 8)?;
        let mut size = u32_at(at + 18)? as u64;
        let name_len = u16_at(at + 26)? as usize;
        let extra_len = u16_at(at + 28)? as usize;
        let name_bytes = bytes.get(at + 30..at + 30 + name_len).ok_or_else(|| fmt("truncated zip member name".into()))?;
        let name = String::from_utf8_lossy(name_bytes).into_owned();
        let extra = bytes.get(at + 30 + name_len..at + 30 + name_len + extra_len).ok_or_else(|| fmt(format!("truncated zip header of {name}")))?;
        if size == 0xFFFF_FFFF {
            // Zip64: the extra field 0x0001 holds the 64-bit uncompressed, then compressed size.
            let mut e = 0;
            while e + 4 <= extra.len() {
                let (id, len) = (u16::from_le_bytes([extra[e], extra[e + 1]]), u16::from_le_bytes([extra[e + 2], extra[e + 3]]) as usize);
                if id == 1 && len >= 16 && e + 4 + 16 <= extra.len() {
                    size = u64::from_le_bytes(extra[e + 12..e + 20].try_into().expect("8 bytes"));
                }
                e += 4 + len;
            }
        }
        if method != 0 {
            return Err(IoError::Unsupported {
                path: path.into(),
                message: format!("member {name} is compressed (method {method}); only numpy.savez's uncompressed .npz is read"),
            });
        }
        if flags & 0x8 != 0 {
            return Err(IoError::Unsupported { path: path.into(), message: format!("member {name} has a trailing data descriptor (streamed zip)") });
        }
        let start = at + 30 + name_len + extra_len;
        let end = usize::try_from(size).ok().and_then(|s| start.checked_add(s)).filter(|&e| e <= bytes.len()).ok_or_else(|| {
            fmt(format!("member {name} announces {size} bytes but the archive ends first (truncated)"))
        })?;
        let member = path.join(&name);
        let array = parse_npy_array(&bytes[start..end], &member)?;
        out.push((name.trim_end_matches(".npy").to_string(), array));
        at = end;
    }
    if out.is_empty() {
        return Err(fmt("not an .npz archive (no zip member at the start)".into()));
    }
    Ok(out)
}

/// Writes `image` as a float32 `.npy` (shape `(H, W)` for one channel, `(H, W, C)` otherwise),
/// atomically.
pub fn write_npy(path: &Path, image: &Image) -> Result<()> {
    let bytes = encode_npy(image);
    write_atomic(path, |w| w.write_all(&bytes))
}

/// The bytes [`write_npy`] writes: a version 1.0 float32 `.npy` of `image`.
pub fn encode_npy(image: &Image) -> Vec<u8> {
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
    let mut out = Vec::with_capacity(10 + header.len() + image.data().len() * 4);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&[1, 0]);
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in image.data() {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
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
