//! MCAP files: the container reader, and the writers of the results Foxglove shows.
//!
//! - [`reader`]: the container, over a memory map (indexed or linear, chunks
//!   decompressed in parallel);
//! - [`decode`] / [`wire`]: the message decoders, which live in
//!   [`crate::io::messages`] (every container uses them) and are re-exported here;
//!   [`gnss_decode`]: `NavSatFix` / `LocationFix` into GNSS fixes;
//! - reading an MCAP log into a `Log` (keyframes, reference, IMU, topics) is
//!   the log assembly's, over every container: `io::read_mcap`, `io::read_log`;
//! - [`write`]: `world.mcap` ([`write_world_mcap`]) and the SLAM-side log
//!   ([`write_slam_log`]);
//! - [`piecewise`]: the writer of `world.mcap`, whose messages go into the
//!   file a piece at a time (the `mcap` crate's writer, which takes each
//!   message whole, writes the SLAM-side logs);
//! - [`grid_msgs`]: the 2-D grid as `nav_msgs/OccupancyGrid` and `foxglove.Grid`.
//!
//! MCAP times are `u64` nanoseconds; everything else is seconds and metres.

pub mod gnss_decode;
pub mod grid_msgs;
pub mod piecewise;
pub mod reader;
pub mod schemas;
pub mod stream;
pub mod write;

pub use crate::io::messages::decode::MessageKind;
pub use crate::io::messages::{
    decode, wire, ChannelInfo, MappedMessage, MappedScan, RawMessage, ReadMode,
};
pub use reader::{McapFile, Scan};
pub use write::{
    write_slam_log, write_slam_log_into, write_world_mcap, write_world_mcap_into,
    write_world_mcap_with_octomap, SlamLogOptions, WorldFlavor, WorldScene,
};
