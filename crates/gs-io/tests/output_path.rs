//! The one output-path check (issue #35): every atomic write refuses a target that is a
//! symbolic link, a device or a folder, and a missing folder or a file in the folder's place
//! is named; the link, device or folder is never replaced.
#![cfg(unix)]

use gs_io::{check_output_path, check_output_writable, write_atomic};

fn write(p: &std::path::Path) -> String {
    write_atomic(p, |w| w.write_all(b"new")).unwrap_err().to_string()
}

#[test]
fn links_devices_and_folders_are_never_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let target = d.join("target.ply");
    std::fs::write(&target, b"old").unwrap();
    let link = d.join("link.ply");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let err = write(&link);
    assert!(err.contains("symbolic link") && err.contains("link.ply"), "{err}");
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink(), "the link was replaced");
    assert_eq!(std::fs::read(&target).unwrap(), b"old");
    // A dangling link too.
    let dangling = d.join("dangling.ply");
    std::os::unix::fs::symlink(d.join("nowhere"), &dangling).unwrap();
    assert!(write(&dangling).contains("symbolic link"));

    // A device (as root, the rename would replace /dev/null itself).
    let err = check_output_path(std::path::Path::new("/dev/null")).unwrap_err().to_string();
    assert!(err.starts_with("/dev/null: ") && err.contains("not a regular file"), "{err}");

    // A folder, or a path ending in '/'.
    for p in [d.to_path_buf(), d.join("new/")] {
        let err = write(&p);
        assert!(err.contains("is a folder") || err.contains("does not exist"), "{err}");
    }
    let err = write(&std::path::PathBuf::from(format!("{}/", d.display())));
    assert!(err.contains("this is a folder"), "{err}");
    assert_eq!(std::fs::read_dir(d).unwrap().count(), 3, "a temporary file was left");
}

#[test]
fn the_folder_is_named_when_missing_or_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let file = d.join("FILE");
    std::fs::write(&file, b"x").unwrap();
    let err = write(&file.join("m.ply"));
    assert!(err.contains(&format!("{} is a file, not a folder", file.display())), "{err}");
    let err = write(&file.join("sub/m.ply"));
    assert!(err.contains(&format!("{} is a file, not a folder", file.display())), "{err}");
    let err = write(&d.join("missing/m.ply"));
    assert!(err.contains(&format!("the folder {} does not exist", d.join("missing").display())), "{err}");
    // A regular file or a new name in a folder is accepted.
    check_output_writable(&file).unwrap();
    check_output_writable(&d.join("new.ply")).unwrap();
    write_atomic(&file, |w| w.write_all(b"new")).unwrap();
    assert_eq!(std::fs::read(&file).unwrap(), b"new");
}

#[test]
fn a_read_only_folder_is_refused_by_the_probe() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let mut ro = dir.path().join("ro");
    std::fs::create_dir(&ro).unwrap();
    std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o555)).unwrap();
    // root writes into any mode-555 folder; sysfs refuses new files even to root.
    if std::fs::File::create(ro.join("probe")).is_ok() {
        ro = std::path::PathBuf::from("/sys");
    }
    let err = check_output_writable(&ro.join("m.ply")).unwrap_err().to_string();
    assert!(err.contains(&format!("cannot write in the folder {}", ro.display())), "{err}");
}
