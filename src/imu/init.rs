//! Inertial initialisation: the metric scale, the gravity direction, the IMU
//! biases and the keyframe velocities of a monocular SLAM trajectory, from raw
//! IMU samples (no pose source needed).
//!
//! Frames: keyframe poses are `T_slam_cam` (SLAM units, unknown scale); the IMU
//! (body) frame is tied to the camera by a known metric `T_imu_cam`. "Metric
//! SLAM axes" are the SLAM axes with lengths in metres (SLAM lengths times the
//! scale `s`); velocities and gravity are solved for in them.
//!
//! Steps (VINS-Mono, Qin et al. 2018; ORB-SLAM3 inertial-only initialisation,
//! Campos et al. 2021):
//! 1. preintegrate the IMU between consecutive keyframes ([`Preintegrated`]);
//! 2. gyroscope bias: Gauss-Newton on `Σ‖Log(ΔR(b_g)ᵀ·R_kᵀ·R_{k+1})‖²` over
//!    the relative keyframe rotations (3 unknowns);
//! 3. one weighted linear system over every interval in the unknowns
//!    `v_0 … v_{K−1}`, `g`, `s` (and `b_a` with a zero-mean prior):
//!    `s·(p_{k+1} − p_k) + (R^c_{k+1} − R^c_k)·p_ci − v_k·Δt − ½·g·Δt² = R_k·Δp(b_a)` and
//!    `v_{k+1} − v_k − g·Δt = R_k·Δv(b_a)`; the velocities are eliminated
//!    (they form a tridiagonal block), leaving a small Schur complement;
//! 4. gravity refined with its magnitude fixed: `g = |g|·ĝ + B·w` with `B` a
//!    tangent basis of `ĝ`, re-solved a few times (VINS-Mono's `RefineGravity`).
//!
//! Each row is weighted by the inverse variance that the IMU noise densities
//! and the keyframe pose noise give it; the covariance of the result is the
//! inverse of the reduced normal matrix, scaled by the variance factor
//! (`χ² / dof`) when that exceeds 1. Motion that does not determine the scale
//! is refused with [`Error::Degenerate`]: too short a window, no acceleration
//! (constant velocity or pure rotation), or a relative scale uncertainty above
//! a threshold.

use nalgebra::{DMatrix, DVector, Matrix2, Matrix3, UnitQuaternion, Vector3};

use super::preintegration::Preintegrated;
use super::ImuSamples;
use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::trajectory::Trajectory;

/// Options of [`imu_initialize`]. Noise defaults are the EuRoC ADIS16448
/// datasheet values (Kalibr convention).
#[derive(Clone, Debug, PartialEq)]
pub struct ImuInitOptions {
    /// `T_imu_cam`: maps camera-frame points into the IMU frame, metres
    /// (scale must be 1; identity by default).
    pub imu_from_cam: Sim3,
    /// Seconds added to the keyframe stamps to get IMU-clock times (0).
    pub time_offset: f64,
    /// Magnitude of gravity, m/s² (9.81).
    pub gravity: f64,
    /// Estimate the accelerometer bias (with a zero-mean prior); `false`
    /// keeps it at zero (default true).
    pub estimate_accel_bias: bool,
    /// Standard deviation of the accelerometer-bias prior, m/s² (0.2).
    pub accel_bias_prior: f64,
    /// Gyroscope white noise density, rad/s/√Hz (1.6968e-4).
    pub gyro_noise_density: f64,
    /// Accelerometer white noise density, m/s²/√Hz (2.0e-3).
    pub accel_noise_density: f64,
    /// Accelerometer bias random walk, m/s³/√Hz (3.0e-3).
    pub accel_random_walk: f64,
    /// Noise of a keyframe position, metres (0.01).
    pub keyframe_position_sigma: f64,
    /// Noise of a keyframe orientation, rad (2e-3).
    pub keyframe_rotation_sigma: f64,
    /// Shortest interval between two keyframes used, seconds (0.5): closer
    /// keyframes are skipped, because the position noise of short intervals
    /// biases the scale low (errors in variables).
    pub min_interval: f64,
    /// Largest gap between IMU samples inside an interval, seconds (0.05).
    pub max_gap: f64,
    /// Shortest window, seconds (2); shorter is refused as degenerate.
    pub min_duration: f64,
    /// Smallest rms variation of the keyframe-interval mean accelerations,
    /// m/s² (0.05); less is refused as degenerate (no acceleration).
    pub min_excitation: f64,
    /// Largest relative standard deviation of the scale (0.05); more is
    /// refused as degenerate.
    pub max_relative_scale_sigma: f64,
    /// Gravity refinement iterations with the magnitude fixed (4).
    pub gravity_iterations: usize,
}

