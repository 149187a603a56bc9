//! The inertial path of `convert`: when a log has raw IMU samples but no
//! reference poses, `T_world_slam` comes from [`imu_initialize`] over the
//! keyframe poses; when it has both, the report carries the IMU result beside
//! the pose-based fit as a consistency check.

use std::time::Instant;

use nalgebra::Vector3;
use serde::Serialize;

use super::{imu_initialize, ImuAlignment, ImuInitOptions, ImuSamples};
use crate::align::{AlignDiagnostics, Alignment};
use crate::cloud::backproject;
use crate::error::{Error, Result};
use crate::io::mcap::Log;
use crate::pipeline::{
    build_octree, camera_centers, keyframe_trajectory, transform_report, ApeReport, Conversion,
    ConvertOptions, PairReport, Report, Timing,
};
use crate::trajectory::{ApeStats, Trajectory, TrajectoryAlignment};

/// The pose-based fit next to the IMU result.
#[derive(Clone, Debug, Serialize)]
pub struct PoseCheck {
    /// Scale of the pose-based Horn fit, metres per SLAM unit.
    pub pose_scale: f64,
    /// `imu_scale / pose_scale − 1`.
    pub scale_difference: f64,
    /// Angle between the two gravity directions in the SLAM frame, degrees.
    pub gravity_angle_deg: f64,
}

/// The inertial initialisation as `report.json` holds it.
#[derive(Clone, Debug, Serialize)]
pub struct ImuReport {
    /// Topic of the raw IMU.
    pub topic: Option<String>,
    /// True when `T_world_slam` came from the IMU (no reference poses).
    pub used_for_transform: bool,
    /// Why the initialisation failed (degenerate motion, too few keyframes, …);
    /// the other fields are then absent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// Metres per SLAM unit and its standard deviation.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scale: Option<[f64; 2]>,
    /// Gravity in SLAM axes, m/s².
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gravity_slam: Option<[f64; 3]>,
    /// Standard deviation of the gravity direction, degrees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gravity_sigma_deg: Option<f64>,
    /// Gyroscope bias and its standard deviation per axis, rad/s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gyro_bias: Option<[[f64; 3]; 2]>,
    /// Accelerometer bias and its standard deviation per axis, m/s².
    #[serde(skip_serializing_if = "Option::is_none")]
    pub accel_bias: Option<[[f64; 3]; 2]>,
    /// Keyframes used, time span (s), excitation (m/s²), variance factor.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub keyframes_used: Option<usize>,
    /// Time span of the keyframes used, seconds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub duration: Option<f64>,
    /// Rms variation of the interval accelerations, m/s².
    #[serde(skip_serializing_if = "Option::is_none")]
    pub excitation: Option<f64>,
    /// `χ² / dof` of the final solve.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub variance_factor: Option<f64>,
    /// Agreement with the pose-based fit, when the log has both.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pose_check: Option<PoseCheck>,
}

