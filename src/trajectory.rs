//! Timestamped poses: association, interpolation, frame-to-frame scale factors.
//!
//! A trajectory of SLAM keyframes holds `T_slam_cam`; a reference trajectory
//! holds `T_world_body`. Timestamps are seconds.

use nalgebra::{UnitQuaternion, Vector3};

use crate::error::{Error, Result};

/// Timestamped positions with optional orientations.
#[derive(Clone, Debug, Default)]
pub struct Trajectory {
    /// Times, seconds, non-decreasing.
    pub timestamps: Vec<f64>,
    /// Positions (the translation of each pose).
    pub positions: Vec<Vector3<f64>>,
    /// Orientations (the rotation of each pose), when known.
    pub orientations: Option<Vec<UnitQuaternion<f64>>>,
}

impl Trajectory {
    /// Checks lengths, finiteness and non-decreasing times.
    pub fn try_new(
        timestamps: Vec<f64>,
        positions: Vec<Vector3<f64>>,
        orientations: Option<Vec<UnitQuaternion<f64>>>,
    ) -> Result<Self> {
        let n = timestamps.len();
        if positions.len() != n {
            return Err(Error::ShapeMismatch {
                what: "positions".into(),
                expected: format!("({n}, 3), one row per timestamp"),
                got: format!("({}, 3)", positions.len()),
            });
        }
        if let Some(o) = &orientations {
            if o.len() != n {
                return Err(Error::ShapeMismatch {
                    what: "orientations".into(),
                    expected: format!("({n}, 4), one row per timestamp"),
                    got: format!("({}, 4)", o.len()),
                });
            }
        }
        for i in 0..n {
            if !timestamps[i].is_finite() || positions[i].iter().any(|v| !v.is_finite()) {
                return Err(Error::NonFinite {
                    what: "trajectory".into(),
                    index: i,
                });
            }
            if i > 0 && timestamps[i] < timestamps[i - 1] {
                return Err(Error::invalid(
                    "timestamps",
                    format!(
                        "must not decrease (pose {i}: {} after {})",
                        timestamps[i],
                        timestamps[i - 1]
                    ),
                ));
            }
        }
        Ok(Trajectory {
            timestamps,
            positions,
            orientations,
        })
    }

    /// Number of poses.
    pub fn len(&self) -> usize {
        self.timestamps.len()
    }

    /// True when there are no poses.
    pub fn is_empty(&self) -> bool {
        self.timestamps.is_empty()
    }
}