impl Default for ImuInitOptions {
    fn default() -> Self {
        ImuInitOptions {
            imu_from_cam: Sim3::identity(),
            time_offset: 0.0,
            gravity: crate::defaults::GRAVITY,
            estimate_accel_bias: true,
            accel_bias_prior: 0.2,
            gyro_noise_density: 1.6968e-4,
            accel_noise_density: 2.0e-3,
            accel_random_walk: 3.0e-3,
            keyframe_position_sigma: crate::defaults::KEYFRAME_POSITION_SIGMA,
            keyframe_rotation_sigma: crate::defaults::KEYFRAME_ROTATION_SIGMA,
            min_interval: crate::defaults::MIN_INTERVAL,
            max_gap: crate::defaults::IMU_MAX_GAP,
            min_duration: 2.0,
            min_excitation: 0.05,
            max_relative_scale_sigma: 0.05,
            gravity_iterations: 4,
        }
    }
}

impl ImuInitOptions {
    /// Checks the options (what [`imu_initialize`] checks before it reads the
    /// data): gravity and the noise levels finite and positive or non-negative.
    pub fn validate(&self) -> Result<()> {
        let positive = [
            ("gravity", self.gravity),
            ("accel_bias_prior", self.accel_bias_prior),
            ("max_gap", self.max_gap),
            ("max_relative_scale_sigma", self.max_relative_scale_sigma),
        ];
        for (what, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::invalid(
                    what,
                    format!("must be finite and > 0, got {v}"),
                ));
            }
        }
        let non_negative = [
            ("gyro_noise_density", self.gyro_noise_density),
            ("accel_noise_density", self.accel_noise_density),
            ("accel_random_walk", self.accel_random_walk),
            ("keyframe_position_sigma", self.keyframe_position_sigma),
            ("keyframe_rotation_sigma", self.keyframe_rotation_sigma),
            ("min_duration", self.min_duration),
            ("min_interval", self.min_interval),
            ("min_excitation", self.min_excitation),
        ];
        for (what, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::invalid(
                    what,
                    format!("must be finite and ≥ 0, got {v}"),
                ));
            }
        }
        if !self.time_offset.is_finite() {
            return Err(Error::invalid("time_offset", "must be finite"));
        }
        if (self.imu_from_cam.scale - 1.0).abs() > 1e-9 {
            return Err(Error::invalid(
                "imu_from_cam",
                format!(
                    "must be rigid (scale 1), got scale {}",
                    self.imu_from_cam.scale
                ),
            ));
        }
        Ok(())
    }
}

/// How well the data determined the result.
#[derive(Clone, Debug, PartialEq, serde::Serialize, schemars::JsonSchema)]
pub struct ImuInitDiagnostics {
    /// Keyframes used (inside the IMU's time span).
    pub n_keyframes: usize,
    /// Keyframes dropped because the IMU does not cover them.
    pub n_dropped: usize,
    /// Keyframes skipped because they follow the previous used one by less
    /// than `min_interval`.
    pub n_skipped: usize,
    /// Time span of the keyframes used, seconds.
    pub duration: f64,
    /// Rms variation of the keyframe-interval mean accelerations (in SLAM
    /// axes, gravity included), m/s²: the motion's excitation of the scale.
    pub excitation: f64,
    /// Scale of the first, unconstrained solve (before the gravity magnitude is fixed).
    pub initial_scale: f64,
    /// `|g|` of the first solve, m/s² (far from the true magnitude means bad data).
    pub initial_gravity_norm: f64,
    /// Rms of the relative-rotation residuals after the gyroscope bias, rad.
    pub rotation_rms: f64,
    /// Rms of the position residuals, metres.
    pub position_rms: f64,
    /// Rms of the velocity residuals, m/s.
    pub velocity_rms: f64,
    /// `χ² / dof` of the final solve (about 1 when the noise options fit the data).
    pub variance_factor: f64,
    /// Relative standard deviation of the scale, `σ_s / s`.
    pub relative_scale_sigma: f64,
}