fn v3(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

impl ImuReport {
    fn new(topic: Option<String>, used: bool, a: &ImuAlignment, pose: Option<PoseCheck>) -> Self {
        ImuReport {
            topic,
            used_for_transform: used,
            error: None,
            scale: Some([a.scale, a.scale_sigma]),
            gravity_slam: Some(v3(&a.gravity_slam)),
            gravity_sigma_deg: Some(a.gravity_sigma.to_degrees()),
            gyro_bias: Some([v3(&a.gyro_bias), v3(&a.gyro_bias_sigma)]),
            accel_bias: Some([v3(&a.accel_bias), v3(&a.accel_bias_sigma)]),
            keyframes_used: Some(a.diagnostics.n_keyframes),
            duration: Some(a.diagnostics.duration),
            excitation: Some(a.diagnostics.excitation),
            variance_factor: Some(a.diagnostics.variance_factor),
            pose_check: pose,
        }
    }

    fn failed(topic: Option<String>, error: String) -> Self {
        ImuReport {
            topic,
            used_for_transform: false,
            error: Some(error),
            scale: None,
            gravity_slam: None,
            gravity_sigma_deg: None,
            gyro_bias: None,
            accel_bias: None,
            keyframes_used: None,
            duration: None,
            excitation: None,
            variance_factor: None,
            pose_check: None,
        }
    }
}

/// The IMU result beside a pose-based `T_world_slam` (both in the log): never
/// fails the conversion; an IMU failure is reported as text.
pub fn consistency_report(
    slam: &Trajectory,
    imu: &ImuSamples,
    topic: Option<String>,
    opts: &ImuInitOptions,
    pose_fit: &crate::geometry::Sim3,
) -> ImuReport {
    match imu_initialize(slam, imu, opts) {
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

/// `convert` without reference poses: `T_world_slam` from the keyframe poses
/// and the log's raw IMU (world z up, the first used keyframe's IMU at the
/// origin with zero heading). The alignment has no pairs (its APE fields are
/// NaN, `null` in the report); keyframes the initialisation did not use are
/// listed as dropped.
pub fn convert_imu(log: &Log, imu: &ImuSamples, opts: &ConvertOptions) -> Result<Conversion> {
    let octree_params = opts.octree_params()?;
    if opts.windowed_cloud {
        return Err(Error::invalid(
            "windowed_cloud",
            "needs reference poses (the raw IMU gives one T_world_slam)",
        ));
    }
    let t0 = Instant::now();
    let (slam, order) = keyframe_trajectory(log)?;
    let a = imu_initialize(&slam, imu, &opts.imu)?;
    let align_s = t0.elapsed().as_secs_f64();
    let t = a.transform;
    let t1 = Instant::now();
    let cloud = backproject(&log.keyframes, &opts.filter, Some(&t))?;
    let backproject_s = t1.elapsed().as_secs_f64();
    let (octree, octree_report) = match octree_params {
        Some(params) => {
            let (map, report) = build_octree(&camera_centers(log, &t), &cloud, params)?;
            (Some(map), Some(report))
        }
        None => (None, None),
    };
    let world_slam = slam.transformed(&t);
    let nan = f64::NAN;
    let alignment = TrajectoryAlignment {
        alignment: Alignment {
            transform: t,
            residuals: Vec::new(),
            rmse: nan,
            diagnostics: AlignDiagnostics {
                n: 0,
                weight_sum: 0.0,
                eigenvalues: [nan; 4],
                relative_eigen_gap: nan,
                singular_values: [nan; 3],
                source_spread: nan,
                target_spread: nan,
                dof: None,
            },
        },
        pairs: Vec::new(),
        ape: ApeStats {
            rmse: nan,
            mean: nan,
            median: nan,
            std: nan,
            min: nan,
            max: nan,
            n_pairs: 0,
        },
        errors: Vec::new(),
    };
    let used: Vec<bool> = slam
        .timestamps
        .iter()
        .map(|s| a.timestamps.binary_search_by(|x| x.total_cmp(s)).is_ok())
        .collect();
    let frames_dropped = (0..slam.len())
        .filter(|&s| !used[s])
        .map(|s| log.keyframes[order[s]].id)
        .collect();
    let pairs: Vec<PairReport> = Vec::new();
    let report = Report {
        input: log.path.clone(),
        keyframe_topic: log.keyframe_topic.clone(),
        graph_topic: log.graph_topic.clone(),
        reference_topic: None,
        keyframes: log.keyframes.len(),
        reference_poses: 0,
        frames_used: used.iter().filter(|u| **u).count(),
        frames_dropped,
        pairs_fitted: 0,
        max_diff: opts.align.max_diff,
        offset: opts.align.offset,
        t_world_slam: transform_report(&t),
        fit_rmse: nan,
        ape: ApeReport::from(&alignment.ape),
        pairs,
        // The options beyond one fit act on pose pairs; the IMU path has none.
        beyond: serde_json::Value::Null,
        windowed: None,
        points: cloud.len(),
        timing: Timing {
            read_s: 0.0,
            align_s,
            backproject_s,
            write_s: 0.0,
        },
        imu: Some(ImuReport::new(log.imu_topic.clone(), true, &a, None)),
        octree: octree_report,
    };
    // No pose pairs: nothing was cut, flagged or searched.
    let alignment = crate::align::extended::ExtendedAlignment {
        trajectory: alignment,
        offset: opts.align.offset,
        offset_estimate: None,
        stages: None,
        fit_start: 0,
        skip_reason: String::new(),
        inliers: None,
        covariance: None,
    };
    Ok(Conversion {
        alignment,
        cloud,
        slam_trajectory: world_slam,
        reference: Trajectory::default(),
        report,
        octree,
    })
}
