//! Raw inertial samples (gyroscope and accelerometer), as `sensor_msgs/Imu` or
//! EuRoC `imu0/data.csv` carry them.

use nalgebra::Vector3;

use crate::error::{Error, Result};

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
        Ok(ImuSamples {
            timestamps,
            gyro,
            accel,
        })
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
