//! Fuzz target: arbitrary bytes as a training checkpoint (`checkpoint.bin`).
//!
//! A checkpoint ends in a CRC-32 of everything before it, which random bytes almost never
//! match, so each input is decoded twice: as it is (the checksum check) and with its correct
//! CRC appended, which lets the fuzzer reach every record behind the checksum (the embedded
//! configuration JSON, the Gaussians, the optimiser groups, the statistics, the exposure and
//! the elapsed time). gs-train's `checkpoint::decode` must return `Ok` or an error naming the
//! problem: a panic, abort, overflow or huge allocation is a bug. A checkpoint that decodes is
//! encoded again and must decode to the same bytes.
#![no_main]

use gs_train::checkpoint::{decode, encode};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("checkpoint.bin");
    let _ = decode(data, path);
    let mut sealed = data.to_vec();
    sealed.extend_from_slice(&gs_features::weights::crc32(data).to_le_bytes());
    if let Ok(ck) = decode(&sealed, path) {
        let bytes = encode(&ck.config, &ck.state, &ck.elapsed.unwrap_or_default());
        let back = decode(&bytes, path).expect("our own checkpoint decodes");
        let again = encode(&back.config, &back.state, &back.elapsed.unwrap_or_default());
        assert!(bytes == again, "a checkpoint re-encodes to the same bytes");
    }
});
