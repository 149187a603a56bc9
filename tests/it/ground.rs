//! Scale and gravity from the ground plane and a known camera height
//! (`align::ground`), scored on simulated ground vehicles: the paper's scene
//! (a floor with boxes on it), LSD-SLAM-style keyframes with default noise,
//! the camera at a constant height drawn per run and looking ahead and down.
//! The bar: scale within 1 % and gravity within 0.5° from the height alone,
//! for cameras 0.8–1.8 m up. Lower ones miss it: the inverse-depth noise
//! leaves the floor points' densest part a few millimetres above the floor
//! (+1.2 % at 0.6 m).
//!
//! The other priors on the same runs: a known distance between two
//! keyframes (the scale to the precision of their positions), the plane the
//! vehicle's cameras ride in (gravity within 1°), and a hand-held walk
//! (1.4–1.7 m with a step bob) that planar motion refuses and the height at
//! its first pose scales.

use nalgebra::Vector3;
use rayon::prelude::*;
use slam2world::align::ground::{
    fit_ground_plane, height_profile, metric_from_height, CameraHeight, GroundOptions,
};
use slam2world::align::priors::{planar_motion, scale_from_distance};
use slam2world::cloud::{backproject, PointFilter};
use slam2world::defaults;
use slam2world::sim::{simulate, SimConfig};

/// Seeds scored (not those the rule was developed on, 0–11).
const SEEDS: std::ops::Range<u64> = 100..110;

/// Run `seed`: a quarter-size paper run, the camera at 0.8–1.8 m (drawn from
/// the seed) with no height change, looking at a point at 0.4–0.9 of its height.
fn ground_vehicle(seed: u64) -> SimConfig {
    let u =
        |k: u64| ((seed.wrapping_mul(2_654_435_761).wrapping_add(k * 97)) % 1000) as f64 / 1000.0;
    let height = 0.8 + 1.0 * u(1);
    SimConfig {
        seed,
        camera_height: height,
        height_loop: 0.0,
        height_slow: 0.0,
        look_height: height * (0.4 + 0.5 * u(2)),
        ..SimConfig::default().reduced(4)
    }
}

/// One run's figures.
struct Score {
    /// Scale error (relative).
    scale: f64,
    /// Relative sigma of the scale stated by the fit.
    scale_sigma: f64,
    /// Gravity error, degrees.
    gravity: f64,
    /// Sigma of the normal stated by the fit, degrees.
    tilt_sigma: f64,
    /// Camera height, metres.
    height: f64,
}

/// The figures of run `seed`.
fn score(seed: u64) -> Score {
    let cfg = ground_vehicle(seed);
    let sim = simulate(&cfg).unwrap();
    let cloud = backproject(&sim.keyframes, &PointFilter::default(), None).unwrap();
    let points: Vec<Vector3<f64>> = cloud
        .points
        .chunks_exact(3)
        .map(|p| Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64))
        .collect();
    let cams = sim.keyframe_trajectory().unwrap();
    let plane = fit_ground_plane(&points, &cams, &GroundOptions::default())
        .unwrap_or_else(|e| panic!("seed {seed}, camera at {} m: {e}", cfg.camera_height));
    let m = metric_from_height(&plane, &cams, &CameraHeight::Constant(cfg.camera_height)).unwrap();
    let truth = sim.truth.t_world_slam;
    let up = truth.rotation * plane.normal;
    Score {
        scale: m.scale / truth.scale - 1.0,
        scale_sigma: m.scale_sigma,
        gravity: up.z.clamp(-1.0, 1.0).acos().to_degrees(),
        tilt_sigma: plane.tilt_sigma_deg(),
        height: cfg.camera_height,
    }
}

