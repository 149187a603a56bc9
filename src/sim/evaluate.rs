//! Scoring a conversion against the simulator's truth: distance of every
//! converted point to the true surfaces (parry point projection), the error of
//! the estimated `T_world_slam`, and the APE of the aligned trajectory.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::path::CameraPath;
use super::scene::Scene;
use super::Truth;
use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::trajectory::Trajectory;

/// Summary of non-negative errors (metres).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, schemars::JsonSchema)]
pub struct ErrorStats {
    /// Number of values.
    pub n: usize,
    /// Mean.
    pub mean: f64,
    /// Median.
    pub median: f64,
    /// Root mean square.
    pub rmse: f64,
    /// 95th percentile (nearest rank).
    pub p95: f64,
    /// Largest value.
    pub max: f64,
}

impl ErrorStats {
    /// Statistics of `values` (any order); errors when empty or non-finite.
    pub fn from_values(what: &str, values: &[f64]) -> Result<Self> {
        if values.is_empty() {
            return Err(Error::TooFew {
                what: what.into(),
                need: 1,
                got: 0,
            });
        }
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: what.into(),
                index: i,
            });
        }
        let n = values.len();
        let mut v = values.to_vec();
        let rank = |q: f64| (((q * n as f64).ceil() as usize).max(1) - 1).min(n - 1);
        let (_, p95, _) = v.select_nth_unstable_by(rank(0.95), f64::total_cmp);
        let p95 = *p95;
        let (_, med, _) = v.select_nth_unstable_by(rank(0.5), f64::total_cmp);
        let median = *med;
        let sum: f64 = v.iter().sum();
        let sq: f64 = v.iter().map(|x| x * x).sum();
        let max = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Ok(ErrorStats {
            n,
            mean: sum / n as f64,
            median,
            rmse: (sq / n as f64).sqrt(),
            p95,
            max,
        })
    }
}

/// Errors of an estimated `T_world_slam` against the true one.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, schemars::JsonSchema)]
pub struct TransformError {
    /// `s_est / s_true − 1` (relative).
    pub scale_error: f64,
    /// Angle of `R_est·R_trueᵀ`, degrees.
    pub rotation_error_deg: f64,
    /// Angle between the world's up direction (+z) seen in the SLAM frame by
    /// the estimate and by the truth, degrees.
    pub gravity_error_deg: f64,
    /// `‖t_est − t_true‖`: where the SLAM origin lands, metres.
    pub translation_error: f64,
}

/// Compares `est` with `truth` (both `T_world_slam`).
pub fn transform_error(est: &Sim3, truth: &Sim3) -> TransformError {
    let up_est = est.rotation.inverse() * Vector3::z();
    let up_true = truth.rotation.inverse() * Vector3::z();
    TransformError {
        scale_error: est.scale / truth.scale - 1.0,
        rotation_error_deg: est.rotation.angle_to(&truth.rotation).to_degrees(),
        gravity_error_deg: up_est
            .cross(&up_true)
            .norm()
            .atan2(up_est.dot(&up_true))
            .to_degrees(),
        translation_error: (est.translation - truth.translation).norm(),
    }
}

/// Distance of every world point (row-major `(N, 3)`, metres) to the nearest
/// true surface, in parallel.
pub fn point_distances(scene: &Scene, points: &[f32]) -> Result<Vec<f64>> {
    if points.len() % 3 != 0 {
        return Err(Error::ShapeMismatch {
            what: "points".into(),
            expected: "(N, 3)".into(),
            got: format!("{} values", points.len()),
        });
    }
    if let Some(i) = points.iter().position(|v| !v.is_finite()) {
        return Err(Error::NonFinite {
            what: "points".into(),
            index: i / 3,
        });
    }
    Ok(points
        .par_chunks_exact(3)
        .map(|p| scene.distance(&[p[0] as f64, p[1] as f64, p[2] as f64]))
        .collect())
}

/// Absolute position error of `slam` (SLAM frame) carried by `est` into the
/// world, against the true camera centre at each timestamp, metres.
pub fn ape(slam: &Trajectory, est: &Sim3, path: &CameraPath) -> Result<ErrorStats> {
    let e: Vec<f64> = slam
        .timestamps
        .iter()
        .zip(&slam.positions)
        .map(|(&t, p)| (est.transform_point(p) - path.kinematics(t).0).norm())
        .collect();
    ErrorStats::from_values("trajectory poses", &e)
}

/// A whole score.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Evaluation {
    /// Distances of the converted points to the true surfaces, metres.
    pub cloud: ErrorStats,
    /// Error of the estimated `T_world_slam`.
    pub transform: TransformError,
    /// APE of the SLAM trajectory carried by the estimate, metres.
    pub ape: ErrorStats,
}

/// Scores world points (converted with `est`) and the trajectory `slam`
/// (SLAM frame) against the truth.
pub fn evaluate(
    truth: &Truth,
    points_world: &[f32],
    est: &Sim3,
    slam: &Trajectory,
) -> Result<Evaluation> {
    let d = point_distances(&truth.scene, points_world)?;
    Ok(Evaluation {
        cloud: ErrorStats::from_values("points", &d)?,
        transform: transform_error(est, &truth.t_world_slam),
        ape: ape(slam, est, &truth.path)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::UnitQuaternion;

    #[test]
    fn stats_by_hand() {
        let v: Vec<f64> = (1..=100).map(f64::from).collect();
        let s = ErrorStats::from_values("v", &v).unwrap();
        assert_eq!(s.median, 50.0);
        assert_eq!(s.p95, 95.0);
        assert_eq!(s.max, 100.0);
        assert!((s.mean - 50.5).abs() < 1e-12);
        assert!((s.rmse - (338350.0f64 / 100.0).sqrt()).abs() < 1e-9);
        assert!(ErrorStats::from_values("v", &[]).is_err());
        assert!(ErrorStats::from_values("v", &[f64::NAN]).is_err());
    }

    #[test]
    fn transform_errors() {
        let truth = Sim3::try_new(
            UnitQuaternion::from_euler_angles(0.3, 0.1, 1.0),
            Vector3::new(1.0, 2.0, 3.0),
            15.0,
        )
        .unwrap();
        let e = transform_error(&truth, &truth);
        assert_eq!(e.scale_error, 0.0);
        assert!(e.rotation_error_deg < 1e-6 && e.gravity_error_deg < 1e-6);
        // A yaw about world z changes the rotation but not the gravity direction.
        let yaw = Sim3::try_new(
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.1),
            Vector3::zeros(),
            1.01,
        )
        .unwrap();
        let e = transform_error(&(yaw * truth), &truth);
        assert!((e.rotation_error_deg - 0.1f64.to_degrees()).abs() < 1e-9);
        assert!(e.gravity_error_deg < 1e-6);
        assert!((e.scale_error - 0.01).abs() < 1e-12);
        let tilt = Sim3::try_new(
            UnitQuaternion::from_euler_angles(0.02, 0.0, 0.0),
            Vector3::zeros(),
            1.0,
        )
        .unwrap();
        let e = transform_error(&(tilt * truth), &truth);
        assert!((e.gravity_error_deg - 0.02f64.to_degrees()).abs() < 1e-9);
    }

    #[test]
    fn distances_of_known_points() {
        let scene = Scene::paper().unwrap();
        let d = point_distances(&scene, &[0.0, 0.0, 0.25, 4.0, -2.0, 0.0]).unwrap();
        assert!((d[0] - 0.25).abs() < 1e-6 && d[1] < 1e-6);
        assert!(point_distances(&scene, &[0.0, 1.0]).is_err());
    }
}
