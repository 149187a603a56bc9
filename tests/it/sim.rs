//! The synthetic experiment: geometry of the keyframes, the SLAM estimate's
//! stages and normalisation, reproducibility.

use nalgebra::Vector3;
use slam2world::sim::{simulate, SimConfig, Simulation};

fn reduced(noisy: bool) -> Simulation {
    let cfg = SimConfig::default().reduced(8);
    let cfg = if noisy { cfg } else { cfg.noiseless() };
    simulate(&cfg).unwrap()
}

/// World points of every keyframe pixel with depth, carried with the true `T_world_slam`.
fn world_points(sim: &Simulation) -> Vec<Vector3<f64>> {
    let t = sim.truth.t_world_slam;
    let mut out = Vec::new();
    for kf in &sim.keyframes {
        let w = kf.camera.width as usize;
        for (i, &d) in kf.idepth.iter().enumerate() {
            if d > 0.0 {
                let p = kf
                    .camera
                    .backproject((i % w) as f64, (i / w) as f64, 1.0 / d as f64);
                out.push(
                    t.transform_point(&kf.pose.transform_point(&Vector3::new(p[0], p[1], p[2]))),
                );
            }
        }
    }
    out
}

#[test]
#[ignore = "slow: make test runs it"]
fn noiseless_keyframes_lie_on_the_true_surfaces() {
    let sim = reduced(false);
    let pts = world_points(&sim);
    assert!(pts.len() > 10_000, "too few points: {}", pts.len());
    let worst = pts
        .iter()
        .step_by(7)
        .map(|p| sim.truth.scene.distance(&[p.x, p.y, p.z]))
        .fold(0.0, f64::max);
    // f32 inverse depth, f32 mesh: float32 precision at a few metres.
    assert!(worst < 2e-5, "worst distance {worst} m");
    // The keyframe poses are the true camera poses in the SLAM frame.
    for (kf, &k) in sim.keyframes.iter().zip(&sim.truth.keyframe_frames) {
        let c = sim.truth.t_world_slam.transform_point(&kf.pose.translation);
        assert!((c - sim.truth.camera.positions[k]).norm() < 1e-9);
    }
}

#[test]
fn keyframes_are_normalised_like_lsd_slam() {
    let sim = reduced(true);
    for kf in &sim.keyframes {
        let valid: Vec<f64> = kf
            .idepth
            .iter()
            .filter(|&&d| d > 0.0)
            .map(|&d| d as f64)
            .collect();
        let mean = valid.iter().sum::<f64>() / valid.len() as f64;
        assert!(
            (mean - 1.0).abs() < 1e-5,
            "keyframe {} mean idepth {mean}",
            kf.id
        );
        let var = kf.idepth_var.as_ref().unwrap();
        assert!(kf
            .idepth
            .iter()
            .zip(var)
            .all(|(&d, &v)| (d > 0.0) == (v > 0.0)));
        let share = valid.len() as f64 / kf.len() as f64;
        // At the reduced 80x60 image the texture cells are a few pixels wide: dense-ish.
        assert!(share > 0.02 && share < 0.9, "semi-dense share {share}");
        // Scale of T_slam_cam times depth in SLAM units is metres / s.
        assert!(kf.pose.scale > 0.0);
    }
}

#[test]
#[ignore = "slow: make test runs it"]
fn noisy_points_scatter_by_the_stated_depth_noise() {
    let sim = reduced(true);
    let pts = world_points(&sim);
    let d: Vec<f64> = pts
        .iter()
        .step_by(5)
        .map(|p| sim.truth.scene.distance(&[p.x, p.y, p.z]))
        .collect();
    let mut s = d.clone();
    s.sort_by(f64::total_cmp);
    let median = s[s.len() / 2];
    // 1 % of depths of a few metres, seen at all angles: millimetres to centimetres.
    assert!(median > 1e-3 && median < 0.05, "median distance {median}");
}

