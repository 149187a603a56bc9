//! `slam2world imu-init` as a user runs it: exit codes 0 / 1 (bad data, one
//! line) / 2 (usage), text and JSON output.

use crate::common::{bin, data, stderr};
use std::path::{Path, PathBuf};

/// A body at rest for 10 s: keyframes at 10 Hz, IMU at 200 Hz reading gravity.
fn at_rest(dir: &Path) -> (PathBuf, PathBuf) {
    let (kf, imu) = (dir.join("kf.txt"), dir.join("imu.csv"));
    let mut k = String::from("# t x y z qx qy qz qw\n");
    for i in 0..=100 {
        k += &format!("{} 1 2 3 0 0 0 1\n", 100.0 + i as f64 * 0.1);
    }
    let mut m = String::from("#timestamp [ns],wx,wy,wz,ax,ay,az\n");
    for j in 0..=2020 {
        let ns = 99_950_000_000u64 + j * 5_000_000;
        m += &format!("{ns},0.001,-0.002,0.0005,0.01,-0.02,9.81\n");
    }
    std::fs::write(&kf, k).unwrap();
    std::fs::write(&imu, m).unwrap();
    (kf, imu)
}

#[test]
fn motion_at_rest_is_reported_unobservable_with_exit_1() {
    let dir = tempfile::tempdir().unwrap();
    let (kf, imu) = at_rest(dir.path());
    let o = bin(&["imu-init", kf.to_str().unwrap(), imu.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.starts_with("slam2world: error: degenerate input"),
        "{err}"
    );
    assert!(err.contains("unobservable"), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
}

#[test]
fn usage_and_argument_errors() {
    let o = bin(&["imu-init", "only-one.txt"]);
    assert_eq!(o.status.code(), Some(2));
    let dir = tempfile::tempdir().unwrap();
    let (kf, imu) = at_rest(dir.path());
    let (k, i) = (kf.to_str().unwrap(), imu.to_str().unwrap());
    let o = bin(&["imu-init", k, i, "--imu-from-cam", "1,0,0"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("16 numbers"), "{}", stderr(&o));
    let o = bin(&["imu-init", k, "/nonexistent/imu.csv"]);
    assert_eq!(o.status.code(), Some(1));
}

#[test]
#[ignore = "slow: make test runs it"]
fn euroc_v102_report_agrees_with_the_reference() {
    let (Some(est), Some(imu), Some(gt)) = (
        data("euroc_v102", "V102.txt"),
        data("euroc_v102_imu", "V102.txt"),
        data("euroc_v102", "V102_groundtruth.csv"),
    ) else {
        return;
    };
    let (e, i, g) = (
        est.to_str().unwrap(),
        imu.to_str().unwrap(),
        gt.to_str().unwrap(),
    );
    let o = bin(&[
        "imu-init",
        e,
        i,
        "--start",
        "10",
        "--reference",
        g,
        "--json",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let c = &v["reference_check"];
    let diff = c["scale_difference"].as_f64().unwrap();
    let angle = c["gravity_angle_deg"].as_f64().unwrap();
    assert!(diff.abs() < 0.02, "scale difference {diff}");
    assert!(angle < 1.0, "gravity {angle}°");
    assert!(v["scale_sigma"].as_f64().unwrap() > 0.0);
    let o = bin(&["imu-init", e, i, "--start", "10", "--reference", g]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("reference      Horn fit"), "{text}");
    assert!(text.contains("accel bias"), "{text}");
}
