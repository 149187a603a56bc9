//! Every option's default, written once.
//!
//! The core's `Default` impls, the command line (clap `default_value_t`) and
//! the Python signatures use these constants; the Python stub and the
//! signatures of the native module are checked against them in a test
//! (`tests/python/test_defaults.py`, through [`TABLE`], which the module
//! exports as `slam2world._slam2world.DEFAULTS`).
//!
//! Units: seconds, metres, m/s², radians unless the name says otherwise.

/// Largest time difference of a matched SLAM/reference pair, seconds (evo's `--t_max_diff`).
pub const MAX_DIFF: f64 = 0.01;
/// Seconds added to the SLAM stamps before matching.
pub const OFFSET: f64 = 0.0;
/// Largest time offset searched when the offset is estimated, seconds (both signs).
pub const MAX_OFFSET: f64 = 0.5;
/// Largest reference gap bridged by interpolation, seconds.
pub const MAX_GAP: f64 = 0.1;
/// Reference intervals (the reference's median interval) that a reference
/// position interpolated at a SLAM stamp bridges unless a gap in seconds is
/// given: a dropout of up to four samples (GNSS fixes: 0.5 s at 10 Hz, 5 s at
/// 1 Hz; the live frames' reference poses: 25 ms at 200 Hz).
pub const GAP_STEPS: f64 = 5.0;
/// Where the ENU origin of a GNSS reference is put (`first`, `mean`, or a position).
pub const ORIGIN: &str = "first";
/// CRS of the georeferenced cloud (`utm`: the zone of the ENU origin; `ecef`).
pub const CRS: &str = "utm";
/// Confidence level of the reported intervals.
pub const CONFIDENCE: f64 = 0.95;
/// IRLS loss of the robust fit.
pub const LOSS: &str = "huber";
/// Rotation solver of the closed-form fit.
pub const METHOD: &str = "horn";
/// RANSAC hypotheses of the robust fit.
pub const ROBUST_ITERATIONS: usize = 500;
/// Degrees of freedom of the fit (`sim3`, `se3`, `4dof`, `scale+4dof`).
pub const DOF: &str = "sim3";
/// Pairing rule of SLAM and reference stamps (`evo`, `one_to_one`).
pub const ASSOCIATION: &str = "evo";
/// Largest tilt of the estimate's gravity (degrees, by the Sim(3) fit) that a
/// yaw-only fit (`4dof`, `scale+4dof`) accepts.
pub const MAX_TILT_DEG: f64 = 2.0;

/// Fit-quality refusals (`align::checks`): a reference whose rms
/// spread about its centroid is at most this many times its noise is static.
pub const MIN_SPREAD_OVER_NOISE: f64 = 2.0;
/// A fit whose rmse is at least this fraction of the reference's rms spread
/// explains none of it (mixed frames).
pub const MAX_RESIDUAL_OVER_SPREAD: f64 = 0.9;
/// A fitted scale within this of 1 counts as not fitted ...
pub const MIN_SCALE_CHANGE: f64 = 1e-9;
/// ... when the rmse is above this many times the reference noise.
pub const MAX_UNFITTED_RESIDUAL_OVER_NOISE: f64 = 10.0;

/// Magnitude of gravity, m/s².
pub const GRAVITY: f64 = 9.81;
/// Noise of a keyframe position in the inertial initialisation, metres.
pub const KEYFRAME_POSITION_SIGMA: f64 = 0.01;
/// Noise of a keyframe orientation in the inertial initialisation, radians.
pub const KEYFRAME_ROTATION_SIGMA: f64 = 2e-3;
/// Shortest interval between two keyframes of the inertial initialisation, seconds.
pub const MIN_INTERVAL: f64 = 0.5;
/// Largest gap between IMU samples inside a keyframe interval, seconds.
pub const IMU_MAX_GAP: f64 = 0.05;

