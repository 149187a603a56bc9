//! Every JSON document the commands write, as one typed model.
//!
//! `convert` writes [`Report`] (`report.json`); `align --json` prints
//! [`AlignReport`], `imu-init --json` [`ImuInitReport`], `evaluate`
//! [`EvaluateReport`], `demo` [`DemoReport`] (`demo.json`) and `simulate` the
//! truth sidecar [`TruthReport`] (`sim.truth.json`). Each type derives
//! `Serialize` and `JsonSchema`; [`schemas`] gives the published JSON Schemas
//! (`schema/*.schema.json`, checked against these types in the tests), and
//! `slam2world schema NAME` prints one.
//!
//! Units: metres, seconds, degrees where a name ends in `_deg`; quaternions
//! `(x, y, z, w)`; transforms `T_world_slam` map SLAM coordinates into metres.

use std::path::PathBuf;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::align::checks::FitQuality;
use crate::align::covariance::Covariance;
use crate::align::dof::{Anchor, Dof, DofDiagnostics};
use crate::align::handeye::HandEye;
use crate::align::stages::Stages;
use crate::align::time_offset::TimeOffset;
use crate::align::trajectories::{ApeStats, TrajectoryAlignment};
use crate::error::{Error, Result};
use crate::geo::TimeBase;
use crate::geometry::Sim3;
use crate::imu::{ImuAlignment, ImuInitDiagnostics};
use crate::io::text::{Delimiter, TextInfo};
use crate::sim::evaluate::{ErrorStats, TransformError};
use crate::sim::SimConfig;
use crate::trajectory::Association;

use super::native::{Pairing, ReconstructionInfo, ReconstructionKind, ReferenceFileInfo};

/// A Sim(3) as the reports write it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct TransformReport {
    /// Rotation `(x, y, z, w)`.
    pub quaternion_xyzw: [f64; 4],
    /// Translation, metres.
    pub translation: [f64; 3],
    /// Scale, metres per SLAM unit.
    pub scale: f64,
    /// The 4×4 matrix `[sR t; 0 1]`, row-major.
    pub matrix: [[f64; 4]; 4],
}

impl From<&Sim3> for TransformReport {
    fn from(t: &Sim3) -> Self {
        let m = t.matrix();
        TransformReport {
            quaternion_xyzw: t.quaternion_xyzw(),
            translation: [t.translation.x, t.translation.y, t.translation.z],
            scale: t.scale,
            matrix: std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)])),
        }
    }
}

impl TransformReport {
    /// The transform back (from the quaternion, translation and scale).
    pub fn to_sim3(&self) -> Result<Sim3> {
        let t = self.translation;
        Sim3::from_quaternion_xyzw(self.quaternion_xyzw, t.into(), self.scale)
    }
}

/// APE statistics, metres (evo's APE, translation part).
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct ApeReport {
    /// Root mean square.
    pub rmse: f64,
    /// Mean.
    pub mean: f64,
    /// Median.
    pub median: f64,
    /// Population standard deviation.
    pub std: f64,
    /// Smallest.
    pub min: f64,
    /// Largest.
    pub max: f64,
    /// Matched pairs the statistics are over.
    pub n_pairs: usize,
}

impl From<&ApeStats> for ApeReport {
    fn from(a: &ApeStats) -> Self {
        ApeReport {
            rmse: a.rmse,
            mean: a.mean,
            median: a.median,
            std: a.std,
            min: a.min,
            max: a.max,
            n_pairs: a.n_pairs,
        }
    }
}

/// The start-up stages found in the scale factors `p_k` (indices into `p_k`).
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct StagesReport {
    /// First factor of the converging stretch.
    pub converging_start: usize,
    /// First factor of the stable stage.
    pub stable_start: usize,
    /// Number of factors.
    pub n_factors: usize,
    /// The stable level of `p_k` (≈ s²).
    pub stable_level: f64,
    /// Robust per-sample standard deviation of `ln p_k` once stable.
    pub noise: f64,
    /// Rolling window, factors.
    pub window: usize,
}

impl From<&Stages> for StagesReport {
    fn from(s: &Stages) -> Self {
        StagesReport {
            converging_start: s.converging_start,
            stable_start: s.stable_start,
            n_factors: s.n,
            stable_level: s.stable_level,
            noise: s.noise,
            window: s.window,
        }
    }
}

/// The time-offset search.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct OffsetReport {
    /// Seconds found (added to the SLAM stamps on top of the given offset).
    pub estimated: f64,
    /// rms residual at that offset, metres.
    pub rmse: f64,
    /// rms residual at offset 0, metres.
    pub rmse_at_zero: f64,
    /// SLAM poses used in the search.
    pub n_used: usize,
}

impl From<&TimeOffset> for OffsetReport {
    fn from(o: &TimeOffset) -> Self {
        OffsetReport {
            estimated: o.offset,
            rmse: o.rmse,
            rmse_at_zero: o.rmse_at_zero,
            n_used: o.n_used,
        }
    }
}

/// Central confidence intervals of the fitted parameters.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct IntervalsReport {
    /// Confidence level, e.g. 0.95.
    pub level: f64,
    /// Scale `[lo, hi]`.
    pub scale: [f64; 2],
    /// Translation `[lo, hi]` per axis, metres.
    pub translation: [[f64; 2]; 3],
    /// Half-width of the rotation interval about each world axis, degrees.
    pub rotation_half_width_deg: [f64; 3],
    /// Residual standard deviation per axis, metres.
    pub sigma: f64,
}

