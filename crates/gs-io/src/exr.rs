//! Float OpenEXR depth and normal maps (via the `exr` crate).
//!
//! Channel naming: a 1-channel [`Image`] (depth = camera z, docs/architecture.md §Conventions) is written as the single
//! f32 channel **`Z`** (the OpenEXR convention for depth); a 3-channel image (normals) as
//! f32 `R G B`; a 4-channel image as `R G B A`. Compression: ZIP (lossless), one layer.
//!
//! Reading takes the first layer at its largest resolution and returns: `R G B` (+ `A` when
//! present) as 3 (4) channels; else a channel `Z`, else `Y`, else the only channel, as 1
//! channel. f16 and u32 samples are converted to f32. Values are returned as stored (NaN or
//! infinite background included; callers decide). Sizes are checked against the
//! [`gs_core::image::MAX_IMAGE_PIXELS`] cap before any pixel is decoded.

use crate::atomic::write_atomic;
use crate::error::{IoError, Result};
use ::exr::prelude as x;
use ::exr::prelude::{ReadChannels, ReadLayers};
use gs_core::Image;
use gs_core::image::MAX_IMAGE_PIXELS;
use std::io::Cursor;
use std::path::Path;

/// The most sample bytes of one layer the reader decodes ([`crate::capped::IMAGE_SAMPLE_CAP`]).
const MAX_SAMPLE_BYTES: usize = crate::capped::IMAGE_SAMPLE_CAP as usize;

/// Writes a 1-channel depth map as an EXR with the single f32 channel `Z`.
pub fn write_depth_exr(path: &Path, depth: &Image) -> Result<()> {
    if depth.channels() != 1 {
        return Err(IoError::invalid(path, format!("a depth map has 1 channel, this image has {}", depth.channels())));
    }
    write_exr(path, depth)
}

/// Writes a 3-channel normal map as an EXR with f32 channels `R G B`.
pub fn write_normal_exr(path: &Path, normal: &Image) -> Result<()> {
    if normal.channels() != 3 {
        return Err(IoError::invalid(path, format!("a normal map has 3 channels, this image has {}", normal.channels())));
    }
    write_exr(path, normal)
}

/// Writes a 1-, 3- or 4-channel image as a float EXR (channel names in the module docs),
/// atomically.
pub fn write_exr(path: &Path, image: &Image) -> Result<()> {
    let bytes = encode_exr(image).map_err(|m| IoError::invalid(path, m))?;
    write_atomic(path, |w| w.write_all(&bytes))
}

/// Encodes `image` as EXR bytes in memory (what [`write_exr`] writes; the error says why an
/// image cannot be written, e.g. its channel count).
pub fn encode_exr(image: &Image) -> std::result::Result<Vec<u8>, String> {
    let names: &[&str] = match image.channels() {
        1 => &["Z"],
        3 => &["R", "G", "B"],
        4 => &["R", "G", "B", "A"],
        c => return Err(format!("cannot write a {c}-channel image as EXR (1, 3 or 4 channels)")),
    };
    let (w, h, c) = (image.width(), image.height(), image.channels());
    let data = image.data();
    let channels: x::SmallVec<[x::AnyChannel<x::FlatSamples>; 4]> = names
        .iter()
        .enumerate()
        .map(|(k, name)| {
            let samples: Vec<f32> = data.iter().skip(k).step_by(c).copied().collect();
            x::AnyChannel::new(*name, x::FlatSamples::F32(samples))
        })
        .collect();
    let layer = x::Layer::new(
        (w, h),
        x::LayerAttributes::default(),
        x::Encoding { compression: x::Compression::ZIP16, ..x::Encoding::default() },
        x::AnyChannels::sort(channels),
    );
    let img = x::Image::from_layer(layer);
    let mut out = Cursor::new(Vec::new());
    x::WritableImage::write(&img).to_buffered(&mut out).map_err(|e| format!("EXR encoding failed: {e}"))?;
    Ok(out.into_inner())
}

/// Reads a float EXR map (see the module docs for the channel rules).
pub fn read_exr(path: &Path) -> Result<Image> {
    let bytes = crate::capped::IMAGE.read(path)?;
    parse_exr(&bytes, path)
}