/// LSD-SLAM viewer's `scaledDepthVarTH`: largest `idepth_var·depth⁴`.
pub const SCALED_DEPTH_VAR: f64 = 1e-3;
/// LSD-SLAM viewer's `absDepthVarTH`: largest `idepth_var·depth⁴·s²`.
pub const ABS_DEPTH_VAR: f64 = 1e-1;
/// LSD-SLAM viewer's `minNearSupport`: neighbours (3×3, the pixel included) that must agree.
pub const MIN_NEAR_SUPPORT: u32 = 7;
/// LSD-SLAM viewer's `sparsifyFactor`: keep one pixel in this many.
pub const SPARSIFY: u32 = 1;
/// LSD-SLAM viewer's `cutFirstNKf`: keyframes whose arrival index is `≤` this are dropped.
pub const CUT_FIRST_KEYFRAMES: usize = 5;

/// DROID-SLAM's depth filter: largest depth difference of an agreeing
/// neighbour keyframe, depth units (its viewers' 0.005).
pub const DEPTH_THRESHOLD: f64 = 0.005;
/// DROID-SLAM's depth filter: neighbour keyframes that must agree (its viewers' 2).
pub const DEPTH_MIN_COUNT: u32 = 2;
/// DROID-SLAM's depth filter: kept disparities exceed this fraction of the
/// keyframe's mean (`visualization.py`'s 0.5).
pub const MIN_DISPARITY_RATIO: f64 = 0.5;

/// OctoMap's `prob_hit`: occupancy probability of a ray's end voxel.
pub const PROB_HIT: f64 = 0.7;
/// OctoMap's `prob_miss`: occupancy probability of a voxel a ray crosses.
pub const PROB_MISS: f64 = 0.4;
/// OctoMap's lower clamping threshold of the occupancy probability.
pub const CLAMP_MIN: f64 = 0.1192;
/// OctoMap's upper clamping threshold of the occupancy probability.
pub const CLAMP_MAX: f64 = 0.971;
/// OctoMap's occupancy threshold: a voxel above it is occupied.
pub const OCCUPANCY_THRESHOLD: f64 = 0.5;

/// Most cloud points embedded in `report.html` (a deterministic stride).
pub const HTML_MAX_POINTS: usize = 300_000;
/// Most reference poses drawn in `report.html` (a deterministic stride, the
/// last pose kept): a line of more has more vertices than the view has pixels.
pub const HTML_MAX_PATH_POINTS: usize = 20_000;
/// Most occupied voxels embedded in `report.html` (coarser levels beyond it).
pub const HTML_MAX_VOXELS: usize = 200_000;
/// Ground plane (`align::ground`): largest angle between a floor candidate's
/// normal and the cameras' mean image "up" (−y), degrees.
pub const GROUND_MAX_UP_ANGLE_DEG: f64 = 35.0;
/// Ground plane: fewest inliers of a floor candidate.
pub const GROUND_MIN_INLIERS: usize = 30;
/// Ground plane: a plane is large with at least this share of the largest
/// one's support, and the ground is the lowest large plane (rows of edges
/// along boxes standing on a floor hold twice the floor's points).
pub const GROUND_LARGE_SHARE: f64 = 0.25;
/// Ground plane: largest share of the points under the floor.
pub const GROUND_MAX_BELOW: f64 = 0.05;
/// Planar motion (`align::priors`): largest tilt, degrees, that the camera
/// centres' spread off their plane (against their spread in it) may hide;
/// a path beyond it (a line, a hand-held camera, stairs) gives no "up".
pub const PLANAR_MAX_TILT_BOUND_DEG: f64 = 3.0;
/// Scale profile of `convert --camera-height`: fewest keyframes per window
/// (each window a tenth of the run beyond it).
pub const PROFILE_MIN_WINDOW: usize = 8;
/// `follow`'s world cloud (`world.mcap`, live in Foxglove): most points kept
/// of one keyframe (every k-th beyond).
pub const LIVE_KEYFRAME_POINTS: usize = 20_000;
/// `follow`'s world cloud: most points in all (every k-th beyond; 8 MB of
/// Foxglove points).
pub const LIVE_MAX_POINTS: usize = 500_000;
/// `follow`'s world (live in Foxglove): most poses of the keyframe path and
/// of the reference path (evenly spread beyond: a 200 Hz motion capture is
/// not re-sent whole at every keyframe).
pub const LIVE_PATH_POSES: usize = 5_000;
/// Voxel edge of the octree `slam2world demo` builds, metres.
pub const DEMO_OCTREE_RESOLUTION: f64 = 0.1;

