//! Inertial initialisation: synthetic motion with known derivatives, the EuRoC
//! IMU reader, degenerate motion, and the real EuRoC V1_02 data (skipped when
//! ../shared/data is absent).

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use nalgebra::{UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use slam2world::imu::{imu_initialize, ImuInitOptions};
use slam2world::io::text::{read_euroc, read_euroc_imu, read_tum};
use slam2world::{Error, ImuSamples, Sim3, Trajectory};

const G: f64 = 9.81;

/// A smooth 3-D motion (metres, seconds) with known derivatives; `excite`
/// scales the acceleration (0: constant velocity), `translate` = false keeps
/// the body in place (pure rotation).
#[derive(Clone, Copy)]
struct Motion {
    excite: f64,
    translate: bool,
}

impl Motion {
    fn position(&self, t: f64) -> Vector3<f64> {
        if !self.translate {
            return Vector3::new(0.5, -0.2, 1.0);
        }
        let e = self.excite;
        Vector3::new(
            0.3 * t + e * 1.2 * (0.9 * t).sin(),
            -0.1 * t + e * 0.8 * (1.3 * t + 0.4).sin(),
            e * 0.4 * (0.7 * t + 1.0).sin(),
        )
    }
    fn acceleration(&self, t: f64) -> Vector3<f64> {
        if !self.translate {
            return Vector3::zeros();
        }
        let e = self.excite;
        Vector3::new(
            -e * 1.2 * 0.81 * (0.9 * t).sin(),
            -e * 0.8 * 1.69 * (1.3 * t + 0.4).sin(),
            -e * 0.4 * 0.49 * (0.7 * t + 1.0).sin(),
        )
    }
    /// `R_world_body`.
    fn orientation(&self, t: f64) -> UnitQuaternion<f64> {
        UnitQuaternion::from_scaled_axis(Vector3::new(
            0.3 * (0.5 * t).sin(),
            0.25 * (0.8 * t + 1.0).sin(),
            0.6 * (0.3 * t).sin() + 0.2,
        ))
    }
    /// Body angular rate (central difference of the orientation, O(h²)).
    fn angular_velocity(&self, t: f64) -> Vector3<f64> {
        let h = 1e-4;
        (self.orientation(t - h).inverse() * self.orientation(t + h)).scaled_axis() / (2.0 * h)
    }
}

struct Noise {
    gyro: f64,
    gyro_walk: f64,
    accel: f64,
    accel_walk: f64,
    keyframe_pos: f64,
    keyframe_rot: f64,
}

const QUIET: Noise = Noise {
    gyro: 0.0,
    gyro_walk: 0.0,
    accel: 0.0,
    accel_walk: 0.0,
    keyframe_pos: 0.0,
    keyframe_rot: 0.0,
};

/// EuRoC ADIS16448 densities; keyframe noise of a good SLAM system.
const EUROC: Noise = Noise {
    gyro: 1.6968e-4,
    gyro_walk: 1.9393e-5,
    accel: 2.0e-3,
    accel_walk: 3.0e-3,
    keyframe_pos: 0.005,
    keyframe_rot: 1e-3,
};

struct Scenario {
    imu: ImuSamples,
    keyframes: Trajectory,
    /// `T_world_slam` used to make the keyframes.
    truth: Sim3,
    imu_from_cam: Sim3,
}

fn gauss(rng: &mut ChaCha8Rng, sigma: f64) -> Vector3<f64> {
    if sigma == 0.0 {
        return Vector3::zeros();
    }
    let n = Normal::new(0.0, sigma).unwrap();
    Vector3::new(n.sample(rng), n.sample(rng), n.sample(rng))
}

fn scenario(motion: Motion, duration: f64, noise: &Noise, seed: u64) -> Scenario {
    // Camera rotated and offset from the IMU (EuRoC-like lever arm).
    let imu_from_cam = Sim3::try_new(
        UnitQuaternion::from_scaled_axis(Vector3::new(0.02, -0.03, PI / 2.0)),
        Vector3::new(-0.02, -0.065, 0.01),
        1.0,
    )
    .unwrap();
    scenario_with(motion, duration, noise, seed, imu_from_cam)
}

fn scenario_with(
    motion: Motion,
    duration: f64,
    noise: &Noise,
    seed: u64,
    imu_from_cam: Sim3,
) -> Scenario {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let rate = 200.0;
    let dt = 1.0 / rate;
    let g = Vector3::new(0.0, 0.0, -G);
    let mut bg = Vector3::new(0.004, -0.006, 0.003);
    let mut ba = Vector3::new(0.05, -0.08, 0.06);
    let (mut ts, mut gyro, mut accel) = (Vec::new(), Vec::new(), Vec::new());
    let t0 = 100.0;
    let n = (duration * rate) as usize + 41;
    for j in 0..n {
        let t = j as f64 * dt - 0.1;
        let r = motion.orientation(t);
        ts.push(t0 + t);
        gyro.push(motion.angular_velocity(t) + bg + gauss(&mut rng, noise.gyro * rate.sqrt()));
        accel.push(
            r.inverse() * (motion.acceleration(t) - g)
                + ba
                + gauss(&mut rng, noise.accel * rate.sqrt()),
        );
        bg += gauss(&mut rng, noise.gyro_walk * dt.sqrt());
        ba += gauss(&mut rng, noise.accel_walk * dt.sqrt());
    }
    let imu = ImuSamples::try_new(ts, gyro, accel).unwrap();
    let truth = Sim3::try_new(
        UnitQuaternion::from_scaled_axis(Vector3::new(0.7, -1.1, 0.4)),
        Vector3::new(2.0, -1.0, 0.5),
        3.7,
    )
    .unwrap();
    let slam_from_world = truth.inverse();
    let (mut kt, mut kp, mut ko) = (Vec::new(), Vec::new(), Vec::new());
    let kf_rate = 10.0;
    let nk = (duration * kf_rate) as usize + 1;
    for k in 0..nk {
        let t = k as f64 / kf_rate;
        let t_world_imu = Sim3::try_new(motion.orientation(t), motion.position(t), 1.0).unwrap();
        let t_world_cam = t_world_imu * imu_from_cam;
        let t_slam_cam = slam_from_world * t_world_cam;
        kt.push(t0 + t);
        kp.push(t_slam_cam.translation + gauss(&mut rng, noise.keyframe_pos / truth.scale));
        ko.push(
            t_slam_cam.rotation
                * UnitQuaternion::from_scaled_axis(gauss(&mut rng, noise.keyframe_rot)),
        );
    }
    Scenario {
        imu,
        keyframes: Trajectory::try_new(kt, kp, Some(ko)).unwrap(),
        truth,
        imu_from_cam,
    }
}

fn options(s: &Scenario) -> ImuInitOptions {
    ImuInitOptions {
        imu_from_cam: s.imu_from_cam,
        ..ImuInitOptions::default()
    }
}

/// Angle between the estimated and the true gravity direction, degrees.
fn gravity_error_deg(s: &Scenario, gravity_slam: &Vector3<f64>) -> f64 {
    let true_dir = s.truth.rotation.inverse() * Vector3::new(0.0, 0.0, -1.0);
    gravity_slam
        .normalize()
        .dot(&true_dir)
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

#[test]
fn noiseless_motion_gives_scale_gravity_and_biases() {
    let s = scenario(
        Motion {
            excite: 1.0,
            translate: true,
        },
        10.0,
        &QUIET,
        1,
    );
    let mut o = options(&s);
    o.keyframe_position_sigma = 1e-4;
    o.keyframe_rotation_sigma = 1e-5;
    let a = imu_initialize(&s.keyframes, &s.imu, &o).unwrap();
    let scale_err = (a.scale / s.truth.scale - 1.0).abs();
    assert!(scale_err < 1e-3, "scale {} vs {}", a.scale, s.truth.scale);
    assert!(gravity_error_deg(&s, &a.gravity_slam) < 0.02);
    assert!(
        (a.gyro_bias - Vector3::new(0.004, -0.006, 0.003)).norm() < 2e-4,
        "{}",
        a.gyro_bias
    );
    assert!(
        (a.accel_bias - Vector3::new(0.05, -0.08, 0.06)).norm() < 0.02,
        "{}",
        a.accel_bias
    );
    assert!((a.gravity_slam.norm() - G).abs() < 1e-9);
    // World z against gravity; the first keyframe's IMU at the origin.
    let g_world = a.transform.rotation * a.gravity_slam;
    assert!((g_world - Vector3::new(0.0, 0.0, -G)).norm() < 1e-9);
    let p_ci = s.imu_from_cam.inverse().translation;
    let r0 = s.keyframes.orientations.as_ref().unwrap()[0];
    let imu0_slam = s.keyframes.positions[0] + r0 * p_ci / a.scale;
    assert!(a.transform.transform_point(&imu0_slam).norm() < 1e-9);
    // The world frame equals the true one up to a yaw and a shift: true and
    // estimated world positions of the keyframes differ by a z rotation.
    let rel = a.transform.rotation * s.truth.rotation.inverse();
    let axis = rel
        .axis()
        .map(|u| u.into_inner())
        .unwrap_or_else(Vector3::z);
    assert!(
        rel.angle() < 1e-6 || axis.z.abs() > 1.0 - 1e-6,
        "relative rotation not a yaw: {rel}"
    );
}

/// Scale error (relative) and gravity error (degrees) of one noisy run.
fn noisy_run(duration: f64, seed: u64) -> (f64, f64) {
    let s = scenario(
        Motion {
            excite: 1.0,
            translate: true,
        },
        duration,
        &EUROC,
        seed,
    );
    let mut o = options(&s);
    o.keyframe_position_sigma = EUROC.keyframe_pos;
    o.keyframe_rotation_sigma = EUROC.keyframe_rot;
    let a = imu_initialize(&s.keyframes, &s.imu, &o).unwrap();
    (
        (a.scale / s.truth.scale - 1.0).abs(),
        gravity_error_deg(&s, &a.gravity_slam),
    )
}

#[test]
fn euroc_grade_noise_ten_seconds() {
    for seed in 0..5 {
        let (es, eg) = noisy_run(10.0, seed);
        assert!(es < 0.01, "seed {seed}: scale error {es}");
        assert!(eg < 0.5, "seed {seed}: gravity error {eg}°");
    }
}

#[test]
#[ignore = "slow: make test runs it"]
fn longer_windows_do_better() {
    let mut curve = Vec::new();
    for w in [5.0, 10.0, 20.0, 40.0] {
        let runs: Vec<(f64, f64)> = (0..6).map(|seed| noisy_run(w, 100 + seed)).collect();
        let rms = |f: fn(&(f64, f64)) -> f64| {
            (runs.iter().map(|r| f(r).powi(2)).sum::<f64>() / runs.len() as f64).sqrt()
        };
        let (es, eg) = (rms(|r| r.0), rms(|r| r.1));
        eprintln!(
            "window {w:>4} s: scale error rms {:.4} %, gravity error rms {eg:.4}°",
            es * 100.0
        );
        curve.push((es, eg));
    }
    assert!(curve[3].0 < curve[0].0, "scale: {curve:?}");
    assert!(curve[3].1 < curve[0].1, "gravity: {curve:?}");
}

fn shared_data(folder: &str, file: &str) -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data")
        .join(folder)
        .join(file);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("skipped: {} is absent", p.display());
        None
    }
}