/// The result of [`imu_initialize`].
#[derive(Clone, Debug, PartialEq)]
pub struct ImuAlignment {
    /// `T_world_slam`: world z against gravity, the origin at the first used
    /// keyframe's IMU, yaw by convention: the first keyframe's IMU frame has
    /// zero heading (its ZYX yaw is 0 in the world).
    pub transform: Sim3,
    /// Metres per SLAM unit (= `transform.scale`).
    pub scale: f64,
    /// Gravity in SLAM axes, m/s² (magnitude = the `gravity` option).
    pub gravity_slam: Vector3<f64>,
    /// Gyroscope bias, rad/s (IMU frame).
    pub gyro_bias: Vector3<f64>,
    /// Accelerometer bias, m/s² (IMU frame; zero when not estimated).
    pub accel_bias: Vector3<f64>,
    /// Keyframe times used (keyframe clock), seconds.
    pub timestamps: Vec<f64>,
    /// IMU velocity at each used keyframe, world frame, m/s.
    pub velocities: Vec<Vector3<f64>>,
    /// Standard deviation of the scale.
    pub scale_sigma: f64,
    /// Standard deviation of the gravity direction, rad.
    pub gravity_sigma: f64,
    /// Standard deviation of each gyroscope-bias component, rad/s.
    pub gyro_bias_sigma: Vector3<f64>,
    /// Standard deviation of each accelerometer-bias component, m/s² (zero when
    /// not estimated).
    pub accel_bias_sigma: Vector3<f64>,
    /// How well the data determined the result.
    pub diagnostics: ImuInitDiagnostics,
}

/// One keyframe interval with everything the linear system needs.
struct Interval {
    dt: f64,
    pre: Preintegrated,
    /// `R_slam_imu` at the start keyframe.
    r_k: Matrix3<f64>,
    /// `p_{k+1} − p_k`, SLAM units.
    dp_slam: Vector3<f64>,
    /// `(R^c_{k+1} − R^c_k)·p_ci`, metres (lever-arm term).
    lever: Vector3<f64>,
    w_p: f64,
    w_v: f64,
}

/// The rows of one interval: `(G_p, y_p, G_v, y_v)` (see [`solve`]).
type Rows = (DMatrix<f64>, Vector3<f64>, DMatrix<f64>, Vector3<f64>);

/// Gravity handling in a solve.
enum GravityMode {
    /// `g` free (3 unknowns).
    Free,
    /// `g = mag·dir + B·w` (2 unknowns `w`).
    Tangent {
        g0: Vector3<f64>,
        basis: nalgebra::Matrix3x2<f64>,
    },
}

struct Solution {
    theta: DVector<f64>,
    cov: DMatrix<f64>,
    velocities: Vec<Vector3<f64>>,
    chi2: f64,
    dof: f64,
    position_rms: f64,
    velocity_rms: f64,
}