impl IntervalsReport {
    /// The intervals of `c` at `level`, `None` where they cannot be formed.
    pub fn of(c: &Covariance, level: f64) -> Option<Self> {
        let s = c.scale_interval(level).ok()?;
        let t = c.translation_intervals(level).ok()?;
        let r = c.rotation_half_widths(level).ok()?;
        Some(IntervalsReport {
            level,
            scale: [s.0, s.1],
            translation: t.map(|p| [p.0, p.1]),
            rotation_half_width_deg: r.map(f64::to_degrees),
            sigma: c.sigma2.sqrt(),
        })
    }
}

/// How the fit was made: the degrees of freedom, anchor and pairing rule,
/// the start-up cut and why, the time offset, the robust fit's inliers, the
/// confidence intervals and the figures of the fit-quality checks.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct FitReport {
    /// Degrees of freedom fitted (`se3` when `sim3` was asked without scale).
    pub dof: Dof,
    /// The pair pinned exactly (`first`: the first fitted pair), or `none`.
    pub anchor: Anchor,
    /// How SLAM and reference stamps were paired.
    pub association: Association,
    /// What a yaw-only or anchored fit adds: horizontal spreads, yaw
    /// determinacy, gravity tilt of the Sim(3) fit (absent for a plain
    /// Sim(3) / SE(3) fit).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dof_diagnostics: Option<DofDiagnostics>,
    /// The figures the fit-quality refusals looked at.
    pub quality: FitQuality,
    /// Index of the first fitted pair.
    pub fit_start: usize,
    /// Why the pairs before it were dropped.
    pub skip_reason: String,
    /// Seconds added to the SLAM stamps (given plus estimated).
    pub offset: f64,
    /// The stages, with `skip_init = auto`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stages: Option<StagesReport>,
    /// The offset search, with `estimate_offset`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub offset_estimate: Option<OffsetReport>,
    /// Inliers of the robust fit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub n_inliers: Option<usize>,
    /// Outliers of the robust fit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub n_outliers: Option<usize>,
    /// Confidence intervals, when the positions determine the covariance.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub intervals: Option<IntervalsReport>,
}

impl FitReport {
    /// What the options of the fit did, intervals at `level`.
    pub fn of(r: &TrajectoryAlignment, level: f64) -> Self {
        let count = |want: bool| {
            r.inliers
                .as_ref()
                .map(|m| m.iter().filter(|&&b| b == want).count())
        };
        FitReport {
            dof: r.dof,
            anchor: r.anchor,
            association: r.association,
            dof_diagnostics: r.alignment.diagnostics.dof.clone(),
            quality: r.quality.clone(),
            fit_start: r.fit_start,
            skip_reason: r.skip_reason.clone(),
            offset: r.offset,
            stages: r.stages.as_ref().map(StagesReport::from),
            offset_estimate: r.offset_estimate.as_ref().map(OffsetReport::from),
            n_inliers: count(true),
            n_outliers: count(false),
            intervals: r
                .covariance
                .as_ref()
                .and_then(|c| IntervalsReport::of(c, level)),
        }
    }
}

/// One keyframe matched with a reference pose.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct PairReport {
    /// Keyframe id (the row of a frame without keyframe).
    pub keyframe_id: i32,
    /// The frame's image name, for reconstructions that name their frames.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Keyframe time, seconds.
    pub keyframe_time: f64,
    /// Time of the matched reference pose, seconds.
    pub reference_time: f64,
    /// `‖p_ref − T(p_slam)‖`, metres.
    pub error: f64,
    /// True when the pair was used in the fit.
    pub fitted: bool,
}

/// The windowed (drift-aware) fit against the single Sim(3).
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct WindowedReport {
    /// Which carried the cloud: `"windowed"` or `"single"`.
    pub cloud: String,
    /// The window, e.g. `Poses(20)` or `Distance(5.0)`.
    pub window: String,
    /// rms residual of the windowed fit, metres.
    pub windowed_rmse: f64,
    /// rms residual of the single fit over the same pairs, metres.
    pub single_rmse: f64,
    /// Smallest local scale.
    pub scale_min: f64,
    /// Largest local scale.
    pub scale_max: f64,
}

/// The pose-based fit next to the IMU result.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct PoseCheck {
    /// Scale of the pose-based fit, metres per SLAM unit.
    pub pose_scale: f64,
    /// `imu_scale / pose_scale − 1`.
    pub scale_difference: f64,
    /// Angle between the two gravity directions in the SLAM frame, degrees.
    pub gravity_angle_deg: f64,
}

/// The cameras' height as `convert --camera-height` was given it.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum HeightGiven {
    /// The same height at every pose, metres.
    Constant {
        /// Metres.
        metres: f64,
    },
    /// The height at the first pose, metres.
    First {
        /// Metres.
        metres: f64,
    },
    /// Heights by time from a file.
    File {
        /// The file.
        path: PathBuf,
    },
}

/// The ground plane found in the SLAM cloud (`report.json`'s `prior.plane`).
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct PlaneReport {
    /// Unit normal in the SLAM frame, towards the cameras.
    pub normal: [f64; 3],
    /// `normal · x + offset` is the height of `x` over the plane, SLAM units.
    pub offset: f64,
    /// Points within the inlier threshold of the plane.
    pub inliers: usize,
    /// Points the plane was fitted among.
    pub n_points: usize,
    /// Robust standard deviation of the inliers' distances, SLAM units.
    pub spread: f64,
    /// Share of the points more than three spreads under the plane.
    pub below: f64,
    /// Share of the cameras above the plane.
    pub cameras_above: f64,
    /// Degrees between the normal and the cameras' mean image "up".
    pub tilt_from_cameras_deg: Option<f64>,
    /// Standard deviation of the normal's direction, degrees.
    pub tilt_sigma_deg: f64,
    /// The strongest other plane under the cameras: its inliers and its
    /// height over this one (SLAM units).
    pub runner_up: Option<(usize, f64)>,
}

