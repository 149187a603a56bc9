//! Helpers shared by the integration-test modules.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the `slam2world` binary with `args`.
pub fn bin(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_slam2world"))
        .args(args)
        .output()
        .expect("the slam2world binary runs")
}

/// A file under ../shared/data, or `None` (with the reason on stderr) when absent:
/// the caller skips.
pub fn data(folder: &str, file: &str) -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data")
        .join(folder)
        .join(file);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("skipped: {} is absent", p.display());
        None
    }
}

/// The process's stderr as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A ROS bag fixture of `tests/data/rosbag` (written by its `make_fixtures.py`).
pub fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/rosbag")
        .join(name)
}

/// The ROS 1 bag with `index_pos` set to 0, as a recorder that did not close it leaves it.
pub fn without_index_pos(bytes: &[u8]) -> Vec<u8> {
    let at = index_pos_field(bytes);
    let mut out = bytes.to_vec();
    out[at..at + 8].fill(0);
    out
}

/// The ROS 1 bag header's `index_pos` value.
pub fn index_pos(bytes: &[u8]) -> usize {
    let at = index_pos_field(bytes);
    u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize
}

/// Where the bag header's `index_pos` value starts.
fn index_pos_field(bytes: &[u8]) -> usize {
    let key = b"index_pos=";
    bytes
        .windows(key.len())
        .position(|w| w == key)
        .expect("bag header has index_pos")
        + key.len()
}
