//! Small quantisation helpers shared by the codecs.

use std::path::Path;

use crate::error::{ExportError, Result};

/// `round(x)` clamped to `0..=255` (NaN gives 0): the byte rounding of spz's `toUint8` and of a
/// JavaScript `Uint8ClampedArray` store.
#[inline]
pub fn to_u8(x: f32) -> u8 {
    if x.is_nan() { 0 } else { x.round().clamp(0.0, 255.0) as u8 }
}

/// sRGB-encoded byte → linear value in `[0, 1]` (the glTF vertex colour space).
pub fn srgb_to_linear(c: u8) -> f32 {
    let s = c as f32 / 255.0;
    if s <= 0.04045 { s / 12.92 } else { ((s + 0.055) / 1.055).powf(2.4) }
}

/// Linear value → sRGB-encoded byte (rounded; out-of-range values clamped).
pub fn linear_to_srgb(l: f32) -> u8 {
    let l = if l.is_nan() { 0.0 } else { l.clamp(0.0, 1.0) };
    let s = if l <= 0.003_130_8 { l * 12.92 } else { 1.055 * l.powf(1.0 / 2.4) - 0.055 };
    to_u8(s * 255.0)
}

/// Little-endian reader over a byte slice that reports truncation as a format error naming
/// `path` and what was being read.
pub struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
    path: &'a Path,
}

impl<'a> Cursor<'a> {
    /// A cursor at the start of `bytes`.
    pub fn new(bytes: &'a [u8], path: &'a Path) -> Self {
        Self { bytes, pos: 0, path }
    }

    /// The next `n` bytes, or an error saying the file ends inside `what`.
    pub fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.bytes.len());
        let Some(end) = end else {
            return Err(ExportError::format(self.path, format!("the file ends inside the {what} (truncated)")));
        };
        let s = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(s)
    }

    /// The next little-endian `u32`.
    pub fn u32(&mut self, what: &str) -> Result<u32> {
        let b = self.take(4, what)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    /// Bytes left.
    pub fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }
}

/// The little-endian `f32` at `b[0..4]`.
#[inline]
pub fn f32_at(b: &[u8]) -> f32 {
    f32::from_le_bytes([b[0], b[1], b[2], b[3]])
}

/// The little-endian `u32` at `b[0..4]`.
#[inline]
pub fn u32_at(b: &[u8]) -> u32 {
    u32::from_le_bytes([b[0], b[1], b[2], b[3]])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips_every_byte() {
        for c in 0..=255u8 {
            assert_eq!(linear_to_srgb(srgb_to_linear(c)), c);
        }
    }

    #[test]
    fn bytes_round_and_clamp() {
        assert_eq!(to_u8(-3.0), 0);
        assert_eq!(to_u8(254.6), 255);
        assert_eq!(to_u8(300.0), 255);
        assert_eq!(to_u8(f32::NAN), 0);
        // The shared rule the codecs quantise through: a degenerate rotation is the identity.
        assert_eq!(gs_core::gaussians::unit_quaternion([0.0; 4]), [1.0, 0.0, 0.0, 0.0]);
    }
}
