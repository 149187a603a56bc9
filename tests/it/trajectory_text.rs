//! Trajectory files as SLAM systems write them: time unit detection on the
//! shared real data (ORB-SLAM3 EuRoC in ns, TUM in s), CSV, headers,
//! repeated stamps, over-long lines.

use crate::common::data;

use std::io::Write;

use slam2world::io::text::{
    detect_time_unit, match_time_units, read_trajectory, Delimiter, TimeUnit, MAX_LINE_BYTES,
};
use slam2world::Error;

#[test]
fn orbslam3_euroc_files_are_nanoseconds() {
    for f in ["kf_dataset-MH01_mono.txt", "f_dataset-MH01_mono.txt"] {
        let Some(p) = data("euroc_mh01_orbslam3_mono", f) else {
            return;
        };
        let (traj, info) = read_trajectory(&p, None).unwrap();
        assert_eq!(
            (info.unit, info.unit_detected),
            (TimeUnit::Nanoseconds, true),
            "{f}"
        );
        assert_eq!(info.delimiter, Delimiter::Whitespace);
        // Same poses as read_tum, times in seconds (1403636579.9 … for MH01).
        let raw = slam2world::io::text::read_tum(&p).unwrap();
        assert_eq!(traj.len() + info.repeated_stamps, raw.len());
        assert!((traj.timestamps[0] - raw.timestamps[0] / 1e9).abs() < 1e-9);
        assert!(traj.timestamps[0] > 1.4e9 && traj.timestamps[0] < 1.41e9);
        assert_eq!(traj.positions[3], raw.positions[3]);
        // Overridden, the unit is taken as given.
        let (s, info) = read_trajectory(&p, Some(TimeUnit::Seconds)).unwrap();
        assert!(!info.unit_detected);
        assert_eq!(s.timestamps[0], raw.timestamps[0]);
    }
    let Some(gt) = data("euroc_mh01_orbslam3_mono", "MH_01_easy.txt") else {
        return;
    };
    let (gt, info) = read_trajectory(&gt, None).unwrap();
    assert_eq!(info.unit, TimeUnit::Seconds);
    assert_eq!(gt.len(), 36382);
}

#[test]
fn tum_files_are_seconds_and_read_as_read_tum_does() {
    for f in [
        "fr2_desk_groundtruth.txt",
        "fr2_desk_ORB.txt",
        "fr2_desk_ORB_kf_mono.txt",
    ] {
        let Some(p) = data("evo_tum_fr2_desk", f) else {
            return;
        };
        let (traj, info) = read_trajectory(&p, None).unwrap();
        assert_eq!(info.unit, TimeUnit::Seconds, "{f}");
        let raw = slam2world::io::text::read_tum(&p).unwrap();
        assert_eq!(traj.len() + info.repeated_stamps, raw.len(), "{f}");
        if info.repeated_stamps == 0 {
            assert_eq!(traj.timestamps, raw.timestamps);
            assert_eq!(traj.positions, raw.positions);
        }
    }
}

#[test]
fn unit_rule_on_magnitudes_and_spacings() {
    let ramp = |t0: f64, dt: f64| (0..50).map(|i| t0 + dt * i as f64).collect::<Vec<_>>();
    assert_eq!(detect_time_unit(&ramp(1.4036e9, 0.05)), TimeUnit::Seconds);
    assert_eq!(
        detect_time_unit(&ramp(1.4036e12, 50.0)),
        TimeUnit::Milliseconds
    );
    assert_eq!(
        detect_time_unit(&ramp(1.4036e15, 5e4)),
        TimeUnit::Microseconds
    );
    assert_eq!(
        detect_time_unit(&ramp(1.4036e18, 5e7)),
        TimeUnit::Nanoseconds
    );
    // Relative stamps: the spacing decides.
    assert_eq!(detect_time_unit(&ramp(0.0, 1.0)), TimeUnit::Seconds); // frame indices
    assert_eq!(detect_time_unit(&ramp(0.0, 33.0)), TimeUnit::Milliseconds);
    assert_eq!(
        detect_time_unit(&ramp(3.0e11, 3.3e7)),
        TimeUnit::Nanoseconds
    ); // ns since boot
    assert_eq!(detect_time_unit(&[1.4e18]), TimeUnit::Nanoseconds);
}

