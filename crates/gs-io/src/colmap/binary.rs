//! COLMAP binary models: `cameras.bin`, `images.bin`, `points3D.bin` (little-endian).
//!
//! Layouts (COLMAP `reconstruction_io.cc`):
//! - cameras: `u64 n`, then per camera `u32 id, i32 model_id, u64 width, u64 height,
//!   f64 params[num_params(model)]`;
//! - images: `u64 n`, then per image `u32 id, f64 qvec[4], f64 tvec[3], u32 camera_id,
//!   name bytes + NUL, u64 n_points2d, (f64 x, f64 y, u64 point3d_id (u64::MAX = none))[n]`;
//! - points3D: `u64 n`, then per point `u64 id, f64 xyz[3], u8 rgb[3], f64 error,
//!   u64 track_length, (u32 image_id, u32 point2d_idx)[track_length]`.
//!
//! The parsers work on byte slices (no files needed, e.g. for fuzzing) and check every count
//! against the bytes left before allocating.

use super::{
    CameraModel, ColmapCamera, ColmapImage, ColmapModel, ColmapPoint3D, ModelFormat, ModelLookup,
    ModelPaths, Point2D,
};
use crate::atomic::write_atomic;
use crate::error::{IoError, Result};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;

/// A little-endian reader over a byte slice that reports truncation with the byte offset.
struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
    path: &'a Path,
}

impl<'a> Reader<'a> {
    fn new(bytes: &'a [u8], path: &'a Path) -> Self {
        Self { bytes, pos: 0, path }
    }

    fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }

    fn take<const N: usize>(&mut self, what: &dyn Fn() -> String) -> Result<[u8; N]> {
        if self.remaining() < N {
            return Err(IoError::format(
                self.path,
                format!(
                    "truncated at byte offset {} while reading {} ({N} bytes needed, {} left)",
                    self.pos,
                    what(),
                    self.remaining()
                ),
            ));
        }
        let mut out = [0u8; N];
        out.copy_from_slice(&self.bytes[self.pos..self.pos + N]);
        self.pos += N;
        Ok(out)
    }

    fn u8(&mut self, what: &dyn Fn() -> String) -> Result<u8> {
        Ok(self.take::<1>(what)?[0])
    }
    fn u32(&mut self, what: &dyn Fn() -> String) -> Result<u32> {
        Ok(u32::from_le_bytes(self.take(what)?))
    }
    fn i32(&mut self, what: &dyn Fn() -> String) -> Result<i32> {
        Ok(i32::from_le_bytes(self.take(what)?))
    }
    fn u64(&mut self, what: &dyn Fn() -> String) -> Result<u64> {
        Ok(u64::from_le_bytes(self.take(what)?))
    }
    fn f64(&mut self, what: &dyn Fn() -> String) -> Result<f64> {
        Ok(f64::from_le_bytes(self.take(what)?))
    }

    /// A finite f64; NaN or infinity is an error naming the record and offset.
    fn finite(&mut self, what: &dyn Fn() -> String) -> Result<f64> {
        let at = self.pos;
        let v = self.f64(what)?;
        if !v.is_finite() {
            return Err(IoError::format(self.path, format!("{} at byte offset {at} is {v} (must be finite)", what())));
        }
        Ok(v)
    }

    /// A count prefix that must fit `min_record` bytes per element in the rest of the file
    /// (checked before anything is allocated for them, [`crate::capped::Cap::check_declared`]).
    fn count(&mut self, min_record: usize, what: &dyn Fn() -> String) -> Result<usize> {
        let at = self.pos;
        let n = self.u64(what)?;
        let subject = format!("the {} at byte offset {at}", what());
        crate::capped::COLMAP.check_declared(self.path, &subject, (n, "records"), min_record as u64, self.remaining() as u64)?;
        Ok(n as usize)
    }

    fn finish(&self) -> Result<()> {
        if self.remaining() != 0 {
            return Err(IoError::format(
                self.path,
                format!("{} unexpected trailing bytes after the last record (byte offset {}): wrong count", self.remaining(), self.pos),
            ));
        }
        Ok(())
    }
}

