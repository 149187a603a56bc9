//! The inertial path of `convert`: when the input has raw IMU samples but no
//! reference poses, `T_world_slam` comes from [`imu_initialize`] over the
//! keyframe poses (world z up, the first used keyframe's IMU at the origin
//! with zero heading); when it has both, the report carries the IMU result
//! beside the pose-based fit as a consistency check.

use nalgebra::Vector3;

use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::imu::{imu_initialize, ImuAlignment, ImuSamples};
use crate::trajectory::Trajectory;

use super::options::ConvertOptions;
use super::report::{ImuReport, PoseCheck};

/// `T_world_slam` from the raw IMU: refused with `windowed_cloud` (the IMU
/// gives one transform).
pub fn fit(slam: &Trajectory, imu: &ImuSamples, opts: &ConvertOptions) -> Result<ImuAlignment> {
    if opts.windowed_cloud {
        return Err(Error::invalid(
            "windowed_cloud",
            "needs reference poses (the raw IMU gives one T_world_slam)",
        ));
    }
    imu_initialize(slam, imu, &opts.imu)
}

/// The IMU result beside a pose-based `T_world_slam` (both in the input):
/// never fails the conversion; an IMU failure is reported as text.
pub fn consistency_report(
    slam: &Trajectory,
    imu: &ImuSamples,
    topic: Option<String>,
    opts: &ConvertOptions,
    pose_fit: &Sim3,
) -> ImuReport {
    match imu_initialize(slam, imu, &opts.imu) {
        Ok(a) => {
            let g_ref = pose_fit.rotation.inverse() * Vector3::new(0.0, 0.0, -1.0);
            let cos = a.gravity_slam.normalize().dot(&g_ref).clamp(-1.0, 1.0);
            let check = PoseCheck {
                pose_scale: pose_fit.scale,
                scale_difference: a.scale / pose_fit.scale - 1.0,
                gravity_angle_deg: cos.acos().to_degrees(),
            };
            ImuReport::new(topic, false, &a, Some(check))
        }
        Err(e) => ImuReport::failed(topic, e.to_string()),
    }
}