/// The V1_02 estimate (body poses, nearly metric) carried by a known Sim(3)
/// into an arbitrary SLAM frame and scale, cut to `[t0 + start, t0 + start + window]`.
fn v102_keyframes(est: &Trajectory, start: f64, window: f64) -> (Trajectory, Sim3) {
    let slam_from_est = Sim3::try_new(
        UnitQuaternion::from_scaled_axis(Vector3::new(1.2, 0.3, -2.0)),
        Vector3::new(4.0, -3.0, 7.0),
        0.2731,
    )
    .unwrap();
    let t0 = est.timestamps[0] + start;
    let keep: Vec<usize> = (0..est.len())
        .filter(|&i| est.timestamps[i] >= t0 && est.timestamps[i] <= t0 + window)
        .collect();
    let o = est.orientations.as_ref().unwrap();
    let cut = Trajectory::try_new(
        keep.iter().map(|&i| est.timestamps[i]).collect(),
        keep.iter().map(|&i| est.positions[i]).collect(),
        Some(keep.iter().map(|&i| o[i]).collect()),
    )
    .unwrap();
    (cut.transformed(&slam_from_est), slam_from_est)
}

#[test]
#[ignore = "slow: make test runs it"]
fn euroc_v102_scale_and_gravity_agree_with_the_pose_fit() {
    let (Some(imu_path), Some(est_path), Some(gt_path)) = (
        shared_data("euroc_v102_imu", "V102.txt"),
        shared_data("euroc_v102", "V102.txt"),
        shared_data("euroc_v102", "V102_groundtruth.csv"),
    ) else {
        return;
    };
    let imu = read_euroc_imu(&imu_path).unwrap();
    let est = read_tum(&est_path).unwrap();
    let gt = read_euroc(&gt_path).unwrap();
    // The estimate's first 10 s are SLAM's own start-up (the pose-based fit
    // over 0–10 s leaves 4× the variance factor): windows start after it.
    for (start, window) in [(10.0, 70.0), (20.0, 60.0), (10.0, 20.0)] {
        let (kf, _) = v102_keyframes(&est, start, window);
        let fit =
            slam2world::align::trajectories::align_trajectories(&kf, &gt, &Default::default())
                .unwrap();
        let horn = fit.alignment.transform;
        let g_ref = horn.rotation.inverse() * Vector3::new(0.0, 0.0, -1.0);
        let a = imu_initialize(&kf, &imu, &ImuInitOptions::default()).unwrap();
        let scale_diff = a.scale / horn.scale - 1.0;
        let eg = a
            .gravity_slam
            .normalize()
            .dot(&g_ref)
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees();
        eprintln!(
            "V1_02 keyframes {start}–{} s: IMU scale {:.5} ± {:.5}, Horn {:.5} ({:+.3} %), gravity {eg:.3}° (σ {:.3}°)",
            start + window,
            a.scale,
            a.scale_sigma,
            horn.scale,
            scale_diff * 100.0,
            a.gravity_sigma.to_degrees()
        );
        assert!(
            scale_diff.abs() < 0.02,
            "window {start}+{window}: scale {scale_diff}"
        );
        assert!(eg < 1.0, "window {start}+{window}: gravity {eg}°");
        // EuRoC's own bias estimates (ground truth columns 11–16) near the start.
        let gt_bg = Vector3::new(-0.002153, 0.020744, 0.075806);
        assert!(
            (a.gyro_bias - gt_bg).norm() < 5e-3,
            "gyro bias {}",
            a.gyro_bias
        );
    }
}

