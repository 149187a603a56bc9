//! `slam2world align` as a user runs it: exit codes 0 / 1 (bad data, one
//! line) / 2 (usage), text and JSON output.

use crate::common::{bin, data, stderr};
use std::path::{Path, PathBuf};

/// A synthetic pair of TUM files: `est` is `ref` mapped by a known Sim(3) inverse.
fn synthetic(dir: &Path) -> (PathBuf, PathBuf) {
    let (est, reference) = (dir.join("est.txt"), dir.join("ref.txt"));
    let mut e = String::from("# t x y z qx qy qz qw\n");
    let mut r = String::new();
    for i in 0..40 {
        let t = i as f64 * 0.1;
        let p = [t.sin(), (2.0 * t).cos(), 0.3 * t];
        // ref = 4 · Rz(90°) · est + (1, 2, 3)  ⇒  est = Rz(−90°)(ref − t) / 4
        let q = [p[0] - 1.0, p[1] - 2.0, p[2] - 3.0];
        let s = [q[1] / 4.0, -q[0] / 4.0, q[2] / 4.0];
        e += &format!("{t} {} {} {} 0 0 0 1\n", s[0], s[1], s[2]);
        r += &format!("{t} {} {} {} 0 0 0 1\n", p[0], p[1], p[2]);
    }
    std::fs::write(&est, e).unwrap();
    std::fs::write(&reference, r).unwrap();
    (est, reference)
}

