//! IMU preintegration between two keyframes (Forster, Carlone, Dellaert,
//! Scaramuzza: "On-Manifold Preintegration for Real-Time Visual-Inertial
//! Odometry", 2017), in the IMU (body) frame of the first keyframe.
//!
//! With `R_i, v_i, p_i` the IMU orientation, velocity and position at the
//! first keyframe (time `t_i`) and `g` gravity, all in one world frame:
//!
//! ```text
//! R_j = R_i · ΔR · Exp(J_R,g · δb_g)
//! v_j = v_i + g·Δt + R_i · (Δv + J_v,g · δb_g + J_v,a · δb_a)
//! p_j = p_i + v_i·Δt + ½·g·Δt² + R_i · (Δp + J_p,g · δb_g + J_p,a · δb_a)
//! ```
//!
//! Integration rule (midpoint): between two samples `h` seconds apart the
//! rotation advances by `Exp(h·(ω_k + ω_{k+1})/2 − h·b_g)`, and the
//! acceleration is the mean of the two bias-corrected accelerometer readings
//! rotated by the orientation at their own times. Samples at the keyframe
//! times are interpolated linearly between their neighbours. The Jacobians
//! w.r.t. the accelerometer bias are exact for this rule (the deltas are
//! linear in it); those w.r.t. the gyroscope bias are Forster's first-order
//! recursion.

use nalgebra::{Matrix3, UnitQuaternion, Vector3};

use super::ImuSamples;
use crate::error::{Error, Result};

/// Rotation, velocity and position deltas between two times, with their
/// Jacobians w.r.t. the biases, in the IMU frame at the first time.
#[derive(Clone, Debug, PartialEq)]
pub struct Preintegrated {
    /// Start time (IMU clock), seconds.
    pub t0: f64,
    /// End time (IMU clock), seconds.
    pub t1: f64,
    /// `ΔR = R_iᵀ·R_j` (the IMU orientation at `t1` seen from the one at `t0`).
    pub delta_r: UnitQuaternion<f64>,
    /// `Δv`, m/s, in the IMU frame at `t0` (gravity not included).
    pub delta_v: Vector3<f64>,
    /// `Δp`, metres, in the IMU frame at `t0` (gravity not included).
    pub delta_p: Vector3<f64>,
    /// `∂ Log(ΔR) / ∂ b_g` (right perturbation), s.
    pub dr_dbg: Matrix3<f64>,
    /// `∂ Δv / ∂ b_g`, m.
    pub dv_dbg: Matrix3<f64>,
    /// `∂ Δv / ∂ b_a`, s.
    pub dv_dba: Matrix3<f64>,
    /// `∂ Δp / ∂ b_g`, m·s.
    pub dp_dbg: Matrix3<f64>,
    /// `∂ Δp / ∂ b_a`, s².
    pub dp_dba: Matrix3<f64>,
    /// Gyroscope bias the deltas were integrated with, rad/s.
    pub gyro_bias: Vector3<f64>,
    /// Accelerometer bias the deltas were integrated with, m/s².
    pub accel_bias: Vector3<f64>,
    /// Number of integration steps.
    pub steps: usize,
}

/// Skew-symmetric matrix `[v]×` (`[v]× w = v × w`).
pub(crate) fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    v.cross_matrix()
}

/// Right Jacobian of SO(3) at the rotation vector `phi`.
pub(crate) fn right_jacobian(phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta2 = phi.norm_squared();
    let k = skew(phi);
    if theta2 < 1e-10 {
        return Matrix3::identity() - 0.5 * k + k * k / 6.0;
    }
    let theta = theta2.sqrt();
    Matrix3::identity() - (1.0 - theta.cos()) / theta2 * k
        + (theta - theta.sin()) / (theta2 * theta) * k * k
}

