//! Beyond one fit on the simulated experiment: the automatic start-up cut
//! against the true stages, and the windowed alignment under scale drift.

use slam2world::align::trajectories::SkipInit;
use slam2world::align::trajectories::{align_trajectories, TrajectoryAlignOptions};
use slam2world::align::windowed::{align_windowed, Window, WindowedOptions};
use slam2world::cloud::{backproject, backproject_per_keyframe, PointFilter};
use slam2world::sim::evaluate::point_distances;
use slam2world::sim::{simulate, ErrorStats, SimConfig};

#[test]
#[ignore = "slow: make test runs it"]
fn auto_skip_starts_at_the_stable_stage_and_fixes_the_scale() {
    for seed in [0, 1, 2] {
        let cfg = SimConfig {
            seed,
            ..SimConfig::default().reduced(8)
        };
        let sim = simulate(&cfg).unwrap();
        let truth = sim.truth.t_world_slam.scale;
        let fit = |skip| {
            align_trajectories(
                &sim.slam_frames,
                &sim.reference,
                &TrajectoryAlignOptions {
                    skip_init: skip,
                    ..Default::default()
                },
            )
            .unwrap()
        };
        let all = fit(SkipInit::None);
        let auto = fit(SkipInit::Auto);
        let stages = auto.stages.clone().unwrap();
        // The first fitted frame (pairs index SLAM frames).
        let start = auto.pairs[auto.fit_start].0;
        let err = |s: f64| (s / truth - 1.0).abs();
        let (e_all, e_auto) = (err(all.transform().scale), err(auto.transform().scale));
        let conv = auto.pairs[stages.converging_start].0;
        eprintln!(
            "seed {seed}: true stages {}..{}..; found converging {conv}, fit start {start}; \
             scale error all {e_all:.2e}, auto {e_auto:.2e}",
            cfg.converge_start, cfg.stable_start
        );
        // Issue 38's bar: the true stable start ± max(1 s, 10 % of the converging span).
        let span = (cfg.stable_start - cfg.converge_start) as f64;
        let slack = (0.1 * span).max(cfg.fps);
        assert!(
            (start as f64 - cfg.stable_start as f64).abs() <= slack,
            "seed {seed}: start {start}, true stable start {} ± {slack}",
            cfg.stable_start
        );
        assert!(e_auto * 5.0 <= e_all, "seed {seed}: {e_auto} vs {e_all}");
        assert!(auto.skip_reason.contains("dropped"));
    }
}

#[test]
#[ignore = "slow: make test runs it"]
fn windowed_alignment_halves_the_cloud_error_under_scale_drift() {
    let sim = simulate(&SimConfig {
        scale_drift: 0.01,
        ..SimConfig::default().reduced(4)
    })
    .unwrap();
    let kf = sim.keyframe_trajectory().unwrap();
    let filter = PointFilter::default();
    let rmse = |points: &[f32]| {
        ErrorStats::from_values("d", &point_distances(&sim.truth.scene, points).unwrap())
            .unwrap()
            .rmse
    };
    let single = align_trajectories(&kf, &sim.reference, &TrajectoryAlignOptions::default())
        .unwrap()
        .alignment
        .transform;
    let single_rmse = rmse(
        &backproject(&sim.keyframes, &filter, Some(&single))
            .unwrap()
            .points,
    );
    let w = align_windowed(
        &kf,
        &sim.reference,
        &WindowedOptions {
            window: Window::Poses(5),
            ..Default::default()
        },
    )
    .unwrap();
    let per_kf: Vec<_> = sim
        .keyframes
        .iter()
        .map(|k| w.transform_at(k.timestamp))
        .collect();
    let cloud = backproject_per_keyframe(&sim.keyframes, &filter, &per_kf).unwrap();
    let windowed_rmse = rmse(&cloud.points);
    eprintln!(
        "cloud rmse: single Sim(3) {single_rmse:.4} m, windowed {windowed_rmse:.4} m; \
         APE single {:.4} m, windowed {:.4} m",
        w.global.rmse, w.rmse
    );
    assert!(
        windowed_rmse < 0.5 * single_rmse,
        "{windowed_rmse} vs {single_rmse}"
    );
}

