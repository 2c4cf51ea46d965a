//! Fuzz target: arbitrary bytes as `cameras.txt`, `images.txt` and `points3D.txt`.
//!
//! The input is `u16 LE length of cameras.txt, u16 LE length of images.txt`, then the three
//! files back to back (lengths clamped to the bytes available; points3D.txt is the rest), as
//! in `colmap_binary`. They go through gs-io's byte-slice text reader (UTF-8 check, the three
//! line parsers, model validation); a panic, abort, overflow or huge allocation is a bug. A
//! model that parses is written back with our text writer and must re-parse identically; its
//! reprojection error and undistorted cameras are computed as the binary target does.
#![no_main]

mod three_files;

use gs_io::colmap::{format_text, parse_text};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Some((cams, imgs, pts)) = three_files::split(data) else {
        return;
    };
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
