//! Fuzz target: arbitrary bytes as a `vagsl train --config FILE` settings file, in JSON and
//! in TOML.
//!
//! Each input goes through gs-train's `parse_settings_file` (as `c.json` and as `c.toml`),
//! then the file's preset, the overlay of its settings on that preset and validation (what
//! `--config` does before the command-line flags): `Ok` or an error naming the file, never a
//! panic, abort, overflow, stack overflow or huge allocation. A configuration that results is
//! written as JSON (the form of a run's `config.json`) and must read back identically.
#![no_main]

use gs_train::config::parse_settings_file;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    for name in ["c.json", "c.toml"] {
        let path = Path::new(name);
        let Ok(file) = parse_settings_file(data, path) else { continue };
        let Ok(config) = file.config(path) else { continue };
        let json = serde_json::to_vec(&config).expect("a configuration serialises");
        let back = parse_settings_file(&json, Path::new("back.json")).expect("our own JSON parses");
        assert_eq!(back.config(Path::new("back.json")).expect("our own configuration is valid"), config);
    }
});
