//! File formats: trajectories as text (TUM, EuRoC ground truth).

pub mod text;