#[test]
#[ignore = "slow: make test runs it"]
fn slam_path_has_the_three_stages() {
    let sim = reduced(true);
    let cfg = &sim.config;
    let slam = &sim.slam_frames.positions;
    let world = &sim.truth.camera.positions;
    let s = sim.truth.t_world_slam.scale;
    // p_k = |Δ world|² / |Δ slam|², averaged over windows (≈ s² once stable).
    let p = |a: usize, b: usize| {
        let mut v: Vec<f64> = (a..b)
            .map(|k| {
                (world[k + 1] - world[k]).norm_squared() / (slam[k + 1] - slam[k]).norm_squared()
            })
            .collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2] / (s * s)
    };
    let n = cfg.n_frames - 1;
    let start = p(0, cfg.converge_start);
    let stable = p(cfg.stable_start, n);
    assert!((stable - 1.0).abs() < 0.1, "stable level {stable}");
    assert!(
        (start - 1.0).abs() > 0.3,
        "start stage should differ: {start}"
    );
    let len: f64 = slam.windows(2).map(|w| (w[1] - w[0]).norm()).sum();
    assert!(
        (len / cfg.slam_path_length - 1.0).abs() < 0.1,
        "SLAM path {len}"
    );
    let true_len = sim.truth.path.length(0.0, cfg.n_frames as f64 / cfg.fps);
    assert!((true_len / cfg.path_length - 1.0).abs() < 0.01);
}

#[test]
#[ignore = "slow: make test runs it"]
fn same_seed_same_run_other_seed_other_noise() {
    let cfg = SimConfig {
        n_keyframes: 4,
        ..SimConfig::default().reduced(16)
    };
    let a = simulate(&cfg).unwrap();
    let b = simulate(&cfg).unwrap();
    let c = simulate(&SimConfig {
        seed: 1,
        ..cfg.clone()
    })
    .unwrap();
    for (x, y) in a.keyframes.iter().zip(&b.keyframes) {
        assert_eq!(x.idepth, y.idepth);
        assert_eq!(x.pose, y.pose);
    }
    assert_eq!(a.slam_frames.positions, b.slam_frames.positions);
    assert_eq!(a.imu.accel, b.imu.accel);
    assert_eq!(a.reference.positions, b.reference.positions);
    assert_eq!(a.truth.t_world_slam, b.truth.t_world_slam);
    assert_ne!(a.keyframes[1].idepth, c.keyframes[1].idepth);
    assert_ne!(a.imu.accel, c.imu.accel);
}

#[test]
fn reference_and_imu_cover_the_run() {
    let sim = reduced(true);
    let t_end = (sim.config.n_frames - 1) as f64 / sim.config.fps;
    assert_eq!(sim.reference.len(), sim.imu.len());
    assert!((sim.reference.timestamps.last().unwrap() - t_end).abs() < 1.0 / sim.config.imu_rate);
    // The reference is the true camera path plus millimetre noise.
    let e: f64 = sim
        .reference
        .timestamps
        .iter()
        .zip(&sim.reference.positions)
        .map(|(&t, p)| (p - sim.truth.path.kinematics(t).0).norm())
        .fold(0.0, f64::max);
    assert!(e > 0.0 && e < 0.01, "reference noise {e}");
    // At rest the accelerometer would read +g along world z; the mean specific force is near g.
    let mean_norm = sim.imu.accel.iter().map(|a| a.norm()).sum::<f64>() / sim.imu.len() as f64;
    assert!((mean_norm - 9.81).abs() < 1.0, "mean |accel| {mean_norm}");
}

#[test]
fn bad_config_is_refused() {
    let cfg = SimConfig {
        n_keyframes: 0,
        ..SimConfig::default()
    };
    assert!(simulate(&cfg).is_err());
    let cfg = SimConfig {
        stable_start: 7000,
        ..SimConfig::default()
    };
    assert!(simulate(&cfg).is_err());
}

// ---------------------------------------------------------------- with the conversion

use slam2world::align::trajectories::{align_trajectories, TrajectoryAlignOptions};
use slam2world::cloud::{backproject, PointFilter};
use slam2world::sim::evaluate::{point_distances, transform_error, ErrorStats};

