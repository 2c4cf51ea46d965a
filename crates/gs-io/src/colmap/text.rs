//! COLMAP text models: `cameras.txt`, `images.txt`, `points3D.txt`.
//!
//! Floats are written with Rust's shortest round-trip formatting, so a value re-parses to the
//! same f64 bit pattern (text → binary → text is lossless).

use super::{
    CameraModel, ColmapCamera, ColmapImage, ColmapModel, ColmapPoint3D, ModelFormat, ModelLookup,
    ModelPaths, Point2D,
};
use crate::atomic::write_atomic;
use crate::error::{IoError, Result};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io::Write;
use std::path::Path;
use std::str::FromStr;

/// Reads the whole file as UTF-8, naming the first invalid byte's line on failure.
fn read_utf8(path: &Path) -> Result<String> {
    utf8(crate::capped::COLMAP.read(path)?, path)
}

/// The bytes of `path` as UTF-8 text, naming the first invalid byte's line on failure.
fn utf8(bytes: Vec<u8>, path: &Path) -> Result<String> {
    String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        let line = 1 + e.as_bytes()[..at].iter().filter(|&&b| b == b'\n').count();
        IoError::parse(path, line, format!("not valid UTF-8 text (byte offset {at})"))
    })
}

/// Parses one whitespace-separated field.
fn field<T: FromStr>(path: &Path, line: usize, tok: Option<&str>, what: &str) -> Result<T> {
    let tok = tok.ok_or_else(|| IoError::parse(path, line, format!("missing {what}")))?;
    tok.parse::<T>().map_err(|_| IoError::parse(path, line, format!("cannot parse {what} from '{tok}'")))
}

fn finite_field(path: &Path, line: usize, tok: Option<&str>, what: &str) -> Result<f64> {
    let v: f64 = field(path, line, tok, what)?;
    if !v.is_finite() {
        return Err(IoError::parse(path, line, format!("{what} is {v} (must be finite)")));
    }
    Ok(v)
}

fn is_skippable(line: &str) -> bool {
    let t = line.trim();
    t.is_empty() || t.starts_with('#')
}

/// Parses `cameras.txt` content.
pub(crate) fn parse_cameras_txt(text: &str, path: &Path) -> Result<BTreeMap<u32, ColmapCamera>> {
    let mut cameras = BTreeMap::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        if is_skippable(raw) {
            continue;
        }
        let mut it = raw.split_whitespace();
        let id: u32 = field(path, line, it.next(), "camera id")?;
        let model_name = it.next().ok_or_else(|| IoError::parse(path, line, "missing camera model"))?;
        let model = match CameraModel::lookup_name(model_name) {
            ModelLookup::Supported(m) => m,
            ModelLookup::Unsupported(name) => {
                return Err(IoError::Unsupported {
                    path: path.to_path_buf(),
                    message: format!("line {line}: camera {id} uses camera model {name} (fisheye and other non-perspective models are not supported)"),
                });
            }
            ModelLookup::Unknown => {
                return Err(IoError::parse(path, line, format!("unknown camera model '{model_name}'")));
            }
        };
        let width: u32 = field(path, line, it.next(), "width")?;
        let height: u32 = field(path, line, it.next(), "height")?;
        let params = it
            .map(|t| finite_field(path, line, Some(t), "camera parameter"))
            .collect::<Result<Vec<f64>>>()?;
        let cam = ColmapCamera { id, model, width, height, params };
        cam.check().map_err(|m| IoError::parse(path, line, m))?;
        if cameras.insert(id, cam).is_some() {
            return Err(IoError::parse(path, line, format!("duplicate camera id {id}")));
        }
    }
    Ok(cameras)
}

