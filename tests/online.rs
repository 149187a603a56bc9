//! The online conversion: a [`Session`] fed the simulated paper run message
//! by message (the log `slam2world simulate` writes, in log order) reports
//! the stable stage within 10 s of log time after the true start and never
//! before it, on five seeds; fed each whole log, it ends on the transform of
//! the batch `convert --skip-init auto` and on its octree, node for node.
//! The five logs are simulated and fed once, in parallel, for both tests.

use slam2world::align::trajectories::SkipInit;
use slam2world::io::mcap::McapFile;
use slam2world::io::messages::decode::MessageKind;
use slam2world::map::MapParams;
use slam2world::pipeline::session::{LogFeed, Pushed, SessionOptions, Stage};
use slam2world::pipeline::{convert_path, ConvertOptions};

/// `slam2world simulate` of the paper run (all 7000 frames and 123
/// keyframes; 32×24 images, the stages live in the tracking) into `dir`.
fn simulate(dir: &std::path::Path, seed: u64) -> std::path::PathBuf {
    let log = dir.join(format!("run{seed}.mcap"));
    let code = slam2world::cli::main_with_args([
        "slam2world".to_string(),
        "simulate".into(),
        "--seed".into(),
        seed.to_string(),
        "--set".into(),
        "width=32".into(),
        "--set".into(),
        "height=24".into(),
        "-o".into(),
        log.display().to_string(),
    ]);
    assert_eq!(code, 0);
    log
}

/// Feeds the log's messages in log order; the log time of every keyframe
/// push with the stage after it.
fn feed(log: &std::path::Path, opts: SessionOptions) -> (LogFeed, Vec<(f64, Stage)>) {
    let file = McapFile::open(log).unwrap();
    let channels = file.channels().unwrap();
    let scan = file.scan(|_| true).unwrap();
    let mut feed = LogFeed::new(opts).unwrap();
    let mut stages = Vec::new();
    for m in scan.iter() {
        let c = &channels[&m.channel_id];
        let kind = MessageKind::from_schema(&c.schema_name);
        if let Pushed::Keyframe { .. } = feed
            .push(&c.topic, kind, &c.message_encoding, m.data)
            .unwrap()
        {
            stages.push((m.log_time as f64 * 1e-9, feed.session.state().stage));
        }
    }
    (feed, stages)
}

const TRUE_STABLE_S: f64 = 4300.0 / 60.0;
const SEEDS: std::ops::Range<u64> = 0..5;

/// What one seed's session gave: the stage after every keyframe push, the
/// state when the log ended (before `finish`), and after `finish` the final
/// transform and the octree's bytes; the log stays in [`runs`]' folder.
struct Run {
    seed: u64,
    log: std::path::PathBuf,
    stages: Vec<(f64, Stage)>,
    stable_reported_at: Option<f64>,
    stable_time: Option<f64>,
    online: slam2world::pipeline::session::SessionTransform,
    nodes: usize,
    ot: Vec<u8>,
}

/// The five seeds simulated and fed once, in parallel, shared by the tests.
fn runs() -> &'static [Run] {
    use rayon::prelude::*;
    static RUNS: std::sync::OnceLock<(tempfile::TempDir, Vec<Run>)> = std::sync::OnceLock::new();
    let (_, runs) = RUNS.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let runs = SEEDS
            .into_par_iter()
            .map(|seed| {
                let log = simulate(dir.path(), seed);
                let (mut f, stages) = feed(&log, SessionOptions::default());
                let stable_reported_at = f.session.state().stable_reported_at;
                f.session.finish().unwrap();
                let online = f.session.transform().expect("a transform");
                let map = f.session.map().unwrap();
                Run {
                    seed,
                    log,
                    stages,
                    stable_reported_at,
                    stable_time: f.session.state().stable_time,
                    online,
                    nodes: map.num_nodes(),
                    ot: map.to_ot_bytes(),
                }
            })
            .collect();
        (dir, runs)
    });
    runs
}

