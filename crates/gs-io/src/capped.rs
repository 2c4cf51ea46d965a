//! The one reader size cap. Every reader of a user's file reads it through [`read_capped`] (or
//! a [`Cap`]): a regular file larger than its kind's cap is refused from its size before a byte
//! is read; a pipe or a device (no size up front) is read up to the cap, at most
//! [`STREAM_CAP`], and refused beyond it, so `--config /dev/zero` or a PLY named `/dev/zero`
//! fails at once instead of filling memory. Counts a header declares (PLY elements, COLMAP
//! records) are checked by [`Cap::check_declared`] against the bytes the file holds before
//! anything is allocated. Each message names the file, what it declares or gives, and the cap.

use crate::error::{IoError, Result};
use gs_core::gaussians::MAX_GAUSSIANS;
use gs_core::image::MAX_IMAGE_PIXELS;
use std::io::Read;
use std::path::Path;

/// Cap of a settings file (`--config`): a few MB of TOML or JSON is far beyond any real one.
pub const SETTINGS_CAP: u64 = 4 << 20;
/// Cap of a JSON document vagsl reads (transforms.json, a run's config.json and report.json):
/// hundreds of thousands of frames fit.
pub const JSON_CAP: u64 = 256 << 20;
/// The most bytes read from a pipe or a device, whatever the kind's cap: such a file has no
/// size to check up front, and 1 GiB (about a second of `/dev/zero`) is more than any piped
/// input vagsl takes, yet far from filling memory.
pub const STREAM_CAP: u64 = 1 << 30;

/// Bytes of one Gaussian in the Inria PLY layout at SH degree 3: position, normal, 48 SH
/// coefficients, opacity, 3 scales, 4 rotation values, 62 f32 in all.
const GAUSSIAN_PLY_RECORD: u64 = 62 * 4;
/// Samples of the largest image any reader decodes: four f32 channels (RGBA, the widest map
/// vagsl writes) at gs-core's pixel cap, 1 GiB.
pub const IMAGE_SAMPLE_CAP: u64 = MAX_IMAGE_PIXELS as u64 * 16;

/// Decoded bytes any image file may declare whatever its size (a 2048 × 1024 RGBA f32 map,
/// or an 11-megapixel RGB photo).
const PLAUSIBLE_FLOOR: usize = 32 << 20;
/// Decoded bytes per file byte no image compression vagsl reads exceeds: deflate (PNG, EXR
/// ZIP) stops at 1032:1 and a baseline JPEG at about 512:1 of RGB; this leaves room for PIZ
/// and DWA on flat EXR maps.
const MAX_RATIO: usize = 4096;

/// Whether a file of `file_len` bytes can hold `decoded` bytes of samples at any compression
/// ratio an image format reaches. A header declaring more is a cut or corrupt file (or a
/// decompression bomb) and is refused before its samples are allocated.
pub(crate) fn holds_decoded(decoded: usize, file_len: usize) -> bool {
    decoded <= PLAUSIBLE_FLOOR || decoded / MAX_RATIO <= file_len
}

/// A kind of file and the most bytes a reader takes of it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Cap {
    /// The cap in bytes.
    pub bytes: u64,
    /// The kind of file, for messages ("a PLY file").
    pub what: &'static str,
}

