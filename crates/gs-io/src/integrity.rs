//! Structural completeness checks of PNG and JPEG files, run before decoding.
//!
//! The `image` crate's JPEG decoder is lenient: a file cut short (an interrupted copy or
//! download) decodes "successfully" with the missing rows filled grey, and vagsl would train on
//! it. These checks walk the file's container structure (JPEG marker segments, PNG chunks) and
//! refuse a file that ends before its end marker or whose structure is broken, naming the file
//! and the byte where it goes wrong. They do not decode pixels; the decoder still catches
//! corrupt compressed data it can detect (PNG checksums, invalid Huffman codes).

use crate::error::{IoError, Result};
use std::path::Path;

const PNG_SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];

/// Checks that `bytes` (the content of `path`) is a complete PNG or JPEG: a JPEG must reach
/// its end-of-image marker, a PNG its `IEND` chunk, every segment or chunk lying inside the
/// file. Other content is left to the decoder, which names the format problem.
pub fn check_complete(path: &Path, bytes: &[u8]) -> Result<()> {
    if bytes.starts_with(&PNG_SIGNATURE) {
        check_png(bytes).map_err(|m| IoError::format(path, m))
    } else if bytes.starts_with(&[0xFF, 0xD8]) {
        check_jpeg(bytes).map_err(|m| IoError::format(path, m))
    } else {
        Ok(())
    }
}

fn be_u16(b: &[u8], at: usize) -> Option<usize> {
    Some(u16::from_be_bytes([*b.get(at)?, *b.get(at + 1)?]) as usize)
}

fn be_u32(b: &[u8], at: usize) -> Option<usize> {
    let s = b.get(at..at + 4)?;
    Some(u32::from_be_bytes([s[0], s[1], s[2], s[3]]) as usize)
}

/// The message for a file that ends before its end marker.
fn truncated(kind: &str, len: usize, what: &str) -> String {
    format!("truncated {kind}: the file ends after {len} bytes, {what} (incomplete copy or download?)")
}

/// Walks the marker segments of a JPEG from SOI to EOI. Inside a scan (after SOS), the
/// entropy-coded data runs to the next marker that is not a stuffed `FF 00` or a restart
/// marker. Garbage between segments is skipped as decoders do; the file must reach EOI.
fn check_jpeg(b: &[u8]) -> std::result::Result<(), String> {
    let mut pos = 2;
    let mut scans = 0usize;
    loop {
        // Find the next 0xFF, then skip fill bytes (repeated 0xFF).
        while pos < b.len() && b[pos] != 0xFF {
            pos += 1;
        }
        while pos < b.len() && b[pos] == 0xFF {
            pos += 1;
        }
        let Some(&marker) = b.get(pos) else {
            let what = if scans == 0 { "before its image data" } else { "before its end-of-image marker" };
            return Err(truncated("JPEG", b.len(), what));
        };
        pos += 1;
        match marker {
            0xD9 if scans == 0 => return Err(format!("JPEG has no image data: end-of-image marker at byte {}", pos - 2)),
            0xD9 => return Ok(()),
            // Standalone markers: restart (RSTn), TEM, a stray 0x00 after a fill byte.
            0xD0..=0xD7 | 0x01 | 0x00 => continue,
            _ => {}
        }
        let seg_start = pos - 2;
        let Some(len) = be_u16(b, pos) else {
            return Err(truncated("JPEG", b.len(), &format!("inside the header of the segment at byte {seg_start}")));
        };
        if len < 2 {
            return Err(format!("corrupt JPEG: segment at byte {seg_start} has an invalid length {len}"));
        }
        if pos + len > b.len() {
            return Err(truncated(
                "JPEG",
                b.len(),
                &format!("inside the segment at byte {seg_start}, which needs {} bytes", pos + len),
            ));
        }
        pos += len;
        if marker == 0xDA {
            scans += 1;
            pos = end_of_entropy_data(b, pos).ok_or_else(|| truncated("JPEG", b.len(), "inside its compressed image data"))?;
        }
    }
}

/// The offset of the marker that ends the entropy-coded data starting at `pos`, or `None`
/// when the file ends first.
fn end_of_entropy_data(b: &[u8], mut pos: usize) -> Option<usize> {
    loop {
        let ff = pos + b.get(pos..)?.iter().position(|&x| x == 0xFF)?;
        let mut next = ff + 1;
        while *b.get(next)? == 0xFF {
            next += 1;
        }
        match b[next] {
            0x00 | 0xD0..=0xD7 => pos = next + 1,
            _ => return Some(ff),
        }
    }
}

/// Walks the chunks of a PNG from the signature to `IEND`; every chunk must lie inside the
/// file and `IDAT` must come before `IEND`.
fn check_png(b: &[u8]) -> std::result::Result<(), String> {
    let mut pos = PNG_SIGNATURE.len();
    let mut idat = false;
    loop {
        let (Some(len), Some(kind)) = (be_u32(b, pos), b.get(pos + 4..pos + 8)) else {
            let what = if idat { "before its IEND chunk" } else { "before its image data" };
            return Err(truncated("PNG", b.len(), what));
        };
        let name = String::from_utf8_lossy(kind).into_owned();
        if !kind.iter().all(u8::is_ascii_alphabetic) {
            return Err(format!("corrupt PNG: invalid chunk type {kind:02x?} at byte {pos}"));
        }
        let end = pos.checked_add(12).and_then(|p| p.checked_add(len)).filter(|&e| e <= b.len());
        let Some(end) = end else {
            return Err(truncated("PNG", b.len(), &format!("inside its {name} chunk at byte {pos}")));
        };
        match kind {
            b"IDAT" => idat = true,
            b"IEND" if !idat => return Err(format!("PNG has no image data: IEND chunk at byte {pos} before any IDAT")),
            b"IEND" => return Ok(()),
            _ => {}
        }
        pos = end;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn png_bytes() -> Vec<u8> {
        let mut v = Vec::new();
        let img = image::RgbImage::from_fn(16, 8, |x, y| image::Rgb([x as u8 * 9, y as u8 * 20, 3]));
        img.write_to(&mut std::io::Cursor::new(&mut v), image::ImageFormat::Png).unwrap();
        v
    }

    #[test]
    fn png_cut_anywhere_is_refused() {
        let full = png_bytes();
        assert!(check_png(&full).is_ok());
        for cut in 8..full.len() {
            let e = check_png(&full[..cut]).unwrap_err();
            assert!(e.starts_with("truncated PNG"), "cut at {cut}: {e}");
        }
    }

    #[test]
    fn jpeg_scan_skips_stuffed_bytes_and_restarts() {
        // SOI, a minimal SOS segment, entropy data with FF 00 and RST0, then EOI.
        let mut b = vec![0xFF, 0xD8, 0xFF, 0xDA, 0x00, 0x02];
        b.extend_from_slice(&[0x12, 0xFF, 0x00, 0x34, 0xFF, 0xD0, 0x56]);
        let complete = [b.clone(), vec![0xFF, 0xD9]].concat();
        assert!(check_jpeg(&complete).is_ok());
        let e = check_jpeg(&b).unwrap_err();
        assert!(e.contains("inside its compressed image data"), "{e}");
        // A lone EOI right after SOI is not an image.
        assert!(check_jpeg(&[0xFF, 0xD8, 0xFF, 0xD9]).unwrap_err().contains("no image data"));
        // A segment length below 2 is corrupt.
        assert!(check_jpeg(&[0xFF, 0xD8, 0xFF, 0xE0, 0x00, 0x01, 0xFF, 0xD9]).unwrap_err().contains("invalid length"));
    }
}