#[test]
fn prints_transform_and_ape_and_exits_0() {
    let dir = tempfile::tempdir().unwrap();
    let (est, reference) = synthetic(dir.path());
    let (e, r) = (est.to_str().unwrap(), reference.to_str().unwrap());
    let o = bin(&["align", e, r]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("matched 40 pairs"), "{text}");
    assert!(text.contains("scale        4.000000000000"), "{text}");

    let o = bin(&["align", e, r, "--json", "--method", "umeyama"]);
    assert_eq!(o.status.code(), Some(0));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!((v["scale"].as_f64().unwrap() - 4.0).abs() < 1e-9);
    let t: Vec<f64> = v["translation"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert!((t[0] - 1.0).abs() < 1e-9 && (t[1] - 2.0).abs() < 1e-9 && (t[2] - 3.0).abs() < 1e-9);
    assert!(v["ape"]["rmse"].as_f64().unwrap() < 1e-9);
    assert_eq!(v["ape"]["n_pairs"], 40);

    let o = bin(&["align", e, r, "--json", "--no-scale", "--n-to-align", "10"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["scale"], 1.0);
    assert_eq!(v["n_fitted"], 10);
    // An offset of a whole second moves every pair off its match but 30 remain.
    let o = bin(&["align", e, r, "--json", "--offset", "-1.0"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["n_pairs"], 30);
}

#[test]
fn bad_data_exits_1_with_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let (est, reference) = synthetic(dir.path());
    let (e, r) = (est.to_str().unwrap(), reference.to_str().unwrap());
    let bad = dir.path().join("bad.txt");
    std::fs::write(&bad, "0 1 2 3 0 0 0 1\n0.1 nan 2 3 0 0 0 1\n").unwrap();
    let line = dir.path().join("line.txt");
    let coincident = dir.path().join("same.txt");
    let (mut l, mut c) = (String::new(), String::new());
    for i in 0..40 {
        let t = i as f64 * 0.1;
        l += &format!("{t} {t} {} {} 0 0 0 1\n", 2.0 * t, -t);
        c += &format!("{t} 1 1 1 0 0 0 1\n");
    }
    std::fs::write(&line, l).unwrap();
    std::fs::write(&coincident, c).unwrap();
    let missing = dir.path().join("missing.txt");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec![missing.to_str().unwrap(), r], "missing.txt"),
        (vec![bad.to_str().unwrap(), r], "bad.txt:2"),
        (
            vec![line.to_str().unwrap(), line.to_str().unwrap()],
            "collinear",
        ),
        (vec![coincident.to_str().unwrap(), r], "coincide"),
        (vec![e, r, "--offset", "100"], "match a reference pose"),
        (vec![e, r, "--n-to-align", "2"], "at least 3"),
        (vec![e, r, "--ref-format", "euroc"], "comma-separated"),
    ];
    for (args, needle) in cases {
        let mut all = vec!["align"];
        all.extend(args);
        let o = bin(&all);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{all:?}: {err}");
        assert!(err.starts_with("slam2world: error: "), "{err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(err.contains(needle), "{all:?}: {err}");
        assert!(!err.contains("panicked"));
        assert!(o.stdout.is_empty());
    }
}

#[test]
fn usage_errors_exit_2() {
    for args in [
        vec!["align"],
        vec!["align", "a.txt"],
        vec!["align", "a", "b", "--format", "csv"],
        vec!["align", "a", "b", "--max-diff", "-1"],
        vec!["align", "a", "b", "--max-diff", "nan"],
        vec!["align", "a", "b", "--n-to-align", "x"],
        vec!["align", "a", "b", "--bogus"],
    ] {
        let o = bin(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        assert!(!stderr(&o).contains("panicked"));
    }
    let o = bin(&["align", "--help"]);
    assert_eq!(o.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&o.stdout).contains("--n-to-align"));
}

#[test]
fn real_data_matches_evo_numbers() {
    let (Some(gt), Some(est)) = (
        data("euroc_v102", "V102_groundtruth.csv"),
        data("euroc_v102", "V102.txt"),
    ) else {
        return;
    };
    let o = bin(&[
        "align",
        est.to_str().unwrap(),
        gt.to_str().unwrap(),
        "--ref-format",
        "euroc",
        "--json",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    // PROVENANCE.md (evo 1.38.1 -as): 798 pairs, scale 0.9796982521745786, rmse 0.083841.
    assert_eq!(v["n_pairs"], 798);
    assert!((v["scale"].as_f64().unwrap() / 0.9796982521745786 - 1.0).abs() < 1e-9);
    assert!((v["ape"]["rmse"].as_f64().unwrap() - 0.083841).abs() < 5e-7);
}

/// The TUM file `from` written to `to` with each stamp `t` as `f(t)`
/// (comment lines left out).
fn restamped(from: &Path, to: &Path, f: impl Fn(f64) -> f64) {
    let rows: String = std::fs::read_to_string(from)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| {
            let (t, rest) = l.split_once(' ').unwrap();
            format!("{} {rest}\n", f(t.parse().unwrap()))
        })
        .collect();
    std::fs::write(to, rows).unwrap();
}

/// ORB-SLAM3's keyframes of EuRoC MH01 (`kf_*.txt`, nanoseconds) against the
/// ground truth in seconds, and the same file rewritten in ms, µs and s:
/// every one aligns with no flag, reads in its unit and gives one fit.
#[test]
fn stamp_units_are_found_against_the_reference() {
    let (Some(kf), Some(gt)) = (
        data("euroc_mh01_orbslam3_mono", "kf_dataset-MH01_mono.txt"),
        data("euroc_mh01_orbslam3_mono", "MH_01_easy.txt"),
    ) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let mut fits = Vec::new();
    for (unit, per_ns) in [("ns", 1.0), ("us", 1e-3), ("ms", 1e-6), ("s", 1e-9)] {
        let est = if unit == "ns" {
            kf.clone()
        } else {
            let f = dir.path().join(format!("kf_{unit}.txt"));
            // From the integer nanoseconds, so each variant is exact in its unit.
            restamped(&kf, &f, |ns| ns * per_ns);
            f
        };
        let o = bin(&[
            "align",
            est.to_str().unwrap(),
            gt.to_str().unwrap(),
            "--json",
        ]);
        assert_eq!(o.status.code(), Some(0), "{unit}: {}", stderr(&o));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(v["time_units"]["est"], unit);
        assert_eq!(v["time_units"]["ref"], "s");
        assert_eq!(v["time_units"]["est_detected"], true);
        let text = bin(&["align", est.to_str().unwrap(), gt.to_str().unwrap()]);
        assert!(
            String::from_utf8_lossy(&text.stdout).contains(&format!(
                "stamps read in {unit} for EST (found), s for REF (found)"
            )),
            "{}",
            String::from_utf8_lossy(&text.stdout)
        );
        fits.push((
            v["n_pairs"].as_u64().unwrap(),
            v["scale"].as_f64().unwrap(),
            v["ape"]["rmse"].as_f64().unwrap(),
        ));
    }
    let (n, scale, rmse) = fits[0];
    assert!(n > 100, "{n} pairs");
    for (k, &(m, s, r)) in fits.iter().enumerate() {
        assert_eq!(m, n, "variant {k}");
        assert!(
            (s / scale - 1.0).abs() < 1e-6 && (r - rmse).abs() < 1e-6,
            "variant {k}: {s} {r} against {scale} {rmse}"
        );
    }
    // A unit given wrong: the one refusal, naming the likely cause.
    let o = bin(&[
        "align",
        kf.to_str().unwrap(),
        gt.to_str().unwrap(),
        "--est-time-unit",
        "s",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("look like nanoseconds"),
        "{}",
        stderr(&o)
    );
    // Given right, the same fit, reported as given.
    let o = bin(&[
        "align",
        kf.to_str().unwrap(),
        gt.to_str().unwrap(),
        "--est-time-unit",
        "ns",
        "--json",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["time_units"]["est_detected"], false);
    assert_eq!(v["scale"].as_f64().unwrap(), scale);
    // A day later: no unit explains it, so the refusal says what it sees.
    let later = dir.path().join("gt_later.txt");
    restamped(&gt, &later, |t| t + 86400.0);
    let o = bin(&["align", kf.to_str().unwrap(), later.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("do not overlap") && e.lines().count() == 1,
        "{e}"
    );
}

/// Issue 38: every automatic option at once (stamp units found, `--skip-init
/// auto`, `--estimate-offset`) on the real pairs gives the fit a careful user
/// gets with the units, pairing and no cut set by hand (evo's numbers): the
/// same scale to 0.5 %, an APE no worse by more than 2 %, at least 90 % of
/// the pairs kept (real runs start after the SLAM's initialisation).
#[test]
fn automatic_options_give_the_hand_set_fit_on_real_pairs() {
    let runs: [(&str, &str, &str, &[&str]); 6] = [
        (
            "euroc_mh01_orbslam3_mono",
            "f_dataset-MH01_mono.txt",
            "MH_01_easy.txt",
            &["--est-time-unit", "ns"],
        ),
        (
            "euroc_mh01_orbslam3_mono",
            "kf_dataset-MH01_mono.txt",
            "MH_01_easy.txt",
            &["--est-time-unit", "ns"],
        ),
        (
            "euroc_v101_orbslam2_map",
            "KeyFrameTrajectory_TUM_Format.txt",
            "V1_01_easy_original.txt",
            &[],
        ),
        (
            "euroc_v102",
            "V102.txt",
            "V102_groundtruth.csv",
            &["--ref-format", "euroc"],
        ),
        (
            "evo_tum_fr1_xyz",
            "freiburg1_xyz-ORB_kf_mono.txt",
            "freiburg1_xyz-groundtruth.txt",
            &[],
        ),
        (
            "evo_tum_fr2_desk",
            "fr2_desk_ORB_kf_mono.txt",
            "fr2_desk_groundtruth.txt",
            &[],
        ),
    ];
    for (folder, est, gt, hand) in runs {
        let (Some(est), Some(gt)) = (data(folder, est), data(folder, gt)) else {
            continue;
        };
        let fit = |extra: &[&str]| -> serde_json::Value {
            let mut args = vec![
                "align",
                est.to_str().unwrap(),
                gt.to_str().unwrap(),
                "--json",
            ];
            args.extend_from_slice(extra);
            let o = bin(&args);
            assert_eq!(o.status.code(), Some(0), "{folder}: {}", stderr(&o));
            serde_json::from_slice(&o.stdout).unwrap()
        };
        let by_hand = fit(hand);
        let ref_format: &[&str] = if hand.contains(&"euroc") {
            &["--ref-format", "euroc"]
        } else {
            &[]
        };
        let mut auto_args = vec!["--skip-init", "auto", "--estimate-offset"];
        auto_args.extend_from_slice(ref_format);
        let auto = fit(&auto_args);
        let f = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap();
        let rmse = |v: &serde_json::Value| v["ape"]["rmse"].as_f64().unwrap();
        assert!(
            (f(&auto, "scale") / f(&by_hand, "scale") - 1.0).abs() < 5e-3,
            "{folder}: scale {} by hand {}",
            f(&auto, "scale"),
            f(&by_hand, "scale")
        );
        assert!(
            rmse(&auto) <= 1.02 * rmse(&by_hand),
            "{folder}: {} vs {}",
            rmse(&auto),
            rmse(&by_hand)
        );
        assert!(
            f(&auto, "n_fitted") >= 0.9 * f(&by_hand, "n_pairs"),
            "{folder}: {} of {} fitted ({})",
            auto["n_fitted"],
            by_hand["n_pairs"],
            auto["fit"]["skip_reason"]
        );
    }
}

/// `convert` finds a reference file's stamp unit against the SLAM stamps as
/// `align` does: MH01's ORB-SLAM3 keyframes in seconds from the start and its
/// ground truth in milliseconds from the start (read alone, steps of 5 look
/// like seconds) are paired in ms, the report says so, and the fit is the
/// one of the original files.
#[test]
fn convert_reads_the_reference_unit_against_the_slam_stamps() {
    let (Some(kf), Some(gt)) = (
        data("euroc_mh01_orbslam3_mono", "kf_dataset-MH01_mono.txt"),
        data("euroc_mh01_orbslam3_mono", "MH_01_easy.txt"),
    ) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let t0 = 1_403_636_579.763_555_5;
    let (kf_rel, gt_ms) = (dir.path().join("kf.txt"), dir.path().join("gt.txt"));
    restamped(&kf, &kf_rel, |t| t * 1e-9 - t0);
    restamped(&gt, &gt_ms, |t| (t - t0) * 1e3);
    let out = dir.path().join("out");
    let o = bin(&[
        "convert",
        kf_rel.to_str().unwrap(),
        "--reference",
        gt_ms.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let text = &r["reference_file"]["text"];
    assert_eq!(text["unit"], "ms", "{text}");
    assert_eq!(text["unit_detected"], true);
    let scale = r["t_world_slam"]["scale"].as_f64().unwrap();
    // PROVENANCE.md (evo -as, keyframes): scale 5.148581120866326.
    assert!((scale / 5.148581120866326 - 1.0).abs() < 1e-6, "{scale}");
}
