//! Inertial initialisation on the simulation (`slam2world::sim`): SLAM-like
//! keyframes with an unknown Sim(3) and raw IMU samples with EuRoC ADIS16448
//! white noise, bias random walk and constant start biases.

use nalgebra::Vector3;
use slam2world::imu::{imu_initialize, ImuInitOptions};
use slam2world::sim::{simulate, SimConfig, Simulation};
use slam2world::Trajectory;

fn run() -> Simulation {
    // Only the poses and the IMU are used: tiny images keep rendering cheap.
    let cfg = SimConfig {
        width: 32,
        height: 24,
        gyro_bias: [-0.002, 0.021, 0.076],
        accel_bias: [-0.013, 0.103, 0.093],
        ..SimConfig::default()
    };
    simulate(&cfg).unwrap()
}

/// Keyframes with `t0 ≤ t ≤ t0 + window`.
fn window(kf: &Trajectory, t0: f64, w: f64) -> Trajectory {
    let keep: Vec<usize> = (0..kf.len())
        .filter(|&i| kf.timestamps[i] >= t0 && kf.timestamps[i] <= t0 + w)
        .collect();
    let o = kf.orientations.as_ref().unwrap();
    Trajectory::try_new(
        keep.iter().map(|&i| kf.timestamps[i]).collect(),
        keep.iter().map(|&i| kf.positions[i]).collect(),
        Some(keep.iter().map(|&i| o[i]).collect()),
    )
    .unwrap()
}

#[test]
#[ignore = "slow: make test runs it"]
fn simulated_windows_scale_and_gravity() {
    let sim = run();
    let kf = sim.keyframe_trajectory().unwrap();
    let truth = sim.truth.t_world_slam;
    let g_true = truth.rotation.inverse() * Vector3::new(0.0, 0.0, -1.0);
    let opts = ImuInitOptions {
        keyframe_position_sigma: sim.config.keyframe_pos_sigma * truth.scale,
        keyframe_rotation_sigma: sim.config.keyframe_rot_sigma,
        ..ImuInitOptions::default()
    };
    let t_end = kf.timestamps[kf.len() - 1];
    let mut curve = Vec::new();
    for w in [5.0, 10.0, 20.0, 40.0] {
        let mut errs = Vec::new();
        let mut t0 = kf.timestamps[0];
        while t0 + w <= t_end + 1e-9 {
            let a = imu_initialize(&window(&kf, t0, w), &sim.imu, &opts).unwrap();
            let es = a.scale / truth.scale - 1.0;
            let eg = a
                .gravity_slam
                .normalize()
                .dot(&g_true)
                .clamp(-1.0, 1.0)
                .acos()
                .to_degrees();
            if w == 10.0 {
                assert!(es.abs() < 0.01, "10 s window at {t0}: scale error {es}");
                assert!(eg < 0.5, "10 s window at {t0}: gravity error {eg}°");
            }
            errs.push((es, eg));
            t0 += w;
        }
        let n = errs.len() as f64;
        let rs = (errs.iter().map(|e| e.0 * e.0).sum::<f64>() / n).sqrt();
        let rg = (errs.iter().map(|e| e.1 * e.1).sum::<f64>() / n).sqrt();
        let ms = errs.iter().map(|e| e.0.abs()).fold(0.0, f64::max);
        let mg = errs.iter().map(|e| e.1).fold(0.0, f64::max);
        eprintln!(
            "window {w:>4} s ({} windows): scale error rms {:.3} % (max {:.3} %), gravity error rms {rg:.3}° (max {mg:.3}°)",
            errs.len(),
            100.0 * rs,
            100.0 * ms
        );
        curve.push((rs, rg));
    }
    assert!(
        curve[3].0 < curve[0].0,
        "scale error should fall with the window: {curve:?}"
    );
    assert!(
        curve[3].1 < curve[0].1,
        "gravity error should fall with the window: {curve:?}"
    );
}
