//! The reference pose source and a raw IMU on the camera (body = camera frame).
//!
//! Reference poses `T_world_body` at `rate` Hz: the true pose with white
//! position noise (metres) and white rotation noise (rotation vector, rad).
//! Raw samples at the same times: `gyro = ω_body + b_g + n_g`,
//! `accel = R_world_bodyᵀ·(a_world − g_world) + b_a + n_a` with `g_world =
//! (0, 0, −9.81)`. White noise has the discrete standard deviation
//! `density·√rate`; the biases follow a random walk with standard deviation
//! `random_walk·√dt` per sample (EuRoC / Kalibr convention).

use nalgebra::{UnitQuaternion, Vector3};

use super::path::CameraPath;
use super::scene::Scene;
use super::slam::{gauss3, stream};
use crate::error::Result;
use crate::imu::ImuSamples;
use crate::trajectory::Trajectory;

/// Noise of the reference poses and of the raw IMU.
#[derive(Clone, Copy, Debug)]
pub struct ImuNoise {
    /// Sample rate, Hz.
    pub rate: f64,
    /// Reference position noise, metres.
    pub pos_sigma: f64,
    /// Reference rotation noise, rad.
    pub rot_sigma: f64,
    /// Gyro white noise density, rad/s/√Hz.
    pub gyro_noise: f64,
    /// Gyro bias random walk, rad/s²/√Hz.
    pub gyro_walk: f64,
    /// Accelerometer white noise density, m/s²/√Hz.
    pub accel_noise: f64,
    /// Accelerometer bias random walk, m/s³/√Hz.
    pub accel_walk: f64,
    /// Gyro bias at the start, rad/s.
    pub gyro_bias: [f64; 3],
    /// Accelerometer bias at the start, m/s².
    pub accel_bias: [f64; 3],
}

/// Sample times `j / rate` from 0 until the first at or after `t_end`, seconds
/// (so that every camera frame lies between two samples).
pub fn sample_times(rate: f64, t_end: f64) -> Vec<f64> {
    let n = (t_end * rate - 1e-9).ceil().max(0.0) as usize + 1;
    (0..n).map(|j| j as f64 / rate).collect()
}

/// Reference poses and raw IMU samples over `[0, t_end]`.
pub fn simulate_imu(
    path: &CameraPath,
    t_end: f64,
    noise: &ImuNoise,
    seed: u64,
) -> Result<(Trajectory, ImuSamples)> {
    let times = sample_times(noise.rate, t_end);
    let mut pose_rng = stream(seed, 4);
    let mut imu_rng = stream(seed, 5);
    let dt = 1.0 / noise.rate;
    let mut bg = Vector3::from(noise.gyro_bias);
    let mut ba = Vector3::from(noise.accel_bias);
    let g = Scene::gravity();
    let mut positions = Vec::with_capacity(times.len());
    let mut orientations = Vec::with_capacity(times.len());
    let mut gyro = Vec::with_capacity(times.len());
    let mut accel = Vec::with_capacity(times.len());
    for &t in &times {
        let s = path.state(t);
        positions.push(s.position + gauss3(&mut pose_rng, noise.pos_sigma));
        orientations.push(
            s.orientation
                * UnitQuaternion::from_scaled_axis(gauss3(&mut pose_rng, noise.rot_sigma)),
        );
        let f = s.orientation.inverse() * (s.acceleration - g);
        gyro.push(
            s.angular_velocity + bg + gauss3(&mut imu_rng, noise.gyro_noise * noise.rate.sqrt()),
        );
        accel.push(f + ba + gauss3(&mut imu_rng, noise.accel_noise * noise.rate.sqrt()));
        bg += gauss3(&mut imu_rng, noise.gyro_walk * dt.sqrt());
        ba += gauss3(&mut imu_rng, noise.accel_walk * dt.sqrt());
    }
    let reference = Trajectory::try_new(times.clone(), positions, Some(orientations))?;
    let imu = ImuSamples::try_new(times, gyro, accel)?;
    Ok((reference, imu))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quiet() -> ImuNoise {
        ImuNoise {
            rate: 200.0,
            pos_sigma: 0.0,
            rot_sigma: 0.0,
            gyro_noise: 0.0,
            gyro_walk: 0.0,
            accel_noise: 0.0,
            accel_walk: 0.0,
            gyro_bias: [0.0; 3],
            accel_bias: [0.0; 3],
        }
    }

    #[test]
    fn noiseless_imu_integrates_to_the_path() {
        let path = CameraPath::paper(20.0, 30.0).unwrap();
        let (reference, imu) = simulate_imu(&path, 5.0, &quiet(), 0).unwrap();
        assert_eq!(imu.len(), 1001);
        // Strapdown integration (midpoint) over 2 s recovers the path.
        let s0 = path.state(1.0);
        let (mut p, mut v, mut q) = (s0.position, s0.velocity, s0.orientation);
        let g = Scene::gravity();
        let dt = 1.0 / 200.0;
        for j in 200..600 {
            let a0 = q * imu.accel[j] + g;
            let q1 =
                q * UnitQuaternion::from_scaled_axis(0.5 * (imu.gyro[j] + imu.gyro[j + 1]) * dt);
            let a1 = q1 * imu.accel[j + 1] + g;
            p += v * dt + 0.25 * (a0 + a1) * dt * dt;
            v += 0.5 * (a0 + a1) * dt;
            q = q1;
        }
        let s1 = path.state(3.0);
        assert!(
            (p - s1.position).norm() < 2e-3,
            "position drift {}",
            (p - s1.position).norm()
        );
        assert!(q.angle_to(&s1.orientation) < 1e-4);
        assert!((reference.positions[600] - s1.position).norm() < 1e-12);
    }

    #[test]
    fn white_noise_has_the_stated_level() {
        let path = CameraPath::paper(20.0, 30.0).unwrap();
        let mut n = quiet();
        n.gyro_noise = 1.6968e-4;
        let (_, noisy) = simulate_imu(&path, 10.0, &n, 3).unwrap();
        let (_, clean) = simulate_imu(&path, 10.0, &quiet(), 3).unwrap();
        let e: Vec<f64> = noisy
            .gyro
            .iter()
            .zip(&clean.gyro)
            .map(|(a, b)| (a - b).x)
            .collect();
        let sd = (e.iter().map(|v| v * v).sum::<f64>() / e.len() as f64).sqrt();
        let want = 1.6968e-4 * 200f64.sqrt();
        assert!((sd / want - 1.0).abs() < 0.1, "gyro noise {sd} vs {want}");
    }
}
