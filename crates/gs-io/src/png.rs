//! 8-bit PNG export of f32 images (renders, normal maps), written atomically.

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
    let color = match image.channels() {
        1 => image::ExtendedColorType::L8,
        3 => image::ExtendedColorType::Rgb8,
        c => return Err(IoError::invalid(path, format!("PNG export takes 1 or 3 channels, this image has {c}"))),
    };
    let bytes: Vec<u8> =
        image.data().iter().map(|v| if v.is_nan() { 0 } else { (v.clamp(0.0, 1.0) * 255.0).round() as u8 }).collect();
    let (w, h) = (image.width() as u32, image.height() as u32);
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(&bytes, w, h, color)
        .map_err(|e| IoError::invalid(path, format!("cannot encode the PNG: {e}")))?;
    Ok(out)
}

use image::ImageEncoder;

#[cfg(test)]
mod tests {
    use super::*;

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
