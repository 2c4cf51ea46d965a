//! Fuzz target: arbitrary bytes as a float OpenEXR depth or normal map.
//!
//! gs-io's byte-slice EXR parser must return `Ok` or an error for any input: a panic, abort,
//! overflow or huge allocation is a bug. An image that parses is encoded with our writer's
//! encoder and parsed again, and must come back bit for bit (sizes, channels, sample bits).
#![no_main]

use gs_io::exr::{encode_exr, parse_exr};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz.exr");
    if let Ok(img) = parse_exr(data, path) {
        let bytes = encode_exr(&img).expect("a parsed map has 1, 3 or 4 channels and encodes");
        let back = parse_exr(&bytes, path).expect("our own EXR parses");
        assert_eq!((back.width(), back.height(), back.channels()), (img.width(), img.height(), img.channels()));
        let bits = |i: &gs_core::Image| i.data().iter().map(|v| v.to_bits()).collect::<Vec<u32>>();
        assert_eq!(bits(&back), bits(&img));
    }
});
