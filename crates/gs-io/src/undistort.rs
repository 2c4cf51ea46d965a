//! Undistortion of COLMAP cameras and images to PINHOLE, as `colmap image_undistorter`.
//!
//! [`undistort_camera`] follows COLMAP's `UndistortCamera` (`src/colmap/image/undistortion.cc`):
//! the new PINHOLE camera keeps the focal lengths and principal point, then the image size is
//! scaled (and the principal point with it) so that, with `blank_pixels = 0`, every pixel of
//! the undistorted image sees the distorted image (no blank border), the scale clamped to
//! `[min_scale, max_scale]`. [`UndistortMap`] resamples images with bilinear interpolation at
//! pixel centres (top-left pixel centre at `(0.5, 0.5)`). COLMAP warps at the source size and
//! rescales afterwards; we sample the target grid directly, which is the same up to the
//! rescale's resampling (the scale is close to 1 because the focal length is kept).

use crate::colmap::{CameraModel, ColmapCamera};
use gs_core::Image;
use rayon::prelude::*;

/// Options of [`undistort_camera`] (COLMAP's `UndistortCameraOptions` defaults).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UndistortOptions {
    /// 0 = no blank pixels in the undistorted image (crop), 1 = keep every source pixel.
    pub blank_pixels: f64,
    /// Smallest allowed image scale.
    pub min_scale: f64,
    /// Largest allowed image scale.
    pub max_scale: f64,
}

impl Default for UndistortOptions {
    fn default() -> Self {
        Self { blank_pixels: 0.0, min_scale: 0.2, max_scale: 2.0 }
    }
}

/// The PINHOLE camera with the same intrinsics as an undistorted camera
/// (SIMPLE_PINHOLE → PINHOLE with `fx = fy = f`; distortion parameters dropped).
pub fn as_pinhole(camera: &ColmapCamera) -> ColmapCamera {
    ColmapCamera {
        id: camera.id,
        model: CameraModel::Pinhole,
        width: camera.width,
        height: camera.height,
        params: camera.pinhole().to_vec(),
    }
}

