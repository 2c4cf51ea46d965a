//! Helpers shared by gs-synth's integration tests.
#![allow(dead_code)]

use std::collections::BTreeMap;
use std::path::Path;

/// Every file under `dir` (relative path → bytes).
pub fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.insert(p.strip_prefix(dir).unwrap().display().to_string(), std::fs::read(&p).unwrap());
            }
        }
    }
    out
}

/// The determinism contract of a scene writer `write(dir, seed)`: the same seed writes the same
/// bytes on 1 and 2 threads (at least `min_files` files), another seed changes each of `differ`,
/// and writing over an existing folder is refused and leaves it as it was.
pub fn assert_deterministic_writer<E: std::fmt::Debug>(write: impl Fn(&Path, u64) -> Result<(), E> + Sync, min_files: usize, differ: &[&str]) {
    let tmp = tempfile::tempdir().unwrap();
    let write_with = |name: &str, seed: u64, threads: usize| {
        let dir = tmp.path().join(name);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| write(&dir, seed).unwrap());
        files(&dir)
    };
    let a = write_with("a", 3, 1);
    let b = write_with("b", 3, 2);
    assert!(a.len() > min_files, "{} files", a.len());
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (k, v) in &a {
        assert!(v == &b[k], "{k} differs between two runs with the same seed");
    }
    let c = write_with("c", 4, 2);
    for f in differ {
        assert_ne!(a[*f], c[*f]);
    }
    // The folder is new: writing over it is refused and leaves it as it was.
    assert!(write(&tmp.path().join("a"), 3).is_err());
    assert_eq!(files(&tmp.path().join("a")).len(), a.len());
}