/// Metric scale, gravity direction, biases and velocities of the keyframes
/// `T_slam_cam` (orientations required) from raw IMU samples.
///
/// Keyframes outside the IMU's time span are dropped, and keyframes that
/// follow the previous used one by less than `min_interval` (or share its
/// stamp) are skipped; the diagnostics count both.
///
/// Errors: [`Error::InvalidArgument`] (no orientations, bad options),
/// [`Error::TooFew`] (fewer than 4 keyframes
/// inside the IMU's time span), [`Error::OutOfRange`] (an IMU gap longer than
/// `max_gap` between two keyframes), [`Error::Degenerate`] (window too short,
/// no acceleration — constant velocity or pure rotation —, or a scale that the
/// motion does not determine; the diagnostic value is in the error).
pub fn imu_initialize(
    keyframes: &Trajectory,
    imu: &ImuSamples,
    opts: &ImuInitOptions,
) -> Result<ImuAlignment> {
    opts.validate()?;
    keyframes.check_lengths()?;
    imu.check()?;
    let orientations = keyframes.orientations.as_ref().ok_or_else(|| {
        Error::invalid(
            "keyframes",
            "orientations are required for the inertial initialisation",
        )
    })?;
    if let Some(i) = (0..keyframes.len()).find(|&i| {
        !keyframes.timestamps[i].is_finite()
            || keyframes.positions[i].iter().any(|v| !v.is_finite())
            || orientations[i].coords.iter().any(|v| !v.is_finite())
    }) {
        return Err(Error::NonFinite {
            what: "keyframes".into(),
            index: i,
        });
    }
    if imu.len() < 2 {
        return Err(Error::TooFew {
            what: "IMU samples".into(),
            need: 2,
            got: imu.len(),
        });
    }
    let (imu_t0, imu_t1) = (imu.timestamps[0], imu.timestamps[imu.len() - 1]);
    let covered: Vec<usize> = (0..keyframes.len())
        .filter(|&i| {
            let t = keyframes.timestamps[i] + opts.time_offset;
            t >= imu_t0 && t <= imu_t1
        })
        .collect();
    let n_dropped = keyframes.len() - covered.len();
    let duration = match (covered.first(), covered.last()) {
        (Some(&a), Some(&b)) => keyframes.timestamps[b] - keyframes.timestamps[a],
        _ => 0.0,
    };
    if covered.len() >= 2 && duration < opts.min_duration {
        return Err(Error::Degenerate {
            reason: format!(
                "the keyframes span {duration:.3} s, less than min_duration {} s: too short to observe the scale",
                opts.min_duration
            ),
            value: duration,
        });
    }
    // Trajectory times do not decrease; a repeated stamp is skipped like a
    // keyframe closer than min_interval.
    let mut used: Vec<usize> = Vec::with_capacity(covered.len());
    for &i in &covered {
        let t = keyframes.timestamps[i];
        match used.last() {
            Some(&j)
                if t <= keyframes.timestamps[j]
                    || t - keyframes.timestamps[j] < opts.min_interval => {}
            _ => used.push(i),
        }
    }
    let n_skipped = covered.len() - used.len();
    if used.len() < 4 {
        return Err(Error::TooFew {
            what: format!(
                "keyframes inside the IMU's time span at least min_interval = {} s apart",
                opts.min_interval
            ),
            need: 4,
            got: used.len(),
        });
    }
    let r_ic = opts.imu_from_cam.rotation;
    let p_ci = -(r_ic.inverse() * opts.imu_from_cam.translation);
    let r_slam_cam: Vec<UnitQuaternion<f64>> = used.iter().map(|&i| orientations[i]).collect();
    let r_slam_imu: Vec<UnitQuaternion<f64>> =
        r_slam_cam.iter().map(|r| r * r_ic.inverse()).collect();
    let positions: Vec<Vector3<f64>> = used.iter().map(|&i| keyframes.positions[i]).collect();
    let times: Vec<f64> = used.iter().map(|&i| keyframes.timestamps[i]).collect();
    let imu_times: Vec<f64> = times.iter().map(|t| t + opts.time_offset).collect();
    let used_duration = times[times.len() - 1] - times[0];

    // Step 2: gyroscope bias (Gauss-Newton, re-integrating each iteration).
    let zero = Vector3::zeros();
    let integrate_all = |bg: &Vector3<f64>| -> Result<Vec<Preintegrated>> {
        imu_times
            .windows(2)
            .map(|w| Preintegrated::integrate(imu, w[0], w[1], bg, &zero, opts.max_gap))
            .collect()
    };
    let mut bg = Vector3::zeros();
    let mut pres = integrate_all(&bg)?;
    let mut h_g = Matrix3::zeros();
    let mut rot_sq = 0.0;
    for _ in 0..3 {
        h_g = Matrix3::zeros();
        let mut b_g = Vector3::zeros();
        for (k, pre) in pres.iter().enumerate() {
            let rel = r_slam_imu[k].inverse() * r_slam_imu[k + 1];
            let r = (pre.delta_r.inverse() * rel).scaled_axis();
            let j = pre.dr_dbg;
            h_g += j.transpose() * j;
            b_g += j.transpose() * r;
        }
        let step = h_g
            .cholesky()
            .ok_or_else(|| Error::Degenerate {
                reason: "the gyroscope-bias normal matrix is singular".into(),
                value: h_g.determinant(),
            })?
            .solve(&b_g);
        bg += step;
        pres = integrate_all(&bg)?;
        rot_sq = pres
            .iter()
            .enumerate()
            .map(|(k, pre)| {
                let rel = r_slam_imu[k].inverse() * r_slam_imu[k + 1];
                (pre.delta_r.inverse() * rel).scaled_axis().norm_squared()
            })
            .sum::<f64>();
        if step.norm() < 1e-9 {
            break;
        }
    }
    let m = pres.len();
    let rotation_rms = (rot_sq / (3 * m) as f64).sqrt();
    let gyro_var = rot_sq / ((3 * m).saturating_sub(3).max(1)) as f64;
    let gyro_cov = h_g.try_inverse().unwrap_or_else(Matrix3::zeros) * gyro_var;
    let gyro_bias_sigma = gyro_cov.diagonal().map(|v| v.max(0.0).sqrt());

    // Excitation before any accelerometer bias is known (a rotating bias adds
    // to it; checked again below with the estimated bias).
    let excitation_raw = excitation(&pres, &r_slam_imu, &Vector3::zeros());
    check_excitation(excitation_raw, opts, &times, &positions)?;

    // Step 3: the weighted linear system.
    let s2 = opts.keyframe_position_sigma.powi(2);
    let intervals: Vec<Interval> = pres
        .into_iter()
        .enumerate()
        .map(|(k, pre)| {
            let dt = pre.dt();
            let rot_var =
                opts.keyframe_rotation_sigma.powi(2) + opts.gyro_noise_density.powi(2) * dt;
            let na = opts.accel_noise_density.powi(2);
            let nw = opts.accel_random_walk.powi(2);
            let var_p = 2.0 * s2
                + na * dt.powi(3) / 3.0
                + nw * dt.powi(5) / 20.0
                + rot_var * pre.delta_p.norm_squared();
            let var_v = na * dt + nw * dt.powi(3) / 3.0 + rot_var * pre.delta_v.norm_squared();
            Interval {
                dt,
                r_k: r_slam_imu[k].to_rotation_matrix().into_inner(),
                dp_slam: positions[k + 1] - positions[k],
                lever: (r_slam_cam[k + 1] * p_ci) - (r_slam_cam[k] * p_ci),
                w_p: 1.0 / var_p.max(1e-18),
                w_v: 1.0 / var_v.max(1e-18),
                pre,
            }
        })
        .collect();
    let with_ba = opts.estimate_accel_bias;
    let free = solve(
        &intervals,
        &GravityMode::Free,
        with_ba,
        opts.accel_bias_prior,
    )?;
    let initial_scale = free.theta[3];
    let g_free = Vector3::new(free.theta[0], free.theta[1], free.theta[2]);
    let initial_gravity_norm = g_free.norm();
    if initial_gravity_norm.is_nan() || initial_gravity_norm <= 1e-9 {
        return Err(Error::Degenerate {
            reason: "the gravity vector came out zero".into(),
            value: initial_gravity_norm,
        });
    }

    // Step 4: gravity with its magnitude fixed.
    let mut dir = g_free / initial_gravity_norm;
    let mut sol = free;
    for _ in 0..opts.gravity_iterations.max(1) {
        let basis = tangent_basis(&dir);
        let g0 = dir * opts.gravity;
        sol = solve(
            &intervals,
            &GravityMode::Tangent { g0, basis },
            with_ba,
            opts.accel_bias_prior,
        )?;
        let g = g0 + basis * nalgebra::Vector2::new(sol.theta[0], sol.theta[1]);
        dir = g.normalize();
    }
    let gravity_slam = dir * opts.gravity;
    let scale = sol.theta[2];
    let ba_est = if with_ba {
        Vector3::new(sol.theta[3], sol.theta[4], sol.theta[5])
    } else {
        Vector3::zeros()
    };
    let pres: Vec<Preintegrated> = intervals.iter().map(|iv| iv.pre.clone()).collect();
    let excitation = excitation(&pres, &r_slam_imu, &ba_est);
    check_excitation(excitation, opts, &times, &positions)?;
    let variance_factor = if sol.dof > 0.0 {
        sol.chi2 / sol.dof
    } else {
        f64::NAN
    };
    let inflate = if variance_factor.is_finite() {
        variance_factor.max(1.0)
    } else {
        1.0
    };
    let scale_sigma = (sol.cov[(2, 2)].max(0.0) * inflate).sqrt();
    let relative_scale_sigma = scale_sigma / scale.abs();
    if scale <= 0.0
        || relative_scale_sigma.is_nan()
        || relative_scale_sigma > opts.max_relative_scale_sigma
    {
        return Err(Error::Degenerate {
            reason: format!(
                "the motion does not determine the scale (scale {scale:.4e} ± {scale_sigma:.3e}, relative σ {relative_scale_sigma:.3e} > max_relative_scale_sigma {})",
                opts.max_relative_scale_sigma
            ),
            value: relative_scale_sigma,
        });
    }
    let cov_w = Matrix2::new(
        sol.cov[(0, 0)],
        sol.cov[(0, 1)],
        sol.cov[(1, 0)],
        sol.cov[(1, 1)],
    ) * inflate;
    let gravity_sigma = cov_w.trace().max(0.0).sqrt() / opts.gravity;
    let (accel_bias, accel_bias_sigma) = if with_ba {
        (
            Vector3::new(sol.theta[3], sol.theta[4], sol.theta[5]),
            Vector3::new(sol.cov[(3, 3)], sol.cov[(4, 4)], sol.cov[(5, 5)])
                .map(|v| (v.max(0.0) * inflate).sqrt()),
        )
    } else {
        (Vector3::zeros(), Vector3::zeros())
    };

    // T_world_slam: level, yaw of the first keyframe's IMU zero, origin there.
    let tilt = UnitQuaternion::rotation_between(&dir, &Vector3::new(0.0, 0.0, -1.0))
        .unwrap_or_else(|| UnitQuaternion::from_scaled_axis(Vector3::x() * std::f64::consts::PI));
    let r_world_imu0 = (tilt * r_slam_imu[0]).to_rotation_matrix();
    let m0 = r_world_imu0.matrix();
    let yaw = m0[(1, 0)].atan2(m0[(0, 0)]);
    let rotation = UnitQuaternion::from_scaled_axis(Vector3::z() * -yaw) * tilt;
    let origin = scale * positions[0] + r_slam_cam[0] * p_ci;
    let transform = Sim3::try_new(rotation, -(rotation * origin), scale)?;
    let velocities = sol.velocities.iter().map(|v| rotation * v).collect();

    Ok(ImuAlignment {
        transform,
        scale,
        gravity_slam,
        gyro_bias: bg,
        accel_bias,
        timestamps: times,
        velocities,
        scale_sigma,
        gravity_sigma,
        gyro_bias_sigma,
        accel_bias_sigma,
        diagnostics: ImuInitDiagnostics {
            n_keyframes: used.len(),
            n_dropped,
            n_skipped,
            duration: used_duration,
            excitation,
            initial_scale,
            initial_gravity_norm,
            rotation_rms,
            position_rms: sol.position_rms,
            velocity_rms: sol.velocity_rms,
            variance_factor,
            relative_scale_sigma,
        },
    })
}

