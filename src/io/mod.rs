//! File formats: trajectories as text (TUM, EuRoC ground truth), point clouds
//! (PLY, x y z text; LAS/LAZ with a CRS and PCD out), MCAP logs, GNSS fixes
//! (NMEA, CSV).

pub mod atomic;
pub mod gnss;
pub mod las;
pub mod mcap;
pub mod pcd;
pub mod ply;
pub mod text;