/// Two poses a known distance apart (`prior.known_distance`).
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct DistanceReport {
    /// The two ends' indices among the SLAM poses (`null`: a map point).
    pub poses: [Option<usize>; 2],
    /// The two ends in the SLAM frame (camera centres or map points).
    pub ends: [[f64; 3]; 2],
    /// Their distance given, metres.
    pub metres: f64,
    /// Their distance in the SLAM frame, SLAM units.
    pub slam_distance: f64,
    /// Metres per SLAM unit it gives.
    pub scale: f64,
}

/// One window of the scale profile (`prior.profile`).
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct ProfileReport {
    /// First SLAM pose of the window (index).
    pub first: usize,
    /// Last SLAM pose of the window (index, inclusive).
    pub last: usize,
    /// Mean stamp of its poses, seconds.
    pub time: f64,
    /// Metres per SLAM unit there (`null` where no ground was found).
    pub scale: Option<f64>,
    /// The window's ground plane inliers (0 without a plane).
    pub inliers: usize,
    /// Why the window has no scale.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
}

/// The plane the cameras ride in (`prior.planar_motion`).
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct PlanarReport {
    /// Unit normal in the SLAM frame, towards the cameras' image "up".
    pub normal: [f64; 3],
    /// Rms distance of the camera centres from the plane, SLAM units.
    pub rms: f64,
    /// Rms spread of the centres along the plane's narrower axis, SLAM units.
    pub extent: f64,
    /// Tilt, degrees, that a slope as large as the out-of-plane spread could
    /// hide: `atan(rms / extent)`.
    pub tilt_bound_deg: f64,
    /// Standard error of the normal for independent errors, degrees.
    pub sigma_deg: f64,
}

/// Metric scale and "up" with no second sensor in `report.json`
/// (`convert --camera-height`, `--known-distance`, `--planar-motion`).
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct PriorReport {
    /// True when `T_world_slam` came from the prior (no reference sensor).
    pub used_for_transform: bool,
    /// Metres per SLAM unit of the prior.
    pub scale: f64,
    /// What set the scale: `known_distance` or `camera_height`.
    pub scale_from: String,
    /// What set "up": `ground_plane` or `planar_motion`.
    pub up_from: String,
    /// "Up" (the world's z) in the SLAM frame, unit.
    pub up: [f64; 3],
    /// The height given, if any.
    pub camera_height: Option<HeightGiven>,
    /// Metres per SLAM unit from the plane and the heights, when given.
    pub height_scale: Option<f64>,
    /// The height's standard deviation given, metres.
    pub camera_height_sigma: Option<f64>,
    /// Relative standard deviation of `height_scale` from the ground plane
    /// and the scatter of the cameras' heights.
    pub scale_sigma_ground: Option<f64>,
    /// Relative standard deviation of `height_scale`: `scale_sigma_ground`
    /// and the given height's own (`camera_height_sigma` over the height).
    pub scale_sigma: Option<f64>,
    /// Rms of the given heights less the fitted ones, metres.
    pub height_rms: Option<f64>,
    /// The known distance, when given.
    pub known_distance: Option<DistanceReport>,
    /// The ground plane, when one was fitted.
    pub plane: Option<PlaneReport>,
    /// The plane the cameras ride in, when it gave "up".
    pub planar_motion: Option<PlanarReport>,
    /// `[stamp, height]` of each SLAM pose over the ground plane, metres (at
    /// the prior's scale; empty without a plane and heights).
    pub heights: Vec<[f64; 2]>,
    /// The scale per window of keyframes along the run (one height at every
    /// pose, keyframes with depth; empty otherwise): where it wanders, the
    /// monocular scale drifted.
    pub profile: Vec<ProfileReport>,
    /// The prior's scale over the sensor's, less 1, when a reference sensor
    /// set the frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scale_vs_sensor: Option<f64>,
    /// Degrees between the prior's "up" and the sensor frame's z, when a
    /// reference sensor set the frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub up_vs_sensor_deg: Option<f64>,
}

/// The inertial initialisation in `report.json`.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct ImuReport {
    /// Topic of the raw IMU.
    pub topic: Option<String>,
    /// True when `T_world_slam` came from the IMU (no reference poses).
    pub used_for_transform: bool,
    /// Why the initialisation failed; the other fields are then absent.
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
    /// Keyframes used.
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

