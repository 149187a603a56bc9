//! The paper's synthetic experiment, inside the crate: a known scene, a known
//! camera path, an IMU, and what LSD-SLAM would publish, with the true
//! `T_world_slam` to score a conversion against.
//!
//! One seed gives bit-identical output: every random stream is a ChaCha8
//! generator seeded from `(seed, stream id)`, and parallel work (one keyframe
//! per task) never shares a generator.

pub mod evaluate;
pub mod imu;
pub mod path;
pub mod render;
pub mod scenario;
pub mod scene;
pub mod slam;

use nalgebra::{UnitQuaternion, Vector3};
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::geometry::{PinholeCamera, Sim3};
use crate::imu::ImuSamples;
use crate::keyframe::Keyframe;
use crate::trajectory::Trajectory;

pub use evaluate::{evaluate, ErrorStats, Evaluation, TransformError};
pub use path::{CameraPath, PathHeights};
pub use scene::Scene;

fn paper_camera_height() -> f64 {
    path::PathHeights::default().height
}
fn paper_height_loop() -> f64 {
    path::PathHeights::default().per_loop
}
fn paper_height_slow() -> f64 {
    path::PathHeights::default().slow
}
fn paper_height_bob() -> f64 {
    path::PathHeights::default().bob
}
fn paper_look_height() -> f64 {
    path::PathHeights::default().look
}

/// Every size, stage boundary and noise level of a run. `Default` is the
/// paper's full size with realistic noise; [`SimConfig::noiseless`] switches
/// every error off.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
pub struct SimConfig {
    /// Seed of every random stream.
    pub seed: u64,
    /// Number of camera frames (paper: 7000).
    pub n_frames: usize,
    /// Camera frame rate, Hz (PS3 Eye: 60).
    pub fps: f64,
    /// Number of keyframes, evenly spread over the frames (paper: 123).
    pub n_keyframes: usize,
    /// Image width, pixels (640).
    pub width: u32,
    /// Image height, pixels (480).
    pub height: u32,
    /// Horizontal field of view, degrees (75).
    pub hfov_deg: f64,
    /// True path length over the run, metres (paper: 195.12).
    pub path_length: f64,
    /// SLAM path length, SLAM units (paper: 12.6); sets the true scale.
    pub slam_path_length: f64,
    /// Mean camera height above the floor, metres (paper: 2).
    #[serde(default = "paper_camera_height")]
    pub camera_height: f64,
    /// Camera height change per loop (amplitude), metres (paper: 0.35; a
    /// ground vehicle: 0).
    #[serde(default = "paper_height_loop")]
    pub height_loop: f64,
    /// Slow camera height change over the run (amplitude), metres (paper: 0.25).
    #[serde(default = "paper_height_slow")]
    pub height_slow: f64,
    /// Step bob of a hand-held camera (amplitude), metres, at
    /// [`path::BOB_HZ`] (paper and ground vehicle: 0; a walk: about 0.03).
    #[serde(default = "paper_height_bob")]
    pub height_bob: f64,
    /// Height of the point the camera looks at, metres (paper: 0.3).
    #[serde(default = "paper_look_height")]
    pub look_height: f64,
    /// Minimum image gradient of a pixel with depth, grey levels per pixel.
    pub min_gradient: f32,
    /// Relative inverse-depth noise `σ_rel` (see [`render`]).
    pub idepth_rel_sigma: f64,
    /// First frame of the converging stretch (paper: about 1100).
    pub converge_start: usize,
    /// First frame of the stable stage (paper: about 4300).
    pub stable_start: usize,
    /// Scale error level in the start stage (1 = none).
    pub init_scale: f64,
    /// Standard deviation of the slow wander of `ln λ` in the start stage.
    pub init_wander: f64,
    /// Probability per frame of a scale jump in the start stage.
    pub jump_prob: f64,
    /// Standard deviation of `ln` of a scale jump.
    pub jump_sigma: f64,
    /// Relative scale drift per second once stable (0 = none).
    pub scale_drift: f64,
    /// Tracking position noise, SLAM units.
    pub frame_pos_sigma: f64,
    /// Tracking rotation noise, rad.
    pub frame_rot_sigma: f64,
    /// Probability per stable frame of a tracking burst.
    pub burst_prob: f64,
    /// Standard deviation of a burst, SLAM units.
    pub burst_sigma: f64,
    /// Keyframe position noise, SLAM units.
    pub keyframe_pos_sigma: f64,
    /// Keyframe rotation noise, rad.
    pub keyframe_rot_sigma: f64,
    /// Reference / IMU rate, Hz (200).
    pub imu_rate: f64,
    /// Reference position noise, metres.
    pub reference_pos_sigma: f64,
    /// Reference rotation noise, rad.
    pub reference_rot_sigma: f64,
    /// Gyro white noise density, rad/s/√Hz (ADIS16448: 1.6968e-4).
    pub gyro_noise_density: f64,
    /// Gyro bias random walk, rad/s²/√Hz (1.9393e-5).
    pub gyro_random_walk: f64,
    /// Accelerometer white noise density, m/s²/√Hz (2.0e-3).
    pub accel_noise_density: f64,
    /// Accelerometer bias random walk, m/s³/√Hz (3.0e-3).
    pub accel_random_walk: f64,
    /// Gyro bias at the start, rad/s.
    pub gyro_bias: [f64; 3],
    /// Accelerometer bias at the start, m/s².
    pub accel_bias: [f64; 3],
}