#[test]
fn stable_is_reported_within_ten_seconds_of_the_true_start_never_before() {
    for r in runs() {
        let seed = r.seed;
        let first = r.stages.iter().find(|s| s.1 == Stage::Stable).map(|s| s.0);
        let at = r.stable_reported_at.expect("stable reported");
        // The first keyframe after the report is the first one that says stable.
        assert!(
            first.is_some_and(|t| t >= at),
            "seed {seed}: {first:?} {at}"
        );
        assert!(
            at >= TRUE_STABLE_S,
            "seed {seed}: stable reported at {at} s, before the true start {TRUE_STABLE_S} s"
        );
        assert!(
            at <= TRUE_STABLE_S + 10.0,
            "seed {seed}: stable reported at {at} s, more than 10 s after {TRUE_STABLE_S} s"
        );
    }
}

#[test]
fn a_whole_log_ends_on_the_batch_transform_and_octree() {
    use rayon::prelude::*;
    runs().par_iter().for_each(|r| {
        let seed = r.seed;
        let batch = convert_path(
            &r.log,
            &ConvertOptions {
                align: slam2world::align::trajectories::TrajectoryAlignOptions {
                    skip_init: SkipInit::Auto,
                    ..Default::default()
                },
                map: Some(MapParams {
                    max_range: Some(10.0),
                    ..MapParams::new(0.1)
                }),
                ..ConvertOptions::default()
            },
        )
        .unwrap();
        let (a, b) = (r.online.transform, batch.transform());
        assert!(
            (a.scale - b.scale).abs() <= 1e-9 * b.scale,
            "seed {seed}: {} {}",
            a.scale,
            b.scale
        );
        assert!(
            (a.translation - b.translation).norm() <= 1e-9,
            "seed {seed}: {a:?} {b:?}"
        );
        assert!(
            a.rotation.angle_to(&b.rotation) <= 1e-9,
            "seed {seed}: {a:?} {b:?}"
        );
        assert_eq!(r.online.pairs, batch.report.pairs_fitted, "seed {seed}");
        // The cut is the batch's (the report says it came from the live frames).
        let startup = batch.report.startup.as_ref().expect("a live cut");
        assert_eq!(Some(startup.stable_time), r.stable_time, "seed {seed}");
        // Node for node, log-odds included (OctoMap's .ot holds every node's value).
        let m_batch = batch.octree.as_ref().unwrap();
        assert_eq!(r.nodes, m_batch.num_nodes(), "seed {seed}");
        assert!(r.ot == m_batch.to_ot_bytes(), "seed {seed}: octrees differ");
        // The covariance is there and small next to the scale.
        let cov = r.online.covariance.as_ref().expect("a covariance");
        assert!(
            cov.matrix[(6, 6)].sqrt() < 0.01,
            "seed {seed}: {}",
            cov.matrix[(6, 6)]
        );
    });
}

#[test]
fn push_errors_are_clear() {
    let mut s = slam2world::pipeline::session::Session::new(SessionOptions::default()).unwrap();
    assert!(s.transform().unwrap_err().reason.contains("too few") || s.transform().is_err());
    s.push_reference(1.0, nalgebra::Vector3::zeros(), None)
        .unwrap();
    let e = s
        .push_reference(0.5, nalgebra::Vector3::zeros(), None)
        .unwrap_err();
    assert!(e.to_string().contains("time order"), "{e}");
    let e = s.push_fix(1.0, [47.0, 8.0, 400.0]).unwrap_err();
    assert!(e.to_string().contains("not supported"), "{e}");
    assert!(s.grid(0.0, 1.0, None).is_err());
    let bad = SessionOptions {
        align: slam2world::align::trajectories::TrajectoryAlignOptions {
            robust: Some(Default::default()),
            ..Default::default()
        },
        ..SessionOptions::default()
    };
    assert!(slam2world::pipeline::session::Session::new(bad).is_err());
}
