//! Fuzz target: arbitrary bytes as a Gaussian PLY and as a mesh PLY.
//!
//! Both byte-slice parsers of gs-io must return `Ok` or an error for any input: a panic,
//! abort, overflow or huge allocation is a bug. Whatever parses is written back with our
//! writer and parsed again, and must come back identical (the writers and readers agree).
#![no_main]

use gs_io::ply::gaussian::write_gaussian_ply_to;
use gs_io::ply::mesh::write_mesh_ply_to;
use gs_io::{parse_gaussian_ply, parse_mesh_ply};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz.ply");
    if let Ok(g) = parse_gaussian_ply(data, path) {
        g.validate().expect("a parsed model validates");
        let mut buf = Vec::new();
        write_gaussian_ply_to(&mut buf, &g).expect("writing to memory");
        let back = parse_gaussian_ply(&buf, path).expect("our own output parses");
        assert_eq!(back, g);
    }
    if let Ok(m) = parse_mesh_ply(data, path) {
        m.validate().expect("a parsed mesh validates");
        let mut buf = Vec::new();
        write_mesh_ply_to(&mut buf, &m).expect("writing to memory");
        let back = parse_mesh_ply(&buf, path).expect("our own output parses");
        assert_eq!(back, m);
    }
});