/// Rms variation of the interval mean accelerations in SLAM axes (gravity
/// included, accelerometer bias `ba` removed), m/s²: zero for constant
/// velocity and for pure rotation about the IMU.
fn excitation(
    pres: &[Preintegrated],
    r_slam_imu: &[UnitQuaternion<f64>],
    ba: &Vector3<f64>,
) -> f64 {
    let means: Vec<Vector3<f64>> = pres
        .iter()
        .enumerate()
        .map(|(k, p)| r_slam_imu[k] * p.delta_v_at(&p.gyro_bias, ba) / p.dt())
        .collect();
    let m = means.len().max(1) as f64;
    let mean = means.iter().sum::<Vector3<f64>>() / m;
    (means.iter().map(|a| (a - mean).norm_squared()).sum::<f64>() / m).sqrt()
}

fn check_excitation(
    value: f64,
    opts: &ImuInitOptions,
    times: &[f64],
    positions: &[Vector3<f64>],
) -> Result<()> {
    if value.is_nan() || value < opts.min_excitation {
        return Err(Error::Degenerate {
            reason: format!(
                "{}: the accelerations vary by {value:.4} m/s² rms (min_excitation {} m/s²), so the scale is unobservable",
                no_acceleration_kind(times, positions),
                opts.min_excitation
            ),
            value,
        });
    }
    Ok(())
}

