//! The one reader size cap: a text file (settings, JSON) is read up to a cap named in the
//! message, so a device or a runaway file (`--config /dev/zero`) fails at once instead of
//! filling memory.

use crate::error::{IoError, Result};
use std::io::Read;
use std::path::Path;

/// Cap of a settings file (`--config`): a few MB of TOML or JSON is far beyond any real one.
pub const SETTINGS_CAP: u64 = 4 << 20;
/// Cap of a JSON document vagsl reads (transforms.json, a run's config.json and report.json):
/// hundreds of thousands of frames fit.
pub const JSON_CAP: u64 = 256 << 20;

/// Reads `path` whole, refusing more than `cap` bytes without reading them (a regular file by
/// its size, a device or pipe after `cap` bytes); `what` names the kind of file in the message.
pub fn read_capped(path: &Path, cap: u64, what: &str) -> Result<Vec<u8>> {
    let file = std::fs::File::open(path).map_err(|e| IoError::io(path, e))?;
    let meta = file.metadata().map_err(|e| IoError::io(path, e))?;
    let too_big = |n: &str| IoError::invalid(path, format!("{n} more than the cap of {} for {what}", bytes(cap)));
    if meta.is_file() && meta.len() > cap {
        return Err(too_big(&format!("the file holds {},", bytes(meta.len()))));
    }
    let mut buf = Vec::with_capacity(if meta.is_file() { meta.len() as usize } else { 0 });
    file.take(cap + 1).read_to_end(&mut buf).map_err(|e| IoError::io(path, e))?;
    if buf.len() as u64 > cap {
        return Err(too_big("it gives"));
    }
    Ok(buf)
}

/// A byte count in words (`4 MiB`, `1.5 GiB`, `512 bytes`).
fn bytes(n: u64) -> String {
    const UNITS: [(&str, u64); 3] = [("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)];
    UNITS.iter().find(|(_, u)| n >= *u).map_or(format!("{n} bytes"), |(name, u)| {
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
    }
}
