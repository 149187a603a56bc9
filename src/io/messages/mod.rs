//! Messages, whatever container they came in: the channel and message types
//! every reader gives ([`ChannelInfo`], [`RawMessage`], [`MappedMessage`],
//! [`MappedScan`], [`ReadMode`]) and the decoders of the message encodings.
//!
//! - [`wire`]: byte-level readers of ROS 1, ROS 2 CDR and protobuf;
//! - [`decode`]: the messages slam2world uses, by [`decode::MessageKind`];
//! - [`gnss`]: `sensor_msgs/NavSatFix` and `foxglove.LocationFix` fixes.
//!
//! [`MessageSource`] is the reading face every container's reader gives
//! (`io::mcap`, `io::rosbag`); the log assembly (`io::log`) reads through it,
//! so that one decoder serves every container. This module is the bottom of
//! `io`: it names no reader.
//! Times are `u64` nanoseconds (a container's log or record time).

use std::collections::BTreeMap;
use std::path::Path;

use crate::error::Result;

pub mod decode;
pub mod gnss;
pub mod wire;

/// A channel of a log with its schema (empty name and encoding when schemaless).
///
/// MCAP channels are what the file says; a ROS 1 connection is a channel with
/// encoding `ros1` and its `message_definition` as `ros1msg` schema; a rosbag2
/// topic has encoding `cdr` and, from a `.db3`, a type name without definition.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ChannelInfo {
    /// Channel id, unique in the log.
    pub id: u16,
    /// Topic name, e.g. `/lsd_slam/keyframes`.
    pub topic: String,
    /// Message encoding: `ros1`, `cdr`, `protobuf`, `json`, …
    pub message_encoding: String,
    /// Schema id (0 for none).
    pub schema_id: u16,
    /// Schema name, e.g. `geometry_msgs/PoseStamped`; empty without a schema.
    pub schema_name: String,
    /// Schema encoding: `ros1msg`, `ros2msg`, `protobuf`, `jsonschema`, …
    pub schema_encoding: String,
    /// Schema data (message definition text, or a protobuf FileDescriptorSet).
    pub schema_data: Vec<u8>,
    /// Channel metadata.
    pub metadata: BTreeMap<String, String>,
}

/// One message; `data` borrows from the memory map or from a decompressed
/// chunk held by the reader.
#[derive(Clone, Copy, Debug)]
pub struct RawMessage<'a> {
    /// Channel id (see [`MappedScan::channels`]).
    pub channel_id: u16,
    /// Publisher sequence number (0 where the container has none).
    pub sequence: u32,
    /// Log time, nanoseconds.
    pub log_time: u64,
    /// Publish time, nanoseconds.
    pub publish_time: u64,
    /// The serialised message.
    pub data: &'a [u8],
}

/// How the messages were found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReadMode {
    /// Through the container's index (an MCAP summary, a ROS 1 bag's index
    /// records, a `.db3`'s tables).
    Indexed,
    /// Record by record from the start of the file.
    Linear,
}

/// One message after mapping: its record fields and the mapped value.
#[derive(Clone, Debug)]
pub struct MappedMessage<T> {
    /// Channel id.
    pub channel_id: u16,
    /// Publisher sequence number.
    pub sequence: u32,
    /// Log time, nanoseconds.
    pub log_time: u64,
    /// Publish time, nanoseconds.
    pub publish_time: u64,
    /// What the map made of the message.
    pub value: T,
}

/// The result of a reader's `scan_map`.
#[derive(Debug)]
pub struct MappedScan<T> {
    /// Channels by id.
    pub channels: BTreeMap<u16, ChannelInfo>,
    /// The wanted messages (in file order for MCAP, in time order for bags).
    pub messages: Vec<MappedMessage<T>>,
    /// Indexed or linear.
    pub mode: ReadMode,
    /// The MCAP Header record's profile; `ros1` / `ros2` for bags.
    pub profile: String,
}

impl<T> MappedScan<T> {
    /// Gives the messages to `sink` in order, a quarter at a time, each
    /// quarter's memory freed before the next: the scan and what the sink
    /// makes of it are not held whole together.
    pub fn into_sink(self, sink: &mut dyn ScanSink<T>) -> ScanInfo {
        let MappedScan {
            channels,
            mut messages,
            mode,
            profile,
        } = self;
        let mut counts: BTreeMap<u16, u64> = BTreeMap::new();
        for m in &messages {
            *counts.entry(m.channel_id).or_default() += 1;
        }
        sink.expect(&counts);
        let quarter = messages.len().div_ceil(4).max(1);
        while !messages.is_empty() {
            let n = quarter.min(messages.len());
            for m in messages.drain(..n) {
                sink.message(m);
            }
            messages.shrink_to_fit();
            crate::buffer::release_free_memory();
        }
        ScanInfo {
            channels,
            mode,
            profile,
        }
    }
}

/// A scan without its messages: what [`MessageSource::scan_into`] returns
/// beside the messages it gave.
#[derive(Debug)]
pub struct ScanInfo {
    /// Channels by id.
    pub channels: BTreeMap<u16, ChannelInfo>,
    /// Indexed or linear.
    pub mode: ReadMode,
    /// The MCAP Header record's profile; `ros1` / `ros2` for bags.
    pub profile: String,
}

impl ScanInfo {
    /// The scan of these messages.
    pub fn with_messages<T>(self, messages: Vec<MappedMessage<T>>) -> MappedScan<T> {
        MappedScan {
            channels: self.channels,
            messages,
            mode: self.mode,
            profile: self.profile,
        }
    }
}

/// Where [`MessageSource::scan_into`] gives a scan's messages, in the scan's
/// order, so that the messages need not be held together (a reader that
/// can gives them a few chunks at a time).
pub trait ScanSink<T> {
    /// The messages the scan expects per channel id (an index's counts, no
    /// more than the file can hold), before the first message: a hint to
    /// size what the sink keeps, so that it need not grow.
    fn expect(&mut self, _counts: &BTreeMap<u16, u64>) {}

    /// The next message.
    fn message(&mut self, m: MappedMessage<T>);

    /// Forgets every message given so far: the scan starts again (an MCAP
    /// read through its index found fewer messages than the index declares,
    /// and reads the file linearly).
    fn restart(&mut self);
}

impl<T> ScanSink<T> for Vec<MappedMessage<T>> {
    fn message(&mut self, m: MappedMessage<T>) {
        self.push(m);
    }

    fn restart(&mut self) {
        self.clear();
    }
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

/// The reading API every container shares: the MCAP reader (`io::mcap::reader::McapFile`),
/// the ROS 1 and the rosbag2 readers (`io::rosbag`) implement it; the log assembly
/// (`io::log`) is written once over it.
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

    /// [`MessageSource::scan_map`] with the messages given to `sink` in the
    /// same order. This default scans whole, then gives the messages a
    /// quarter at a time ([`MappedScan::into_sink`]); the MCAP reader gives
    /// them a wave of chunks at a time.
    fn scan_into<T: Send + Default>(
        &self,
        want: impl Fn(&ChannelInfo) -> bool + Sync,
        map: impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync,
        sink: &mut dyn ScanSink<T>,
    ) -> Result<ScanInfo> {
        Ok(self.scan_map(want, map)?.into_sink(sink))
    }

    /// Counts and time ranges per channel, from the index where there is one.
    fn inventory(&self) -> Result<Inventory>;
}