/// The PINHOLE camera that `colmap image_undistorter` produces for `camera`. Cameras without
/// distortion ([`ColmapCamera::is_undistorted`]) pass through as [`as_pinhole`]. An error
/// message for invalid options or a distortion model too degenerate to invert at the border.
pub fn undistort_camera(camera: &ColmapCamera, opts: &UndistortOptions) -> Result<ColmapCamera, String> {
    if !(0.0..=1.0).contains(&opts.blank_pixels)
        || !(opts.min_scale > 0.0 && opts.min_scale <= opts.max_scale && opts.max_scale.is_finite())
    {
        return Err(format!(
            "invalid undistortion options: blank_pixels {} must be in [0, 1], 0 < min_scale {} <= max_scale {}",
            opts.blank_pixels, opts.min_scale, opts.max_scale
        ));
    }
    camera.check()?;
    if (camera.width as usize).saturating_mul(camera.height as usize) > gs_core::image::MAX_IMAGE_PIXELS {
        return Err(format!(
            "camera {}: image size {}x{} exceeds the cap of {} pixels",
            camera.id,
            camera.width,
            camera.height,
            gs_core::image::MAX_IMAGE_PIXELS
        ));
    }
    let mut out = as_pinhole(camera);
    if camera.is_undistorted() {
        return Ok(out);
    }
    let (w, h) = (camera.width as f64, camera.height as f64);
    // Undistorted x (resp. y) of distorted border pixel centres, through the new PINHOLE camera.
    let undist = |x: f64, y: f64| -> Option<[f64; 2]> {
        let n = camera.cam_from_img([x, y])?;
        Some(out.img_from_cam(n))
    };
    let fail = |x: f64, y: f64| format!("camera {}: cannot invert the {} distortion at pixel ({x}, {y})", camera.id, camera.model);
    let (mut left_min, mut left_max) = (f64::MAX, f64::MIN);
    let (mut right_min, mut right_max) = (f64::MAX, f64::MIN);
    for y in 0..camera.height {
        let yc = y as f64 + 0.5;
        let l = undist(0.5, yc).ok_or_else(|| fail(0.5, yc))?;
        let r = undist(w - 0.5, yc).ok_or_else(|| fail(w - 0.5, yc))?;
        left_min = left_min.min(l[0]);
        left_max = left_max.max(l[0]);
        right_min = right_min.min(r[0]);
        right_max = right_max.max(r[0]);
    }
    let (mut top_min, mut top_max) = (f64::MAX, f64::MIN);
    let (mut bottom_min, mut bottom_max) = (f64::MAX, f64::MIN);
    for x in 0..camera.width {
        let xc = x as f64 + 0.5;
        let t = undist(xc, 0.5).ok_or_else(|| fail(xc, 0.5))?;
        let b = undist(xc, h - 0.5).ok_or_else(|| fail(xc, h - 0.5))?;
        top_min = top_min.min(t[1]);
        top_max = top_max.max(t[1]);
        bottom_min = bottom_min.min(b[1]);
        bottom_max = bottom_max.max(b[1]);
    }
    let [fx, fy, cx, cy] = out.pinhole();
    // Scale so that the undistorted image contains all pixels of the distorted image...
    let min_scale_x = (cx / (cx - left_min)).min((w - 0.5 - cx) / (right_max - cx));
    let min_scale_y = (cy / (cy - top_min)).min((h - 0.5 - cy) / (bottom_max - cy));
    // ...or so that it has no blank pixels.
    let max_scale_x = (cx / (cx - left_max)).max((w - 0.5 - cx) / (right_min - cx));
    let max_scale_y = (cy / (cy - top_max)).max((h - 0.5 - cy) / (bottom_min - cy));
    let sx = 1.0 / (min_scale_x * opts.blank_pixels + max_scale_x * (1.0 - opts.blank_pixels));
    let sy = 1.0 / (min_scale_y * opts.blank_pixels + max_scale_y * (1.0 - opts.blank_pixels));
    if !(sx.is_finite() && sy.is_finite()) {
        return Err(format!("camera {}: degenerate undistortion scale ({sx}, {sy})", camera.id));
    }
    let sx = sx.clamp(opts.min_scale, opts.max_scale);
    let sy = sy.clamp(opts.min_scale, opts.max_scale);
    // COLMAP truncates the scaled size (static_cast<size_t>) and keeps at least 1 pixel.
    let new_w = (sx * w).max(1.0) as u32;
    let new_h = (sy * h).max(1.0) as u32;
    out.width = new_w;
    out.height = new_h;
    out.params = vec![fx, fy, cx * new_w as f64 / w, cy * new_h as f64 / h];
    Ok(out)
}

/// A resampling map from a PINHOLE target camera to a (distorted) source camera: for every
/// target pixel centre, the continuous source pixel coordinates it samples. Built once per
/// camera and applied to every image (and mask) taken with it.
#[derive(Debug, Clone)]
pub struct UndistortMap {
    width: usize,
    height: usize,
    source_width: usize,
    source_height: usize,
    coords: Vec<[f32; 2]>,
}

impl UndistortMap {
    /// The map from `target` (PINHOLE) pixels to `source` pixels: target pixel centre →
    /// normalised ray → `source.img_from_cam` (with distortion).
    pub fn new(source: &ColmapCamera, target: &ColmapCamera) -> Self {
        let (width, height) = (target.width as usize, target.height as usize);
        let [fx, fy, cx, cy] = target.pinhole();
        let mut coords = vec![[0.0f32; 2]; width * height];
        coords.par_chunks_mut(width).enumerate().for_each(|(y, row)| {
            let v = (y as f64 + 0.5 - cy) / fy;
            for (x, c) in row.iter_mut().enumerate() {
                let u = (x as f64 + 0.5 - cx) / fx;
                let s = source.img_from_cam([u, v]);
                *c = [s[0] as f32, s[1] as f32];
            }
        });
        Self {
            width,
            height,
            source_width: source.width as usize,
            source_height: source.height as usize,
            coords,
        }
    }

    /// Target width.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Target height.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Source pixel coordinates sampled by target pixel `(x, y)`.
    pub fn source_coords(&self, x: usize, y: usize) -> [f32; 2] {
        self.coords[y * self.width + x]
    }