impl Default for SimConfig {
    fn default() -> Self {
        SimConfig {
            seed: 0,
            n_frames: 7000,
            fps: 60.0,
            n_keyframes: 123,
            width: 640,
            height: 480,
            hfov_deg: 75.0,
            path_length: 195.12,
            slam_path_length: 12.6,
            camera_height: paper_camera_height(),
            height_loop: paper_height_loop(),
            height_slow: paper_height_slow(),
            height_bob: paper_height_bob(),
            look_height: paper_look_height(),
            min_gradient: 5.0,
            idepth_rel_sigma: 0.01,
            converge_start: 1100,
            stable_start: 4300,
            init_scale: 1.8,
            init_wander: 0.25,
            jump_prob: 0.03,
            jump_sigma: 0.8,
            scale_drift: 0.0,
            frame_pos_sigma: 1e-4,
            frame_rot_sigma: 5e-4,
            burst_prob: 2e-3,
            burst_sigma: 2e-3,
            keyframe_pos_sigma: 2e-4,
            keyframe_rot_sigma: 2e-4,
            imu_rate: 200.0,
            reference_pos_sigma: 1e-3,
            reference_rot_sigma: 1e-3,
            gyro_noise_density: 1.6968e-4,
            gyro_random_walk: 1.9393e-5,
            accel_noise_density: 2.0e-3,
            accel_random_walk: 3.0e-3,
            gyro_bias: [0.0; 3],
            accel_bias: [0.0; 3],
        }
    }
}

impl SimConfig {
    /// The camera path's heights.
    pub fn path_heights(&self) -> path::PathHeights {
        path::PathHeights {
            height: self.camera_height,
            per_loop: self.height_loop,
            slow: self.height_slow,
            bob: self.height_bob,
            look: self.look_height,
        }
    }

    /// The same run with every error off: no scale wander, no drift, no pose,
    /// depth, reference or IMU noise.
    pub fn noiseless(mut self) -> Self {
        self.idepth_rel_sigma = 0.0;
        self.converge_start = 0;
        self.stable_start = 0;
        self.init_scale = 1.0;
        self.init_wander = 0.0;
        self.jump_prob = 0.0;
        self.scale_drift = 0.0;
        self.frame_pos_sigma = 0.0;
        self.frame_rot_sigma = 0.0;
        self.burst_prob = 0.0;
        self.keyframe_pos_sigma = 0.0;
        self.keyframe_rot_sigma = 0.0;
        self.reference_pos_sigma = 0.0;
        self.reference_rot_sigma = 0.0;
        self.gyro_noise_density = 0.0;
        self.gyro_random_walk = 0.0;
        self.accel_noise_density = 0.0;
        self.accel_random_walk = 0.0;
        self.gyro_bias = [0.0; 3];
        self.accel_bias = [0.0; 3];
        self
    }

    /// A reduced run for tests: `1/scale` of the frames, keyframes, stage
    /// boundaries and path length (same speed), a `1/scale` image.
    pub fn reduced(mut self, scale: usize) -> Self {
        let k = scale.max(1);
        self.n_frames /= k;
        self.n_keyframes = (self.n_keyframes / k).max(3);
        self.converge_start /= k;
        self.stable_start /= k;
        self.path_length /= k as f64;
        self.slam_path_length /= k as f64;
        self.width = (self.width / k as u32).max(8);
        self.height = (self.height / k as u32).max(8);
        self
    }