#[test]
#[ignore = "slow: make test runs it"]
fn convert_reports_the_cut_the_inliers_and_the_windowed_comparison() {
    use slam2world::align::robust::RobustOptions;
    use slam2world::pipeline::{convert, ConvertOptions, Recording};
    let sim = simulate(&SimConfig {
        scale_drift: 0.01,
        ..SimConfig::default().reduced(8)
    })
    .unwrap();
    let log = Recording {
        keyframes: sim.keyframes.clone(),
        reference: Some(sim.reference.clone().into()),
        ..Default::default()
    };
    let opts = ConvertOptions {
        filter: PointFilter::none(),
        align: TrajectoryAlignOptions {
            skip_init: SkipInit::First(3),
            robust: Some(RobustOptions::default()),
            ..Default::default()
        },
        compare_windowed: Some(Window::Poses(5)),
        ..Default::default()
    };
    let c = convert(&log, &opts).unwrap();
    let r = &c.report;
    let fit = r.fit.as_ref().unwrap();
    assert_eq!(fit.fit_start, 3);
    assert!(fit.skip_reason.contains("first 3"));
    let n_in = fit.n_inliers.unwrap();
    assert_eq!(r.pairs.iter().filter(|p| p.fitted).count(), n_in);
    assert!(r.pairs.iter().take(3).all(|p| !p.fitted));
    let w = r.windowed.as_ref().unwrap();
    assert!(w.windowed_rmse < w.single_rmse);
    let iv = fit.intervals.as_ref().unwrap().scale;
    let s = r.t_world_slam.scale;
    assert!(iv[0] < s && s < iv[1]);
}

#[test]
#[ignore = "slow: make test runs it"]
fn convert_with_the_windowed_cloud_follows_the_drift() {
    use slam2world::map::MapParams;
    use slam2world::pipeline::{convert, ConvertOptions, Recording};
    // SLAM whose scale drifts 1 %/s: the cloud, map and world poses carried
    // keyframe by keyframe with the windowed Sim(3) lie closer to the true
    // surfaces and path than with the single one.
    let sim = simulate(&SimConfig {
        scale_drift: 0.01,
        ..SimConfig::default().reduced(4)
    })
    .unwrap();
    let log = Recording {
        keyframes: sim.keyframes.clone(),
        reference: Some(sim.reference.clone().into()),
        ..Default::default()
    };
    let rmse = |points: &[f32]| {
        ErrorStats::from_values("d", &point_distances(&sim.truth.scene, points).unwrap())
            .unwrap()
            .rmse
    };
    let base = ConvertOptions {
        compare_windowed: Some(Window::Poses(5)),
        map: Some(MapParams::new(0.2)),
        ..Default::default()
    };
    let single = convert(&log, &base).unwrap();
    let windowed = convert(
        &log,
        &ConvertOptions {
            windowed_cloud: true,
            ..base.clone()
        },
    )
    .unwrap();
    let (e_single, e_windowed) = (rmse(&single.cloud.points), rmse(&windowed.cloud.points));
    eprintln!("cloud rmse: single Sim(3) {e_single:.4} m, windowed {e_windowed:.4} m");
    assert!(e_windowed < 0.5 * e_single, "{e_windowed} vs {e_single}");
    assert_eq!(windowed.report.windowed.as_ref().unwrap().cloud, "windowed");
    assert_eq!(single.report.windowed.as_ref().unwrap().cloud, "single");
    // The single fit is still the one reported; the map is built from the
    // windowed cloud and the windowed camera centres.
    assert_eq!(
        windowed.report.t_world_slam.scale,
        single.report.t_world_slam.scale
    );
    assert!(windowed.octree.is_some());
    let path_err = |c: &slam2world::pipeline::Conversion| {
        slam2world::sim::evaluate::ape(
            &c.slam_trajectory,
            &slam2world::Sim3::identity(),
            &sim.truth.path,
        )
        .unwrap()
        .rmse
    };
    assert!(path_err(&windowed) < path_err(&single));
    // Without the window it is refused.
    let no_window = ConvertOptions {
        windowed_cloud: true,
        compare_windowed: None,
        ..base
    };
    assert!(matches!(
        convert(&log, &no_window),
        Err(slam2world::Error::InvalidArgument { .. })
    ));
}
