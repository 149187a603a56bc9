//! File formats: trajectories as text (TUM, EuRoC ground truth), point clouds
//! (PLY, x y z text), MCAP logs, ROS bags (ROS 1 `.bag`, rosbag2), reconstructions
//! (COLMAP models, DROID-SLAM arrays).

pub mod atomic;
pub mod colmap;
pub mod container;
pub mod droid;
pub mod mapped;
pub mod mcap;
pub mod npy;
pub mod ply;
pub mod rosbag;
pub mod text;