/// Parses the content of a `cameras.bin`; `path` is only used to name the file in errors.
/// Unknown model ids are a format error, fisheye and other known-but-unsupported models an
/// [`IoError::Unsupported`] naming the model.
pub fn parse_cameras_bin(bytes: &[u8], path: &Path) -> Result<BTreeMap<u32, ColmapCamera>> {
    let mut r = Reader::new(bytes, path);
    let n = r.count(24, &|| "number of cameras".into())?;
    let mut cameras = BTreeMap::new();
    for k in 0..n {
        let start = r.pos;
        let id = r.u32(&|| format!("camera #{k} id"))?;
        let what = |field: &str| format!("camera {id} (record #{k}, byte offset {start}) {field}");
        let model_id = r.i32(&|| what("model id"))?;
        let model = match CameraModel::lookup_id(model_id) {
            ModelLookup::Supported(m) => m,
            ModelLookup::Unsupported(name) => {
                return Err(IoError::Unsupported {
                    path: path.to_path_buf(),
                    message: format!("{} is {model_id} = {name} (fisheye and other non-perspective models are not supported)", what("model id")),
                });
            }
            ModelLookup::Unknown => {
                return Err(IoError::format(path, format!("{}: unknown camera model id {model_id}", what("model"))));
            }
        };
        let width = r.u64(&|| what("width"))?;
        let height = r.u64(&|| what("height"))?;
        let (Ok(width), Ok(height)) = (u32::try_from(width), u32::try_from(height)) else {
            return Err(IoError::format(path, format!("{}: image size {width}x{height} is out of range", what("size"))));
        };
        let mut params = Vec::with_capacity(model.num_params());
        for p in 0..model.num_params() {
            params.push(r.finite(&|| what(&format!("parameter {p}")))?);
        }
        let cam = ColmapCamera { id, model, width, height, params };
        cam.check().map_err(|m| IoError::format(path, format!("{m} (record #{k}, byte offset {start})")))?;
        if cameras.insert(id, cam).is_some() {
            return Err(IoError::format(path, format!("duplicate camera id {id} (record #{k}, byte offset {start})")));
        }
    }
    r.finish()?;
    Ok(cameras)
}

/// Parses the content of an `images.bin`; `path` is only used to name the file in errors.
pub fn parse_images_bin(bytes: &[u8], path: &Path) -> Result<BTreeMap<u32, ColmapImage>> {
    let mut r = Reader::new(bytes, path);
    // id 4 + pose 56 + camera id 4 + name ≥ 1 + count 8.
    let n = r.count(73, &|| "number of images".into())?;
    let mut images = BTreeMap::new();
    for k in 0..n {
        let start = r.pos;
        let id = r.u32(&|| format!("image #{k} id"))?;
        let what = |field: &str| format!("image {id} (record #{k}, byte offset {start}) {field}");
        let mut qvec = [0.0; 4];
        for (c, q) in qvec.iter_mut().enumerate() {
            *q = r.finite(&|| what(&format!("quaternion component {c}")))?;
        }
        let mut tvec = [0.0; 3];
        for (c, t) in tvec.iter_mut().enumerate() {
            *t = r.finite(&|| what(&format!("translation component {c}")))?;
        }
        let camera_id = r.u32(&|| what("camera id"))?;
        let name_start = r.pos;
        let Some(len) = r.bytes[name_start..].iter().position(|&b| b == 0) else {
            return Err(IoError::format(path, format!("truncated: {} has no terminating NUL byte", what("name"))));
        };
        let name = std::str::from_utf8(&r.bytes[name_start..name_start + len])
            .map_err(|_| IoError::format(path, format!("{} at byte offset {name_start} is not valid UTF-8", what("name"))))?
            .to_owned();
        r.pos = name_start + len + 1;
        if name.is_empty() {
            return Err(IoError::format(path, format!("{} is empty", what("name"))));
        }
        let n2 = r.count(24, &|| what("number of 2D points"))?;
        let mut points2d = Vec::with_capacity(n2);
        for p in 0..n2 {
            let x = r.finite(&|| what(&format!("point2D {p} x")))?;
            let y = r.finite(&|| what(&format!("point2D {p} y")))?;
            let pid = r.u64(&|| what(&format!("point2D {p} point3D id")))?;
            points2d.push(Point2D { xy: [x, y], point3d_id: (pid != u64::MAX).then_some(pid) });
        }
        let img = ColmapImage { id, qvec, tvec, camera_id, name, points2d };
        img.check_pose().map_err(|m| IoError::format(path, format!("{m} (record #{k}, byte offset {start})")))?;
        if images.insert(id, img).is_some() {
            return Err(IoError::format(path, format!("duplicate image id {id} (record #{k}, byte offset {start})")));
        }
    }
    r.finish()?;
    Ok(images)
}

