//! ROS bags: ROS 1 `.bag` files (format 2.0) and rosbag2 bags (folders with
//! `metadata.yaml`, single `.db3` files).
//!
//! - [`ros1`]: [`Ros1Bag`], over a memory map, indexed or linear, chunks
//!   (none / bz2 / lz4) decompressed in parallel;
//! - [`ros2`]: [`Ros2Bag`], SQLite (`.db3`) or MCAP storage, zstd per file or
//!   per message; a `.db3`'s messages table read from its pages
//!   (`sqlite_pages`), in parallel;
//! - [`BagError`]: what can be wrong, the `reason` of [`crate::Error::Bag`].
//!
//! Both readers have the MCAP reader's `scan_map` (see
//! [`crate::io::messages::MessageSource`]): channels are
//! [`crate::io::messages::ChannelInfo`], messages [`crate::io::messages::RawMessage`]
//! with `log_time` = `publish_time` = the record time in nanoseconds.

pub mod ros1;
pub mod ros2;
mod sqlite_pages;

pub use crate::error::BagError;
pub use ros1::{BagHeader, Ros1Bag};
pub use ros2::{Ros2Bag, Ros2Compression, Ros2Storage};

use crate::io::messages::MappedMessage;

/// Sorts messages by record time, keeping file order among equal times (a
/// stable sort: linear when the messages are already in order, as they are in
/// a bag recorded live).
pub(crate) fn sort_by_time<T>(messages: &mut [MappedMessage<T>]) {
    if !messages.is_sorted_by_key(|m| m.log_time) {
        messages.sort_by_key(|m| m.log_time);
    }
}