    /// Resamples `image` (of the source camera's size) into the target camera with bilinear
    /// interpolation at pixel centres; samples outside the source clamp to its border.
    pub fn apply(&self, image: &Image) -> Result<Image, String> {
        if image.width() != self.source_width || image.height() != self.source_height {
            return Err(format!(
                "image is {}x{}, the camera is {}x{}",
                image.width(),
                image.height(),
                self.source_width,
                self.source_height
            ));
        }
        let ch = image.channels();
        let (sw, sh) = (image.width(), image.height());
        let src = image.data();
        let mut out = vec![0.0f32; self.width * self.height * ch];
        out.par_chunks_mut(self.width * ch).enumerate().for_each(|(y, row)| {
            let coords = &self.coords[y * self.width..(y + 1) * self.width];
            for (x, c) in coords.iter().enumerate() {
                let fx = (c[0] - 0.5).clamp(0.0, (sw - 1) as f32);
                let fy = (c[1] - 0.5).clamp(0.0, (sh - 1) as f32);
                let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
                let (x1, y1) = ((x0 + 1).min(sw - 1), (y0 + 1).min(sh - 1));
                let (ax, ay) = (fx - x0 as f32, fy - y0 as f32);
                let w00 = (1.0 - ax) * (1.0 - ay);
                let w10 = ax * (1.0 - ay);
                let w01 = (1.0 - ax) * ay;
                let w11 = ax * ay;
                let (i00, i10) = ((y0 * sw + x0) * ch, (y0 * sw + x1) * ch);
                let (i01, i11) = ((y1 * sw + x0) * ch, (y1 * sw + x1) * ch);
                for k in 0..ch {
                    row[x * ch + k] =
                        w00 * src[i00 + k] + w10 * src[i10 + k] + w01 * src[i01 + k] + w11 * src[i11 + k];
                }
            }
        });
        Image::from_vec(self.width, self.height, ch, out).map_err(|e| e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pinhole_models_pass_through() {
        let sp = ColmapCamera { id: 1, model: CameraModel::SimplePinhole, width: 64, height: 48, params: vec![50.0, 32.0, 24.0] };
        let out = undistort_camera(&sp, &UndistortOptions::default()).unwrap();
        assert_eq!(out.model, CameraModel::Pinhole);
        assert_eq!(out.params, vec![50.0, 50.0, 32.0, 24.0]);
        assert_eq!((out.width, out.height), (64, 48));
        let zero = ColmapCamera {
            id: 2,
            model: CameraModel::OpenCv,
            width: 64,
            height: 48,
            params: vec![50.0, 51.0, 32.0, 24.0, 0.0, 0.0, 0.0, 0.0],
        };
        let out = undistort_camera(&zero, &UndistortOptions::default()).unwrap();
        assert_eq!(out.params, vec![50.0, 51.0, 32.0, 24.0]);
        assert_eq!((out.width, out.height), (64, 48));
    }

    #[test]
    fn no_blank_pixels_after_undistortion() {
        // With blank_pixels = 0 every target pixel samples inside the source image (up to the
        // half-pixel border of the outermost source pixel centres).
        let cam = ColmapCamera {
            id: 1,
            model: CameraModel::SimpleRadial,
            width: 200,
            height: 150,
            params: vec![180.0, 100.0, 75.0, -0.2],
        };
        let out = undistort_camera(&cam, &UndistortOptions::default()).unwrap();
        let map = UndistortMap::new(&cam, &out);
        for y in 0..map.height() {
            for x in 0..map.width() {
                let [u, v] = map.source_coords(x, y);
                assert!(u >= 0.5 - 1e-3 && v >= 0.5 - 1e-3 && u <= 199.5 + 1e-3 && v <= 149.5 + 1e-3, "({x},{y}) -> ({u},{v})");
            }
        }
    }

    #[test]
    fn rejects_bad_options() {
        let cam = ColmapCamera { id: 1, model: CameraModel::Radial, width: 20, height: 10, params: vec![10.0, 10.0, 5.0, 0.1, 0.0] };
        let bad = UndistortOptions { blank_pixels: 2.0, ..Default::default() };
        assert!(undistort_camera(&cam, &bad).is_err());
        let bad = UndistortOptions { min_scale: 0.0, ..Default::default() };
        assert!(undistort_camera(&cam, &bad).is_err());
    }
}
