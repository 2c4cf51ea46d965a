//! Fuzz target: arbitrary bytes as `cameras.txt`, `images.txt` and `points3D.txt`.
//!
//! The input is `u16 LE length of cameras.txt, u16 LE length of images.txt`, then the three
//! files back to back (lengths clamped to the bytes available; points3D.txt is the rest), as
//! in `colmap_binary`. They go through gs-io's byte-slice text reader (UTF-8 check, the three
//! line parsers, model validation); a panic, abort, overflow or huge allocation is a bug. A
//! model that parses is written back with our text writer and must re-parse identically; its
//! reprojection error and undistorted cameras are computed as the binary target does.
#![no_main]

use gs_io::colmap::{format_text, parse_text};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    if data.len() < 4 {
        return;
    }
    let (head, rest) = data.split_at(4);
    let a = (u16::from_le_bytes([head[0], head[1]]) as usize).min(rest.len());
    let (cams, tail) = rest.split_at(a);
    let b = (u16::from_le_bytes([head[2], head[3]]) as usize).min(tail.len());
    let (imgs, pts) = tail.split_at(b);
    let dir = Path::new("fuzz");
    if let Ok(model) = parse_text(cams, imgs, pts, dir) {
        let [c, i, p] = format_text(&model);
        let back = parse_text(&c, &i, &p, dir).expect("our own text model parses");
        assert_eq!(back, model);
        let _ = model.mean_reprojection_error();
        for cam in model.cameras.values().filter(|c| c.width <= 2048 && c.height <= 2048) {
            let _ = gs_io::undistort::undistort_camera(cam, &Default::default());
        }
    }
});
