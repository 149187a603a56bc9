//! A smooth analytic camera path around and among the cubes.
//!
//! The position is a closed-form curve in the loop angle `θ = ω·t + θ0`:
//! `x = (rx + a·sin 3θ)·cos θ`, `y = (ry + a·sin 3θ)·sin θ`,
//! `z = h0 + hz·sin(2θ + 0.5) + hs·sin(2π·t/T) + hb·sin(2π·f_b·t)` (the last
//! a walker's step bob at [`BOB_HZ`]), so that position, velocity and
//! acceleration are exact. The camera looks at a target point that circles the
//! scene centre on the far side of the loop, with a slow yaw wobble (turns).
//! `ω` is solved so that the path is `length` metres long over `[0, T]`.
//! Orientation is `R_world_cam` (camera x right, y down, z forward); its
//! angular rate is the central difference of the rotation (step 1e-4 s,
//! error O(h²) ≈ 1e-8 rad/s).

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

use crate::error::{Error, Result};

/// Position, derivatives and attitude of the camera at one time.
#[derive(Clone, Copy, Debug)]
pub struct PathState {
    /// Camera centre in the world, metres.
    pub position: Vector3<f64>,
    /// World-frame velocity, m/s.
    pub velocity: Vector3<f64>,
    /// World-frame acceleration (without gravity), m/s².
    pub acceleration: Vector3<f64>,
    /// `R_world_cam`.
    pub orientation: UnitQuaternion<f64>,
    /// Angular rate in the camera (body) frame, rad/s.
    pub angular_velocity: Vector3<f64>,
}

/// The camera path (world frame, metres, seconds).
#[derive(Clone, Debug)]
pub struct CameraPath {
    /// Duration `T`, seconds.
    pub duration: f64,
    /// Loop rate `ω`, rad/s (solved from the length).
    pub omega: f64,
    /// Semi-axes of the loop along x and y, metres.
    pub radii: [f64; 2],
    /// Amplitude of the in/out wobble (three per loop), metres.
    pub wobble: f64,
    /// Mean height, metres.
    pub height: f64,
    /// Height change per loop (amplitude), metres.
    pub height_loop: f64,
    /// Slow height change over the run (amplitude), metres.
    pub height_slow: f64,
    /// Step bob (amplitude), metres, at [`BOB_HZ`].
    pub height_bob: f64,
    /// Height of the point the camera looks at, metres.
    pub look_height: f64,
}

/// Step frequency of a walker's bob, Hz (two steps a second, a little under).
pub const BOB_HZ: f64 = 1.8;

/// The heights of a path (see [`CameraPath`]'s fields), metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathHeights {
    /// Mean camera height.
    pub height: f64,
    /// Change per loop (amplitude).
    pub per_loop: f64,
    /// Slow change over the run (amplitude).
    pub slow: f64,
    /// Step bob (amplitude).
    pub bob: f64,
    /// Height of the point looked at.
    pub look: f64,
}

impl Default for PathHeights {
    /// The paper's: 2 m ± 0.35 m per loop ± 0.25 m over the run, looking at 0.3 m.
    fn default() -> Self {
        PathHeights {
            height: 2.0,
            per_loop: 0.35,
            slow: 0.25,
            bob: 0.0,
            look: 0.3,
        }
    }
}

const THETA0: f64 = -std::f64::consts::FRAC_PI_2;
const ROT_STEP: f64 = 1e-4;

impl CameraPath {
    /// The paper's path: `duration` seconds long, `length` metres long.
    pub fn paper(duration: f64, length: f64) -> Result<Self> {
        Self::with_heights(duration, length, PathHeights::default())
    }

