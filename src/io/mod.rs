//! File formats: trajectories as text (TUM, EuRoC ground truth, KITTI) and
//! nerfstudio / instant-ngp `transforms.json`, point clouds
//! (PLY, x y z text; LAS/LAZ with a CRS and PCD out), MCAP logs, ROS bags (ROS 1
//! `.bag`, rosbag2), GNSS fixes (NMEA, CSV), reconstructions (COLMAP models,
//! DROID-SLAM arrays), nav2 `map_server` grids.
//!
//! Logs of every container are read through one door, [`read_log`]
//! ([`log`]): the container is found from the bytes ([`container`]), its
//! reader ([`mcap`], [`rosbag`]) gives [`messages`], and one set of decoders
//! and one assembly make the [`Log`].

pub mod atomic;
pub mod colmap;
pub mod container;
pub mod droid;
pub mod gnss;
pub mod kitti;
pub mod las;
pub mod lines;
pub mod log;
pub(crate) mod lz4_frame;
pub mod mapped;
pub mod mcap;
pub mod messages;
pub mod nav2;
pub mod npy;
pub mod pcd;
pub mod ply;
pub mod rosbag;
pub mod spill;
pub mod text;
pub mod transforms;

pub use log::{
    inspect_log, inspect_mcap, read_log, read_mcap, AnyContainer, Inspection, Log, LogError,
    ReadOptions, TopicInfo,
};
