//! File formats: point clouds (PLY, x y z text).

pub mod ply;
