//! MCAP logs: reading SLAM and pose logs, writing results Foxglove shows.
//!
//! - [`reader`]: the container, over a memory map (indexed or linear, chunks
//!   decompressed in parallel);
//! - [`decode`] / [`wire`]: message decoders (ROS 1, ROS 2 CDR, protobuf, JSON);
//!   [`gnss_decode`]: `NavSatFix` / `LocationFix` into GNSS fixes;
//! - [`log`]: [`read_mcap`] into [`Log`] (keyframes, reference, IMU, topics);
//! - [`write`]: `world.mcap` ([`write_world_mcap`]) and the SLAM-side log
//!   ([`write_slam_log`]);
//! - [`grid_msgs`]: the 2-D grid as `nav_msgs/OccupancyGrid` and `foxglove.Grid`.
//!
//! MCAP times are `u64` nanoseconds; everything else is seconds and metres.

pub mod decode;
pub mod gnss_decode;
pub mod grid_msgs;
pub mod log;
pub mod reader;
pub mod schemas;
pub mod stream;
pub mod wire;
pub mod write;

pub use decode::MessageKind;
pub use log::{inspect_mcap, read_mcap, Inventory, Log, ReadOptions, TopicInfo};
pub use reader::{ChannelInfo, McapFile, RawMessage, ReadMode, Scan};
pub use stream::{MappedMessage, MappedScan};
pub use write::{
    write_slam_log, write_slam_log_into, write_world_mcap, write_world_mcap_into,
    write_world_mcap_with_octomap, SlamLogOptions, WorldFlavor, WorldScene,
};
