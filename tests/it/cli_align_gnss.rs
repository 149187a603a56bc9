//! `slam2world align` against GNSS fixes: a REF file of fixes (CSV, NMEA;
//! found from its lines) or a log's fix topic is the reference in ENU at the
//! origin, fitted as `convert` fits it (the same APE on the same data).

use std::path::{Path, PathBuf};

use nalgebra::{UnitQuaternion, Vector3};
use slam2world::geo::{EnuFrame, Geodetic};

use crate::common::{bin, data, stderr};

/// The ENU origin of the synthetic track (Munich).
const ORIGIN: (f64, f64, f64) = (48.1372, 11.5755, 519.0);

/// A drive in ENU metres at `t` seconds: loops with a slope.
fn enu_at(t: f64) -> Vector3<f64> {
    Vector3::new(
        40.0 * (0.05 * t).sin(),
        25.0 * (0.08 * t).cos() + 0.5 * t,
        0.02 * t,
    )
}

/// `T_enu_est`: scale 2.5, yaw 30° with a small tilt, a translation.
fn truth() -> (f64, UnitQuaternion<f64>, Vector3<f64>) {
    (
        2.5,
        UnitQuaternion::from_euler_angles(0.01, -0.02, 30f64.to_radians()),
        Vector3::new(5.0, -3.0, 1.0),
    )
}

/// A TUM estimate with stamps in nanoseconds (ORB-SLAM3's `kf_*.txt` way)
/// and a CSV of 10 Hz fixes at Unix seconds (with variances when `variances`).
fn synthetic(dir: &Path, variances: bool) -> (PathBuf, PathBuf) {
    let frame = EnuFrame::new(Geodetic::try_new(ORIGIN.0, ORIGIN.1, ORIGIN.2).unwrap()).unwrap();
    let (s, q, t) = truth();
    let t0 = 1_700_000_000.0;
    let mut est = String::from("# timestamp tx ty tz qx qy qz qw\n");
    let mut fixes = String::from(if variances {
        "time,lat,lon,alt,var_e,var_n,var_u\n"
    } else {
        "time,lat,lon,alt\n"
    });
    for i in 0..600 {
        let time = i as f64 * 0.1;
        let p = enu_at(time);
        let g = frame.enu_to_geodetic(&p).unwrap();
        fixes += &format!("{},{},{},{}", t0 + time, g.lat, g.lon, g.alt);
        if variances {
            let v = 0.01 * (1 + i % 3) as f64;
            fixes += &format!(",{v},{v},{}", 4.0 * v);
        }
        fixes.push('\n');
        // Every other fix has a keyframe; est = T⁻¹ · enu.
        if i % 2 == 0 {
            let e = q.inverse() * (p - t) / s;
            let ns = (t0 * 1e9) as i64 + (time * 1e9).round() as i64;
            est += &format!("{ns} {} {} {} 0 0 0 1\n", e.x, e.y, e.z);
        }
    }
    let (e, f) = (dir.join("kf.txt"), dir.join("fixes.csv"));
    std::fs::write(&e, est).unwrap();
    std::fs::write(&f, fixes).unwrap();
    (e, f)
}

fn json(args: &[&str]) -> serde_json::Value {
    let o = bin(args);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    serde_json::from_slice(&o.stdout).unwrap()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn fixes_are_the_reference_in_enu_at_the_origin() {
    let dir = tempfile::tempdir().unwrap();
    for variances in [false, true] {
        let (est, fixes) = synthetic(dir.path(), variances);
        let origin = format!("{},{},{}", ORIGIN.0, ORIGIN.1, ORIGIN.2);
        let v = json(&["align", s(&est), s(&fixes), "--origin", &origin, "--json"]);
        let (scale, q, t) = truth();
        assert!(
            (v["scale"].as_f64().unwrap() / scale - 1.0).abs() < 1e-9,
            "{v}"
        );
        let got: Vec<f64> = (0..3)
            .map(|k| v["translation"][k].as_f64().unwrap())
            .collect();
        assert!((Vector3::from_vec(got) - t).norm() < 1e-6, "{v}");
        let qx: Vec<f64> = (0..4)
            .map(|k| v["quaternion_xyzw"][k].as_f64().unwrap())
            .collect();
        let fitted =
            UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(qx[3], qx[0], qx[1], qx[2]));
        assert!(fitted.angle_to(&q) < 1e-9, "{v}");
        assert!(v["ape"]["rmse"].as_f64().unwrap() < 1e-6, "{v}");
        assert_eq!(v["n_pairs"], 300);
        // The estimate's nanoseconds are found against the fixes' seconds.
        assert_eq!(v["time_units"]["est"], "ns");
        assert_eq!(v["time_units"]["est_detected"], true);
        let g = &v["gnss"];
        assert_eq!(g["fixes"], 600);
        assert_eq!(g["origin_rule"], "given");
        assert_eq!(g["utm_zone"], "32N");
        assert_eq!(g["weighted"], variances);
        assert_eq!(g["file"], s(&fixes));
    }
}