/// Gaussian and mesh PLY: a Gaussian model at gs-core's `MAX_GAUSSIANS` (50 M) and SH degree 3
/// is 11.5 GiB, the largest scene vagsl accepts; a fused mesh of 200 M triangles is half that.
pub const PLY: Cap = Cap { bytes: MAX_GAUSSIANS as u64 * GAUSSIAN_PLY_RECORD + (1 << 20), what: "a PLY file" };
/// COLMAP models (text or binary): `points3D.txt` of `MAX_GAUSSIANS` points with tracks of a
/// few dozen views is about 10 GB, beyond any SfM model vagsl has met (a few hundred MB).
pub const COLMAP: Cap = Cap { bytes: 16 << 30, what: "a COLMAP model file" };
/// OBJ meshes (text): 100 M triangles over 50 M vertices take about 5 GB.
pub const OBJ: Cap = Cap { bytes: 8 << 30, what: "an OBJ file" };
/// Photos, masks and EXR maps: twice the samples of the largest decoded image, room for any
/// container around uncompressed samples.
pub const IMAGE: Cap = Cap { bytes: 2 * IMAGE_SAMPLE_CAP, what: "an image file" };
/// NumPy `.npy` / `.npz`: a depth or normal map at the pixel cap (1 GiB at four f32 channels),
/// twice over; weight archives are a few MB.
pub const NPY: Cap = Cap { bytes: 2 * IMAGE_SAMPLE_CAP, what: "a NumPy file" };
/// Training checkpoints: 59 parameters, two Adam moments and 4 statistics per Gaussian (about
/// 724 bytes) at `MAX_GAUSSIANS` are 34 GiB, plus the source depths.
pub const CHECKPOINT: Cap = Cap { bytes: 40 << 30, what: "a checkpoint" };
/// Feature-extractor weights: the VGG16 blob vagsl uses is 7 MB.
pub const WEIGHTS: Cap = Cap { bytes: 64 << 20, what: "a weights file" };

impl Cap {
    /// Reads `path` whole under this cap (see [`read_capped`]).
    pub fn read(self, path: &Path) -> Result<Vec<u8>> {
        read_capped(path, self.bytes, self.what)
    }

    /// Refuses `subject`'s declaration (a header, a count prefix) of `count` `noun`s of at
    /// least `min_bytes` each when the `available` bytes after it cannot hold them (a truncated
    /// file or a wrong count), before anything is allocated for them. The message names the
    /// file, the declaration and the cap.
    pub fn check_declared(self, path: &Path, subject: &str, (count, noun): (u64, &str), min_bytes: u64, available: u64) -> Result<()> {
        match count.checked_mul(min_bytes) {
            Some(need) if need <= available => Ok(()),
            need => Err(IoError::format(
                path,
                format!(
                    "{subject} declares {count} {noun} of at least {min_bytes} bytes each ({}), more than the {} left in the file can hold (truncated, or a wrong count?); the cap for {} is {}",
                    need.map_or_else(|| "more than 16 EiB".to_string(), bytes),
                    bytes(available),
                    self.what,
                    bytes(self.bytes)
                ),
            )),
        }
    }
}

/// Reads `path` whole, refusing more than `cap` bytes without reading them (a regular file by
/// its size, a device or pipe after `cap` bytes, at most [`STREAM_CAP`]); `what` names the
/// kind of file in the message.
pub fn read_capped(path: &Path, cap: u64, what: &str) -> Result<Vec<u8>> {
    let file = std::fs::File::open(path).map_err(|e| IoError::io(path, e))?;
    let meta = file.metadata().map_err(|e| IoError::io(path, e))?;
    if meta.is_dir() {
        return Err(IoError::invalid(path, format!("is a folder, not {what}")));
    }
    let too_big = |n: &str, cap: u64, tail: &str| {
        IoError::invalid(path, format!("{n} more than the cap of {} for {what}{tail}", bytes(cap)))
    };
    if meta.is_file() && meta.len() > cap {
        return Err(too_big(&format!("the file holds {},", bytes(meta.len())), cap, ""));
    }
    let (limit, tail) = if meta.is_file() || cap <= STREAM_CAP { (cap, "") } else { (STREAM_CAP, " read from a pipe or device") };
    let mut buf = Vec::with_capacity(if meta.is_file() { meta.len() as usize } else { 0 });
    file.take(limit + 1).read_to_end(&mut buf).map_err(|e| IoError::io(path, e))?;
    if buf.len() as u64 > limit {
        return Err(too_big("it gives", limit, tail));
    }
    Ok(buf)
}

