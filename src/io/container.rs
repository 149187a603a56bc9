//! Which container a log is, from its bytes.
//!
//! [`detect`] tells an MCAP file, a ROS 1 bag, a rosbag2 folder and a rosbag2
//! SQLite database apart by their first bytes (or, for a folder, by its
//! `metadata.yaml`), never by the file name. The readers share one face
//! (`io::messages::MessageSource`); the log assembly (`io::log`) opens
//! whichever container [`detect`] finds.

use std::io::Read;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// The first line of a ROS 1 bag of version 2.0.
pub const ROS1_MAGIC: &[u8; 13] = b"#ROSBAG V2.0\n";
/// The first 16 bytes of every SQLite 3 database.
pub const SQLITE_MAGIC: &[u8; 16] = b"SQLite format 3\0";

/// The kinds of log slam2world reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Container {
    /// An MCAP file (magic `\x89MCAP0\r\n`).
    Mcap,
    /// A ROS 1 bag, version 2.0 (`#ROSBAG V2.0\n`).
    Ros1Bag,
    /// A rosbag2 folder: `metadata.yaml` beside `.db3` or `.mcap` files.
    Ros2Folder,
    /// A single rosbag2 SQLite database (`.db3`, `SQLite format 3\0`).
    Ros2Sqlite,
}

pub use crate::error::ContainerError;

impl Container {
    /// The name reports and `inspect` give the container (`mcap`, `ros1 bag`,
    /// `rosbag2 folder`, `rosbag2 db3`).
    pub fn name(self) -> &'static str {
        match self {
            Container::Mcap => "mcap",
            Container::Ros1Bag => "ros1 bag",
            Container::Ros2Folder => "rosbag2 folder",
            Container::Ros2Sqlite => "rosbag2 db3",
        }
    }
}

fn container_err(path: &Path, reason: ContainerError) -> Error {
    Error::Container {
        path: path.to_path_buf(),
        reason,
    }
}

/// What kind of log `path` is, from its first bytes (a folder: from its
/// `metadata.yaml`; a file named `metadata.yaml`: its folder). FIFOs, sockets
/// and devices are refused without being opened.
pub fn detect(path: impl AsRef<Path>) -> Result<Container> {
    let path = path.as_ref();
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if meta.is_dir() {
        return if path.join("metadata.yaml").is_file() {
            Ok(Container::Ros2Folder)
        } else {
            Err(container_err(path, ContainerError::NoMetadata))
        };
    }
    if !meta.is_file() {
        return Err(container_err(
            path,
            ContainerError::NotAFile {
                kind: crate::io::mapped::special_kind(&meta),
            },
        ));
    }
    if path.file_name().is_some_and(|n| n == "metadata.yaml") {
        return Ok(Container::Ros2Folder);
    }
    let mut head = Vec::with_capacity(32);
    std::fs::File::open(path)
        .and_then(|f| f.take(32).read_to_end(&mut head))
        .map_err(|e| Error::io(path, e))?;
    classify(&head).map_err(|r| container_err(path, r))
}

pub use crate::io::mapped::require_file;

/// The container of a file that starts with `head` (its first 32 bytes or all of it).
pub fn classify(head: &[u8]) -> std::result::Result<Container, ContainerError> {
    if head.is_empty() {
        return Err(ContainerError::Empty);
    }
    if head.starts_with(crate::io::mcap::reader::MAGIC) {
        return Ok(Container::Mcap);
    }
    if head.starts_with(ROS1_MAGIC) {
        return Ok(Container::Ros1Bag);
    }
    if let Some(rest) = head.strip_prefix(b"#ROSBAG V") {
        let line = rest.split(|&b| b == b'\n').next().unwrap_or(rest);
        return Err(ContainerError::BagVersion {
            version: String::from_utf8_lossy(line).into_owned(),
        });
    }
    if head.starts_with(SQLITE_MAGIC) {
        return Ok(Container::Ros2Sqlite);
    }
    Err(ContainerError::Unknown {
        head: head[..head.len().min(16)].escape_ascii().to_string(),
    })
}

/// A path for error messages: the folder of a rosbag2 `metadata.yaml`.
pub(crate) fn folder_of(path: &Path) -> PathBuf {
    if path.file_name().is_some_and(|n| n == "metadata.yaml") {
        path.parent().map(Path::to_path_buf).unwrap_or_default()
    } else {
        path.to_path_buf()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classify_by_magic() {
        assert_eq!(classify(b"\x89MCAP0\r\n\x01").unwrap(), Container::Mcap);
        assert_eq!(classify(b"#ROSBAG V2.0\nxx").unwrap(), Container::Ros1Bag);
        assert_eq!(
            classify(b"SQLite format 3\0abc").unwrap(),
            Container::Ros2Sqlite
        );
        assert!(matches!(
            classify(b"#ROSBAG V1.2\n"),
            Err(ContainerError::BagVersion { version }) if version == "1.2"
        ));
        assert!(matches!(classify(b""), Err(ContainerError::Empty)));
        assert!(matches!(
            classify(b"hello"),
            Err(ContainerError::Unknown { head }) if head == "hello"
        ));
    }
}
