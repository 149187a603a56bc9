//! File formats: trajectories as text (TUM, EuRoC ground truth), point clouds
//! (PLY, x y z text), MCAP logs, ROS bags.

pub mod atomic;
pub mod container;
pub mod mcap;
pub mod ply;
pub mod rosbag;
pub mod text;
