//! File formats: trajectories as text (TUM, EuRoC ground truth), point clouds
//! (PLY, x y z text; LAS/LAZ with a CRS and PCD out), MCAP logs, ROS bags (ROS 1
//! `.bag`, rosbag2), GNSS fixes (NMEA, CSV), reconstructions (COLMAP models,
//! DROID-SLAM arrays), nav2 `map_server` grids.

pub mod atomic;
pub mod colmap;
pub mod container;
pub mod droid;
pub mod gnss;
pub mod las;
pub mod mapped;
pub mod mcap;
pub mod nav2;
pub mod npy;
pub mod pcd;
pub mod ply;
pub mod rosbag;
pub mod text;