#[test]
fn the_reference_kind_is_found_or_given() {
    let dir = tempfile::tempdir().unwrap();
    let (est, fixes) = synthetic(dir.path(), false);
    // Text: the GNSS line and the ENU frame named.
    let o = bin(&["align", s(&est), s(&fixes)]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("600 fixes"), "{text}");
    // ENU at the first fix, 25 m north of the drive's origin: T_enu_est moves with it.
    assert!(text.contains("world = ENU at lat 48.1374248"), "{text}");
    assert!(text.contains("(first), UTM zone 32N"), "{text}");
    assert!(
        text.contains("translation  [5.000000000, -28.0000"),
        "{text}"
    );
    // Said to be TUM, the fixes are refused as TUM rows: one line, exit 1.
    let o = bin(&["align", s(&est), s(&fixes), "--ref-format", "tum"]);
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(stderr(&o).lines().count(), 1, "{}", stderr(&o));
    // Fixes have no orientations to calibrate a camera against.
    let o = bin(&["align", s(&est), s(&fixes), "--estimate-body-from-cam"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("GNSS fixes have none"),
        "{}",
        stderr(&o)
    );
    // A TUM reference is not taken for fixes.
    let reference = dir.path().join("ref.txt");
    let est_text = std::fs::read_to_string(&est).unwrap();
    let seconds: String = est_text
        .lines()
        .skip(1)
        .map(|l| {
            let (ns, rest) = l.split_once(' ').unwrap();
            format!("{} {rest}\n", ns.parse::<f64>().unwrap() / 1e9)
        })
        .collect();
    std::fs::write(&reference, seconds).unwrap();
    let v = json(&["align", s(&est), s(&reference), "--json"]);
    assert!(v.get("gnss").is_none(), "{v}");
    assert!((v["scale"].as_f64().unwrap() - 1.0).abs() < 1e-9);
    // --gnss-format names the format where the lines do not show it.
    let odd = dir.path().join("fixes.dat");
    let csv = std::fs::read_to_string(&fixes).unwrap();
    std::fs::write(&odd, csv.replace(',', " ")).unwrap();
    let v = json(&["align", s(&est), s(&odd), "--gnss-format", "csv", "--json"]);
    assert_eq!(v["gnss"]["fixes"], 600);
}

/// `convert`'s report of the same fit, in a temporary folder.
fn convert_report(args: &[&str]) -> serde_json::Value {
    let dir = tempfile::tempdir().unwrap();
    let mut all = vec!["convert"];
    all.extend_from_slice(args);
    all.extend_from_slice(&["-o", s(dir.path())]);
    let o = bin(&all);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    serde_json::from_str(&std::fs::read_to_string(dir.path().join("report.json")).unwrap()).unwrap()
}

fn same_ape(a: &serde_json::Value, c: &serde_json::Value) {
    for k in ["rmse", "mean", "median", "std", "min", "max", "n_pairs"] {
        let (x, y) = (a["ape"][k].as_f64().unwrap(), c["ape"][k].as_f64().unwrap());
        assert!(
            (x - y).abs() <= 1e-9 * y.abs().max(1.0),
            "{k}: align {x}, convert {y}"
        );
    }
}

#[test]
fn fourseasons_vio_against_its_rtk_nmea_as_convert_fits_it() {
    let (Some(vio), Some(nmea)) = (
        data("fourseasons_sample", "result.txt"),
        data("fourseasons_sample", "septentrio.nmea"),
    ) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("ape.png");
    let html = dir.path().join("ape.html");
    let fit = ["--dof", "scale+4dof", "--max-diff", "0.05"];
    let mut args = vec!["align", s(&vio), s(&nmea), "--json", "--save-plot", s(&map)];
    args.extend_from_slice(&["--html", s(&html)]);
    args.extend_from_slice(&fit);
    let a = json(&args);
    let mut args = vec![s(&vio), "--gnss", s(&nmea)];
    args.extend_from_slice(&fit);
    let c = convert_report(&args);
    same_ape(&a, &c);
    assert_eq!(a["gnss"]["fixes"], 3414);
    // PROVENANCE.md: the VIO scale is about 0.96-0.98 of GNSS.
    assert!((0.96..0.98).contains(&a["scale"].as_f64().unwrap()), "{a}");
    for p in [
        dir.path().join("ape_map.png"),
        dir.path().join("ape_raw.png"),
        html,
    ] {
        assert!(
            std::fs::metadata(&p).unwrap().len() > 10_000,
            "{}",
            p.display()
        );
    }
}

#[test]
fn a_one_hz_receiver_pairs_as_a_ten_hz_one() {
    let (Some(vio), Some(nmea)) = (
        data("fourseasons_sample", "result.txt"),
        data("fourseasons_sample", "septentrio.nmea"),
    ) else {
        return;
    };
    // The 10 Hz log cut to the sentences of whole seconds: what most receivers log.
    let dir = tempfile::tempdir().unwrap();
    let one_hz = dir.path().join("1hz.nmea");
    let text = String::from_utf8_lossy(&std::fs::read(&nmea).unwrap()).into_owned();
    let whole: String = text
        .lines()
        .filter(|l| {
            l.split(',')
                .nth(1)
                .is_some_and(|t| t.len() > 7 && t[7..].bytes().all(|b| b == b'0'))
        })
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(&one_hz, whole).unwrap();
    let ten = json(&["align", s(&vio), s(&nmea), "--json"]);
    let one = json(&["align", s(&vio), s(&one_hz), "--json"]);
    assert!(
        one["gnss"]["fixes"].as_u64().unwrap() < 400,
        "{}",
        one["gnss"]
    );
    assert!((one["gnss"]["max_gap"].as_f64().unwrap() - 5.0).abs() < 1e-6);
    // Every VIO pose within the fixes' span is paired; the fit is the 10 Hz one's.
    assert!(
        one["n_pairs"].as_u64().unwrap() > 9900,
        "{}",
        one["n_pairs"]
    );
    let (s1, s10) = (
        one["scale"].as_f64().unwrap(),
        ten["scale"].as_f64().unwrap(),
    );
    assert!((s1 / s10 - 1.0).abs() < 1e-3, "{s1} {s10}");
    // A gap given in seconds holds: 0.5 s bridges no 1 s interval.
    let o = bin(&["align", s(&vio), s(&one_hz), "--gnss-max-gap", "0.5"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("at most 0.5 s apart"), "{}", stderr(&o));
}

#[test]
fn husky_wheel_odometry_against_its_fix_topic_as_convert_fits_it() {
    let Some(bag) = data("ros1_husky_gps", "test1.bag") else {
        return;
    };
    let topics = [
        "--est-topic",
        "/husky_velocity_controller/odom",
        "--gnss-topic",
        "/fix",
    ];
    let fit = ["--dof", "4dof", "--max-tilt", "none"];
    let mut args = vec!["align", s(&bag), "--json"];
    args.extend_from_slice(&topics);
    args.extend_from_slice(&fit);
    let a = json(&args);
    let mut args = vec![s(&bag)];
    args.extend_from_slice(&topics);
    args.extend_from_slice(&fit);
    let c = convert_report(&args);
    same_ape(&a, &c);
    assert_eq!(a["gnss"]["topic"], "/fix");
    assert_eq!(a["gnss"]["fixes"], 989);
    assert_eq!(a["ref"], format!("{}:/fix", bag.display()));
    assert_eq!(a["scale"], 1.0);
}