/// Parses the content of a `points3D.bin`; `path` is only used to name the file in errors.
pub fn parse_points3d_bin(bytes: &[u8], path: &Path) -> Result<BTreeMap<u64, ColmapPoint3D>> {
    let mut r = Reader::new(bytes, path);
    // id 8 + xyz 24 + rgb 3 + error 8 + track length 8.
    let n = r.count(51, &|| "number of points".into())?;
    let mut points = BTreeMap::new();
    for k in 0..n {
        let start = r.pos;
        let id = r.u64(&|| format!("point #{k} id"))?;
        let what = |field: &str| format!("point {id} (record #{k}, byte offset {start}) {field}");
        let mut xyz = [0.0; 3];
        for (c, x) in xyz.iter_mut().enumerate() {
            *x = r.finite(&|| what(&format!("coordinate {c}")))?;
        }
        let mut rgb = [0u8; 3];
        for (c, v) in rgb.iter_mut().enumerate() {
            *v = r.u8(&|| what(&format!("colour component {c}")))?;
        }
        let error = r.finite(&|| what("error"))?;
        let nt = r.count(8, &|| what("track length"))?;
        let mut track = Vec::with_capacity(nt);
        for t in 0..nt {
            let image_id = r.u32(&|| what(&format!("track entry {t} image id")))?;
            let idx = r.u32(&|| what(&format!("track entry {t} point2D index")))?;
            track.push((image_id, idx));
        }
        if points.insert(id, ColmapPoint3D { id, xyz, rgb, error, track }).is_some() {
            return Err(IoError::format(path, format!("duplicate point id {id} (record #{k}, byte offset {start})")));
        }
    }
    r.finish()?;
    Ok(points)
}

fn read_bytes(path: &Path) -> Result<Vec<u8>> {
    crate::capped::COLMAP.read(path)
}

/// Reads a binary model from `dir` (`cameras.bin`, `images.bin`, `points3D.bin`) and
/// validates it.
pub fn read_binary(dir: &Path) -> Result<ColmapModel> {
    let paths = ModelPaths::new(dir, ModelFormat::Binary);
    let cameras = parse_cameras_bin(&read_bytes(&paths.cameras)?, &paths.cameras)?;
    let images = parse_images_bin(&read_bytes(&paths.images)?, &paths.images)?;
    let points3d = parse_points3d_bin(&read_bytes(&paths.points3d)?, &paths.points3d)?;
    let model = ColmapModel { cameras, images, points3d };
    model.validate(&paths)?;
    Ok(model)
}

/// Serialises the cameras as `cameras.bin` bytes.
pub fn write_cameras_bin(model: &ColmapModel, w: &mut dyn Write) -> std::io::Result<()> {
    w.write_all(&(model.cameras.len() as u64).to_le_bytes())?;
    for c in model.cameras.values() {
        w.write_all(&c.id.to_le_bytes())?;
        w.write_all(&c.model.id().to_le_bytes())?;
        w.write_all(&(c.width as u64).to_le_bytes())?;
        w.write_all(&(c.height as u64).to_le_bytes())?;
        for p in &c.params {
            w.write_all(&p.to_le_bytes())?;
        }
    }
    Ok(())
}

/// Serialises the images as `images.bin` bytes.
pub fn write_images_bin(model: &ColmapModel, w: &mut dyn Write) -> std::io::Result<()> {
    w.write_all(&(model.images.len() as u64).to_le_bytes())?;
    for img in model.images.values() {
        w.write_all(&img.id.to_le_bytes())?;
        for q in img.qvec {
            w.write_all(&q.to_le_bytes())?;
        }
        for t in img.tvec {
            w.write_all(&t.to_le_bytes())?;
        }
        w.write_all(&img.camera_id.to_le_bytes())?;
        w.write_all(img.name.as_bytes())?;
        w.write_all(&[0])?;
        w.write_all(&(img.points2d.len() as u64).to_le_bytes())?;
        for p in &img.points2d {
            w.write_all(&p.xy[0].to_le_bytes())?;
            w.write_all(&p.xy[1].to_le_bytes())?;
            w.write_all(&p.point3d_id.unwrap_or(u64::MAX).to_le_bytes())?;
        }
    }
    Ok(())
}

/// Serialises the points as `points3D.bin` bytes.
pub fn write_points3d_bin(model: &ColmapModel, w: &mut dyn Write) -> std::io::Result<()> {
    w.write_all(&(model.points3d.len() as u64).to_le_bytes())?;
    for p in model.points3d.values() {
        w.write_all(&p.id.to_le_bytes())?;
        for x in p.xyz {
            w.write_all(&x.to_le_bytes())?;
        }
        w.write_all(&p.rgb)?;
        w.write_all(&p.error.to_le_bytes())?;
        w.write_all(&(p.track.len() as u64).to_le_bytes())?;
        for &(image_id, idx) in &p.track {
            w.write_all(&image_id.to_le_bytes())?;
            w.write_all(&idx.to_le_bytes())?;
        }
    }
    Ok(())
}

/// Writes `model` as a binary model into `dir` (created if missing); each file atomically.
pub fn write_binary(model: &ColmapModel, dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| IoError::io(dir, e))?;
    let paths = ModelPaths::new(dir, ModelFormat::Binary);
    write_atomic(&paths.cameras, |w| write_cameras_bin(model, w))?;
    write_atomic(&paths.images, |w| write_images_bin(model, w))?;
    write_atomic(&paths.points3d, |w| write_points3d_bin(model, w))?;
    Ok(())
}
