//! File formats: trajectories as text (TUM, EuRoC ground truth), point clouds
//! (PLY, x y z text), MCAP logs, nav2 `map_server` grids.

pub mod atomic;
pub mod mcap;
pub mod nav2;
pub mod ply;
pub mod text;