#[test]
fn constant_velocity_is_unobservable() {
    let s = scenario(
        Motion {
            excite: 0.0,
            translate: true,
        },
        10.0,
        &EUROC,
        7,
    );
    match imu_initialize(&s.keyframes, &s.imu, &options(&s)) {
        Err(Error::Degenerate { reason, value }) => {
            assert!(reason.contains("constant velocity"), "{reason}");
            assert!(value < 0.05, "{value}");
        }
        other => panic!("expected Degenerate, got {other:?}"),
    }
}

#[test]
fn pure_rotation_is_unobservable() {
    // The camera sits on the IMU: no lever arm to give away the scale.
    let motion = Motion {
        excite: 1.0,
        translate: false,
    };
    let s = scenario_with(motion, 10.0, &EUROC, 8, Sim3::identity());
    let o = options(&s);
    match imu_initialize(&s.keyframes, &s.imu, &o) {
        Err(Error::Degenerate { reason, .. }) => {
            assert!(reason.contains("pure rotation"), "{reason}")
        }
        other => panic!("expected Degenerate, got {other:?}"),
    }
}

#[test]
fn weak_acceleration_is_refused_by_the_scale_uncertainty() {
    // Just above the excitation threshold, too little to fix the scale to 5 %.
    let s = scenario(
        Motion {
            excite: 0.02,
            translate: true,
        },
        10.0,
        &EUROC,
        9,
    );
    match imu_initialize(&s.keyframes, &s.imu, &options(&s)) {
        Err(Error::Degenerate { value, .. }) => assert!(value > 0.0),
        Ok(a) => panic!(
            "expected Degenerate, got scale {} ± {}",
            a.scale, a.scale_sigma
        ),
        Err(e) => panic!("expected Degenerate, got {e}"),
    }
}