    /// Sets one parameter by its field name (integers must be whole and ≥ 0;
    /// `gyro_bias` / `accel_bias` set all three axes). The CLI's `--set` and
    /// Python's `simulate(**params)` go through here.
    pub fn set(&mut self, name: &str, value: f64) -> Result<()> {
        let whole = |v: f64| -> Result<u64> {
            if v.is_finite() && v >= 0.0 && v.fract() == 0.0 && v < 1e15 {
                Ok(v as u64)
            } else {
                Err(Error::invalid(
                    name,
                    format!("must be a whole number ≥ 0, got {v}"),
                ))
            }
        };
        match name {
            "seed" => self.seed = whole(value)?,
            "n_frames" => self.n_frames = whole(value)? as usize,
            "n_keyframes" => self.n_keyframes = whole(value)? as usize,
            "width" => self.width = whole(value)?.min(u32::MAX as u64) as u32,
            "height" => self.height = whole(value)?.min(u32::MAX as u64) as u32,
            "converge_start" => self.converge_start = whole(value)? as usize,
            "stable_start" => self.stable_start = whole(value)? as usize,
            "fps" => self.fps = value,
            "hfov_deg" => self.hfov_deg = value,
            "path_length" => self.path_length = value,
            "slam_path_length" => self.slam_path_length = value,
            "camera_height" => self.camera_height = value,
            "height_loop" => self.height_loop = value,
            "height_slow" => self.height_slow = value,
            "height_bob" => self.height_bob = value,
            "look_height" => self.look_height = value,
            "min_gradient" => self.min_gradient = value as f32,
            "idepth_rel_sigma" => self.idepth_rel_sigma = value,
            "init_scale" => self.init_scale = value,
            "init_wander" => self.init_wander = value,
            "jump_prob" => self.jump_prob = value,
            "jump_sigma" => self.jump_sigma = value,
            "scale_drift" => self.scale_drift = value,
            "frame_pos_sigma" => self.frame_pos_sigma = value,
            "frame_rot_sigma" => self.frame_rot_sigma = value,
            "burst_prob" => self.burst_prob = value,
            "burst_sigma" => self.burst_sigma = value,
            "keyframe_pos_sigma" => self.keyframe_pos_sigma = value,
            "keyframe_rot_sigma" => self.keyframe_rot_sigma = value,
            "imu_rate" => self.imu_rate = value,
            "reference_pos_sigma" => self.reference_pos_sigma = value,
            "reference_rot_sigma" => self.reference_rot_sigma = value,
            "gyro_noise_density" => self.gyro_noise_density = value,
            "gyro_random_walk" => self.gyro_random_walk = value,
            "accel_noise_density" => self.accel_noise_density = value,
            "accel_random_walk" => self.accel_random_walk = value,
            "gyro_bias" => self.gyro_bias = [value; 3],
            "accel_bias" => self.accel_bias = [value; 3],
            _ => {
                return Err(Error::invalid(
                    "simulation parameter",
                    format!("unknown name {name:?} (see SimConfig's fields)"),
                ))
            }
        }
        Ok(())
    }

