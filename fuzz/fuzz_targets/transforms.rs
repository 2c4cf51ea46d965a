//! Fuzz target: arbitrary bytes as a `transforms.json`.
//!
//! gs-io's byte-slice parser must return `Ok` or an error for any input: a panic, abort,
//! overflow or huge allocation is a bug. For every parsed frame that carries its image size,
//! the COLMAP camera is built too (an error is fine, a panic is not), and the poses it yields
//! are unit quaternions with finite translations. A parsed frame set is written back with our
//! writer and parsed again, and must give the same cameras and poses (to rounding).
#![no_main]

use gs_io::colmap::{ColmapImage, ColmapModel};
use gs_io::transforms::{parse_transforms, transforms_json};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("transforms.json");
    let Ok(file) = parse_transforms(data, path) else { return };
    let mut model = ColmapModel::default();
    for frame in &file.frames {
        let n = frame.qvec.iter().map(|q| q * q).sum::<f64>().sqrt();
        assert!((n - 1.0).abs() < 1e-9, "quaternion norm {n}");
        assert!(frame.tvec.iter().all(|t| t.is_finite()));
        let [Some(w), Some(h)] = frame.lens.size else { continue };
        let Ok(cam) = frame.lens.camera(frame.index as u32 + 1, w, h) else { continue };
        let id = cam.id;
        model.cameras.insert(id, cam);
        let name = format!("{id}.png");
        model.images.insert(id, ColmapImage { id, qvec: frame.qvec, tvec: frame.tvec, camera_id: id, name, points2d: vec![] });
    }
    if model.images.is_empty() {
        return;
    }
    let Ok(text) = transforms_json(&model, "", false) else { return };
    let back = parse_transforms(text.as_bytes(), path).expect("our own output parses");
    assert_eq!(back.frames.len(), model.images.len());
    for frame in &back.frames {
        // Frames are written in name order; match them to the images by name.
        let img = model.images.values().find(|i| i.name == frame.file_path).expect("every frame is an image");
        let cam = &model.cameras[&img.camera_id];
        let again = frame.lens.camera(cam.id, cam.width, cam.height).expect("our own camera is valid");
        let [a, b] = [cam.pinhole(), again.pinhole()];
        for k in 0..4 {
            assert!((a[k] - b[k]).abs() <= 1e-9 * a[k].abs().max(1.0), "{a:?} vs {b:?}");
        }
        let scale = 1.0 + img.tvec.iter().fold(0.0f64, |m, t| m.max(t.abs()));
        for k in 0..3 {
            assert!((img.tvec[k] - frame.tvec[k]).abs() <= 1e-9 * scale, "{:?} vs {:?}", img.tvec, frame.tvec);
        }
    }
});