#[test]
fn too_short_and_malformed_inputs_are_refused() {
    let s = scenario(
        Motion {
            excite: 1.0,
            translate: true,
        },
        1.5,
        &QUIET,
        2,
    );
    assert!(matches!(
        imu_initialize(&s.keyframes, &s.imu, &options(&s)),
        Err(Error::Degenerate { value, .. }) if (value - 1.5).abs() < 1e-6
    ));
    let s = scenario(
        Motion {
            excite: 1.0,
            translate: true,
        },
        10.0,
        &QUIET,
        2,
    );
    let no_rot = Trajectory::try_new(
        s.keyframes.timestamps.clone(),
        s.keyframes.positions.clone(),
        None,
    )
    .unwrap();
    assert!(matches!(
        imu_initialize(&no_rot, &s.imu, &options(&s)),
        Err(Error::InvalidArgument { .. })
    ));
    let bad = ImuInitOptions {
        gravity: -1.0,
        ..options(&s)
    };
    assert!(matches!(
        imu_initialize(&s.keyframes, &s.imu, &bad),
        Err(Error::InvalidArgument { .. })
    ));
    let scaled = ImuInitOptions {
        imu_from_cam: Sim3::try_new(UnitQuaternion::identity(), Vector3::zeros(), 2.0).unwrap(),
        ..options(&s)
    };
    assert!(matches!(
        imu_initialize(&s.keyframes, &s.imu, &scaled),
        Err(Error::InvalidArgument { .. })
    ));
    // A time offset that puts the keyframes outside the IMU's span.
    let late = ImuInitOptions {
        time_offset: 1000.0,
        ..options(&s)
    };
    assert!(matches!(
        imu_initialize(&s.keyframes, &s.imu, &late),
        Err(Error::TooFew { got: 0, .. })
    ));
}