/// A byte count in words (`4 MiB`, `1.5 GiB`, `512 bytes`).
pub fn bytes(n: u64) -> String {
    const UNITS: [(&str, u64); 5] =
        [("EiB", 1 << 60), ("PiB", 1 << 50), ("TiB", 1 << 40), ("GiB", 1 << 30), ("MiB", 1 << 20)];
    const KIB: (&str, u64) = ("KiB", 1 << 10);
    UNITS.iter().chain([&KIB]).find(|(_, u)| n >= *u).map_or(format!("{n} bytes"), |(name, u)| {
        let v = n as f64 / *u as f64;
        if v.fract() == 0.0 { format!("{v:.0} {name}") } else { format!("{v:.1} {name}") }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_device_or_a_big_file_stops_at_the_cap() {
        let t = std::time::Instant::now();
        let e = read_capped(Path::new("/dev/zero"), SETTINGS_CAP, "a settings file").unwrap_err().to_string();
        assert_eq!(e, "/dev/zero: it gives more than the cap of 4 MiB for a settings file");
        assert!(t.elapsed().as_secs() < 5);
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("big.json");
        std::fs::write(&p, vec![b' '; 2000]).unwrap();
        let e = read_capped(&p, 1024, "a JSON file").unwrap_err().to_string();
        assert!(e.ends_with("the file holds 2.0 KiB, more than the cap of 1 KiB for a JSON file"), "{e}");
        assert_eq!(read_capped(&p, 2000, "x").unwrap().len(), 2000);
        let e = read_capped(dir.path(), 10, "a PLY file").unwrap_err().to_string();
        assert!(e.ends_with("is a folder, not a PLY file"), "{e}");
    }

    #[test]
    fn an_endless_pipe_stops_at_the_cap() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status().unwrap();
        assert!(made.success());
        let writer = {
            let fifo = fifo.clone();
            // Writes until the reader closes the pipe (then the write fails: Rust ignores SIGPIPE).
            std::thread::spawn(move || {
                let mut w = std::fs::OpenOptions::new().write(true).open(&fifo).unwrap();
                let block = vec![b'#'; 1 << 16];
                while std::io::Write::write_all(&mut w, &block).is_ok() {}
            })
        };
        let e = read_capped(&fifo, SETTINGS_CAP, "a settings file").unwrap_err().to_string();
        assert_eq!(e, format!("{}: it gives more than the cap of 4 MiB for a settings file", fifo.display()));
        writer.join().unwrap();
    }

    #[test]
    fn caps_cover_the_largest_scene_and_stay_below_memory() {
        // One Gaussian PLY at the Gaussian cap fits; a pipe never gives more than 1 GiB.
        assert!(PLY.bytes >= MAX_GAUSSIANS as u64 * GAUSSIAN_PLY_RECORD);
        assert_eq!(bytes(PLY.bytes), "11.5 GiB");
        assert_eq!(bytes(IMAGE_SAMPLE_CAP), "1 GiB");
        assert!(IMAGE.bytes > IMAGE_SAMPLE_CAP && NPY.bytes > IMAGE_SAMPLE_CAP);
    }

    #[test]
    fn a_declaration_beyond_the_file_names_it_and_the_cap() {
        let p = Path::new("m.ply");
        assert!(PLY.check_declared(p, "element 'vertex'", (10, "records"), 12, 120).is_ok());
        let e = PLY.check_declared(p, "element 'vertex'", (1_000_000_000_000, "records"), 12, 120).unwrap_err().to_string();
        assert_eq!(
            e,
            "m.ply: element 'vertex' declares 1000000000000 records of at least 12 bytes each (10.9 TiB), more than the 120 bytes left in the file can hold (truncated, or a wrong count?); the cap for a PLY file is 11.5 GiB"
        );
        let e = COLMAP.check_declared(p, "the point count", (u64::MAX, "points"), 43, 0).unwrap_err().to_string();
        assert!(e.contains("(more than 16 EiB)"), "{e}");
    }
}
