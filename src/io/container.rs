//! Which container a log is, from its bytes, and one face over all of them.
//!
//! [`detect`] tells an MCAP file, a ROS 1 bag, a rosbag2 folder and a rosbag2
//! SQLite database apart by their first bytes (or, for a folder, by its
//! `metadata.yaml`), never by the file name. [`MessageSource`] is the reading
//! API the three readers share ([`McapFile`], [`Ros1Bag`], [`Ros2Bag`]), and
//! [`AnyContainer`] opens whichever [`detect`] finds, so that the log assembly
//! can be written once for every container.
//!
//! Times are `u64` nanoseconds throughout (record or log time, not header stamps).

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::mcap::{ChannelInfo, MappedScan, McapFile, RawMessage, ReadMode};
use crate::io::rosbag::{Ros1Bag, Ros2Bag};

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

/// Messages and time range of one channel, as an index or a scan gives them.
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelCount {
    /// The channel (topic, type, encoding).
    pub channel: ChannelInfo,
    /// Messages on it.
    pub count: u64,
    /// First and last record (log) time, nanoseconds; `None` without messages.
    pub time_range: Option<(u64, u64)>,
}

/// Every channel of a log with its counts: what `slam2world inspect` lists.
#[derive(Clone, Debug, PartialEq)]
pub struct Inventory {
    /// Channels by id.
    pub channels: Vec<ChannelCount>,
    /// How the counts were found: `Indexed` when from the index (a ROS 1 bag's
    /// index records, a `.db3`'s SQL counts), `Linear` when by a scan.
    pub mode: ReadMode,
    /// True when no chunk had to be decompressed for the counts.
    pub from_index: bool,
}

impl Inventory {
    /// Counts of the messages of a scan (every channel listed, with 0 where none).
    pub fn of_scan<T>(scan: &MappedScan<T>) -> Inventory {
        let mut stats: BTreeMap<u16, (u64, u64, u64)> = BTreeMap::new();
        for m in &scan.messages {
            let s = stats.entry(m.channel_id).or_insert((0, u64::MAX, 0));
            s.0 += 1;
            s.1 = s.1.min(m.log_time);
            s.2 = s.2.max(m.log_time);
        }
        let channels = scan
            .channels
            .values()
            .map(|c| {
                let (count, lo, hi) = stats.get(&c.id).copied().unwrap_or((0, 0, 0));
                ChannelCount {
                    channel: c.clone(),
                    count,
                    time_range: (count > 0).then_some((lo, hi)),
                }
            })
            .collect();
        Inventory {
            channels,
            mode: scan.mode,
            from_index: false,
        }
    }
}

/// The reading API every container shares (the one of [`McapFile`]).
pub trait MessageSource {
    /// The file (or folder) read.
    fn path(&self) -> &Path;

    /// The channels (topics with their types), by id.
    fn channels(&self) -> Result<BTreeMap<u16, ChannelInfo>>;

    /// Every message of a channel `want` keeps, passed to `map` (with its
    /// channel) inside the parallel decompression tasks; only the mapped value
    /// is kept. See each reader for the order of the messages.
    fn scan_map<T: Send + Default>(
        &self,
        want: impl Fn(&ChannelInfo) -> bool + Sync,
        map: impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync,
    ) -> Result<MappedScan<T>>;

    /// Counts and time ranges per channel, from the index where there is one.
    fn inventory(&self) -> Result<Inventory>;
}

impl MessageSource for McapFile {
    fn path(&self) -> &Path {
        McapFile::path(self)
    }

    fn channels(&self) -> Result<BTreeMap<u16, ChannelInfo>> {
        McapFile::channels(self)
    }

    fn scan_map<T: Send + Default>(
        &self,
        want: impl Fn(&ChannelInfo) -> bool + Sync,
        map: impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync,
    ) -> Result<MappedScan<T>> {
        McapFile::scan_map(self, want, map)
    }

    fn inventory(&self) -> Result<Inventory> {
        Ok(Inventory::of_scan(&McapFile::scan_map(
            self,
            |_| true,
            |_, _| (),
        )?))
    }
}

/// Whichever container [`detect`] found, opened.
pub enum AnyContainer {
    /// An MCAP file.
    Mcap(McapFile),
    /// A ROS 1 bag.
    Ros1(Ros1Bag),
    /// A rosbag2 folder or `.db3` file.
    Ros2(Ros2Bag),
}

impl AnyContainer {
    /// Detects the container of `path` and opens it.
    pub fn open(path: impl AsRef<Path>) -> Result<AnyContainer> {
        let path = path.as_ref();
        Ok(match detect(path)? {
            Container::Mcap => AnyContainer::Mcap(McapFile::open(path)?),
            Container::Ros1Bag => AnyContainer::Ros1(Ros1Bag::open(path)?),
            Container::Ros2Folder | Container::Ros2Sqlite => {
                AnyContainer::Ros2(Ros2Bag::open(path)?)
            }
        })
    }

    /// The kind of container.
    pub fn kind(&self) -> Container {
        match self {
            AnyContainer::Mcap(_) => Container::Mcap,
            AnyContainer::Ros1(_) => Container::Ros1Bag,
            AnyContainer::Ros2(b) if b.is_folder() => Container::Ros2Folder,
            AnyContainer::Ros2(_) => Container::Ros2Sqlite,
        }
    }
}

impl MessageSource for AnyContainer {
    fn path(&self) -> &Path {
        match self {
            AnyContainer::Mcap(f) => MessageSource::path(f),
            AnyContainer::Ros1(b) => MessageSource::path(b),
            AnyContainer::Ros2(b) => MessageSource::path(b),
        }
    }

    fn channels(&self) -> Result<BTreeMap<u16, ChannelInfo>> {
        match self {
            AnyContainer::Mcap(f) => MessageSource::channels(f),
            AnyContainer::Ros1(b) => MessageSource::channels(b),
            AnyContainer::Ros2(b) => MessageSource::channels(b),
        }
    }

    fn scan_map<T: Send + Default>(
        &self,
        want: impl Fn(&ChannelInfo) -> bool + Sync,
        map: impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync,
    ) -> Result<MappedScan<T>> {
        match self {
            AnyContainer::Mcap(f) => MessageSource::scan_map(f, want, map),
            AnyContainer::Ros1(b) => MessageSource::scan_map(b, want, map),
            AnyContainer::Ros2(b) => MessageSource::scan_map(b, want, map),
        }
    }

    fn inventory(&self) -> Result<Inventory> {
        match self {
            AnyContainer::Mcap(f) => f.inventory(),
            AnyContainer::Ros1(b) => b.inventory(),
            AnyContainer::Ros2(b) => b.inventory(),
        }
    }
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