#[test]
fn time_offset_moves_keyframes_onto_the_imu_clock() {
    let s = scenario(
        Motion {
            excite: 1.0,
            translate: true,
        },
        10.0,
        &QUIET,
        3,
    );
    let shifted = Trajectory::try_new(
        s.keyframes.timestamps.iter().map(|t| t - 0.25).collect(),
        s.keyframes.positions.clone(),
        s.keyframes.orientations.clone(),
    )
    .unwrap();
    let mut o = options(&s);
    o.keyframe_position_sigma = 1e-4;
    o.time_offset = 0.25;
    let a = imu_initialize(&shifted, &s.imu, &o).unwrap();
    assert!((a.scale / s.truth.scale - 1.0).abs() < 1e-3);
    o.time_offset = 0.0;
    let b = imu_initialize(&shifted, &s.imu, &o);
    let wrong = b
        .map(|b| (b.scale / s.truth.scale - 1.0).abs())
        .unwrap_or(1.0);
    assert!(
        wrong > 1e-3,
        "without the offset the scale should be off ({wrong})"
    );
}

#[test]
fn euroc_csv_reader() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("data.csv");
    std::fs::write(
        &p,
        "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n\
         1403715523912143104,-0.0007,0.0195,0.0768,9.218,0.302,-3.154\n\
         1403715523917143040,0.001,0.02,0.07,9.2,0.3,-3.1\n",
    )
    .unwrap();
    let imu = read_euroc_imu(&p).unwrap();
    assert_eq!(imu.len(), 2);
    assert!((imu.timestamps[1] - imu.timestamps[0] - 0.004999936).abs() < 1e-6);
    assert_eq!(imu.gyro[0], Vector3::new(-0.0007, 0.0195, 0.0768));
    assert_eq!(imu.accel[1], Vector3::new(9.2, 0.3, -3.1));
    std::fs::write(&p, "1,2,3\n").unwrap();
    assert!(matches!(
        read_euroc_imu(&p),
        Err(Error::Parse { line: 1, .. })
    ));
    std::fs::write(&p, "1,2,3,4,5,6,x\n").unwrap();
    assert!(matches!(
        read_euroc_imu(&p),
        Err(Error::Parse { line: 1, .. })
    ));
    std::fs::write(&p, "2,0,0,0,0,0,0\n1,0,0,0,0,0,0\n").unwrap();
    assert!(matches!(
        read_euroc_imu(&p),
        Err(Error::InvalidArgument { .. })
    ));
    assert!(matches!(
        read_euroc_imu(dir.path().join("none.csv")),
        Err(Error::Io { .. })
    ));
}