fn v3(v: &nalgebra::Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

impl ImuReport {
    /// A successful initialisation.
    pub fn new(
        topic: Option<String>,
        used: bool,
        a: &ImuAlignment,
        pose_check: Option<PoseCheck>,
    ) -> Self {
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
            pose_check,
        }
    }

    /// A failed initialisation (only the reason).
    pub fn failed(topic: Option<String>, error: String) -> Self {
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

/// What the report says of the octree.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct OctreeReport {
    /// Voxel edge length, metres.
    pub resolution: f64,
    /// Max range of the rays, metres (`null`: no limit).
    pub max_range: Option<f64>,
    /// OctoMap's `prob_hit`.
    pub prob_hit: f64,
    /// OctoMap's `prob_miss`.
    pub prob_miss: f64,
    /// OctoMap's lower clamping threshold.
    pub clamp_min: f64,
    /// OctoMap's upper clamping threshold.
    pub clamp_max: f64,
    /// Scans inserted (keyframes with points).
    pub scans: usize,
    /// Points inserted.
    pub points: usize,
    /// Occupied leaves (pruned leaves count once).
    pub leaves_occupied: usize,
    /// Free leaves (pruned leaves count once).
    pub leaves_free: usize,
    /// Nodes of the tree, inner and leaf.
    pub nodes: usize,
    /// Heap bytes held by the tree.
    pub memory_bytes: usize,
    /// Wall time of the insertion, seconds.
    pub time_s: f64,
}

/// The start-up cut found in the live frames (`skip_init auto` on a log
/// that has them).
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct StartupReport {
    /// Topic of the live frames.
    pub topic: Option<String>,
    /// Live frames in the log.
    pub live_frames: usize,
    /// Live frames matched with a reference pose (the scale factors are
    /// those of consecutive matched frames).
    pub pairs: usize,
    /// SLAM stamp where the converging stretch starts, seconds.
    pub converging_time: f64,
    /// SLAM stamp where the stable stage starts, seconds: keyframes stamped
    /// before it are not fitted.
    pub stable_time: f64,
    /// The stages, indices into the live frames' scale factors.
    pub stages: StagesReport,
}

/// What `follow` writes as `report.json` after every keyframe: the online
/// session's state and the latest update's timing.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct FollowReport {
    /// The log followed.
    pub input: PathBuf,
    /// Start-up stage: `waiting`, `start`, `converging` or `stable`.
    pub stage: String,
    /// Why (one line).
    pub reason: String,
    /// Latest SLAM stamp seen, seconds.
    pub time: f64,
    /// Id of the keyframe this report follows (-1: written at the end).
    pub last_keyframe: i32,
    /// Keyframes (latest version per id).
    pub keyframes: usize,
    /// Live (tracked) frames.
    pub frames: usize,
    /// Points in the map.
    pub points: usize,
    /// Times the map was rebuilt because inserted keyframes moved.
    pub rebuilds: usize,
    /// Where the stable stage starts (SLAM stamp), as detected so far.
    pub stable_time: Option<f64>,
    /// SLAM stamp at which the stable stage was first reported.
    pub stable_reported_at: Option<f64>,
    /// `T_world_slam`, once stable.
    pub t_world_slam: Option<TransformReport>,
    /// With a GNSS reference: the world frame is ENU at this origin
    /// (latitude, longitude in degrees, height above the WGS84 ellipsoid in
    /// metres), and `t_world_slam` is `T_enu_slam`.
    pub enu_origin: Option<[f64; 3]>,
    /// GNSS fixes taken.
    pub fixes: usize,
    /// GNSS fixes dropped for having no fix.
    pub fixes_dropped: usize,
    /// rms residual of the fitted keyframe pairs, metres.
    pub fit_rmse: Option<f64>,
    /// Keyframe pairs fitted.
    pub pairs_fitted: usize,
    /// Decoding the keyframe message, seconds.
    pub decode_s: f64,
    /// Stage detection and fit, seconds.
    pub fit_s: f64,
    /// Backprojection, seconds.
    pub backproject_s: f64,
    /// Octree insertion (or rebuild), seconds.
    pub insert_s: f64,
    /// From the keyframe message read to the map updated, seconds.
    pub latency_s: f64,
    /// True in the report written at the end (the map then exact).
    pub finished: bool,
    /// Why it ended: `end of log`, `idle timeout`, `server gone (…)`
    /// (empty while running).
    pub end: String,
    /// Times the connection to a live source (`follow ws://`) was lost;
    /// what the server sent meanwhile is lost.
    pub disconnections: usize,
}

impl FollowReport {
    /// The report before anything was read.
    pub fn new(input: &std::path::Path) -> Self {
        FollowReport {
            input: input.to_path_buf(),
            stage: "waiting".into(),
            reason: String::new(),
            time: 0.0,
            last_keyframe: -1,
            keyframes: 0,
            frames: 0,
            points: 0,
            rebuilds: 0,
            stable_time: None,
            stable_reported_at: None,
            t_world_slam: None,
            enu_origin: None,
            fixes: 0,
            fixes_dropped: 0,
            fit_rmse: None,
            pairs_fitted: 0,
            disconnections: 0,
            decode_s: 0.0,
            fit_s: 0.0,
            backproject_s: 0.0,
            insert_s: 0.0,
            latency_s: 0.0,
            finished: false,
            end: String::new(),
        }
    }
}

/// What the report says of the 2-D occupancy grid (`map.pgm` / `map.yaml`).
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct GridReport {
    /// The band of voxel centre heights projected, `[z_min, z_max]`, metres.
    pub z_band: [f64; 2],
    /// Cell edge, metres.
    pub resolution: f64,
    /// `(x, y)` of the lower-left corner of cell `(0, 0)`, world frame, metres.
    pub origin: [f64; 2],
    /// Columns (cells along x).
    pub width: usize,
    /// Rows (cells along y).
    pub height: usize,
    /// Probability at or above which a cell is occupied in `map.pgm`.
    pub occupied_threshold: f64,
    /// Occupied cells.
    pub cells_occupied: usize,
    /// Free cells (known, below the threshold).
    pub cells_free: usize,
    /// Unknown cells.
    pub cells_unknown: usize,
    /// Wall time of the projection, seconds.
    pub time_s: f64,
}

impl GridReport {
    /// The report of `grid` read with `occupied_threshold`, projected in `time_s`.
    pub fn of(grid: &crate::map::Grid2d, occupied_threshold: f64, time_s: f64) -> Self {
        use crate::map::CellState;
        let states = grid.states(occupied_threshold);
        let count = |c: CellState| states.iter().filter(|s| **s == c).count();
        GridReport {
            z_band: grid.z_band,
            resolution: grid.resolution,
            origin: grid.origin,
            width: grid.width,
            height: grid.height,
            occupied_threshold,
            cells_occupied: count(CellState::Occupied),
            cells_free: count(CellState::Free),
            cells_unknown: count(CellState::Unknown),
            time_s,
        }
    }
}

