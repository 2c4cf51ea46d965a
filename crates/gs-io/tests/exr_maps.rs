//! EXR depth and normal maps: bit-exact round trips, channel names, bad input.

use gs_core::Image;
use gs_io::{read_exr, write_depth_exr, write_exr, write_normal_exr};

fn ramp(w: usize, h: usize, c: usize) -> Image {
    let data = (0..w * h * c).map(|i| ((i * 7919) % 1000) as f32 * 0.001234 - 0.3).collect();
    Image::from_vec(w, h, c, data).unwrap()
}

#[test]
fn depth_and_normal_round_trip_bit_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let mut depth = ramp(37, 23, 1);
    depth.set(0, 0, 0, 0.0);
    depth.set(5, 5, 0, 1e-30);
    let p = dir.path().join("depth.exr");
    write_depth_exr(&p, &depth).unwrap();
    let back = read_exr(&p).unwrap();
    assert_eq!((back.width(), back.height(), back.channels()), (37, 23, 1));
    assert!(back.data().iter().zip(depth.data()).all(|(a, b)| a.to_bits() == b.to_bits()));

    let normal = ramp(16, 9, 3);
    let p = dir.path().join("normal.exr");
    write_normal_exr(&p, &normal).unwrap();
    let back = read_exr(&p).unwrap();
    assert_eq!(back, normal);
    // Channel names as documented: Z for depth, R G B for normals.
    let meta = exr::meta::MetaData::read_from_file(dir.path().join("depth.exr"), false).unwrap();
    let names: Vec<String> = meta.headers[0].channels.list.iter().map(|c| c.name.to_string()).collect();
    assert_eq!(names, ["Z"]);
    let meta = exr::meta::MetaData::read_from_file(&p, false).unwrap();
    let names: Vec<String> = meta.headers[0].channels.list.iter().map(|c| c.name.to_string()).collect();
    assert_eq!(names, ["B", "G", "R"]); // EXR stores channels sorted by name.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
}

#[test]
fn wrong_channel_counts_and_bad_files() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("x.exr");
    assert!(write_depth_exr(&p, &ramp(4, 4, 3)).unwrap_err().to_string().contains("x.exr"));
    assert!(write_normal_exr(&p, &ramp(4, 4, 1)).is_err());
    assert!(write_exr(&p, &ramp(4, 4, 2)).unwrap_err().to_string().contains("2-channel"));
    assert!(!p.exists());
    std::fs::write(&p, b"not an exr at all").unwrap();
    let e = read_exr(&p).unwrap_err().to_string();
    assert!(e.contains("x.exr") && e.contains("EXR"), "{e}");
    // A truncated real file.
    let good = dir.path().join("good.exr");
    write_exr(&good, &ramp(64, 64, 3)).unwrap();
    let bytes = std::fs::read(&good).unwrap();
    std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
    assert!(read_exr(&p).unwrap_err().to_string().contains("x.exr"));
}

/// Found by the `exr` fuzz target: a B44 block whose deltas wrap around. The exr crate's B44
/// decoder computes in u32 with wrap-around on purpose, as OpenEXR's C reference does, so an
/// overflow-checked build panicked on it; a release build must read it (as the wrapped values)
/// or refuse it with a message, and never panic.
#[test]
fn a_b44_block_with_wrapping_deltas_is_not_a_panic() {
    let bytes = include_bytes!("fixtures/fuzz/exr_b44_wrapping.exr");
    let path = std::path::Path::new("b44.exr");
    match gs_io::exr::parse_exr(bytes, path) {
        Ok(img) => assert!(img.width() * img.height() > 0),
        Err(e) => assert!(e.to_string().contains("b44.exr"), "{e}"),
    }
}

/// Found by the `exr` fuzz target: a tiled, single-level file whose tile names level (1, 0).
/// The exr crate's debug assertion on its own line indexing fired; a release build must read
/// the file or refuse it with a message, and never panic.
#[test]
fn a_tile_of_a_level_the_file_does_not_have_is_not_a_panic() {
    let bytes = include_bytes!("fixtures/fuzz/exr_tile_level_mismatch.exr");
    let path = std::path::Path::new("tiles.exr");
    match gs_io::exr::parse_exr(bytes, path) {
        Ok(img) => assert_eq!((img.width(), img.height(), img.channels()), (5, 3, 4)),
        Err(e) => assert!(e.to_string().contains("tiles.exr"), "{e}"),
    }
}

/// A small file whose header names a large layer with many channels is refused from the
/// header, before the decoder allocates every channel's samples (the `exr` fuzz run peaked at
/// 2 GiB on such inputs).
#[test]
fn a_header_naming_more_samples_than_the_cap_is_refused_before_decoding() {
    use exr::prelude::*;
    let channels: SmallVec<[AnyChannel<FlatSamples>; 4]> =
        ["A", "B", "G", "R", "Z"].iter().map(|n| AnyChannel::new(*n, FlatSamples::F32(vec![0.5; 4]))).collect();
    let layer = Layer::new((2, 2), LayerAttributes::default(), Encoding::UNCOMPRESSED, AnyChannels::sort(channels));
    let mut out = std::io::Cursor::new(Vec::new());
    Image::from_layer(layer).write().to_buffered(&mut out).unwrap();
    let mut bytes = out.into_inner();
    let path = std::path::Path::new("wide.exr");
    assert!(gs_io::exr::parse_exr(&bytes, path).is_ok());
    // dataWindow (box2i: xmin, ymin, xmax, ymax) → 8192 × 8192, the pixel cap, × 5 channels.
    let key = b"dataWindow\0box2i\0";
    let at = bytes.windows(key.len()).position(|w| w == key).unwrap() + key.len() + 4;
    bytes[at + 8..at + 12].copy_from_slice(&8191i32.to_le_bytes());
    bytes[at + 12..at + 16].copy_from_slice(&8191i32.to_le_bytes());
    let e = gs_io::exr::parse_exr(&bytes, path).unwrap_err().to_string();
    assert!(e.contains("wide.exr") && e.contains("8192x8192 with 5 channels") && e.contains("more than the cap of 1024 MiB"), "{e}");
    // Within the cap (8192 × 4096 × 5 f32 = 640 MiB) but far more than a file of a few hundred
    // bytes can hold at any compression: refused too, before any sample is allocated.
    let key = b"dataWindow\0box2i\0";
    let at = bytes.windows(key.len()).position(|w| w == key).unwrap() + key.len() + 4;
    bytes[at + 12..at + 16].copy_from_slice(&4095i32.to_le_bytes());
    let e = gs_io::exr::parse_exr(&bytes, path).unwrap_err().to_string();
    assert!(e.contains("8192x4096 with 5 channels needs 640 MiB") && e.contains("at any compression"), "{e}");
}

/// Found by the `exr` fuzz target: a 5×3 layer of 134225922×2 tiles, whose chunk buffer the
/// exr crate sizes from the tile (1.8 GB for a 754-byte file). Refused from the header.
#[test]
fn a_tile_larger_than_the_file_can_hold_is_refused() {
    let bytes = include_bytes!("fixtures/fuzz/exr_huge_tile.exr");
    let e = gs_io::exr::parse_exr(bytes, std::path::Path::new("tile.exr")).unwrap_err().to_string();
    assert!(e.contains("tile.exr") && e.contains("EXR tiles of 134225922x2 with 4 channels"), "{e}");
}
