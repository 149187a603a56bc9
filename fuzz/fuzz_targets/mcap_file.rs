//! The container reader and `read_mcap` on arbitrary files (the MCAP magic is
//! prepended so the input gets past the first check).
#![no_main]

use libfuzzer_sys::fuzz_target;
use slam2world::io::{read_mcap, ReadOptions};

fuzz_target!(|data: &[u8]| {
    let path = std::env::temp_dir().join(format!("slam2world-fuzz-{}.mcap", std::process::id()));
    let mut bytes = b"\x89MCAP0\r\n".to_vec();
    bytes.extend_from_slice(data);
    if std::fs::write(&path, &bytes).is_ok() {
        let _ = read_mcap(&path, &ReadOptions::default());
    }
});
