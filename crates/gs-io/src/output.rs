//! The one check of an output file path, made by [`crate::write_atomic`] before every write and
//! by the command line before any expensive work: the target is a regular file or new, never a
//! symbolic link, device, pipe or folder (the atomic rename would replace it with a regular
//! file), and its folder exists and is a folder.

use crate::error::{IoError, Result};
use std::path::Path;

/// Refuses an output path that an atomic write must not replace, in words: a folder (or a
/// path ending in `/`), a symbolic link, a device, pipe or socket, or a path whose folder is
/// missing or is a file. A new path in an existing folder, or an existing regular file, is
/// accepted. Writability is not probed (see [`check_output_writable`]).
pub fn check_output_path(path: &Path) -> Result<()> {
    let text = path.as_os_str().as_encoded_bytes();
    if text.is_empty() {
        return Err(IoError::invalid(path, "the output path is empty; give a file name"));
    }
    if text.ends_with(b"/") || path.is_dir() {
        return Err(IoError::invalid(path, "this is a folder, not a file: give a file name inside it (e.g. DIR/mesh.ply)"));
    }
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => Err(IoError::invalid(
            path,
            "this is a symbolic link; vagsl writes its outputs as new files, which would replace the link, so it never writes through one: give the link's target or another name",
        )),
        Ok(m) if !m.is_file() => Err(IoError::invalid(
            path,
            "this is not a regular file (a device, pipe or socket), which the output would replace; give a file name",
        )),
        Ok(_) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound || e.kind() == std::io::ErrorKind::NotADirectory => {
            check_folder(path)
        }
        Err(e) => Err(IoError::io(path, e)),
    }
}

/// The folder of a new output `path`: it must exist and be a folder. Names the first part of
/// the path that is a file, or the missing folder.
fn check_folder(path: &Path) -> Result<()> {
    let dir = folder_of(path);
    if dir.is_dir() {
        return Ok(());
    }
    // The nearest part of the path that exists says whether a file stands in the way.
    for a in dir.ancestors().filter(|a| !a.as_os_str().is_empty()) {
        if let Ok(m) = std::fs::metadata(a) {
            if !m.is_dir() {
                return Err(IoError::invalid(
                    path,
                    format!("cannot write there: {} is a file, not a folder", a.display()),
                ));
            }
            break;
        }
    }
    Err(IoError::invalid(path, format!("cannot write there: the folder {} does not exist", dir.display())))
}

/// The folder an output file is written into (`.` for a bare file name).
pub fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// [`check_output_path`], then a probe that the folder accepts a new file (a hidden file,
/// removed again), so a read-only folder is refused before hours of work rather than after.
pub fn check_output_writable(path: &Path) -> Result<()> {
    check_output_path(path)?;
    let dir = folder_of(path);
    let probe = dir.join(format!(".vagsl-write-test-{}", std::process::id()));
    match std::fs::OpenOptions::new().write(true).create_new(true).open(&probe) {
        Ok(_) => {
            let _ = std::fs::remove_file(&probe);
            Ok(())
        }
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(()),
        Err(e) => Err(IoError::invalid(path, format!("cannot write in the folder {}: {e}", dir.display()))),
    }
}