    /// Checks sizes, stage order and that every noise level is finite and ≥ 0.
    pub fn validate(&self) -> Result<()> {
        if self.n_frames < 10 {
            return Err(Error::TooFew {
                what: "n_frames".into(),
                need: 10,
                got: self.n_frames,
            });
        }
        // Upper bounds keep a typo from asking for terabytes.
        let pixels = self.width as u64 * self.height as u64;
        let samples = self.n_frames as f64 / self.fps * self.imu_rate;
        if self.n_frames > 10_000_000 || pixels > 4096 * 4096 || self.n_keyframes > 100_000 {
            return Err(Error::invalid(
                "size",
                format!(
                    "at most 1e7 frames, 4096x4096 pixels and 1e5 keyframes, got {} frames, {}x{}, {} keyframes",
                    self.n_frames, self.width, self.height, self.n_keyframes
                ),
            ));
        }
        if samples.is_finite() && samples > 1e8 {
            return Err(Error::invalid(
                "imu_rate",
                format!("{samples:.3e} samples is too many (at most 1e8)"),
            ));
        }
        if self.n_keyframes < 1 || self.n_keyframes > self.n_frames {
            return Err(Error::invalid(
                "n_keyframes",
                format!("must be in 1..={}, got {}", self.n_frames, self.n_keyframes),
            ));
        }
        if !(self.converge_start <= self.stable_start && self.stable_start < self.n_frames) {
            return Err(Error::invalid(
                "stages",
                format!(
                    "need converge_start ≤ stable_start < n_frames, got {} ≤ {} < {}",
                    self.converge_start, self.stable_start, self.n_frames
                ),
            ));
        }
        for (name, v) in [
            ("fps", self.fps),
            ("imu_rate", self.imu_rate),
            ("path_length", self.path_length),
            ("slam_path_length", self.slam_path_length),
            ("init_scale", self.init_scale),
            ("camera_height", self.camera_height),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::invalid(
                    name,
                    format!("must be finite and > 0, got {v}"),
                ));
            }
        }
        for (name, v) in [
            ("min_gradient", self.min_gradient as f64),
            ("idepth_rel_sigma", self.idepth_rel_sigma),
            ("init_wander", self.init_wander),
            ("jump_prob", self.jump_prob),
            ("jump_sigma", self.jump_sigma),
            ("frame_pos_sigma", self.frame_pos_sigma),
            ("frame_rot_sigma", self.frame_rot_sigma),
            ("burst_prob", self.burst_prob),
            ("burst_sigma", self.burst_sigma),
            ("keyframe_pos_sigma", self.keyframe_pos_sigma),
            ("keyframe_rot_sigma", self.keyframe_rot_sigma),
            ("reference_pos_sigma", self.reference_pos_sigma),
            ("reference_rot_sigma", self.reference_rot_sigma),
            ("gyro_noise_density", self.gyro_noise_density),
            ("gyro_random_walk", self.gyro_random_walk),
            ("accel_noise_density", self.accel_noise_density),
            ("accel_random_walk", self.accel_random_walk),
            ("height_loop", self.height_loop),
            ("height_slow", self.height_slow),
            ("height_bob", self.height_bob),
            ("look_height", self.look_height),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::invalid(
                    name,
                    format!("must be finite and ≥ 0, got {v}"),
                ));
            }
        }
        if self.height_loop + self.height_slow + self.height_bob >= self.camera_height {
            return Err(Error::invalid(
                "camera_height",
                format!(
                    "the camera would reach the floor: {} m less {} + {} + {} m of height change",
                    self.camera_height, self.height_loop, self.height_slow, self.height_bob
                ),
            ));
        }
        if !self.scale_drift.is_finite() {
            return Err(Error::invalid("scale_drift", "must be finite"));
        }
        if self.jump_prob > 1.0 || self.burst_prob > 1.0 {
            return Err(Error::invalid(
                "jump_prob / burst_prob",
                "probabilities must be ≤ 1",
            ));
        }
        if self.idepth_rel_sigma >= 0.5 {
            return Err(Error::invalid("idepth_rel_sigma", "must be < 0.5"));
        }
        if self
            .gyro_bias
            .iter()
            .chain(&self.accel_bias)
            .any(|v| !v.is_finite())
        {
            return Err(Error::invalid("gyro_bias / accel_bias", "must be finite"));
        }
        Ok(())
    }

    /// Frame times `k / fps`, seconds.
    pub fn frame_times(&self) -> Vec<f64> {
        (0..self.n_frames).map(|k| k as f64 / self.fps).collect()
    }

    /// Frame indices of the keyframes: `⌊j·n_frames / n_keyframes⌋`.
    pub fn keyframe_frames(&self) -> Vec<usize> {
        (0..self.n_keyframes)
            .map(|j| j * self.n_frames / self.n_keyframes)
            .collect()
    }
}

/// What only the simulator knows.
#[derive(Clone, Debug)]
pub struct Truth {
    /// The true `T_world_slam` (maps SLAM units into world metres).
    pub t_world_slam: Sim3,
    /// The scene (world frame).
    pub scene: Scene,
    /// The camera path (world frame).
    pub path: CameraPath,
    /// True `T_world_cam` at every frame time.
    pub camera: Trajectory,
    /// Scale error `λ_k` of every frame-to-frame step of the tracking (`n_frames − 1`).
    pub scale_errors: Vec<f64>,
    /// Frame index of each keyframe.
    pub keyframe_frames: Vec<usize>,
}

