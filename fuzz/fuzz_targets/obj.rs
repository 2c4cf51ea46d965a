//! Fuzz target: arbitrary bytes as a Wavefront OBJ mesh.
//!
//! gs-io's byte-slice OBJ parser must return `Ok` or an error naming the problem for any input:
//! a panic, abort, overflow or huge allocation is a bug. What parses must be a valid mesh
//! (every face index in range, every position finite). There is no OBJ writer to round-trip.
#![no_main]

use gs_io::obj::parse_obj;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    if let Ok(m) = parse_obj(data, Path::new("fuzz.obj")) {
        m.validate().expect("a parsed OBJ mesh validates");
    }
});