#[test]
#[ignore = "slow: make test runs it"]
fn noiseless_alignment_recovers_the_truth() {
    // A 60 Hz reference shares the camera's clock, so association is exact.
    let mut cfg = SimConfig::default().reduced(4).noiseless();
    cfg.imu_rate = 60.0;
    let sim = simulate(&cfg).unwrap();
    let fit = align_trajectories(
        &sim.keyframe_trajectory().unwrap(),
        &sim.reference,
        &TrajectoryAlignOptions::default(),
    )
    .unwrap();
    let est = fit.alignment.transform;
    let truth = sim.truth.t_world_slam;
    assert_eq!(fit.pairs.len(), sim.keyframes.len());
    assert!(
        (est.scale / truth.scale - 1.0).abs() < 1e-9,
        "{} vs {}",
        est.scale,
        truth.scale
    );
    assert!(est.rotation.angle_to(&truth.rotation) < 1e-9);
    assert!((est.translation - truth.translation).norm() < 1e-9);
    let cloud = backproject(&sim.keyframes, &PointFilter::none(), Some(&est)).unwrap();
    assert!(cloud.len() > 50_000);
    let d = point_distances(&sim.truth.scene, &cloud.points).unwrap();
    let worst = d.iter().copied().fold(0.0, f64::max);
    // float32 storage of inverse depth, of the points and of the mesh, a few metres away.
    assert!(worst < 1e-5, "worst distance {worst} m");
}

#[test]
#[ignore = "slow: make test runs it"]
fn default_noise_alignment_adds_almost_nothing() {
    let sim = simulate(&SimConfig::default().reduced(4)).unwrap();
    let fit = align_trajectories(
        &sim.keyframe_trajectory().unwrap(),
        &sim.reference,
        &TrajectoryAlignOptions::default(),
    )
    .unwrap();
    let est = fit.alignment.transform;
    let e = transform_error(&est, &sim.truth.t_world_slam);
    assert!(e.scale_error.abs() < 5e-3, "scale error {}", e.scale_error);
    assert!(
        e.gravity_error_deg < 0.5,
        "gravity error {} deg",
        e.gravity_error_deg
    );
    let filter = PointFilter::default();
    let cloud = backproject(&sim.keyframes, &filter, Some(&est)).unwrap();
    let cloud_true = backproject(&sim.keyframes, &filter, Some(&sim.truth.t_world_slam)).unwrap();
    assert_eq!(cloud.len(), cloud_true.len());
    let err = ErrorStats::from_values(
        "d",
        &point_distances(&sim.truth.scene, &cloud.points).unwrap(),
    )
    .unwrap();
    let err_true = ErrorStats::from_values(
        "d",
        &point_distances(&sim.truth.scene, &cloud_true.points).unwrap(),
    )
    .unwrap();
    assert!(
        err.rmse <= 1.1 * err_true.rmse,
        "rmse {} vs {} with the true transform",
        err.rmse,
        err_true.rmse
    );
    assert!(err.median <= 1.1 * err_true.median);
    // The start-up frames bias a fit over every tracked frame: the paper's reason to cut them.
    let all = align_trajectories(
        &sim.slam_frames,
        &sim.reference,
        &TrajectoryAlignOptions::default(),
    )
    .unwrap();
    let e_all = transform_error(&all.alignment.transform, &sim.truth.t_world_slam);
    assert!(e_all.scale_error.abs() > 10.0 * e.scale_error.abs().max(1e-4));
}

#[test]
#[ignore = "slow: make test runs it"]
fn scale_drift_degrades_a_single_transform() {
    // The paper's conclusion: the scale is not constant, and one Sim(3) cannot follow it.
    let rmse = |drift: f64| {
        let sim = simulate(&SimConfig {
            scale_drift: drift,
            ..SimConfig::default().reduced(4)
        })
        .unwrap();
        let fit = align_trajectories(
            &sim.keyframe_trajectory().unwrap(),
            &sim.reference,
            &TrajectoryAlignOptions::default(),
        )
        .unwrap();
        let cloud = backproject(
            &sim.keyframes,
            &PointFilter::default(),
            Some(&fit.alignment.transform),
        )
        .unwrap();
        let d = point_distances(&sim.truth.scene, &cloud.points).unwrap();
        (ErrorStats::from_values("d", &d).unwrap().rmse, fit.ape.rmse)
    };
    let (still, ape_still) = rmse(0.0);
    let (drifting, ape_drifting) = rmse(0.01);
    assert!(
        drifting > 1.5 * still,
        "cloud rmse {drifting} with drift vs {still} without"
    );
    assert!(
        ape_drifting > 3.0 * ape_still,
        "APE {ape_drifting} vs {ape_still}"
    );
}
