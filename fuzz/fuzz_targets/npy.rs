//! Fuzz target: arbitrary bytes as a NumPy `.npy` array, an `.npy` image and an `.npz` archive.
//!
//! gs-io's byte-slice parsers must return `Ok` or an error for any input: a panic, abort,
//! overflow or huge allocation is a bug. An image that parses is written back with our `.npy`
//! encoder and parsed again, and must come back bit for bit (f16 input widens to f32 once).
#![no_main]

use gs_io::npy::{encode_npy, parse_npy, parse_npy_array, parse_npz};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz.npy");
    if let Ok(a) = parse_npy_array(data, path) {
        let count: usize = a.shape.iter().product();
        assert_eq!(count, a.data.len(), "shape and values agree");
    }
    if let Ok(img) = parse_npy(data, path) {
        let back = parse_npy(&encode_npy(&img), path).expect("our own .npy parses");
        assert_eq!((back.width(), back.height(), back.channels()), (img.width(), img.height(), img.channels()));
        let bits = |i: &gs_core::Image| i.data().iter().map(|v| v.to_bits()).collect::<Vec<u32>>();
        assert_eq!(bits(&back), bits(&img));
    }
    if let Ok(members) = parse_npz(data, Path::new("fuzz.npz")) {
        assert!(!members.is_empty(), "an archive that parses has a member");
    }
});