/// Wall time of each stage, seconds.
#[derive(Clone, Debug, Default, PartialEq, Serialize, JsonSchema)]
pub struct Timing {
    /// Reading and decoding the input.
    pub read_s: f64,
    /// Association and fit.
    pub align_s: f64,
    /// Backprojection into the world frame.
    pub backproject_s: f64,
    /// Writing the outputs.
    pub write_s: f64,
}

/// What `report.json` holds (`convert`).
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct Report {
    /// The input read.
    pub input: PathBuf,
    /// Its format (`mcap`, `trajectory files`, …).
    pub format: String,
    /// Topic of the keyframes.
    pub keyframe_topic: Option<String>,
    /// Topic of the graph updates.
    pub graph_topic: Option<String>,
    /// Topic of the reference poses.
    pub reference_topic: Option<String>,
    /// Keyframes (latest version per id), or frames without depth.
    pub keyframes: usize,
    /// Reference poses.
    pub reference_poses: usize,
    /// Keyframes matched with a reference pose (frames used).
    pub frames_used: usize,
    /// Keyframes without a reference pose within `max_diff`, by id.
    pub frames_dropped: Vec<i32>,
    /// Pairs the fit used.
    pub pairs_fitted: usize,
    /// Association window, seconds.
    pub max_diff: f64,
    /// Seconds added to the SLAM stamps.
    pub offset: f64,
    /// `T_world_slam`.
    pub t_world_slam: TransformReport,
    /// Fit residual rms over the fitted pairs, metres (`null` on the IMU path).
    pub fit_rmse: Option<f64>,
    /// APE over all pairs (`null` on the IMU path).
    pub ape: Option<ApeReport>,
    /// Every matched pair.
    pub pairs: Vec<PairReport>,
    /// How the fit was made (`null` on the IMU path).
    pub fit: Option<FitReport>,
    /// The windowed alignment against the single Sim(3), when asked for.
    pub windowed: Option<WindowedReport>,
    /// Points in the world cloud.
    pub points: usize,
    /// Points dropped because a coordinate was not finite (an inverse depth
    /// so small that its depth overflows `f32`); 0 for a sound input.
    pub points_non_finite: usize,
    /// The keyframes those points came from, by id.
    pub non_finite_keyframes: Vec<i32>,
    /// Stage timings.
    pub timing: Timing,
    /// The inertial initialisation, when the input has raw IMU samples.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub imu: Option<ImuReport>,
    /// Metric scale and "up" with no second sensor, when a prior was given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub prior: Option<PriorReport>,
    /// The occupancy octree, when one was built.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub octree: Option<OctreeReport>,
    /// The start-up cut found in the live frames, when the log has them and
    /// the cut is `auto`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub startup: Option<StartupReport>,
    /// The 2-D occupancy grid, when one was projected.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub grid: Option<GridReport>,
    /// How a reconstruction input was read (absent for logs).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reconstruction: Option<ReconstructionReport>,
    /// The reference file given beside the input (absent when the input
    /// carries its reference).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference_file: Option<ReferenceReport>,
    /// The GNSS reference, when the reference was GNSS fixes: the world frame
    /// is then ENU at `gnss.origin` and `t_world_slam` is `T_enu_slam`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gnss: Option<GnssReport>,
    /// How a bounded-memory conversion streamed the keyframes (absent when
    /// the recording was converted in memory).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stream: Option<StreamReport>,
}

/// A bounded-memory conversion: the keyframes' pixels and the world cloud
/// were kept on disk, the keyframes backprojected and inserted a batch at a
/// time.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct StreamReport {
    /// Keyframes per batch.
    pub batch_keyframes: usize,
    /// The most keyframes whose pixels were in memory at once.
    pub max_keyframes_in_memory: usize,
    /// Bytes of keyframe pixels set aside on disk (every version read).
    pub pixel_bytes: u64,
    /// Bytes of the world cloud on disk.
    pub cloud_bytes: u64,
}

/// A GNSS reference: where its fixes came from, what was dropped, the ENU
/// frame the world is (its geodetic origin), the CRS of the georeferenced
/// cloud, the lever arm and weights of the fit.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct GnssReport {
    /// The topic the fixes came from (a log's `NavSatFix` / `LocationFix`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub topic: Option<String>,
    /// The file the fixes came from (CSV / NMEA beside the input).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub file: Option<PathBuf>,
    /// Fixes kept.
    pub fixes: usize,
    /// Fixes whose status said no fix (dropped).
    pub dropped_no_fix: usize,
    /// What the fix times count: `source` (the stamps as given: Unix time for
    /// ROS / Foxglove and NMEA with a date) or `time_of_day` (NMEA without a date).
    pub time_base: TimeBase,
    /// How the origin was chosen: `first`, `mean` or `given`.
    pub origin_rule: String,
    /// The ENU origin: latitude, longitude (degrees), height above the WGS84
    /// ellipsoid (metres).
    pub origin: [f64; 3],
    /// The origin in ECEF (EPSG:4978), metres.
    pub origin_ecef: [f64; 3],
    /// What the world frame is.
    pub world_frame: String,
    /// The UTM zone of the origin (`32N`), the CRS of `cloud.las` unless `ecef` is asked.
    pub utm_zone: Option<String>,
    /// Its EPSG code (326xx north, 327xx south).
    pub utm_epsg: Option<u16>,
    /// The antenna in the body frame (`T_body_antenna`'s translation), metres.
    pub lever_arm: Option<[f64; 3]>,
    /// True when the pairs were weighed by the fixes' covariances.
    pub weighted: bool,
    /// Smallest and largest pair weight, 1/m².
    pub weight_range: Option<[f64; 2]>,
    /// True when the fixes were interpolated at the SLAM stamps (false: used
    /// at their own stamps, nearest-stamp pairing within `max_diff`).
    pub interpolated: bool,
    /// Largest time between two fixes an interpolated position bridges, seconds.
    pub max_gap: f64,
    /// Reference positions given to the fit.
    pub reference_positions: usize,
    /// SLAM stamps with no two fixes around them within `max_gap` (not
    /// paired), when interpolated.
    pub unpaired_stamps: usize,
    /// The georeferenced clouds written (`cloud.las` / `cloud.laz`: CRS EPSG
    /// code; `cloud.pcd`: ENU), filled in when written.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub outputs: Vec<GeoOutputReport>,
}

