//! File formats: trajectories as text (TUM, EuRoC ground truth), point clouds
//! (PLY, x y z text), MCAP logs.

pub mod atomic;
pub mod mcap;
pub mod ply;
pub mod text;