/// "pure rotation" when the SLAM positions barely move compared with their
/// jitter about a straight line, "constant velocity" otherwise.
fn no_acceleration_kind(times: &[f64], positions: &[Vector3<f64>]) -> &'static str {
    let n = positions.len() as f64;
    let tm = times.iter().sum::<f64>() / n;
    let pm = positions.iter().sum::<Vector3<f64>>() / n;
    let stt: f64 = times.iter().map(|t| (t - tm).powi(2)).sum();
    let vel: Vector3<f64> = times
        .iter()
        .zip(positions)
        .map(|(t, p)| (t - tm) * (p - pm))
        .sum::<Vector3<f64>>()
        / stt.max(f64::MIN_POSITIVE);
    let jitter = (positions
        .iter()
        .zip(times)
        .map(|(p, t)| (p - pm - vel * (t - tm)).norm_squared())
        .sum::<f64>()
        / n)
        .sqrt();
    let span = times.last().copied().unwrap_or(0.0) - times.first().copied().unwrap_or(0.0);
    if vel.norm() * span <= 10.0 * jitter + 1e-12 * (1.0 + pm.norm()) {
        "pure rotation (the keyframes do not translate)"
    } else {
        "constant velocity"
    }
}

/// Two unit vectors orthogonal to `d` (unit) and to each other.
fn tangent_basis(d: &Vector3<f64>) -> nalgebra::Matrix3x2<f64> {
    let helper = if d.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let b1 = (helper - d * d.dot(&helper)).normalize();
    let b2 = d.cross(&b1);
    nalgebra::Matrix3x2::from_columns(&[b1, b2])
}