#[test]
fn euroc_v102_imu_file_reads() {
    let Some(p) = shared_data("euroc_v102_imu", "V102.txt") else {
        return;
    };
    let imu = read_euroc_imu(p).unwrap();
    assert_eq!(imu.len(), 17100);
    let dt = imu.timestamps[imu.len() - 1] - imu.timestamps[0];
    assert!((dt - 85.49).abs() < 0.01, "{dt}");
    // Static first second: |a| ≈ 9.80 m/s² (PROVENANCE.md: 9.8034).
    let first: Vec<f64> = (0..200).map(|i| imu.accel[i].norm()).collect();
    let mean = first.iter().sum::<f64>() / 200.0;
    assert!((mean - 9.8034).abs() < 1e-3, "{mean}");
}

#[test]
fn inconsistent_public_fields_are_refused() {
    let s = scenario(
        Motion {
            excite: 1.0,
            translate: true,
        },
        5.0,
        &QUIET,
        4,
    );
    let mut imu = s.imu.clone();
    imu.accel.pop();
    assert!(matches!(
        imu_initialize(&s.keyframes, &imu, &options(&s)),
        Err(Error::ShapeMismatch { .. })
    ));
    let mut kf = s.keyframes.clone();
    kf.positions[3].x = f64::NAN;
    assert!(matches!(
        imu_initialize(&kf, &s.imu, &options(&s)),
        Err(Error::NonFinite { index: 3, .. })
    ));
    let mut kf = s.keyframes.clone();
    kf.positions.pop();
    assert!(matches!(
        imu_initialize(&kf, &s.imu, &options(&s)),
        Err(Error::ShapeMismatch { .. })
    ));
}

/// The scenario as a LSD-SLAM log: keyframes (tiny depth maps) + raw IMU,
/// with or without the reference poses.
fn write_log(s: &Scenario, path: &Path, with_reference: bool) {
    use slam2world::io::mcap::{write_slam_log, SlamLogOptions};
    use slam2world::{Keyframe, PinholeCamera};
    let camera = PinholeCamera::try_new(4.0, 4.0, 2.0, 2.0, 4, 4).unwrap();
    let o = s.keyframes.orientations.as_ref().unwrap();
    let kfs: Vec<Keyframe> = (0..s.keyframes.len())
        .map(|i| {
            let pose = Sim3::try_new(o[i], s.keyframes.positions[i], 1.0).unwrap();
            Keyframe::try_new(
                i as i32,
                s.keyframes.timestamps[i],
                pose,
                camera,
                vec![0.5; 16],
                Some(vec![1e-6; 16]),
                None,
            )
            .unwrap()
        })
        .collect();
    let reference = with_reference.then(|| {
        // T_world_cam of the keyframes = truth · T_slam_cam.
        s.keyframes.transformed(&s.truth)
    });
    write_slam_log(
        path,
        &kfs,
        reference.as_ref(),
        Some(&s.imu),
        &[],
        &SlamLogOptions::default(),
    )
    .unwrap();
}

