//! 8-bit PNG and JPEG export of f32 images (renders, normal maps, report pages), written
//! atomically.

use crate::atomic::write_atomic;
use crate::error::{IoError, Result};
use gs_core::Image;
use std::path::Path;

/// Writes a 1- or 3-channel image in [0, 1] as an 8-bit PNG (values clamped, round to
/// nearest, no gamma: the inverse of how images are read). NaN is written as 0.
pub fn write_png(path: &Path, image: &Image) -> Result<()> {
    let bytes = encode_png(image, path)?;
    write_atomic(path, |out| out.write_all(&bytes))
}

/// The bytes [`write_png`] writes; `path` only names the file in errors.
pub fn encode_png(image: &Image, path: &Path) -> Result<Vec<u8>> {
    let (bytes, color) = to_8bit(path, image, "PNG")?;
    let (w, h) = (image.width() as u32, image.height() as u32);
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(&bytes, w, h, color)
        .map_err(|e| IoError::invalid(path, format!("cannot encode the PNG: {e}")))?;
    Ok(out)
}

/// Writes a 1- or 3-channel image in [0, 1] as a baseline JPEG of `quality` (1–100; values
/// outside are clamped), converted to 8 bits as [`write_png`] does. For pictures people look
/// at (report pages), where a PNG would be ten times larger.
pub fn write_jpeg(path: &Path, image: &Image, quality: u8) -> Result<()> {
    let (bytes, color) = to_8bit(path, image, "JPEG")?;
    let (w, h) = (image.width() as u32, image.height() as u32);
    write_atomic(path, |out| {
        image::codecs::jpeg::JpegEncoder::new_with_quality(out, quality.clamp(1, 100))
            .write_image(&bytes, w, h, color)
            .map_err(std::io::Error::other)
    })
}

/// 8-bit samples of a 1- or 3-channel image: clamped to [0, 1], rounded, NaN as 0.
fn to_8bit(path: &Path, image: &Image, format: &str) -> Result<(Vec<u8>, image::ExtendedColorType)> {
    let color = match image.channels() {
        1 => image::ExtendedColorType::L8,
        3 => image::ExtendedColorType::Rgb8,
        c => return Err(IoError::invalid(path, format!("{format} export takes 1 or 3 channels, this image has {c}"))),
    };
    let bytes = image.data().iter().map(|v| if v.is_nan() { 0 } else { (v.clamp(0.0, 1.0) * 255.0).round() as u8 }).collect();
    Ok((bytes, color))
}

use image::ImageEncoder;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jpeg_round_trip_is_close() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.jpg");
        let img = Image::from_vec(16, 16, 3, (0..768).map(|i| 0.3 + 0.4 * ((i / 3) % 16) as f32 / 15.0).collect()).unwrap();
        write_jpeg(&p, &img, 95).unwrap();
        let back = crate::scene::decode_rgb(&p).unwrap();
        let err = img.data().iter().zip(back.data()).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        assert!(err < 0.05, "max error {err}");
    }

    #[test]
    fn round_trip_through_the_reader() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.png");
        let img = Image::from_vec(3, 2, 3, (0..18).map(|i| i as f32 / 17.0).collect()).unwrap();
        write_png(&p, &img).unwrap();
        let back = crate::scene::decode_rgb(&p).unwrap();
        for (a, b) in img.data().iter().zip(back.data()) {
            assert!((a - b).abs() <= 0.5 / 255.0 + 1e-6);
        }
        assert!(write_png(&p, &Image::new(2, 2, 2).unwrap()).unwrap_err().to_string().contains("2"));
    }
}
