//! The `.db3` reader on arbitrary files: its own walk of the SQLite pages of
//! the `messages` table, and SQLite where that walk gives way (the rosbag2
//! fixtures of tests/data/rosbag seed the corpus): open, scan, count.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slam2world::io::rosbag::Ros2Bag;

fuzz_target!(|data: &[u8]| {
    let path = std::env::temp_dir().join(format!("slam2world-fuzz-{}.db3", std::process::id()));
    if std::fs::write(&path, data).is_ok() {
        if let Ok(bag) = Ros2Bag::open(&path) {
            let _ = bag.scan_map(|_| true, |_, m| m.data.len());
            let _ = bag.inventory();
        }
    }
});
