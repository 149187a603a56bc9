//! File formats: trajectories as text (TUM, EuRoC ground truth), point clouds
//! (PLY, x y z text), MCAP logs, reconstructions (COLMAP models, DROID-SLAM
//! arrays).

pub mod atomic;
pub mod colmap;
pub mod droid;
pub mod mcap;
pub mod npy;
pub mod ply;
pub mod text;