/// One simulated run.
#[derive(Clone, Debug)]
pub struct Simulation {
    /// The configuration it was made with.
    pub config: SimConfig,
    /// The camera (PS3 Eye by default).
    pub camera: PinholeCamera,
    /// Keyframes as LSD-SLAM's final map publishes them (`pose` = `T_slam_cam`,
    /// normalised inverse depth, variance, grey colour); id = frame index.
    pub keyframes: Vec<Keyframe>,
    /// Tracked `T_slam_cam` of every frame (60 Hz), with the start-up scale error.
    pub slam_frames: Trajectory,
    /// Reference `T_world_body` (body = camera) at `imu_rate`, with noise.
    pub reference: Trajectory,
    /// Raw gyro and accelerometer samples at the reference times.
    pub imu: ImuSamples,
    /// The answer.
    pub truth: Truth,
}

/// Runs the whole simulation (keyframes rendered in parallel).
pub fn simulate(cfg: &SimConfig) -> Result<Simulation> {
    cfg.validate()?;
    let camera = PinholeCamera::from_hfov(cfg.width, cfg.height, cfg.hfov_deg)?;
    let scene = Scene::paper()?;
    let duration = cfg.n_frames as f64 / cfg.fps;
    let path = CameraPath::with_heights(duration, cfg.path_length, cfg.path_heights())?;
    let times = cfg.frame_times();
    let states: Vec<_> = times.par_iter().map(|&t| path.state(t)).collect();
    let world_pos: Vec<Vector3<f64>> = states.iter().map(|s| s.position).collect();
    let world_rot: Vec<UnitQuaternion<f64>> = states.iter().map(|s| s.orientation).collect();

    let model = slam::ScaleModel {
        converge_start: cfg.converge_start,
        stable_start: cfg.stable_start,
        init_scale: cfg.init_scale,
        init_wander: cfg.init_wander,
        jump_prob: cfg.jump_prob,
        jump_sigma: cfg.jump_sigma,
        drift: cfg.scale_drift,
    };
    let lambda = slam::scale_errors(
        &model,
        cfg.n_frames,
        cfg.fps,
        &mut slam::stream(cfg.seed, 1),
    );
    let noise = slam::TrackingNoise {
        pos_sigma: cfg.frame_pos_sigma,
        rot_sigma: cfg.frame_rot_sigma,
        burst_prob: cfg.burst_prob,
        burst_sigma: cfg.burst_sigma,
    };
    let tracking = slam::track(
        &world_pos,
        &world_rot,
        &lambda,
        cfg.stable_start,
        cfg.slam_path_length,
        &noise,
        &mut slam::stream(cfg.seed, 2),
    )?;
    let t_world_slam = tracking.t_world_slam;
    let t_slam_world = t_world_slam.inverse();

    let kf_frames = cfg.keyframe_frames();
    let mut kf_rng = slam::stream(cfg.seed, 3);
    // Keyframe poses (before the depth scale): drawn in order, so one seed gives one answer.
    let kf_poses: Vec<(Vector3<f64>, UnitQuaternion<f64>, f64)> = kf_frames
        .iter()
        .map(|&k| {
            let (pos, lam) = if k >= cfg.stable_start {
                let lam = 1.0 + cfg.scale_drift * (k - cfg.stable_start) as f64 / cfg.fps;
                (tracking.clean_positions[k], lam)
            } else {
                (t_slam_world.transform_point(&world_pos[k]), 1.0)
            };
            let p = pos + slam::gauss3(&mut kf_rng, cfg.keyframe_pos_sigma);
            let dq =
                UnitQuaternion::from_scaled_axis(slam::gauss3(&mut kf_rng, cfg.keyframe_rot_sigma));
            (p, t_slam_world.rotation * world_rot[k] * dq, lam)
        })
        .collect();
    let (w, h) = (cfg.width as usize, cfg.height as usize);
    let keyframes: Vec<Keyframe> = kf_frames
        .par_iter()
        .zip(kf_poses.par_iter())
        .enumerate()
        .map(|(j, (&k, (p, q, lam)))| {
            // Rendering is the long part: a Ctrl-C stops it (crate::interrupt).
            crate::interrupt::check()?;
            let view = render::render(&scene, &camera, &world_rot[k], &world_pos[k]);
            let dm = render::depth_map(
                &view,
                w,
                h,
                cfg.min_gradient,
                cfg.idepth_rel_sigma,
                slam::mix(cfg.seed, 1000 + j as u64),
            );
            let (mut idepth, mut var) = (dm.idepth, dm.idepth_var);
            // Metric inverse depth in, mean-1 inverse depth out; the factor is 1/mean (metres).
            let k_metric = slam::normalise(&mut idepth, &mut var)?;
            // SLAM units: depth_slam = λ·depth_world / s.
            let sigma = k_metric * lam / t_world_slam.scale;
            let pose = Sim3::try_new(*q, *p, sigma)?;
            let color: Vec<u8> = view.intensity.iter().flat_map(|&g| [g, g, g]).collect();
            Keyframe::try_new(
                k as i32,
                times[k],
                pose,
                camera,
                idepth,
                Some(var),
                Some(color),
            )
        })
        .collect::<Result<_>>()?;

    let slam_frames = Trajectory::try_new(
        times.clone(),
        tracking.positions,
        Some(tracking.orientations),
    )?;
    let imu_noise = imu::ImuNoise {
        rate: cfg.imu_rate,
        pos_sigma: cfg.reference_pos_sigma,
        rot_sigma: cfg.reference_rot_sigma,
        gyro_noise: cfg.gyro_noise_density,
        gyro_walk: cfg.gyro_random_walk,
        accel_noise: cfg.accel_noise_density,
        accel_walk: cfg.accel_random_walk,
        gyro_bias: cfg.gyro_bias,
        accel_bias: cfg.accel_bias,
    };
    let t_end = times.last().copied().unwrap_or(0.0);
    let (reference, imu) = imu::simulate_imu(&path, t_end, &imu_noise, cfg.seed)?;
    let camera_truth = Trajectory::try_new(times, world_pos, Some(world_rot))?;
    Ok(Simulation {
        config: cfg.clone(),
        camera,
        keyframes,
        slam_frames,
        reference,
        imu,
        truth: Truth {
            t_world_slam,
            scene,
            path,
            camera: camera_truth,
            scale_errors: lambda,
            keyframe_frames: kf_frames,
        },
    })
}