impl Preintegrated {
    /// Preintegrates the samples of `imu` over `[t0, t1]` (IMU clock, seconds)
    /// with the given biases (rad/s, m/s²).
    ///
    /// Errors: [`Error::InvalidArgument`] unless `t0 < t1` (both finite);
    /// [`Error::OutOfRange`] when the samples do not cover `[t0, t1]` or two
    /// consecutive samples inside it are more than `max_gap` seconds apart.
    pub fn integrate(
        imu: &ImuSamples,
        t0: f64,
        t1: f64,
        gyro_bias: &Vector3<f64>,
        accel_bias: &Vector3<f64>,
        max_gap: f64,
    ) -> Result<Preintegrated> {
        if !(t0.is_finite() && t1.is_finite() && t0 < t1) {
            return Err(Error::invalid(
                "preintegration interval",
                format!("need finite t0 < t1, got [{t0}, {t1}]"),
            ));
        }
        let ts = &imu.timestamps;
        let n = ts.len();
        let out_of_range = |reason: String| Error::OutOfRange {
            what: format!("IMU samples over [{t0:.6}, {t1:.6}] s"),
            reason,
        };
        if n < 2 || t0 < ts[0] || t1 > ts[n - 1] {
            return Err(out_of_range(match n {
                0 | 1 => format!("{n} samples"),
                _ => format!("the samples cover [{:.6}, {:.6}] s", ts[0], ts[n - 1]),
            }));
        }
        // First sample strictly after t0, last strictly before t1.
        let a = ts.partition_point(|&t| t <= t0);
        let b = ts.partition_point(|&t| t < t1);
        let at = |t: f64, k: usize| -> (Vector3<f64>, Vector3<f64>) {
            // Linear interpolation between samples k-1 and k (k ≥ 1, k < n).
            let (i, j) = (k.saturating_sub(1), k.min(n - 1));
            if i == j || ts[j] == ts[i] {
                return (imu.gyro[j], imu.accel[j]);
            }
            let w = (t - ts[i]) / (ts[j] - ts[i]);
            (
                imu.gyro[i].lerp(&imu.gyro[j], w),
                imu.accel[i].lerp(&imu.accel[j], w),
            )
        };
        let mut knots: Vec<(f64, Vector3<f64>, Vector3<f64>)> =
            Vec::with_capacity(b.saturating_sub(a) + 2);
        let (g0, a0) = at(t0, a);
        knots.push((t0, g0, a0));
        knots.extend((a..b).map(|k| (ts[k], imu.gyro[k], imu.accel[k])));
        let (g1, a1) = at(t1, b);
        knots.push((t1, g1, a1));

        let mut r = UnitQuaternion::identity();
        let mut rm = Matrix3::identity();
        let mut v = Vector3::zeros();
        let mut p = Vector3::zeros();
        let mut dr_dbg = Matrix3::zeros();
        let mut dv_dbg = Matrix3::zeros();
        let mut dv_dba = Matrix3::zeros();
        let mut dp_dbg = Matrix3::zeros();
        let mut dp_dba = Matrix3::zeros();
        for w in knots.windows(2) {
            let (ta, ga, aa) = w[0];
            let (tb, gb, ab) = w[1];
            let h = tb - ta;
            if h > max_gap {
                return Err(out_of_range(format!(
                    "a gap of {h:.4} s between samples at {ta:.6} and {tb:.6} s (max_gap {max_gap} s)"
                )));
            }
            if h <= 0.0 {
                continue;
            }
            let omega = 0.5 * (ga + gb) - gyro_bias;
            let phi = omega * h;
            let d = UnitQuaternion::from_scaled_axis(phi);
            let dm = d.to_rotation_matrix().into_inner();
            let r_next = r * d;
            let rm_next = r_next.to_rotation_matrix().into_inner();
            let fa = aa - accel_bias;
            let fb = ab - accel_bias;
            let acc = 0.5 * (rm * fa + rm_next * fb);
            let f_mean = 0.5 * (fa + fb);
            let r_sum = rm + rm_next;
            // Jacobians first (they use the state at the start of the step).
            let rot_term = rm * skew(&f_mean) * dr_dbg;
            dp_dba += dv_dba * h - 0.25 * r_sum * h * h;
            dv_dba -= 0.5 * r_sum * h;
            dp_dbg += dv_dbg * h - 0.5 * rot_term * h * h;
            dv_dbg -= rot_term * h;
            dr_dbg = dm.transpose() * dr_dbg - right_jacobian(&phi) * h;
            p += v * h + 0.5 * acc * h * h;
            v += acc * h;
            r = r_next;
            rm = rm_next;
        }
        Ok(Preintegrated {
            t0,
            t1,
            delta_r: r,
            delta_v: v,
            delta_p: p,
            dr_dbg,
            dv_dbg,
            dv_dba,
            dp_dbg,
            dp_dba,
            gyro_bias: *gyro_bias,
            accel_bias: *accel_bias,
            steps: knots.len() - 1,
        })
    }

    /// Duration `t1 − t0`, seconds.
    pub fn dt(&self) -> f64 {
        self.t1 - self.t0
    }

    /// `ΔR` corrected to the gyroscope bias `bg` to first order.
    pub fn delta_r_at(&self, bg: &Vector3<f64>) -> UnitQuaternion<f64> {
        self.delta_r * UnitQuaternion::from_scaled_axis(self.dr_dbg * (bg - self.gyro_bias))
    }

    /// `Δv` corrected to the biases `bg`, `ba` to first order (exact in `ba`).
    pub fn delta_v_at(&self, bg: &Vector3<f64>, ba: &Vector3<f64>) -> Vector3<f64> {
        self.delta_v + self.dv_dbg * (bg - self.gyro_bias) + self.dv_dba * (ba - self.accel_bias)
    }