/// Parses an EXR held in memory; `path` only names the file in errors.
pub fn parse_exr(bytes: &[u8], path: &Path) -> Result<Image> {
    let fmt = |m: String| IoError::format(path, m);
    // Check the sizes in the headers before decoding any pixel.
    let meta = ::exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), false)
        .map_err(|e| fmt(format!("not a readable EXR file: {e}")))?;
    let first = meta.headers.first().ok_or_else(|| fmt("EXR file has no layer".into()))?;
    for h in meta.headers.iter() {
        let size = h.layer_size;
        let pixels = size.width().checked_mul(size.height());
        if pixels.is_none_or(|p| p > MAX_IMAGE_PIXELS) {
            return Err(fmt(format!("EXR layer of {}x{} exceeds the cap of {MAX_IMAGE_PIXELS} pixels", size.width(), size.height())));
        }
        // Every channel of the layer is decoded: bound the samples too, or a small file naming
        // many channels would have the decoder allocate gigabytes before its data runs out.
        let per_pixel: usize = h.channels.list.iter().map(|c| c.sample_type.bytes_per_sample()).sum();
        if pixels.and_then(|p| p.checked_mul(per_pixel)).is_none_or(|b| b > MAX_SAMPLE_BYTES) {
            return Err(fmt(format!(
                "EXR layer of {}x{} with {} channels needs {} MiB of samples, more than the cap of {} MiB (4 float channels at {MAX_IMAGE_PIXELS} pixels)",
                size.width(),
                size.height(),
                h.channels.list.len(),
                pixels.unwrap_or(usize::MAX).saturating_mul(per_pixel) >> 20,
                MAX_SAMPLE_BYTES >> 20
            )));
        }
        // A layer the file's size cannot hold even at an extreme compression ratio is a cut or
        // corrupt file: refuse it before its samples are allocated (any file may name up to
        // 32 MiB; beyond that the file must hold the samples at 4096:1).
        let needed = pixels.unwrap_or(0).saturating_mul(per_pixel);
        // The exr crate sizes a chunk's buffer from the tile (not the layer), so a tile of
        // absurd size is held to the same rule.
        if let ::exr::meta::BlockDescription::Tiles(t) = h.blocks {
            let tile = t.tile_size.width().saturating_mul(t.tile_size.height()).saturating_mul(per_pixel);
            if !crate::capped::holds_decoded(tile, bytes.len()) {
                return Err(fmt(format!(
                    "EXR tiles of {}x{} with {} channels need {} MiB each, more than a file of {} bytes can hold (a corrupt header?)",
                    t.tile_size.width(),
                    t.tile_size.height(),
                    h.channels.list.len(),
                    tile >> 20,
                    bytes.len()
                )));
            }
        }
        if !crate::capped::holds_decoded(needed, bytes.len()) {
            return Err(fmt(format!(
                "EXR layer of {}x{} with {} channels needs {} MiB of samples, more than a file of {} bytes can hold at any compression (cut short, or a corrupt header?)",
                size.width(),
                size.height(),
                h.channels.list.len(),
                needed >> 20,
                bytes.len()
            )));
        }
    }
    if first.deep {
        return Err(IoError::Unsupported { path: path.into(), message: "deep EXR data".into() });
    }
    // Sequential: the exr crate builds a new thread pool for every parallel read, which costs
    // more than it gains on maps of this size and, over many reads, grew the process by
    // gigabytes (found by the `exr` fuzz target).
    let image = x::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_buffered(Cursor::new(bytes))
        .map_err(|e| fmt(format!("EXR decoding failed: {e}")))?;
    let layer = &image.layer_data;
    let (w, h) = (layer.size.width(), layer.size.height());
    let list = &layer.channel_data.list;
    let find = |name: &str| list.iter().position(|c| c.name.to_string() == name);
    let picked: Vec<usize> = if let (Some(r), Some(g), Some(b)) = (find("R"), find("G"), find("B")) {
        let mut v = vec![r, g, b];
        v.extend(find("A"));
        v
    } else if let Some(z) = find("Z").or_else(|| find("Y")) {
        vec![z]
    } else if list.len() == 1 {
        vec![0]
    } else {
        let names: Vec<String> = list.iter().map(|c| c.name.to_string()).collect();
        return Err(IoError::Unsupported {
            path: path.into(),
            message: format!("EXR channels {names:?}: expected R G B (normals) or a single Z / Y channel (depth)"),
        });
    };
    let c = picked.len();
    let mut data = vec![0f32; w * h * c];
    for (k, &ci) in picked.iter().enumerate() {
        let samples = &list[ci].sample_data;
        if samples.len() != w * h {
            return Err(fmt(format!("EXR channel '{}' has {} samples for {w}x{h} pixels", list[ci].name, samples.len())));
        }
        for (p, v) in samples.values_as_f32().enumerate() {
            data[p * c + k] = v;
        }
    }
    Image::from_vec(w, h, c, data).map_err(|source| IoError::Core { path: path.into(), source })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn in_memory_round_trip_keeps_bits_and_channel_names() {
        let mut img = Image::new(5, 3, 3).unwrap();
        for (i, v) in img.data_mut().iter_mut().enumerate() {
            *v = (i as f32 * 0.37).sin() * 1e-3 + i as f32;
        }
        let bytes = encode_exr(&img).unwrap();
        let back = parse_exr(&bytes, Path::new("n.exr")).unwrap();
        assert_eq!(back.width(), 5);
        assert_eq!(back.height(), 3);
        let a: Vec<u32> = img.data().iter().map(|v| v.to_bits()).collect();
        let b: Vec<u32> = back.data().iter().map(|v| v.to_bits()).collect();
        assert_eq!(a, b);
        assert!(encode_exr(&Image::new(2, 2, 2).unwrap()).is_err());
    }
}
