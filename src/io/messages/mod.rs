//! Messages, whatever container they came in: the channel and message types
//! every reader gives ([`ChannelInfo`], [`RawMessage`], [`MappedMessage`],
//! [`MappedScan`], [`ReadMode`]) and the decoders of the message encodings.
//!
//! - [`wire`]: byte-level readers of ROS 1, ROS 2 CDR and protobuf;
//! - [`decode`]: the messages slam2world uses, by [`decode::MessageKind`];
//! - [`gnss`]: `sensor_msgs/NavSatFix` and `foxglove.LocationFix` fixes.
//!
//! The readers of MCAP files ([`crate::io::mcap`]) and ROS bags
//! ([`crate::io::rosbag`]) fill these types; the log assembly
//! ([`crate::io::log`]) reads them, so that one decoder serves every container.
//! Times are `u64` nanoseconds (a container's log or record time).

use std::collections::BTreeMap;

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