/// Builds and solves the weighted normal equations over all intervals, the
/// velocities eliminated through their tridiagonal structure (every velocity
/// block is a multiple of the identity). Unknown order in `theta`: gravity (3
/// free, or 2 tangent), scale, accelerometer bias (3, optional).
fn solve(
    intervals: &[Interval],
    mode: &GravityMode,
    with_ba: bool,
    ba_prior: f64,
) -> Result<Solution> {
    let ng = match mode {
        GravityMode::Free => 3,
        GravityMode::Tangent { .. } => 2,
    };
    let nt = ng + 1 + if with_ba { 3 } else { 0 };
    let kf = intervals.len() + 1;
    // Per interval: position rows Gp·θ + (−Δt)·v_k = y_p; velocity rows
    // Gv·θ − v_k + v_{k+1} = y_v.
    let rows: Vec<Rows> = intervals
        .iter()
        .map(|iv| {
            let dt = iv.dt;
            let mut gp = DMatrix::zeros(3, nt);
            let mut gv = DMatrix::zeros(3, nt);
            let mut yp = iv.r_k * iv.pre.delta_p - iv.lever;
            let mut yv = iv.r_k * iv.pre.delta_v;
            match mode {
                GravityMode::Free => {
                    for a in 0..3 {
                        gp[(a, a)] = -0.5 * dt * dt;
                        gv[(a, a)] = -dt;
                    }
                }
                GravityMode::Tangent { g0, basis } => {
                    yp += 0.5 * dt * dt * g0;
                    yv += dt * g0;
                    gp.view_mut((0, 0), (3, 2))
                        .copy_from(&(-0.5 * dt * dt * basis));
                    gv.view_mut((0, 0), (3, 2)).copy_from(&(-dt * basis));
                }
            }
            gp.view_mut((0, ng), (3, 1)).copy_from(&iv.dp_slam);
            if with_ba {
                gp.view_mut((0, ng + 1), (3, 3))
                    .copy_from(&(-(iv.r_k * iv.pre.dp_dba)));
                gv.view_mut((0, ng + 1), (3, 3))
                    .copy_from(&(-(iv.r_k * iv.pre.dv_dba)));
            }
            (gp, yp, gv, yv)
        })
        .collect();

    // Normal equations: tridiagonal scalar d (diagonal) and c (upper),
    // H_vθ blocks (3 × nt) with b_v appended as the last column.
    let mut d = vec![0.0; kf];
    let mut c = vec![0.0; kf - 1];
    let mut hv: Vec<DMatrix<f64>> = vec![DMatrix::zeros(3, nt + 1); kf];
    let mut htt = DMatrix::<f64>::zeros(nt, nt);
    let mut bt = DVector::<f64>::zeros(nt);
    for (k, (iv, (gp, yp, gv, yv))) in intervals.iter().zip(&rows).enumerate() {
        let (wp, wv, dt) = (iv.w_p, iv.w_v, iv.dt);
        d[k] += wp * dt * dt + wv;
        d[k + 1] += wv;
        c[k] -= wv;
        {
            let mut a = hv[k].view_mut((0, 0), (3, nt));
            a -= gp * (wp * dt) + gv * wv;
        }
        {
            let mut a = hv[k].view_mut((0, nt), (3, 1));
            a -= yp * (wp * dt) + yv * wv;
        }
        {
            let mut a = hv[k + 1].view_mut((0, 0), (3, nt));
            a += gv * wv;
        }
        {
            let mut a = hv[k + 1].view_mut((0, nt), (3, 1));
            a += yv * wv;
        }
        htt += gp.transpose() * gp * wp + gv.transpose() * gv * wv;
        bt += gp.transpose() * yp * wp + gv.transpose() * yv * wv;
    }
    if with_ba {
        for a in 0..3 {
            htt[(ng + 1 + a, ng + 1 + a)] += 1.0 / (ba_prior * ba_prior);
        }
    }
    // Thomas algorithm on the scalar tridiagonal matrix, for all columns.
    let mut dp = d.clone();
    let mut x = hv.clone();
    for k in 1..kf {
        let l = c[k - 1] / dp[k - 1];
        dp[k] -= l * c[k - 1];
        let prev = x[k - 1].clone();
        x[k] -= prev * l;
    }
    if let Some(k) = dp.iter().position(|v| v.is_nan() || *v <= 0.0) {
        return Err(Error::Degenerate {
            reason: format!(
                "the velocity block of the normal equations is singular at keyframe {k}"
            ),
            value: dp[k],
        });
    }
    x[kf - 1] /= dp[kf - 1];
    for k in (0..kf - 1).rev() {
        let next = x[k + 1].clone();
        x[k] = (&x[k] - next * c[k]) / dp[k];
    }
    // Schur complement on θ.
    let mut s = htt;
    let mut rhs = bt;
    for k in 0..kf {
        let hk = hv[k].view((0, 0), (3, nt));
        s -= hk.transpose() * x[k].view((0, 0), (3, nt));
        rhs -= hk.transpose() * x[k].column(nt);
    }
    let s = (&s + s.transpose()) * 0.5;
    let chol = s.clone().cholesky().ok_or_else(|| {
        let ev = s.symmetric_eigenvalues();
        Error::Degenerate {
            reason:
                "the scale/gravity normal matrix is singular: the motion does not determine them"
                    .into(),
            value: ev.min(),
        }
    })?;
    let theta = chol.solve(&rhs);
    let cov = chol.inverse();
    let velocities: Vec<Vector3<f64>> = (0..kf)
        .map(|k| {
            let v = x[k].column(nt) - x[k].view((0, 0), (3, nt)) * &theta;
            Vector3::new(v[0], v[1], v[2])
        })
        .collect();
    let (mut chi2, mut sp, mut sv) = (0.0, 0.0, 0.0);
    for (k, (iv, (gp, yp, gv, yv))) in intervals.iter().zip(&rows).enumerate() {
        let gpt = gp * &theta;
        let gvt = gv * &theta;
        let rp = Vector3::new(gpt[0], gpt[1], gpt[2]) - velocities[k] * iv.dt - yp;
        let rv = Vector3::new(gvt[0], gvt[1], gvt[2]) - velocities[k] + velocities[k + 1] - yv;
        chi2 += iv.w_p * rp.norm_squared() + iv.w_v * rv.norm_squared();
        sp += rp.norm_squared();
        sv += rv.norm_squared();
    }
    let mut n_rows = 6 * intervals.len();
    if with_ba {
        chi2 += (ng + 1..nt)
            .map(|a| (theta[a] / ba_prior).powi(2))
            .sum::<f64>();
        n_rows += 3;
    }
    let n_unknowns = 3 * kf + nt;
    let m = intervals.len() as f64;
    Ok(Solution {
        theta,
        cov,
        velocities,
        chi2,
        dof: n_rows as f64 - n_unknowns as f64,
        position_rms: (sp / (3.0 * m)).sqrt(),
        velocity_rms: (sv / (3.0 * m)).sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tangent_basis_is_orthonormal() {
        for d in [
            Vector3::z(),
            Vector3::x(),
            Vector3::new(0.3, -0.5, 0.8).normalize(),
        ] {
            let b = tangent_basis(&d);
            let (b1, b2) = (b.column(0), b.column(1));
            assert!(b1.dot(&d).abs() < 1e-12 && b2.dot(&d).abs() < 1e-12);
            assert!(b1.dot(&b2).abs() < 1e-12);
            assert!((b1.norm() - 1.0).abs() < 1e-12 && (b2.norm() - 1.0).abs() < 1e-12);
        }
    }
}
