//! File formats: MCAP logs in and out.

pub mod mcap;