impl Simulation {
    /// Each keyframe's pose as LSD-SLAM first publishes it: the tracked pose
    /// of its frame (with the start-up scale error of the tracking) and the
    /// keyframe's depth scale; the keyframes' own poses are the refined ones.
    pub fn first_published_poses(&self) -> Result<Vec<Sim3>> {
        let f = &self.slam_frames;
        self.keyframes
            .iter()
            .zip(&self.truth.keyframe_frames)
            .map(|(kf, &k)| {
                let q = f.orientations.as_ref().map_or(kf.pose.rotation, |o| o[k]);
                Sim3::try_new(q, f.positions[k], kf.pose.scale)
            })
            .collect()
    }

    /// Keyframe positions as a trajectory (`T_slam_cam` translations and rotations).
    pub fn keyframe_trajectory(&self) -> Result<Trajectory> {
        Trajectory::try_new(
            self.keyframes.iter().map(|k| k.timestamp).collect(),
            self.keyframes.iter().map(|k| k.pose.translation).collect(),
            Some(self.keyframes.iter().map(|k| k.pose.rotation).collect()),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn config_checks() {
        assert!(SimConfig::default().validate().is_ok());
        let bad = SimConfig {
            stable_start: 100,
            converge_start: 200,
            ..SimConfig::default()
        };
        assert!(bad.validate().is_err());
        let bad = SimConfig {
            frame_pos_sigma: -1.0,
            ..SimConfig::default()
        };
        assert!(bad.validate().is_err());
        let bad = SimConfig {
            camera_height: 0.5,
            ..SimConfig::default()
        };
        let e = bad.validate().unwrap_err().to_string();
        assert!(e.contains("reach the floor"), "{e}");
        // A truth sidecar written before the path's heights were knobs reads
        // with the paper's.
        let mut old = serde_json::to_value(SimConfig::default()).unwrap();
        for k in [
            "camera_height",
            "height_loop",
            "height_slow",
            "height_bob",
            "look_height",
        ] {
            old.as_object_mut().unwrap().remove(k);
        }
        let back: SimConfig = serde_json::from_value(old).unwrap();
        assert_eq!(back, SimConfig::default());
        let kf = SimConfig::default().keyframe_frames();
        assert_eq!(kf.len(), 123);
        assert_eq!(kf[0], 0);
        assert!(*kf.last().unwrap() < 7000);
    }
}
