//! Photos and masks: PNG/JPEG files decoded to f32 images under the size caps (the pixel cap
//! from the header, then the `image` crate's [`image::Limits`] inside the decoders, the file
//! read under [`crate::capped::IMAGE`]) and checked complete ([`crate::integrity`]).

use crate::error::{IoError, Result};
use image::ImageDecoder;
use gs_core::Image;
use std::path::Path;

/// Decodes an 8- or 16-bit PNG/JPEG as RGB f32 (value / 255 or / 65535, grey replicated,
/// alpha dropped). A truncated or structurally broken file is an error naming it
/// ([`crate::integrity`]), never a partial image.
pub fn decode_rgb(path: &Path) -> Result<Image> {
    rgb_of(open_checked(path)?, path)
}

/// [`decode_rgb`] of a file's bytes held in memory; `path` names the file in errors and its
/// extension gives the format, as for a file on disk.
pub fn decode_rgb_bytes(bytes: &[u8], path: &Path) -> Result<Image> {
    rgb_of(decode_checked(bytes, path)?, path)
}

/// Decodes a mask as one channel in `[0, 1]` (grey, or the luma of a colour file).
pub fn decode_mask(path: &Path) -> Result<Image> {
    mask_of(open_checked(path)?, path)
}

/// [`decode_mask`] of a file's bytes held in memory (see [`decode_rgb_bytes`]).
pub fn decode_mask_bytes(bytes: &[u8], path: &Path) -> Result<Image> {
    mask_of(decode_checked(bytes, path)?, path)
}

fn rgb_of(img: image::DynamicImage, path: &Path) -> Result<Image> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let data: Vec<f32> = if is_16bit(&img) {
        img.into_rgb16().into_raw().into_iter().map(|v| v as f32 / 65535.0).collect()
    } else {
        img.into_rgb8().into_raw().into_iter().map(|v| v as f32 / 255.0).collect()
    };
    Image::from_vec(w, h, 3, data).map_err(|e| IoError::Core { path: path.to_path_buf(), source: e })
}

fn mask_of(img: image::DynamicImage, path: &Path) -> Result<Image> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let data: Vec<f32> = if is_16bit(&img) {
        img.into_luma16().into_raw().into_iter().map(|v| v as f32 / 65535.0).collect()
    } else {
        img.into_luma8().into_raw().into_iter().map(|v| v as f32 / 255.0).collect()
    };
    Image::from_vec(w, h, 1, data).map_err(|e| IoError::Core { path: path.to_path_buf(), source: e })
}

fn is_16bit(img: &image::DynamicImage) -> bool {
    use image::DynamicImage::*;
    matches!(img, ImageLuma16(_) | ImageLumaA16(_) | ImageRgb16(_) | ImageRgba16(_))
}

/// The size of an image file from its header; an error naming a missing or unreadable file.
pub(crate) fn image_size(path: &Path) -> Result<(u32, u32)> {
    if !path.exists() {
        return Err(IoError::invalid(path, "missing image file"));
    }
    if !path.is_file() {
        return Err(IoError::invalid(path, "not a regular file (an image is read from a file, not a folder, pipe or device)"));
    }
    let mut reader = image::ImageReader::open(path).map_err(|e| IoError::io(path, e))?;
    reader.limits(decoder_limits());
    reader.into_dimensions().map_err(|e| image_error(path, e, "cannot read image header"))
}

fn open_checked(path: &Path) -> Result<image::DynamicImage> {
    check_pixel_cap(image_size(path)?, path)?;
    decode_checked(&crate::capped::IMAGE.read(path)?, path)
}

/// Refuses an image larger than [`gs_core::image::MAX_IMAGE_PIXELS`] before it is decoded.
fn check_pixel_cap((w, h): (u32, u32), path: &Path) -> Result<()> {
    if (w as usize).saturating_mul(h as usize) > gs_core::image::MAX_IMAGE_PIXELS {
        return Err(IoError::invalid(
            path,
            format!("image {w}x{h} exceeds the cap of {} pixels", gs_core::image::MAX_IMAGE_PIXELS),
        ));
    }
    Ok(())
}

/// Checks the size caps from the header (pixels, and samples the file's size can hold) and
/// that the container is complete (a cut JPEG would otherwise decode with grey rows), then
/// decodes the bytes as `image::open` would (format from the extension of `path`).
fn decode_checked(bytes: &[u8], path: &Path) -> Result<image::DynamicImage> {
    let reader = || -> image::ImageResult<image::ImageReader<std::io::Cursor<&[u8]>>> {
        let mut r = image::ImageReader::with_format(std::io::Cursor::new(bytes), image::ImageFormat::from_path(path)?);
        r.limits(decoder_limits());
        Ok(r)
    };
    let header = reader().and_then(|r| r.into_decoder()).map(|d| (d.dimensions(), d.total_bytes()));
    let ((w, h), decoded) = header.map_err(|e| image_error(path, e, "cannot read image header"))?;
    check_pixel_cap((w, h), path)?;
    // A header declaring more samples than the file could hold at any compression is a bomb or
    // a corrupt file: a 720-byte JPEG naming 65519x1012 pixels would otherwise allocate ~1 GB.
    if !crate::capped::holds_decoded(usize::try_from(decoded).unwrap_or(usize::MAX), bytes.len()) {
        return Err(IoError::format(
            path,
            format!(
                "image of {w}x{h} needs {} of samples, more than a file of {} bytes can hold at any compression (cut short, or a corrupt header?)",
                crate::capped::bytes(decoded),
                bytes.len()
            ),
        ));
    }
    crate::integrity::check_complete(path, bytes)?;
    reader().and_then(|r| r.decode()).map_err(|e| image_error(path, e, "cannot decode image"))
}

/// An `image` crate error in words; one over the [`decoder_limits`] names the caps.
fn image_error(path: &Path, e: image::ImageError, stage: &str) -> IoError {
    match e {
        image::ImageError::Limits(e) => IoError::invalid(
            path,
            format!(
                "{stage}: {e} (caps: {MAX_IMAGE_SIDE} pixels a side, {} pixels, {} decoded)",
                gs_core::image::MAX_IMAGE_PIXELS,
                crate::capped::bytes(DECODE_ALLOC_CAP)
            ),
        ),
        e => IoError::format(path, format!("{stage}: {e}")),
    }
}

/// The widest side of an image the decoders accept: the pixel cap as one strip 1024 rows high.
const MAX_IMAGE_SIDE: u32 = (gs_core::image::MAX_IMAGE_PIXELS >> 10) as u32;
/// The most the decoders allocate for one image: four 16-bit channels at the pixel cap (512 MiB).
const DECODE_ALLOC_CAP: u64 = gs_core::image::MAX_IMAGE_PIXELS as u64 * 8;

/// The `image` crate's decoder limits: sides and allocation, enforced inside the decoders
/// (the pixel count itself is [`check_pixel_cap`]'s, which `Limits` does not express).
fn decoder_limits() -> image::Limits {
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_IMAGE_SIDE);
    limits.max_image_height = Some(MAX_IMAGE_SIDE);
    limits.max_alloc = Some(DECODE_ALLOC_CAP);
    limits
}