#[test]
#[ignore = "slow: make test runs it"]
fn a_ground_vehicle_gets_scale_and_gravity_from_its_camera_height() {
    let runs: Vec<(u64, Score)> = SEEDS.into_par_iter().map(|s| (s, score(s))).collect();
    for (seed, r) in &runs {
        println!(
            "seed {seed}: camera {:.2} m, scale {:+.3} % (sigma {:.3} %), gravity {:.3} deg \
             (sigma {:.3})",
            r.height,
            100.0 * r.scale,
            100.0 * r.scale_sigma,
            r.gravity,
            r.tilt_sigma
        );
    }
    for (seed, r) in runs {
        // The stated sigmas are honest: the errors lie within 3 of them
        // (scale) and 4 (gravity: the truth's own "up" carries the
        // keyframes' noise too), and the scale's is useful (under 1 %).
        assert!(
            r.scale.abs() <= 3.0 * r.scale_sigma && r.scale_sigma < 0.01,
            "seed {seed}: scale {:+.4} with sigma {:.4}",
            r.scale,
            r.scale_sigma
        );
        assert!(
            r.gravity <= 4.0 * r.tilt_sigma,
            "seed {seed}: gravity {:.3} deg with sigma {:.3}",
            r.gravity,
            r.tilt_sigma
        );
        let Score {
            scale,
            gravity,
            height,
            ..
        } = r;
        assert!(
            scale.abs() <= 0.01,
            "seed {seed} ({height:.2} m): scale {scale:+.4}"
        );
        assert!(
            gravity <= 0.5,
            "seed {seed} ({height:.2} m): gravity {gravity:.3} deg"
        );
    }
}

/// `cfg` with tiny images: the tests of the pose priors read no pixels.
fn poses_only(cfg: SimConfig) -> SimConfig {
    SimConfig {
        width: 32,
        height: 24,
        ..cfg
    }
}

/// Keyframe `i`'s true camera centre (world, metres).
fn true_centre(sim: &slam2world::sim::Simulation, i: usize) -> Vector3<f64> {
    sim.truth.camera.positions[sim.truth.keyframe_frames[i]]
}

#[test]
#[ignore = "slow: make test runs it"]
fn a_known_distance_gives_the_scale_to_the_precision_of_its_two_poses() {
    let runs: Vec<(u64, usize, f64, f64, f64)> = SEEDS
        .into_par_iter()
        .map(|seed| {
            let cfg = poses_only(ground_vehicle(seed));
            let sim = simulate(&cfg).unwrap();
            let cams = sim.keyframe_trajectory().unwrap();
            // The first keyframe and the one farthest from it.
            let d = |k: usize| (cams.positions[k] - cams.positions[0]).norm();
            let b = (1..cams.len())
                .max_by(|&i, &j| d(i).total_cmp(&d(j)))
                .unwrap();
            let metres = (true_centre(&sim, b) - true_centre(&sim, 0)).norm();
            let k = scale_from_distance(&cams, 0, b, metres).unwrap();
            // Each position is off by keyframe_pos_sigma per axis: the
            // distance by √2 of it, the scale by that over the distance.
            let sigma = std::f64::consts::SQRT_2 * cfg.keyframe_pos_sigma / k.slam_distance;
            (
                seed,
                b,
                metres,
                k.scale / sim.truth.t_world_slam.scale - 1.0,
                sigma,
            )
        })
        .collect();
    for &(seed, b, metres, error, sigma) in &runs {
        println!(
            "seed {seed}: poses 0 and {b}, {metres:.2} m, scale {:+.4} % (sigma {:.4} %)",
            100.0 * error,
            100.0 * sigma
        );
    }
    for (seed, _, _, error, sigma) in runs {
        assert!(
            error.abs() <= 4.0 * sigma,
            "seed {seed}: {error:+.3e} vs sigma {sigma:.3e}"
        );
    }
}

/// A hand-held walk: the camera at 1.4–1.7 m (slowly) with a 3 cm step bob.
fn walk(seed: u64) -> SimConfig {
    SimConfig {
        seed,
        camera_height: 1.55,
        height_loop: 0.0,
        height_slow: 0.15,
        height_bob: 0.03,
        look_height: 0.9,
        ..SimConfig::default().reduced(4)
    }
}

#[test]
#[ignore = "slow: make test runs it"]
fn planar_motion_gives_gravity_for_a_ground_vehicle_and_refuses_a_walk() {
    let runs: Vec<(u64, f64, f64, String)> = SEEDS
        .into_par_iter()
        .map(|seed| {
            let sim = simulate(&poses_only(ground_vehicle(seed))).unwrap();
            let cams = sim.keyframe_trajectory().unwrap();
            let p = planar_motion(&cams, defaults::PLANAR_MAX_TILT_BOUND_DEG).unwrap();
            let up = sim.truth.t_world_slam.rotation * p.normal;
            let gravity = up.z.clamp(-1.0, 1.0).acos().to_degrees();
            let sim = simulate(&poses_only(walk(seed))).unwrap();
            let cams = sim.keyframe_trajectory().unwrap();
            let walk = planar_motion(&cams, defaults::PLANAR_MAX_TILT_BOUND_DEG)
                .map_or_else(|e| e.to_string(), |p| format!("accepted: {p:?}"));
            (seed, gravity, p.tilt_bound_deg, walk)
        })
        .collect();
    for (seed, gravity, bound, walk) in &runs {
        println!("seed {seed}: gravity {gravity:.4} deg (bound {bound:.4}); walk: {walk}");
    }
    for (seed, gravity, _, walk) in runs {
        assert!(gravity <= 1.0, "seed {seed}: {gravity} deg");
        assert!(
            walk.contains("do not ride in one plane"),
            "seed {seed}: {walk}"
        );
    }
}