/// A georeferenced cloud file.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct GeoOutputReport {
    /// The file name in the output folder.
    pub name: String,
    /// EPSG code of its coordinates (326xx / 327xx UTM, 4978 ECEF); `null`
    /// for ENU (PCD: local metres at the origin).
    pub epsg: Option<u16>,
    /// LAS offset per axis, metres (LAS only).
    pub offset: Option<[f64; 3]>,
}

/// What a trajectory file's reader found out about it.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct TextInfoReport {
    /// The unit its stamps were read in (`s`, `ms`, `us`, `ns`), converted to seconds.
    pub unit: String,
    /// True when the unit was detected from the stamps, false when it was given.
    pub unit_detected: bool,
    /// `whitespace` or `comma`.
    pub delimiter: String,
    /// True when a header line was skipped.
    pub header: bool,
    /// Rows whose stamp repeated the previous row's: dropped, the first row of
    /// each stamp kept.
    pub repeated_stamps: usize,
}

impl From<&TextInfo> for TextInfoReport {
    fn from(t: &TextInfo) -> Self {
        TextInfoReport {
            unit: t.unit.symbol().into(),
            unit_detected: t.unit_detected,
            delimiter: match t.delimiter {
                Delimiter::Whitespace => "whitespace",
                Delimiter::Comma => "comma",
            }
            .into(),
            header: t.header,
            repeated_stamps: t.repeated_stamps,
        }
    }
}

/// How a reconstruction input was read.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct ReconstructionReport {
    /// `colmap`, `droid` or `trajectory`.
    pub kind: String,
    /// The COLMAP flavour, `bin` or `txt`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub flavour: Option<String>,
    /// SLAM frames (images, keyframes or poses) the fit could use.
    pub frames: usize,
    /// How the frame stamps were made.
    pub frame_times: String,
    /// What the trajectory reader found out, for trajectory files.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub text: Option<TextInfoReport>,
    /// The cloud file, when it is not the input itself.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cloud: Option<PathBuf>,
    /// Where an octree's rays start, for inputs whose points have origins.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub octree_origins: Option<String>,
    /// Decisions the reader made (shared stamps of a rig, the depth filter, …).
    pub notes: Vec<String>,
}

impl ReconstructionReport {
    /// The report of `r`, with `frames` SLAM poses and the cloud file.
    pub fn of(r: &ReconstructionInfo, frames: usize, cloud: Option<PathBuf>) -> Self {
        ReconstructionReport {
            kind: r.kind.name().into(),
            flavour: match r.kind {
                ReconstructionKind::Colmap(f) => Some(f.extension().into()),
                _ => None,
            },
            frames,
            frame_times: r.frame_times.describe().into(),
            text: r.slam_text.as_ref().map(TextInfoReport::from),
            cloud,
            octree_origins: r.octree_origins.clone(),
            notes: r.notes.clone(),
        }
    }
}

/// The outcome of pairing frames with a reference by image name.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct NamesReport {
    /// Names in the reference file.
    pub reference_names: usize,
    /// Of those, names of the input's images.
    pub matched: usize,
    /// Reference names that name no image of the input.
    pub unknown: usize,
    /// The first of those (at most 10).
    pub unknown_examples: Vec<String>,
}

/// The reference file given beside the input.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct ReferenceReport {
    /// The file.
    pub path: PathBuf,
    /// `tum`, `euroc` or `names`.
    pub format: String,
    /// True when the format was detected, false when it was given.
    pub format_detected: bool,
    /// `time` or `name`.
    pub pairing: String,
    /// What the trajectory reader found out, for TUM-order files.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub text: Option<TextInfoReport>,
    /// The name pairing, when paired by name.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub names: Option<NamesReport>,
}

impl From<&ReferenceFileInfo> for ReferenceReport {
    fn from(r: &ReferenceFileInfo) -> Self {
        ReferenceReport {
            path: r.path.clone(),
            format: r.format.name().into(),
            format_detected: r.format_detected,
            pairing: match r.pairing {
                Pairing::Time => "time",
                Pairing::Name => "name",
            }
            .into(),
            text: r.text.as_ref().map(TextInfoReport::from),
            names: r.names.as_ref().map(|n| NamesReport {
                reference_names: n.reference_names,
                matched: n.matched,
                unknown: n.unknown,
                unknown_examples: n.unknown_examples.clone(),
            }),
        }
    }
}

/// The estimated camera–body extrinsic in `align --json`.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct HandEyeReport {
    /// `T_body_cam` translation, metres.
    pub translation: [f64; 3],
    /// `T_body_cam` rotation `(x, y, z, w)`.
    pub quaternion_xyzw: [f64; 4],
    /// Scale of `T_world_slam` fitted with it.
    pub scale: f64,
    /// Translation of `T_world_slam` fitted with it, metres.
    pub world_from_slam_translation: [f64; 3],
    /// Rotation of `T_world_slam` fitted with it.
    pub world_from_slam_quaternion_xyzw: [f64; 4],
    /// rms of the body-position residuals, metres.
    pub position_rmse: f64,
    /// rms of the rotation residuals, degrees.
    pub rotation_rmse_deg: f64,
    /// Pose pairs used.
    pub n_pairs: usize,
}

