//! Fuzz target: arbitrary bytes as `cameras.bin`, `images.bin` and `points3D.bin`.
//!
//! The input is `u16 LE length of cameras.bin, u16 LE length of images.bin`, then the three
//! files back to back (lengths clamped to the bytes available; points3D.bin is the rest). Each
//! part is parsed by the byte-slice parsers of gs-io and, when all three parse, the assembled
//! model is validated, its reprojection error computed and its cameras undistorted. Any
//! panic, abort, overflow or huge allocation is a bug: every malformed input must give an error.
#![no_main]

mod three_files;

use gs_io::colmap::{ColmapModel, ModelFormat, ModelPaths, parse_cameras_bin, parse_images_bin, parse_points3d_bin};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Some((cams, imgs, pts)) = three_files::split(data) else {
        return;
    };
    let paths = ModelPaths::new(Path::new("fuzz"), ModelFormat::Binary);
    let cameras = parse_cameras_bin(cams, &paths.cameras);
    let images = parse_images_bin(imgs, &paths.images);
    let points3d = parse_points3d_bin(pts, &paths.points3d);
    if let (Ok(cameras), Ok(images), Ok(points3d)) = (cameras, images, points3d) {
        let model = ColmapModel { cameras, images, points3d };
        let _ = model.validate(&paths);
        let _ = model.mean_reprojection_error();
        // Undistortion walks the image border: keep sizes small so each input stays fast.
        for cam in model.cameras.values().filter(|c| c.width <= 2048 && c.height <= 2048) {
            let _ = gs_io::undistort::undistort_camera(cam, &Default::default());
        }
    }
});