/// Parses `images.txt` content: a header line per image followed by its `POINTS2D` line
/// (which may be empty).
pub(crate) fn parse_images_txt(text: &str, path: &Path) -> Result<BTreeMap<u32, ColmapImage>> {
    let mut images = BTreeMap::new();
    let mut lines = text.lines().enumerate();
    while let Some((i, raw)) = lines.next() {
        let line = i + 1;
        if is_skippable(raw) {
            continue;
        }
        let mut it = raw.split_whitespace();
        let id: u32 = field(path, line, it.next(), "image id")?;
        let mut qvec = [0.0; 4];
        for (k, q) in qvec.iter_mut().enumerate() {
            *q = finite_field(path, line, it.next(), &format!("image {id} quaternion component {k}"))?;
        }
        let mut tvec = [0.0; 3];
        for (k, t) in tvec.iter_mut().enumerate() {
            *t = finite_field(path, line, it.next(), &format!("image {id} translation component {k}"))?;
        }
        let camera_id: u32 = field(path, line, it.next(), "camera id")?;
        // The name is the rest of the line (COLMAP names have no spaces, but be lenient).
        let name = it.collect::<Vec<_>>().join(" ");
        if name.is_empty() {
            return Err(IoError::parse(path, line, format!("image {id}: missing image name")));
        }
        let (pline, praw) = match lines.next() {
            Some((j, r)) => (j + 1, r),
            None => (line + 1, ""),
        };
        let toks: Vec<&str> = praw.split_whitespace().collect();
        if toks.len() % 3 != 0 {
            return Err(IoError::parse(
                path,
                pline,
                format!("image {id}: POINTS2D has {} values, not a multiple of 3 (X Y POINT3D_ID)", toks.len()),
            ));
        }
        let mut points2d = Vec::with_capacity(toks.len() / 3);
        for c in toks.chunks_exact(3) {
            let x = finite_field(path, pline, Some(c[0]), &format!("image {id} point2D x"))?;
            let y = finite_field(path, pline, Some(c[1]), &format!("image {id} point2D y"))?;
            let pid: i64 = field(path, pline, Some(c[2]), &format!("image {id} POINT3D_ID"))?;
            let point3d_id = match pid {
                -1 => None,
                p if p >= 0 => Some(p as u64),
                p => return Err(IoError::parse(path, pline, format!("image {id}: invalid POINT3D_ID {p}"))),
            };
            points2d.push(Point2D { xy: [x, y], point3d_id });
        }
        let img = ColmapImage { id, qvec, tvec, camera_id, name, points2d };
        img.check_pose().map_err(|m| IoError::parse(path, line, m))?;
        if images.insert(id, img).is_some() {
            return Err(IoError::parse(path, line, format!("duplicate image id {id}")));
        }
    }
    Ok(images)
}

/// Parses `points3D.txt` content.
pub(crate) fn parse_points3d_txt(text: &str, path: &Path) -> Result<BTreeMap<u64, ColmapPoint3D>> {
    let mut points = BTreeMap::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        if is_skippable(raw) {
            continue;
        }
        let mut it = raw.split_whitespace();
        let id: u64 = field(path, line, it.next(), "point id")?;
        let mut xyz = [0.0; 3];
        for (k, x) in xyz.iter_mut().enumerate() {
            *x = finite_field(path, line, it.next(), &format!("point {id} coordinate {k}"))?;
        }
        let mut rgb = [0u8; 3];
        for (k, c) in rgb.iter_mut().enumerate() {
            *c = field(path, line, it.next(), &format!("point {id} colour component {k} (0-255)"))?;
        }
        let error = finite_field(path, line, it.next(), &format!("point {id} error"))?;
        let toks: Vec<&str> = it.collect();
        if toks.len() % 2 != 0 {
            return Err(IoError::parse(
                path,
                line,
                format!("point {id}: TRACK has {} values, not pairs of IMAGE_ID POINT2D_IDX", toks.len()),
            ));
        }
        let track = toks
            .chunks_exact(2)
            .map(|c| {
                Ok((
                    field(path, line, Some(c[0]), &format!("point {id} track image id"))?,
                    field(path, line, Some(c[1]), &format!("point {id} track POINT2D_IDX"))?,
                ))
            })
            .collect::<Result<Vec<(u32, u32)>>>()?;
        if points.insert(id, ColmapPoint3D { id, xyz, rgb, error, track }).is_some() {
            return Err(IoError::parse(path, line, format!("duplicate point id {id}")));
        }
    }
    Ok(points)
}

/// Reads a text model from `dir` (`cameras.txt`, `images.txt`, `points3D.txt`) and validates
/// it. Non-UTF-8 content, bad fields and unknown models are errors with the line number.
pub fn read_text(dir: &Path) -> Result<ColmapModel> {
    let paths = ModelPaths::new(dir, ModelFormat::Text);
    let cameras = parse_cameras_txt(&read_utf8(&paths.cameras)?, &paths.cameras)?;
    let images = parse_images_txt(&read_utf8(&paths.images)?, &paths.images)?;
    let points3d = parse_points3d_txt(&read_utf8(&paths.points3d)?, &paths.points3d)?;
    let model = ColmapModel { cameras, images, points3d };
    model.validate(&paths)?;
    Ok(model)
}

/// [`read_text`] of the three files' contents held in memory (`cameras.txt`, `images.txt`,
/// `points3D.txt`); `dir` only names the files in errors. Same checks, same errors.
pub fn parse_text(cameras: &[u8], images: &[u8], points3d: &[u8], dir: &Path) -> Result<ColmapModel> {
    let paths = ModelPaths::new(dir, ModelFormat::Text);
    let cameras = parse_cameras_txt(&utf8(cameras.to_vec(), &paths.cameras)?, &paths.cameras)?;
    let images = parse_images_txt(&utf8(images.to_vec(), &paths.images)?, &paths.images)?;
    let points3d = parse_points3d_txt(&utf8(points3d.to_vec(), &paths.points3d)?, &paths.points3d)?;
    let model = ColmapModel { cameras, images, points3d };
    model.validate(&paths)?;
    Ok(model)
}