const UNITS: [TimeUnit; 4] = [
    TimeUnit::Seconds,
    TimeUnit::Milliseconds,
    TimeUnit::Microseconds,
    TimeUnit::Nanoseconds,
];

/// An estimate and its reference as files would hold them, drawn over the
/// runs users have: 5 s to 15 min long, the reference at 10–200 Hz, the
/// estimate at 0.05–60 Hz (keyframes up to 20 s apart) over part of it, both
/// on one clock (Unix time, time since boot, or from 0), each written in its
/// own unit. Returns the stamps as written, the two true units and whether
/// the clock is Unix time.
fn drawn_pair(rng: &mut impl rand::Rng) -> (Vec<f64>, Vec<f64>, TimeUnit, TimeUnit, bool) {
    let duration = rng.random_range(5.0..900.0);
    let unix = rng.random_range(0..3) == 0;
    let base = match (unix, rng.random_bool(0.5)) {
        (true, _) => rng.random_range(1.2e9..1.8e9),
        (false, true) => rng.random_range(10.0..1e4),
        (false, false) => 0.0,
    };
    fn ramp(rng: &mut impl rand::Rng, t0: f64, t1: f64, rate: f64) -> Vec<f64> {
        let mut t = t0;
        let mut out = Vec::new();
        while t <= t1 {
            out.push(t);
            t += rng.random_range(0.8..1.2) / rate;
        }
        out
    }
    let ref_rate = rng.random_range(10.0..200.0);
    let reference = ramp(rng, base, base + duration, ref_rate);
    let (a, b) = (
        base + rng.random_range(0.0..0.3) * duration,
        base + rng.random_range(0.7..1.0) * duration,
    );
    let est_rate = if rng.random_bool(0.2) {
        rng.random_range(0.05..1.0)
    } else {
        rng.random_range(5.0..60.0)
    };
    let mut est = ramp(rng, a, b, est_rate);
    if est.len() < 3 {
        est = vec![a, 0.5 * (a + b), b];
    }
    let (ue, ur) = (UNITS[rng.random_range(0..4)], UNITS[rng.random_range(0..4)]);
    let write = |t: &[f64], u: TimeUnit| t.iter().map(|s| s * u.per_second()).collect::<Vec<_>>();
    (write(&est, ue), write(&reference, ur), ue, ur, unix)
}

#[test]
#[ignore = "slow: make test runs it"]
fn units_are_found_against_the_other_file_over_a_family_of_runs() {
    use rand::SeedableRng;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(20261207);
    let (mut runs, mut own_right, mut found_right, mut told) = (0, 0, 0, 0);
    for run in 0..200 {
        let (est, reference, ue, ur, unix) = drawn_pair(&mut rng);
        runs += 1;
        let own = (
            detect_time_unit(&est) == ue,
            detect_time_unit(&reference) == ur,
        );
        own_right += usize::from(own.0 && own.1);
        let found = match_time_units(&est, &reference, None, None, 0.0);
        found_right += usize::from(found == (ue, ur));
        // What the stamps can tell: a Unix clock, or one file whose own unit
        // is right (two files from 0 both read a unit off alike overlap as
        // well as read right).
        if unix || own.0 || own.1 {
            told += 1;
            assert_eq!(
                found,
                (ue, ur),
                "run {run}: {} .. {} against {} .. {}",
                est[0],
                est[est.len() - 1],
                reference[0],
                reference[reference.len() - 1]
            );
        }
        // A unit given stays, and the other side is found against it.
        assert_eq!(
            match_time_units(&est, &reference, Some(ue), Some(ur), 0.0),
            (ue, ur)
        );
    }
    eprintln!(
        "{found_right} of {runs} runs found ({told} tellable), {own_right} by each file alone"
    );
    assert!(
        found_right > own_right,
        "{found_right} against {own_right} of {runs}"
    );
}