#[test]
#[ignore = "slow: make test runs it"]
fn a_walk_gets_its_scale_from_the_height_at_the_first_pose() {
    let runs: Vec<(u64, f64, f64, f64)> = SEEDS
        .into_par_iter()
        .map(|seed| {
            let sim = simulate(&walk(seed)).unwrap();
            let cloud = backproject(&sim.keyframes, &PointFilter::default(), None).unwrap();
            let points: Vec<Vector3<f64>> = cloud
                .points
                .chunks_exact(3)
                .map(|p| Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64))
                .collect();
            let cams = sim.keyframe_trajectory().unwrap();
            let plane = fit_ground_plane(&points, &cams, &GroundOptions::default()).unwrap();
            let scale = |h: CameraHeight| {
                metric_from_height(&plane, &cams, &h).unwrap().scale / sim.truth.t_world_slam.scale
                    - 1.0
            };
            let first = scale(CameraHeight::First(true_centre(&sim, 0).z));
            let constant = scale(CameraHeight::Constant(walk(seed).camera_height));
            let up = sim.truth.t_world_slam.rotation * plane.normal;
            (
                seed,
                first,
                constant,
                up.z.clamp(-1.0, 1.0).acos().to_degrees(),
            )
        })
        .collect();
    for &(seed, first, constant, gravity) in &runs {
        println!(
            "seed {seed}: first height {:+.3} %, mean height {:+.3} %, gravity {gravity:.3} deg",
            100.0 * first,
            100.0 * constant
        );
    }
    for (seed, first, _, gravity) in runs {
        assert!(first.abs() <= 0.02, "seed {seed}: {first:+.4}");
        assert!(gravity <= 0.5, "seed {seed}: {gravity} deg");
    }
}

#[test]
#[ignore = "slow: make test runs it"]
fn the_windowed_profile_follows_a_drifting_scale_where_the_floor_is_seen() {
    // Scale drift of 0.5 % a second from a stable stage that starts at 5 s:
    // over 10 % across the run, so that one scale for it misses its ends by
    // more than the bar; windows of 8 keyframes (8 s) see 4 % of it.
    // Per run: (seed, (time, true scale, error) per window with a scale, windows without).
    type Run = (u64, Vec<(f64, f64, f64)>, usize);
    let runs: Vec<Run> = (SEEDS.start..SEEDS.start + 4)
        .into_par_iter()
        .map(|seed| {
            let cfg = SimConfig {
                scale_drift: 0.005,
                converge_start: 100,
                stable_start: 300,
                ..ground_vehicle(seed)
            };
            let sim = simulate(&cfg).unwrap();
            let cams = sim.keyframe_trajectory().unwrap();
            // Each point with the index of the keyframe it came from.
            let cloud = backproject(&sim.keyframes, &PointFilter::default(), None).unwrap();
            let index: std::collections::HashMap<i32, usize> = sim
                .keyframes
                .iter()
                .enumerate()
                .map(|(k, kf)| (kf.id, k))
                .collect();
            let owner: Vec<usize> = cloud.keyframe_ids.iter().map(|id| index[id]).collect();
            let points: Vec<Vector3<f64>> = cloud
                .points
                .chunks_exact(3)
                .map(|p| Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64))
                .collect();
            let profile = height_profile(
                &points,
                &owner,
                &cams,
                cfg.camera_height,
                8,
                &GroundOptions::default(),
            )
            .unwrap();
            // The true metres per SLAM unit over a window: the scale over
            // the drift factor of its keyframes (1 before the stable stage).
            let lambda = |k: usize| {
                let f = sim.truth.keyframe_frames[k];
                if f >= cfg.stable_start {
                    1.0 + cfg.scale_drift * (f - cfg.stable_start) as f64 / cfg.fps
                } else {
                    1.0
                }
            };
            let s = sim.truth.t_world_slam.scale;
            let refused = profile.iter().filter(|w| w.scale.is_none()).count();
            for w in profile.iter().filter(|w| w.scale.is_none()).take(2) {
                println!("seed {seed}: {}..{}: {:?}", w.first, w.last, w.reason);
            }
            let scored = profile
                .iter()
                .filter_map(|w| {
                    let truth = (w.first..=w.last).map(|k| s / lambda(k)).sum::<f64>()
                        / (w.last - w.first + 1) as f64;
                    w.scale.map(|m| (w.time, truth, m / truth - 1.0))
                })
                .collect();
            (seed, scored, refused)
        })
        .collect();
    for (seed, scored, refused) in &runs {
        let worst = scored.iter().map(|w| w.2.abs()).fold(0.0, f64::max);
        let span = scored.iter().map(|w| w.1).fold(f64::NAN, f64::max)
            / scored.iter().map(|w| w.1).fold(f64::NAN, f64::min)
            - 1.0;
        println!(
            "seed {seed}: {} windows ({refused} without floor), true scale varies {:.2} %, \
             worst window {:+.3} %",
            scored.len(),
            100.0 * span,
            100.0 * worst
        );
    }
    for (seed, scored, refused) in runs {
        assert!(
            scored.len() >= 3 * refused.max(1),
            "seed {seed}: {refused} refused"
        );
        // One scale for the run would miss the bar at one end or the other.
        let truths: Vec<f64> = scored.iter().map(|w| w.1).collect();
        let span = truths.iter().fold(f64::NAN, |a, &b| a.max(b))
            / truths.iter().fold(f64::NAN, |a, &b| a.min(b));
        assert!(span > 1.08, "seed {seed}: the scale varies by {span} only");
        for (t, truth, e) in scored {
            assert!(
                e.abs() <= 0.02,
                "seed {seed} at {t:.1} s: {e:+.4} of {truth}"
            );
        }
    }
}