impl HandEyeReport {
    /// The report of an estimate over `n_pairs` pairs.
    pub fn of(he: &HandEye, n_pairs: usize) -> Self {
        let b = &he.body_from_cam;
        let w = &he.alignment.transform;
        HandEyeReport {
            translation: v3(&b.translation),
            quaternion_xyzw: b.quaternion_xyzw(),
            scale: w.scale,
            world_from_slam_translation: v3(&w.translation),
            world_from_slam_quaternion_xyzw: w.quaternion_xyzw(),
            position_rmse: he.alignment.rmse,
            rotation_rmse_deg: he.rotation_rmse.to_degrees(),
            n_pairs,
        }
    }
}

/// The units of the stamps of `align EST REF`'s two files.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct TimeUnitsReport {
    /// EST's unit: `s`, `ms`, `us` or `ns`.
    pub est: String,
    /// REF's unit.
    #[serde(rename = "ref")]
    pub reference: String,
    /// Whether EST's unit was found from the stamps (false: given by
    /// `--est-time-unit`).
    pub est_detected: bool,
    /// Whether REF's unit was found from the stamps (false: given by
    /// `--ref-time-unit`, or the EuRoC format's nanoseconds).
    pub ref_detected: bool,
    /// Whether the two files are KITTI poses without stamps, paired by
    /// index (pose i at i seconds).
    pub paired_by_index: bool,
}

/// What `align --json` prints.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct AlignReport {
    /// The estimate file (`LOG:TOPIC` for a topic of a log).
    pub est: String,
    /// The reference file (`LOG:TOPIC` for a topic of a log).
    #[serde(rename = "ref")]
    pub reference: String,
    /// Poses of the estimate.
    pub n_est: usize,
    /// Poses of the reference.
    pub n_ref: usize,
    /// Matched pairs.
    pub n_pairs: usize,
    /// Pairs fitted.
    pub n_fitted: usize,
    /// Association window, seconds.
    pub max_diff: f64,
    /// Seconds given to add to the EST stamps.
    pub offset: f64,
    /// The units the two files' stamps were read in (none for two topics of a
    /// log, whose stamps are nanoseconds).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time_units: Option<TimeUnitsReport>,
    /// Whether the scale was fitted (`sim3`, `scale+4dof`); the dof is in `fit`.
    pub with_scale: bool,
    /// Scale of `T_ref_est`.
    pub scale: f64,
    /// Rotation of `T_ref_est`, row-major.
    pub rotation: [[f64; 3]; 3],
    /// Rotation `(x, y, z, w)`.
    pub quaternion_xyzw: [f64; 4],
    /// Translation, metres.
    pub translation: [f64; 3],
    /// Fit residual rms, metres.
    pub fit_rmse: f64,
    /// APE over every pair.
    pub ape: ApeReport,
    /// How the fit was made.
    pub fit: FitReport,
    /// The estimated camera–body extrinsic, with `--estimate-body-from-cam`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub body_from_cam_estimate: Option<HandEyeReport>,
    /// The GNSS reference (fixes, ENU origin, weights), when REF is fixes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gnss: Option<GnssReport>,
}

/// A transform without its matrix (the inertial initialisation's report).
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct ScaledPose {
    /// Scale, metres per SLAM unit.
    pub scale: f64,
    /// Rotation `(x, y, z, w)`.
    pub quaternion_xyzw: [f64; 4],
    /// Translation, metres.
    pub translation: [f64; 3],
}

/// The pose-based comparison of `imu-init --reference`.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct ReferenceCheck {
    /// Matched pairs.
    pub n_pairs: usize,
    /// Scale of the pose-based Horn fit.
    pub horn_scale: f64,
    /// `imu_scale / horn_scale − 1`.
    pub scale_difference: f64,
    /// Angle between the two gravity directions in the SLAM frame, degrees.
    pub gravity_angle_deg: f64,
    /// APE of the Horn fit, metres.
    pub ape_rmse: f64,
}

/// What `imu-init --json` prints.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct ImuInitReport {
    /// The keyframe file.
    pub keyframes: String,
    /// The IMU file.
    pub imu: String,
    /// Metres per SLAM unit.
    pub scale: f64,
    /// Its standard deviation.
    pub scale_sigma: f64,
    /// Gravity in SLAM axes, m/s².
    pub gravity_slam: [f64; 3],
    /// Standard deviation of the gravity direction, degrees.
    pub gravity_sigma_deg: f64,
    /// Gyroscope bias, rad/s.
    pub gyro_bias: [f64; 3],
    /// Its standard deviation per axis.
    pub gyro_bias_sigma: [f64; 3],
    /// Accelerometer bias, m/s².
    pub accel_bias: [f64; 3],
    /// Its standard deviation per axis.
    pub accel_bias_sigma: [f64; 3],
    /// `T_world_slam` (world z up).
    pub transform: ScaledPose,
    /// How well the data determined the result.
    pub diagnostics: ImuInitDiagnostics,
    /// The comparison with a pose reference, with `--reference`.
    pub reference_check: Option<ReferenceCheck>,
}