#[test]
fn convert_takes_the_imu_path_without_reference_poses() {
    use slam2world::io::{read_mcap, ReadOptions};
    use slam2world::pipeline::{convert, ConvertOptions, Recording};
    let s = scenario(
        Motion {
            excite: 1.0,
            translate: true,
        },
        10.0,
        &QUIET,
        5,
    );
    let dir = tempfile::tempdir().unwrap();
    let opts = ConvertOptions {
        imu: ImuInitOptions {
            imu_from_cam: s.imu_from_cam,
            keyframe_position_sigma: 1e-4,
            ..ImuInitOptions::default()
        },
        ..ConvertOptions::default()
    };
    // No reference: T_world_slam from the IMU.
    let p = dir.path().join("imu_only.mcap");
    write_log(&s, &p, false);
    let log = Recording::from(read_mcap(&p, &ReadOptions::default()).unwrap());
    assert!(log.reference.is_none() && log.imu.is_some());
    let c = convert(&log, &opts).unwrap();
    assert!((c.transform().scale / s.truth.scale - 1.0).abs() < 1e-3);
    let imu = c.report.imu.as_ref().unwrap();
    assert!(imu.used_for_transform);
    assert!(!c.cloud.is_empty());
    let json = serde_json::to_value(&c.report).unwrap();
    assert!(json["imu"]["scale"][0].as_f64().unwrap() > 0.0);
    assert!(c.report.frames_used >= 4);
    // Both: the pose fit gives T_world_slam, the IMU is the consistency check.
    let p = dir.path().join("both.mcap");
    write_log(&s, &p, true);
    let log = Recording::from(read_mcap(&p, &ReadOptions::default()).unwrap());
    let c = convert(&log, &opts).unwrap();
    let imu = c.report.imu.as_ref().unwrap();
    assert!(!imu.used_for_transform);
    let chk = imu.pose_check.as_ref().unwrap();
    assert!(
        chk.scale_difference.abs() < 1e-3,
        "{}",
        chk.scale_difference
    );
    assert!(chk.gravity_angle_deg < 0.05, "{}", chk.gravity_angle_deg);
}

#[test]
fn convert_command_with_imu_topic() {
    let s = scenario(
        Motion {
            excite: 1.0,
            translate: true,
        },
        10.0,
        &QUIET,
        6,
    );
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("imu_only.mcap");
    write_log(&s, &p, false);
    let m = s.imu_from_cam.matrix();
    let m: Vec<String> = (0..16).map(|k| format!("{}", m[(k / 4, k % 4)])).collect();
    let out = dir.path().join("out");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_slam2world"))
        .args(["convert", p.to_str().unwrap(), "-o", out.to_str().unwrap()])
        .args(["--imu-topic", "/imu0", "--imu-from-cam", &m.join(",")])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        stdout.contains("IMU (gives T_world_slam): scale"),
        "{stdout}"
    );
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    let scale = report["t_world_slam"]["scale"].as_f64().unwrap();
    assert!((scale / s.truth.scale - 1.0).abs() < 0.01, "{scale}");
    assert_eq!(report["imu"]["used_for_transform"], true);
    // A topic that is not in the log is a data error (exit 1).
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_slam2world"))
        .args(["convert", p.to_str().unwrap(), "-o", out.to_str().unwrap()])
        .args(["--imu-topic", "/nope"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
}