#[test]
fn units_no_overlap_explains_stay_the_files_own() {
    let ramp = |t0: f64, dt: f64| (0..50).map(|i| t0 + dt * i as f64).collect::<Vec<_>>();
    // ORB-SLAM3's nanoseconds against a ground truth in seconds.
    let ns = ramp(1.4036365797635558e18, 5e7);
    let s = ramp(1403636580.0, 0.005);
    assert_eq!(
        match_time_units(&ns, &s, None, None, 0.0),
        (TimeUnit::Nanoseconds, TimeUnit::Seconds)
    );
    // A day apart: no unit makes them overlap; each file's own unit stands.
    let later = ramp(1403636580.0 + 86400.0, 0.005);
    assert_eq!(
        match_time_units(&ns, &later, None, None, 0.0),
        (TimeUnit::Nanoseconds, TimeUnit::Seconds)
    );
    // ... unless an offset (seconds, added to the estimate) lines them up.
    assert_eq!(
        match_time_units(&ns, &later, None, None, 86400.0),
        (TimeUnit::Nanoseconds, TimeUnit::Seconds)
    );
    // Keyframes 15 s apart from 0 read alone as milliseconds; against a
    // reference in seconds over the same minutes they are seconds.
    let sparse = ramp(0.0, 15.0);
    assert_eq!(detect_time_unit(&sparse), TimeUnit::Milliseconds);
    let gt: Vec<f64> = (0..=75_000).map(|i| 0.01 * i as f64).collect();
    assert_eq!(detect_time_unit(&gt), TimeUnit::Seconds);
    assert_eq!(
        match_time_units(&sparse, &gt, None, None, 0.0),
        (TimeUnit::Seconds, TimeUnit::Seconds)
    );
    // Empty sides: the own units.
    assert_eq!(
        match_time_units(&[], &s, None, None, 0.0),
        (TimeUnit::Seconds, TimeUnit::Seconds)
    );
}

fn file(text: &str) -> tempfile::NamedTempFile {
    let mut f = tempfile::NamedTempFile::new().unwrap();
    f.write_all(text.as_bytes()).unwrap();
    f
}

#[test]
fn csv_header_and_repeated_stamps_are_reported() {
    let f = file(
        "timestamp,tx,ty,tz,qx,qy,qz,qw\n\
         1000, 0,0,0, 0,0,0,1\n\
         1033, 1,0,0, 0,0,0,1\n\
         1033, 9,9,9, 0,0,0,1\n\
         1066, 2,0,0, 0,0,0,1\n\
         1100, 3,0,0, 0,0,0,1\n",
    );
    let (t, info) = read_trajectory(f.path(), None).unwrap();
    assert_eq!(info.delimiter, Delimiter::Comma);
    assert!(info.header);
    assert_eq!(info.repeated_stamps, 1);
    assert_eq!(info.unit, TimeUnit::Milliseconds);
    assert_eq!(t.len(), 4);
    // The first row of a repeated stamp is the one kept.
    assert_eq!(t.positions[1].x, 1.0);
    assert!((t.timestamps[1] - 1.033).abs() < 1e-12);
}

#[test]
fn bad_lines_are_typed_errors_with_their_line() {
    let cases = [
        ("0 0 0 0 0 0 0 1\n1 0 0 0 0 0 1\n", 2),
        ("0 0 0 0 0 0 0 1\n1 0 0 x 0 0 0 1\n", 2),
        ("5 0 0 0 0 0 0 1\n4 0 0 0 0 0 0 1\n", 2),
        ("0 0 0 0 0 0 0 0\n", 1),
    ];
    for (text, line) in cases {
        match read_trajectory(file(text).path(), None) {
            Err(Error::Parse { line: l, .. }) => assert_eq!(l, line, "{text:?}"),
            other => panic!("{text:?}: {other:?}"),
        }
    }
    let long = format!("0 0 0 0 0 0 0 1\n# {}\n", "x".repeat(MAX_LINE_BYTES + 10));
    match read_trajectory(file(&long).path(), None) {
        Err(Error::Parse {
            line: 2, reason, ..
        }) => assert!(reason.contains("longer than")),
        other => panic!("{other:?}"),
    }
}

#[cfg(target_os = "linux")]
#[test]
fn dev_zero_is_refused_without_reading_it_all() {
    assert!(matches!(
        read_trajectory(std::path::Path::new("/dev/zero"), None),
        Err(Error::Parse { .. })
    ));
}