/// A default as the Python side sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Value {
    /// A float.
    Float(f64),
    /// An integer.
    Int(i64),
    /// A string.
    Str(&'static str),
}

/// `(Python parameter name, default)` for every option whose default lives
/// here; a name that means another thing in one function is given as
/// `function.parameter` (the IMU's `max_gap` is not the reference's).
pub const TABLE: &[(&str, Value)] = &[
    ("max_diff", Value::Float(MAX_DIFF)),
    ("offset", Value::Float(OFFSET)),
    ("max_offset", Value::Float(MAX_OFFSET)),
    ("max_gap", Value::Float(MAX_GAP)),
    ("convert.origin", Value::Str(ORIGIN)),
    ("convert.crs", Value::Str(CRS)),
    ("level", Value::Float(CONFIDENCE)),
    ("loss", Value::Str(LOSS)),
    ("method", Value::Str(METHOD)),
    ("dof", Value::Str(DOF)),
    ("association", Value::Str(ASSOCIATION)),
    ("max_tilt_deg", Value::Float(MAX_TILT_DEG)),
    ("max_up_angle_deg", Value::Float(GROUND_MAX_UP_ANGLE_DEG)),
    ("min_inliers", Value::Int(GROUND_MIN_INLIERS as i64)),
    ("large_share", Value::Float(GROUND_LARGE_SHARE)),
    ("max_below", Value::Float(GROUND_MAX_BELOW)),
    (
        "max_tilt_bound_deg",
        Value::Float(PLANAR_MAX_TILT_BOUND_DEG),
    ),
    ("gravity", Value::Float(GRAVITY)),
    (
        "keyframe_position_sigma",
        Value::Float(KEYFRAME_POSITION_SIGMA),
    ),
    (
        "keyframe_rotation_sigma",
        Value::Float(KEYFRAME_ROTATION_SIGMA),
    ),
    ("min_interval", Value::Float(MIN_INTERVAL)),
    ("imu_initialize.max_gap", Value::Float(IMU_MAX_GAP)),
    ("scaled_depth_var", Value::Float(SCALED_DEPTH_VAR)),
    ("abs_depth_var", Value::Float(ABS_DEPTH_VAR)),
    ("min_near_support", Value::Int(MIN_NEAR_SUPPORT as i64)),
    ("serve.points", Value::Int(LIVE_MAX_POINTS as i64)),
    ("sparsify", Value::Int(SPARSIFY as i64)),
    (
        "cut_first_keyframes",
        Value::Int(CUT_FIRST_KEYFRAMES as i64),
    ),
    ("depth_threshold", Value::Float(DEPTH_THRESHOLD)),
    ("depth_min_count", Value::Int(DEPTH_MIN_COUNT as i64)),
    ("min_disparity_ratio", Value::Float(MIN_DISPARITY_RATIO)),
    ("prob_hit", Value::Float(PROB_HIT)),
    ("prob_miss", Value::Float(PROB_MISS)),
    ("clamp_min", Value::Float(CLAMP_MIN)),
    ("clamp_max", Value::Float(CLAMP_MAX)),
    ("max_points", Value::Int(HTML_MAX_POINTS as i64)),
    ("max_cubes", Value::Int(HTML_MAX_VOXELS as i64)),
];