impl ImuInitReport {
    /// The report of `a` for the two input files.
    pub fn of(
        keyframes: String,
        imu: String,
        a: &ImuAlignment,
        reference_check: Option<ReferenceCheck>,
    ) -> Self {
        let t = a.transform;
        ImuInitReport {
            keyframes,
            imu,
            scale: a.scale,
            scale_sigma: a.scale_sigma,
            gravity_slam: v3(&a.gravity_slam),
            gravity_sigma_deg: a.gravity_sigma.to_degrees(),
            gyro_bias: v3(&a.gyro_bias),
            gyro_bias_sigma: v3(&a.gyro_bias_sigma),
            accel_bias: v3(&a.accel_bias),
            accel_bias_sigma: v3(&a.accel_bias_sigma),
            transform: ScaledPose {
                scale: t.scale,
                quaternion_xyzw: t.quaternion_xyzw(),
                translation: v3(&t.translation),
            },
            diagnostics: a.diagnostics.clone(),
            reference_check,
        }
    }
}

/// The start-up stage boundaries of a simulated run, frame indices.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SimStages {
    /// First frame of the converging stretch.
    pub converge_start: usize,
    /// First frame of the stable stage.
    pub stable_start: usize,
}

/// The paper's scene: a square plane and eight cubes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct SceneReport {
    /// Half the extent of the ground plane in x and y, metres.
    pub plane_half: [f64; 2],
    /// Lower corner of each cube, metres.
    pub cube_min: Vec<[f64; 3]>,
    /// Edge of the cubes, metres.
    pub cube_size: f64,
    /// Gravity in the world frame, m/s².
    pub gravity: [f64; 3],
}

/// Tracked SLAM frames of a simulation (SLAM frame, SLAM units).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct FramesReport {
    /// Times, seconds.
    pub timestamps: Vec<f64>,
    /// Camera positions.
    pub positions: Vec<[f64; 3]>,
    /// Camera orientations `(x, y, z, w)`.
    pub orientations_xyzw: Option<Vec<[f64; 4]>>,
}

/// The truth of a simulated run (`sim.truth.json`, and in the log's metadata
/// without the frames).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct TruthReport {
    /// The true `T_world_slam`.
    pub t_world_slam: TransformReport,
    /// Every simulation parameter.
    pub config: SimConfig,
    /// The true stage boundaries.
    pub stages: SimStages,
    /// The scene.
    pub scene: SceneReport,
    /// Frame index of each keyframe.
    pub keyframe_frames: Vec<usize>,
    /// Length of the true path, metres.
    pub true_path_length: f64,
    /// The tracked frames (in the sidecar only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slam_frames: Option<FramesReport>,
}

/// What `evaluate` prints.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct EvaluateReport {
    /// Distance of the converted points to the true surfaces, metres.
    pub cloud: ErrorStats,
    /// Error of the estimated `T_world_slam`.
    pub transform: TransformError,
    /// APE of the tracked frames of the stable stage, when the truth holds them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ape_stable_frames: Option<ErrorStats>,
}

/// The truth side of `demo.json`.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct DemoTruth {
    /// The true `T_world_slam`.
    pub t_world_slam: TransformReport,
    /// Its scale.
    pub scale: f64,
}

/// The alignment side of `demo.json`.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct DemoAlignment {
    /// What was fitted.
    pub fit: String,
    /// Matched pairs.
    pub pairs: usize,
    /// APE rmse, metres.
    pub rmse: f64,
    /// Scale error of a fit on every tracked frame (start-up included).
    pub scale_error_all_frames: f64,
    /// Scale error of a fit on the tracked frames of the stable stage.
    pub scale_error_stable_frames: f64,
}

/// Wall time of the demo's steps, seconds.
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct DemoSeconds {
    /// Simulation.
    pub simulate: f64,
    /// Writing the log.
    pub write_log: f64,
    /// Reading, converting, writing the outputs.
    pub convert: f64,
    /// Scoring.
    pub score: f64,
}

/// What `demo` writes (`demo.json`).
#[derive(Clone, Debug, PartialEq, Serialize, JsonSchema)]
pub struct DemoReport {
    /// The estimated `T_world_slam`.
    pub t_world_slam: TransformReport,
    /// The truth.
    pub truth: DemoTruth,
    /// Error of the estimate.
    pub transform_error: TransformError,
    /// Distance of the converted points to the true surfaces, metres.
    pub cloud_error: ErrorStats,
    /// The same with the true transform (SLAM's own depth error).
    pub cloud_error_true_transform: ErrorStats,
    /// APE of the aligned keyframes against the true path, metres.
    pub ape_keyframes: ErrorStats,
    /// The fit.
    pub alignment: DemoAlignment,
    /// The true stage boundaries.
    pub stages: SimStages,
    /// The scene.
    pub scene: SceneReport,
    /// Every simulation parameter.
    pub config: SimConfig,
    /// The figures' raw arrays (little-endian), by name: paths relative to the folder.
    pub files: std::collections::BTreeMap<String, String>,
    /// Step timings.
    pub seconds: DemoSeconds,
}

/// `(name, JSON Schema)` of every document above, as published in `schema/`.
pub fn schemas() -> Vec<(&'static str, schemars::Schema)> {
    vec![
        ("report", schemars::schema_for!(Report)),
        ("align", schemars::schema_for!(AlignReport)),
        ("imu-init", schemars::schema_for!(ImuInitReport)),
        ("evaluate", schemars::schema_for!(EvaluateReport)),
        ("demo", schemars::schema_for!(DemoReport)),
        ("truth", schemars::schema_for!(TruthReport)),
        ("follow", schemars::schema_for!(FollowReport)),
    ]
}

/// A document as pretty JSON with a final newline.
pub fn to_json_bytes<T: Serialize>(value: &T) -> Result<Vec<u8>> {
    let mut b =
        serde_json::to_vec_pretty(value).map_err(|e| Error::invalid("report", e.to_string()))?;
    b.push(b'\n');
    Ok(b)
}