    /// `Δp` corrected to the biases `bg`, `ba` to first order (exact in `ba`).
    pub fn delta_p_at(&self, bg: &Vector3<f64>, ba: &Vector3<f64>) -> Vector3<f64> {
        self.delta_p + self.dp_dbg * (bg - self.gyro_bias) + self.dp_dba * (ba - self.accel_bias)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type State = (UnitQuaternion<f64>, Vector3<f64>, Vector3<f64>);

    /// A body spinning about a tilted axis while moving on a curve; gravity
    /// `(0, 0, −9.81)`. Returns the samples and `t ↦ (R, p, v)`.
    fn analytic(rate: f64, t_end: f64) -> (ImuSamples, impl Fn(f64) -> State) {
        let w = Vector3::new(0.3, -0.2, 0.5); // constant body rate, rad/s
        let state = move |t: f64| {
            let r = UnitQuaternion::from_scaled_axis(w * t);
            let p = Vector3::new((0.7 * t).sin(), (0.5 * t).cos() - 1.0, 0.2 * t * t);
            let v = Vector3::new(0.7 * (0.7 * t).cos(), -0.5 * (0.5 * t).sin(), 0.4 * t);
            (r, p, v)
        };
        let acc = |t: f64| Vector3::new(-0.49 * (0.7 * t).sin(), -0.25 * (0.5 * t).cos(), 0.4);
        let g = Vector3::new(0.0, 0.0, -9.81);
        let n = (t_end * rate) as usize + 1;
        let times: Vec<f64> = (0..n).map(|k| k as f64 / rate).collect();
        let gyro = times.iter().map(|_| w).collect();
        let accel = times
            .iter()
            .map(|&t| state(t).0.inverse() * (acc(t) - g))
            .collect();
        (ImuSamples::try_new(times, gyro, accel).unwrap(), state)
    }

    #[test]
    fn deltas_match_the_analytic_motion() {
        let (imu, state) = analytic(400.0, 3.0);
        let (t0, t1) = (0.5123, 2.2);
        let pre = Preintegrated::integrate(&imu, t0, t1, &Vector3::zeros(), &Vector3::zeros(), 0.1)
            .unwrap();
        let (r0, p0, v0) = state(t0);
        let (r1, p1, v1) = state(t1);
        let g = Vector3::new(0.0, 0.0, -9.81);
        let dt = t1 - t0;
        assert!((r0 * pre.delta_r).angle_to(&r1) < 1e-9);
        let v_pred = v0 + g * dt + r0 * pre.delta_v;
        let p_pred = p0 + v0 * dt + 0.5 * g * dt * dt + r0 * pre.delta_p;
        assert!((v_pred - v1).norm() < 1e-4, "{}", (v_pred - v1).norm());
        assert!((p_pred - p1).norm() < 1e-4, "{}", (p_pred - p1).norm());
    }

    #[test]
    fn bias_jacobians_match_reintegration() {
        let (imu, _) = analytic(200.0, 3.0);
        let z = Vector3::zeros();
        let pre = Preintegrated::integrate(&imu, 0.2, 1.7, &z, &z, 0.1).unwrap();
        let bg = Vector3::new(2e-3, -1e-3, 3e-3);
        let ba = Vector3::new(0.05, -0.08, 0.02);
        let re = Preintegrated::integrate(&imu, 0.2, 1.7, &bg, &ba, 0.1).unwrap();
        assert!(pre.delta_r_at(&bg).angle_to(&re.delta_r) < 1e-6);
        // First order in bg: the correction removes nearly all of the change.
        let (ev, ev0) = (
            (pre.delta_v_at(&bg, &ba) - re.delta_v).norm(),
            (pre.delta_v_at(&z, &ba) - re.delta_v).norm(),
        );
        let (ep, ep0) = (
            (pre.delta_p_at(&bg, &ba) - re.delta_p).norm(),
            (pre.delta_p_at(&z, &ba) - re.delta_p).norm(),
        );
        assert!(ev < 0.02 * ev0, "Δv: {ev} after correction, {ev0} before");
        assert!(ep < 0.02 * ep0, "Δp: {ep} after correction, {ep0} before");
        // Exact in ba alone.
        let re_a = Preintegrated::integrate(&imu, 0.2, 1.7, &z, &ba, 0.1).unwrap();
        assert!((pre.delta_v_at(&z, &ba) - re_a.delta_v).norm() < 1e-12);
        assert!((pre.delta_p_at(&z, &ba) - re_a.delta_p).norm() < 1e-12);
    }

    #[test]
    fn coverage_and_gaps_are_refused() {
        let (imu, _) = analytic(100.0, 1.0);
        let z = Vector3::zeros();
        assert!(matches!(
            Preintegrated::integrate(&imu, 0.5, 1.5, &z, &z, 0.1),
            Err(Error::OutOfRange { .. })
        ));
        assert!(matches!(
            Preintegrated::integrate(&imu, 0.5, 0.5, &z, &z, 0.1),
            Err(Error::InvalidArgument { .. })
        ));
        assert!(matches!(
            Preintegrated::integrate(&imu, 0.1, 0.9, &z, &z, 0.005),
            Err(Error::OutOfRange { .. })
        ));
    }
}
