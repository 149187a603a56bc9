//! Raw inertial samples (gyroscope and accelerometer), as `sensor_msgs/Imu` or
//! EuRoC `imu0/data.csv` carry them, and the inertial initialisation that
//! recovers the metric scale and the gravity direction of a monocular SLAM
//! trajectory from them ([`imu_initialize`]).
//!
//! - [`preintegration`]: rotation, velocity and position deltas between two
//!   keyframes with their Jacobians with respect to the biases (Forster et al.,
//!   on-manifold preintegration; midpoint rule).
//! - [`init`]: gyroscope bias, then scale, gravity and keyframe velocities from
//!   one linear system over the keyframes (VINS-Mono / ORB-SLAM3 style), then
//!   gravity refined with its magnitude fixed, optionally the accelerometer bias.

use nalgebra::Vector3;

use crate::error::{Error, Result};

pub mod init;
pub mod preintegration;

pub use init::{imu_initialize, ImuAlignment, ImuInitDiagnostics, ImuInitOptions};
pub use preintegration::Preintegrated;

/// A stream of IMU samples in the IMU (body) frame.
#[derive(Clone, Debug, Default)]
pub struct ImuSamples {
    /// Sample times, seconds, strictly increasing.
    pub timestamps: Vec<f64>,
    /// Angular rate, rad/s.
    pub gyro: Vec<Vector3<f64>>,
    /// Specific force (acceleration minus gravity, as an accelerometer measures it), m/s².
    pub accel: Vec<Vector3<f64>>,
}

impl ImuSamples {
    /// Checks lengths, finiteness and strictly increasing times.
    pub fn try_new(
        timestamps: Vec<f64>,
        gyro: Vec<Vector3<f64>>,
        accel: Vec<Vector3<f64>>,
    ) -> Result<Self> {
        ImuSamples::validate(&timestamps, &gyro, &accel)?;
        Ok(ImuSamples {
            timestamps,
            gyro,
            accel,
        })
    }

    /// Checks what [`ImuSamples::try_new`] checks on a value built from its
    /// public fields (lengths, finiteness, strictly increasing times).
    pub fn check(&self) -> Result<()> {
        ImuSamples::validate(&self.timestamps, &self.gyro, &self.accel)
    }

    fn validate(timestamps: &[f64], gyro: &[Vector3<f64>], accel: &[Vector3<f64>]) -> Result<()> {
        let n = timestamps.len();
        if gyro.len() != n || accel.len() != n {
            return Err(Error::ShapeMismatch {
                what: "imu samples".into(),
                expected: format!("{n} gyro and {n} accel rows (one per timestamp)"),
                got: format!("{} gyro, {} accel", gyro.len(), accel.len()),
            });
        }
        for i in 0..n {
            if !timestamps[i].is_finite()
                || gyro[i]
                    .iter()
                    .chain(accel[i].iter())
                    .any(|v| !v.is_finite())
            {
                return Err(Error::NonFinite {
                    what: "imu samples".into(),
                    index: i,
                });
            }
            if i > 0 && timestamps[i] <= timestamps[i - 1] {
                return Err(Error::invalid(
                    "imu timestamps",
                    format!(
                        "must increase strictly (sample {i}: {} after {})",
                        timestamps[i],
                        timestamps[i - 1]
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.timestamps.len()
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.timestamps.is_empty()
    }
}