/// The contents [`write_text`] writes: `cameras.txt`, `images.txt`, `points3D.txt`.
pub fn format_text(model: &ColmapModel) -> [Vec<u8>; 3] {
    let mut images = Vec::new();
    let mut points = Vec::new();
    write_images_txt(model, &mut images).expect("writing to memory cannot fail");
    write_points3d_txt(model, &mut points).expect("writing to memory cannot fail");
    [format_cameras_txt(model).into_bytes(), images, points]
}

/// Formats a model's `cameras.txt`.
pub(crate) fn format_cameras_txt(model: &ColmapModel) -> String {
    let mut s = String::new();
    s.push_str("# Camera list with one line of data per camera:\n");
    s.push_str("#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n");
    let _ = writeln!(s, "# Number of cameras: {}", model.cameras.len());
    for c in model.cameras.values() {
        let _ = write!(s, "{} {} {} {}", c.id, c.model.name(), c.width, c.height);
        for p in &c.params {
            let _ = write!(s, " {p}");
        }
        s.push('\n');
    }
    s
}

fn write_images_txt(model: &ColmapModel, w: &mut dyn Write) -> std::io::Result<()> {
    let n_obs: usize = model.images.values().map(|i| i.points2d.len()).sum();
    let mean = if model.images.is_empty() { 0.0 } else { n_obs as f64 / model.images.len() as f64 };
    writeln!(w, "# Image list with two lines of data per image:")?;
    writeln!(w, "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME")?;
    writeln!(w, "#   POINTS2D[] as (X, Y, POINT3D_ID)")?;
    writeln!(w, "# Number of images: {}, mean observations per image: {mean}", model.images.len())?;
    let mut line = String::new();
    for img in model.images.values() {
        let [qw, qx, qy, qz] = img.qvec;
        let [tx, ty, tz] = img.tvec;
        writeln!(w, "{} {qw} {qx} {qy} {qz} {tx} {ty} {tz} {} {}", img.id, img.camera_id, img.name)?;
        line.clear();
        for (k, p) in img.points2d.iter().enumerate() {
            if k > 0 {
                line.push(' ');
            }
            let _ = match p.point3d_id {
                Some(id) => write!(line, "{} {} {id}", p.xy[0], p.xy[1]),
                None => write!(line, "{} {} -1", p.xy[0], p.xy[1]),
            };
        }
        line.push('\n');
        w.write_all(line.as_bytes())?;
    }
    Ok(())
}

fn write_points3d_txt(model: &ColmapModel, w: &mut dyn Write) -> std::io::Result<()> {
    writeln!(w, "# 3D point list with one line of data per point:")?;
    writeln!(w, "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)")?;
    writeln!(
        w,
        "# Number of points: {}, mean track length: {}",
        model.points3d.len(),
        model.mean_track_length()
    )?;
    let mut line = String::new();
    for p in model.points3d.values() {
        line.clear();
        let [x, y, z] = p.xyz;
        let [r, g, b] = p.rgb;
        let _ = write!(line, "{} {x} {y} {z} {r} {g} {b} {}", p.id, p.error);
        for (image_id, idx) in &p.track {
            let _ = write!(line, " {image_id} {idx}");
        }
        line.push('\n');
        w.write_all(line.as_bytes())?;
    }
    Ok(())
}

/// Writes `model` as a text model into `dir` (created if missing); each file atomically.
pub fn write_text(model: &ColmapModel, dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| IoError::io(dir, e))?;
    let paths = ModelPaths::new(dir, ModelFormat::Text);
    let cams = format_cameras_txt(model);
    write_atomic(&paths.cameras, |w| w.write_all(cams.as_bytes()))?;
    write_atomic(&paths.images, |w| write_images_txt(model, w))?;
    write_atomic(&paths.points3d, |w| write_points3d_txt(model, w))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_points2d_line_is_kept() {
        let text = "# c\n1 1 0 0 0 0 0 0 1 a.png\n\n2 1 0 0 0 0 0 0 1 b.png\n1 2 -1 3 4 7\n";
        let imgs = parse_images_txt(text, Path::new("images.txt")).unwrap();
        assert_eq!(imgs[&1].points2d.len(), 0);
        assert_eq!(imgs[&2].points2d, vec![
            Point2D { xy: [1.0, 2.0], point3d_id: None },
            Point2D { xy: [3.0, 4.0], point3d_id: Some(7) }
        ]);
    }

    #[test]
    fn floats_round_trip_bit_exactly() {
        let vals: [f64; 7] = [0.1, 1.0 / 3.0, 1e-300, 5e-324, 1.7976931348623157e308, -0.0, 411.6026476727383];
        for v in vals {
            let s = format!("{v}");
            assert_eq!(s.parse::<f64>().unwrap().to_bits(), v.to_bits(), "{s}");
        }
    }
}
