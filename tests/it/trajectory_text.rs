//! Trajectory files as SLAM systems write them: time unit detection on the
//! shared real data (ORB-SLAM3 EuRoC in ns, TUM in s), CSV, headers,
//! repeated stamps, over-long lines.

use crate::common::data;

use std::io::Write;

use slam2world::io::text::{
    detect_time_unit, read_trajectory, Delimiter, TimeUnit, MAX_LINE_BYTES,
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
