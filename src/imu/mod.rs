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

use std::path::Path;

use nalgebra::Vector3;

use crate::error::{Error, Result};

pub mod convert;
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

    /// Reads EuRoC `imu0/data.csv` content: `timestamp [ns], w_x, w_y, w_z
    /// [rad/s], a_x, a_y, a_z [m/s²]` per line, `#` comment lines and blank
    /// lines skipped. Times become seconds.
    ///
    /// Errors: [`Error::Io`], [`Error::Parse`] (with the line number) for a
    /// malformed line, and the checks of [`ImuSamples::try_new`].
    pub fn read_euroc(path: impl AsRef<Path>) -> Result<ImuSamples> {
        let path = path.as_ref();
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(&bytes);
        let text = std::str::from_utf8(bytes).map_err(|e| {
            Error::parse(
                path,
                0,
                format!("not UTF-8 text (byte {})", e.valid_up_to()),
            )
        })?;
        let (mut timestamps, mut gyro, mut accel) = (Vec::new(), Vec::new(), Vec::new());
        for (k, raw) in text.lines().enumerate() {
            let line = raw.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            if fields.len() != 7 {
                return Err(Error::parse(
                    path,
                    k + 1,
                    format!(
                        "expected 7 comma-separated values (ns, gyro x y z, accel x y z), got {}",
                        fields.len()
                    ),
                ));
            }
            // Integer nanoseconds where they are written so (EuRoC); a float otherwise.
            let t = match fields[0].parse::<i64>() {
                Ok(ns) => ns as f64 * 1e-9,
                Err(_) => fields[0].parse::<f64>().map(|ns| ns * 1e-9).map_err(|_| {
                    Error::parse(
                        path,
                        k + 1,
                        format!("timestamp is not a number: {:?}", fields[0]),
                    )
                })?,
            };
            let mut v = [0.0; 6];
            for (j, f) in fields[1..].iter().enumerate() {
                v[j] = f.parse().map_err(|_| {
                    Error::parse(
                        path,
                        k + 1,
                        format!("field {} is not a number: {f:?}", j + 2),
                    )
                })?;
            }
            timestamps.push(t);
            gyro.push(Vector3::new(v[0], v[1], v[2]));
            accel.push(Vector3::new(v[3], v[4], v[5]));
        }
        ImuSamples::try_new(timestamps, gyro, accel).map_err(|e| match e {
            Error::NonFinite { index, .. } => {
                Error::parse(path, 0, format!("sample {index} is not finite"))
            }
            other => other,
        })
    }
}