    /// The paper's loop at other heights (a ground vehicle: a constant
    /// height, looking ahead).
    pub fn with_heights(duration: f64, length: f64, heights: PathHeights) -> Result<Self> {
        if !(duration.is_finite() && duration > 0.0) {
            return Err(Error::invalid(
                "duration",
                format!("must be > 0 s, got {duration}"),
            ));
        }
        if !(length.is_finite() && length > 0.0) {
            return Err(Error::invalid(
                "path length",
                format!("must be > 0 m, got {length}"),
            ));
        }
        let mut path = CameraPath {
            duration,
            omega: 1.0,
            radii: [3.6, 1.5],
            wobble: 0.6,
            height: heights.height,
            height_loop: heights.per_loop,
            height_slow: heights.slow,
            height_bob: heights.bob,
            look_height: heights.look,
        };
        // The length grows with ω: bisect.
        let (mut lo, mut hi) = (1e-3, 50.0);
        path.omega = hi;
        if path.length(0.0, duration) < length {
            return Err(Error::invalid(
                "path length",
                format!("{length} m in {duration} s is faster than this path allows"),
            ));
        }
        for _ in 0..80 {
            let mid = 0.5 * (lo + hi);
            path.omega = mid;
            if path.length(0.0, duration) < length {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        path.omega = 0.5 * (lo + hi);
        Ok(path)
    }

    /// Path length between `t0` and `t1` (Simpson's rule on the exact speed), metres.
    pub fn length(&self, t0: f64, t1: f64) -> f64 {
        let n = 20_000usize;
        let h = (t1 - t0) / n as f64;
        let speed = |t: f64| self.kinematics(t).1.norm();
        let mut s = speed(t0) + speed(t1);
        for i in 1..n {
            let w = if i % 2 == 1 { 4.0 } else { 2.0 };
            s += w * speed(t0 + i as f64 * h);
        }
        s * h / 3.0
    }

    /// Position, velocity and acceleration at `t` (exact).
    pub fn kinematics(&self, t: f64) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
        let w = self.omega;
        let th = w * t + THETA0;
        let (s, c) = th.sin_cos();
        let (s3, c3) = (3.0 * th).sin_cos();
        let a = self.wobble;
        let r = a * s3;
        let r1 = 3.0 * a * c3;
        let r2 = -9.0 * a * s3;
        let (rx, ry) = (self.radii[0] + r, self.radii[1] + r);
        let x = rx * c;
        let y = ry * s;
        let dx = r1 * c - rx * s;
        let dy = r1 * s + ry * c;
        let ddx = r2 * c - 2.0 * r1 * s - rx * c;
        let ddy = r2 * s + 2.0 * r1 * c - ry * s;
        let ws = 2.0 * std::f64::consts::PI / self.duration;
        let phase = 2.0 * th + 0.5;
        let (sp, cp) = phase.sin_cos();
        let (ss, cs) = (ws * t).sin_cos();
        let wb = 2.0 * std::f64::consts::PI * BOB_HZ;
        let (sb, cb) = (wb * t).sin_cos();
        let hb = self.height_bob;
        let z = self.height + self.height_loop * sp + self.height_slow * ss + hb * sb;
        let dz = self.height_loop * 2.0 * w * cp + self.height_slow * ws * cs + hb * wb * cb;
        let ddz = -self.height_loop * 4.0 * w * w * sp
            - self.height_slow * ws * ws * ss
            - hb * wb * wb * sb;
        (
            Vector3::new(x, y, z),
            Vector3::new(w * dx, w * dy, dz),
            Vector3::new(w * w * ddx, w * w * ddy, ddz),
        )
    }

    /// The point the camera looks at, world frame, metres.
    pub fn target(&self, t: f64) -> Vector3<f64> {
        let th = self.omega * t + THETA0;
        let yaw = th + std::f64::consts::PI + 0.5 * (0.37 * th).sin() + 0.3 * (2.0 * th).sin();
        let (s, c) = yaw.sin_cos();
        Vector3::new(1.4 * c, 0.7 * s, self.look_height)
    }

    /// `R_world_cam` at `t`: z towards the target, x horizontal (right), y down.
    pub fn orientation(&self, t: f64) -> UnitQuaternion<f64> {
        let p = self.kinematics(t).0;
        let f = (self.target(t) - p).normalize();
        let right = f.cross(&Vector3::z()).normalize();
        let down = f.cross(&right);
        let m = Matrix3::from_columns(&[right, down, f]);
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m))
    }

    /// Angular rate in the camera frame at `t`, rad/s.
    pub fn angular_velocity(&self, t: f64) -> Vector3<f64> {
        let a = self.orientation(t - ROT_STEP);
        let b = self.orientation(t + ROT_STEP);
        (a.inverse() * b).scaled_axis() / (2.0 * ROT_STEP)
    }

    /// Everything at `t`.
    pub fn state(&self, t: f64) -> PathState {
        let (position, velocity, acceleration) = self.kinematics(t);
        PathState {
            position,
            velocity,
            acceleration,
            orientation: self.orientation(t),
            angular_velocity: self.angular_velocity(t),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn length_is_solved() {
        let p = CameraPath::paper(7000.0 / 60.0, 195.12).unwrap();
        let l = p.length(0.0, p.duration);
        assert!((l / 195.12 - 1.0).abs() < 1e-6, "length {l}");
        assert!(CameraPath::paper(1.0, 1e6).is_err());
        assert!(CameraPath::paper(-1.0, 10.0).is_err());
    }

    #[test]
    fn derivatives_match_finite_differences() {
        // The paper's heights with a walker's bob on top.
        let heights = PathHeights {
            bob: 0.03,
            ..PathHeights::default()
        };
        let p = CameraPath::with_heights(100.0, 150.0, heights).unwrap();
        let h = 1e-5;
        for &t in &[0.3, 17.0, 55.5, 99.0] {
            let (x0, v0, a0) = p.kinematics(t);
            let (xm, vm, _) = p.kinematics(t - h);
            let (xp, vp, _) = p.kinematics(t + h);
            assert!(((xp - xm) / (2.0 * h) - v0).norm() < 1e-6);
            assert!(((vp - vm) / (2.0 * h) - a0).norm() < 1e-5);
            assert!(x0.z > 1.2, "camera too low: {}", x0.z);
            // The angular rate integrates the attitude over a short step.
            let w = p.angular_velocity(t);
            let q1 = p.orientation(t) * UnitQuaternion::from_scaled_axis(w * 1e-3);
            assert!(q1.angle_to(&p.orientation(t + 1e-3)) < 1e-6);
            // The camera sees its target in front of it.
            let f = p.orientation(t) * Vector3::z();
            assert!(f.dot(&(p.target(t) - x0).normalize()) > 0.999_999);
        }
    }
}
