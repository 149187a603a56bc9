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