/// A session that defers its ground refits (`Session::defer_refits`, what a
/// served session does) carries the keyframe that calls for one by the
/// transform it had, and after `catch_up` is where a session that refits at
/// once is: the same transform, bit for bit, after every keyframe, and the
/// same octree at the end.
#[test]
#[ignore = "slow: make test runs it"]
fn a_deferred_refit_catches_up_to_the_session_that_refits_at_once() {
    use slam2world::pipeline::prior::HeightSpec;
    use slam2world::pipeline::session::{Session, SessionOptions};
    let sim = simulate(&ground_vehicle(3)).unwrap();
    let opts = SessionOptions {
        camera_height: Some(HeightSpec::Constant(sim.config.camera_height)),
        ..SessionOptions::default()
    };
    let mut now = Session::new(opts.clone()).unwrap();
    let mut later = Session::new(opts).unwrap();
    later.defer_refits(true);
    let (mut deferred, mut first) = (0, None);
    for (i, kf) in sim.keyframes.iter().enumerate() {
        let before = now.transform().ok().map(|t| t.transform);
        now.push_keyframe(kf.clone()).unwrap();
        later.push_keyframe(kf.clone()).unwrap();
        let after = now.transform().ok().map(|t| t.transform);
        first = first.or(after.map(|_| i));
        let pushed = later.transform().ok().map(|t| t.transform);
        if later.has_deferred() {
            // A refit is never deferred before there is a transform.
            assert!(before.is_some(), "keyframe {i}");
            assert_eq!(
                pushed, before,
                "keyframe {i}: carried by the transform it had"
            );
            deferred += 1;
            let t = later.catch_up().unwrap();
            assert!(t.fit_s > 0.0);
            assert!(!later.has_deferred());
        } else {
            assert_eq!(later.catch_up().unwrap().fit_s, 0.0);
        }
        assert_eq!(
            later.transform().ok().map(|t| t.transform),
            after,
            "keyframe {i}"
        );
    }
    let first = first.expect("a transform before the end");
    assert!(
        deferred >= 3,
        "{deferred} refits deferred after keyframe {first}"
    );
    now.finish().unwrap();
    later.finish().unwrap();
    assert_eq!(
        later.transform().unwrap().transform,
        now.transform().unwrap().transform
    );
    let bt = |s: &Session| s.map().unwrap().to_bt_bytes();
    assert!(bt(&later) == bt(&now), "the end's octree");
}
