//! A minimal `.npy` reader (little-endian `<f2`, `<f4`, `<f8`, C order) for reference data and
//! tests; values are returned as f64.

use crate::error::{LossError, Result};
use std::path::Path;

/// An array read from a `.npy` file.
#[derive(Debug, Clone, PartialEq)]
pub struct NpyArray {
    /// Shape, C order.
    pub shape: Vec<usize>,
    /// Values in C order, converted to f64.
    pub data: Vec<f64>,
}

/// IEEE half → f32 (exact, including subnormals, infinities and NaN).
pub fn f16_to_f32(h: u16) -> f32 {
    let sign = ((h >> 15) as u32) << 31;
    let exp = ((h >> 10) & 0x1f) as u32;
    let man = (h & 0x3ff) as u32;
    let bits = if exp == 0 {
        if man == 0 {
            sign
        } else {
            // Subnormal: value = man · 2^-24.
            let v = man as f32 * (1.0 / 16_777_216.0);
            return if sign != 0 { -v } else { v };
        }
    } else if exp == 0x1f {
        sign | 0x7f80_0000 | (man << 13)
    } else {
        sign | ((exp + 112) << 23) | (man << 13)
    };
    f32::from_bits(bits)
}

/// Reads a `.npy` file.
pub fn read_npy(path: &Path) -> Result<NpyArray> {
    let bytes = std::fs::read(path).map_err(|e| LossError::Npy {
        file: path.display().to_string(),
        problem: e.to_string(),
    })?;
    parse_npy(&bytes).map_err(|problem| LossError::Npy {
        file: path.display().to_string(),
        problem,
    })
}

/// Parses the bytes of a `.npy` file.
pub fn parse_npy(b: &[u8]) -> std::result::Result<NpyArray, String> {
    if b.len() < 10 || &b[..6] != b"\x93NUMPY" {
        return Err("not a .npy file (bad magic)".into());
    }
    let (hlen, start) = match b[6] {
        1 => (u16::from_le_bytes([b[8], b[9]]) as usize, 10),
        2 | 3 => {
            if b.len() < 12 {
                return Err("truncated header".into());
            }
            (u32::from_le_bytes([b[8], b[9], b[10], b[11]]) as usize, 12)
        }
        v => return Err(format!("unsupported .npy version {v}")),
    };
    let header = b.get(start..start + hlen).ok_or("truncated header")?;
    let header = std::str::from_utf8(header).map_err(|_| "header is not UTF-8")?;
    let field = |key: &str| -> std::result::Result<&str, String> {
        let i = header.find(key).ok_or(format!("header lacks {key}"))?;
        Ok(header[i + key.len()..].trim_start_matches([' ', ':']))
    };
    let descr = field("'descr'")?;
    let descr = descr.trim_start_matches(['\'', '"']);
    let (size, kind) = if descr.starts_with("<f4") {
        (4, 4)
    } else if descr.starts_with("<f8") {
        (8, 8)
    } else if descr.starts_with("<f2") {
        (2, 2)
    } else {
        return Err(format!(
            "unsupported dtype {}",
            &descr[..descr.len().min(6)]
        ));
    };
    if field("'fortran_order'")?.starts_with("True") {
        return Err("Fortran-order arrays are not supported".into());
    }
    let shape_s = field("'shape'")?;
    let open = shape_s.find('(').ok_or("bad shape")?;
    let close = shape_s.find(')').ok_or("bad shape")?;
    let shape: Vec<usize> = shape_s[open + 1..close]
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse::<usize>()
                .map_err(|_| format!("bad shape entry {s}"))
        })
        .collect::<std::result::Result<_, _>>()?;
    let n = shape
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .ok_or("shape overflows")?;
    let body = &b[start + hlen..];
    if body.len() < n * size {
        return Err(format!(
            "truncated data: {} bytes for {n} values of {size} bytes",
            body.len()
        ));
    }
    let data = body[..n * size]
        .chunks_exact(size)
        .map(|c| match kind {
            4 => f32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64,
            8 => f64::from_le_bytes(c.try_into().expect("8 bytes")),
            _ => f16_to_f32(u16::from_le_bytes([c[0], c[1]])) as f64,
        })
        .collect();
    Ok(NpyArray { shape, data })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_conversion() {
        assert_eq!(f16_to_f32(0x3c00), 1.0);
        assert_eq!(f16_to_f32(0xc000), -2.0);
        assert_eq!(f16_to_f32(0x3555), 0.333_251_95);
        assert_eq!(f16_to_f32(0x0001), 2f32.powi(-24));
        assert_eq!(f16_to_f32(0x7c00), f32::INFINITY);
        assert!(f16_to_f32(0x7e00).is_nan());
        assert_eq!(f16_to_f32(0x8000).to_bits(), (-0.0f32).to_bits());
    }

    fn npy(descr: &str, shape: &str, data: &[u8]) -> Vec<u8> {
        let h = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
        let mut v = b"\x93NUMPY\x01\x00".to_vec();
        v.extend_from_slice(&(h.len() as u16).to_le_bytes());
        v.extend_from_slice(h.as_bytes());
        v.extend_from_slice(data);
        v
    }

    #[test]
    fn parses_f4_f2_and_rejects_bad_files() {
        let d: Vec<u8> = [1.5f32, -2.0, 3.25]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let a = parse_npy(&npy("<f4", "(3,)", &d)).unwrap();
        assert_eq!(a.shape, vec![3]);
        assert_eq!(a.data, vec![1.5, -2.0, 3.25]);
        let h = parse_npy(&npy("<f2", "(1, 2)", &[0x00, 0x3c, 0x00, 0xc0])).unwrap();
        assert_eq!((h.shape, h.data), (vec![1, 2], vec![1.0, -2.0]));
        assert!(
            parse_npy(&npy("<f4", "(4,)", &d))
                .unwrap_err()
                .contains("truncated")
        );
        assert!(
            parse_npy(&npy("<i4", "(3,)", &d))
                .unwrap_err()
                .contains("dtype")
        );
        assert!(parse_npy(b"not an npy file").is_err());
        assert!(
            read_npy(Path::new("/nonexistent.npy"))
                .unwrap_err()
                .to_string()
                .contains("/nonexistent.npy")
        );
    }
}
