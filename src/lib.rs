//! slam2world: the map of a monocular SLAM system, made metric and gravity-aligned.
//!
//! A monocular SLAM system estimates keyframe poses `T_slam_cam` and semi-dense
//! depth in its own frame (unknown scale, orientation and origin). A metric,
//! gravity-aligned pose source (IMU, motion capture, GNSS/INS) measures the
//! same motion as `T_world_body`. slam2world finds `T_world_slam` (a Sim(3)) in
//! closed form, carries the SLAM point cloud into the world frame and builds an
//! occupancy map of it.
//!
//! Units are metres and seconds; `T_a_b` maps coordinates in frame `b` into
//! frame `a` (`p_a = s·R·p_b + t`); quaternions at public boundaries are
//! `(x, y, z, w)`.

#![warn(missing_docs)]

pub mod align;
pub mod buffer;
#[cfg(feature = "cli")]
pub mod cli;
pub mod cloud;
pub mod defaults;
pub mod error;
pub mod geo;
pub mod geometry;
pub mod imu;
pub mod interrupt;
pub mod io;
pub mod keyframe;
#[cfg(feature = "live")]
pub mod live;
pub mod map;
pub mod pipeline;
pub mod sim;
pub mod simd;
pub mod trajectory;

#[cfg(feature = "python")]
mod python;

pub use error::{Error, Result};
pub use geometry::{PinholeCamera, Sim3};
pub use imu::ImuSamples;
pub use keyframe::Keyframe;
pub use trajectory::Trajectory;
