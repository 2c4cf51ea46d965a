//! Fuzz target: arbitrary bytes as a photo or mask (PNG and JPEG).
//!
//! Each input goes through gs-io's strict container check (`integrity::check_complete`) and
//! the byte-slice decoders that scene loading uses (`decode_rgb_bytes` as `.png` and `.jpg`,
//! `decode_mask_bytes` as `.png`): `Ok` or an error, never a panic, abort, overflow or huge
//! allocation. A decoded image has values in [0, 1]; an 8-bit PNG written back with our PNG
//! encoder decodes to the same values.
#![no_main]

use gs_io::png::encode_png;
use gs_io::scene::{decode_mask_bytes, decode_rgb_bytes};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let _ = gs_io::integrity::check_complete(Path::new("fuzz.png"), data);
    let png = Path::new("fuzz.png");
    for (path, img) in [(png, decode_rgb_bytes(data, png)), (Path::new("fuzz.jpg"), decode_rgb_bytes(data, Path::new("fuzz.jpg"))), (png, decode_mask_bytes(data, png))] {
        let Ok(img) = img else { continue };
        assert!(img.data().iter().all(|v| (0.0..=1.0).contains(v)), "decoded values lie in [0, 1]");
        let Ok(bytes) = encode_png(&img, path) else { panic!("a decoded image has 1 or 3 channels") };
        let back = if img.channels() == 1 { decode_mask_bytes(&bytes, png) } else { decode_rgb_bytes(&bytes, png) };
        let back = back.expect("our own PNG decodes");
        assert_eq!((back.width(), back.height(), back.channels()), (img.width(), img.height(), img.channels()));
        for (a, b) in img.data().iter().zip(back.data()) {
            assert!((a - b).abs() <= 0.5 / 255.0 + 1e-6, "PNG round trip moved {a} to {b}");
        }
    }
});
