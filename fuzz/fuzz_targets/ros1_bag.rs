//! The ROS 1 bag reader on arbitrary files (the version line is prepended,
//! unless the input has one, so that it gets past the first check; the
//! fixtures of tests/data/rosbag seed the corpus): open, scan, count, and
//! the whole log assembly with its decoders (`read_log`).
#![no_main]

use libfuzzer_sys::fuzz_target;
use slam2world::io::rosbag::Ros1Bag;

fuzz_target!(|data: &[u8]| {
    let path = std::env::temp_dir().join(format!("slam2world-fuzz-{}.bag", std::process::id()));
    let mut bytes = Vec::with_capacity(data.len() + 13);
    if !data.starts_with(b"#ROSBAG V") {
        bytes.extend_from_slice(b"#ROSBAG V2.0\n");
    }
    bytes.extend_from_slice(data);
    if std::fs::write(&path, &bytes).is_ok() {
        if let Ok(bag) = Ros1Bag::open(&path) {
            let _ = bag.scan_map(|_| true, |_, m| m.data.len());
            let _ = bag.inventory();
        }
        let _ = slam2world::io::read_log(&path, &Default::default());
    }
});
