//! Atomic file writes: write to a temporary file in the same folder, then rename.
//!
//! The temporary file is `.NAME.PID.tmp`. A process killed mid-write leaves its temporary file
//! behind; the next write of the same target removes such leftovers of processes that no longer
//! exist ([`remove_stale_temps`]).

use crate::error::{IoError, Result};
use std::io::{BufWriter, Write};
use std::path::Path;
use std::time::Duration;

/// A leftover temporary file is removed only when it has not been modified for this long, so a
/// live writer that `/proc` cannot see (another PID namespace sharing the folder) is spared.
pub const STALE_TEMP_AGE: Duration = Duration::from_secs(10 * 60);

/// Writes a file atomically: `write` fills a buffered temporary file next to `path`
/// (same folder, so the rename is atomic), which is flushed, synced and renamed onto `path`.
/// On any error the temporary file is removed and `path` is left untouched.
/// The target is checked first ([`crate::check_output_path`]): a symbolic link, device, pipe
/// or folder is refused, never replaced.
pub fn write_atomic(path: &Path, write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>) -> Result<()> {
    crate::check_output_path(path)?;
    let dir = crate::output::folder_of(path).to_path_buf();
    let file_name = path
        .file_name()
        .ok_or_else(|| IoError::invalid(path, "output path has no file name"))?
        .to_string_lossy()
        .into_owned();
    remove_stale_temps(&dir, &file_name);
    let tmp = dir.join(format!(".{file_name}.{}.tmp", std::process::id()));
    let result = (|| -> std::io::Result<()> {
        let file = std::fs::File::create(&tmp)?;
        let mut w = BufWriter::new(file);
        write(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(IoError::io(path, e));
    }
    Ok(())
}

/// Removes `dir/.FILE_NAME.PID.tmp` files and folders left by killed writes of the same target
/// (a file of [`write_atomic`], a folder assembled whole and swapped in, as `view`'s
/// `.report.PID.tmp/`): PID is not this process, `/proc/PID` does not exist (Linux, with
/// `/proc` mounted; elsewhere nothing is removed, as liveness cannot be told) and the entry is
/// older than [`STALE_TEMP_AGE`]. A symbolic link is never followed or removed. Best effort: a
/// failure to list or remove never fails the write. Returns the entries removed.
pub fn remove_stale_temps(dir: &Path, file_name: &str) -> Vec<std::path::PathBuf> {
    let mut removed = Vec::new();
    let proc = Path::new("/proc");
    if !cfg!(target_os = "linux") || !proc.join("self").exists() {
        return removed;
    }
    let Ok(entries) = std::fs::read_dir(dir) else { return removed };
    let prefix = format!(".{file_name}.");
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(|n| n.strip_prefix(&prefix)).and_then(|r| r.strip_suffix(".tmp")) else {
            continue;
        };
        if pid.is_empty() || !pid.bytes().all(|b| b.is_ascii_digit()) || pid.parse::<u32>().ok() == Some(std::process::id()) {
            continue;
        }
        let Ok(meta) = entry.path().symlink_metadata() else { continue };
        let old = meta.modified().ok().and_then(|m| m.elapsed().ok()).is_some_and(|age| age >= STALE_TEMP_AGE);
        if !old || proc.join(pid).exists() {
            continue;
        }
        let gone = if meta.is_file() {
            std::fs::remove_file(entry.path()).is_ok()
        } else {
            meta.is_dir() && std::fs::remove_dir_all(entry.path()).is_ok()
        };
        if gone {
            removed.push(entry.path());
        }
    }
    removed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_write_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.bin");
        std::fs::write(&p, b"old").unwrap();
        let err = write_atomic(&p, |w| {
            w.write_all(b"partial")?;
            Err(std::io::Error::other("boom"))
        });
        assert!(err.is_err());
        assert_eq!(std::fs::read(&p).unwrap(), b"old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        write_atomic(&p, |w| w.write_all(b"new")).unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"new");
    }
}
