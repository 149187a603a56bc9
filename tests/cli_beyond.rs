//! `slam2world align` with the options beyond one fit, as a user runs it.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_slam2world"))
        .args(args)
        .output()
        .expect("the slam2world binary runs")
}

fn data(file: &str) -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data/euroc_mh01_orbslam3_mono")
        .join(file);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("skipped: {} is absent", p.display());
        None
    }
}

/// The ORB-SLAM3 file with its nanosecond stamps turned into seconds.
fn seconds_copy(src: &Path, dst: &Path) {
    let text = std::fs::read_to_string(src).unwrap();
    let mut out = String::new();
    for line in text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
    {
        let mut it = line.split_whitespace();
        let t: f64 = it.next().unwrap().parse().unwrap();
        let rest: Vec<&str> = it.collect();
        out += &format!("{:.9} {}\n", t * 1e-9, rest.join(" "));
    }
    std::fs::write(dst, out).unwrap();
}

const T_BS: &str = "0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975, \
                    0.999557249008, 0.0149672133247, 0.025715529948, -0.064676986768, \
                    -0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949, \
                    0, 0, 0, 1";

#[test]
fn align_reports_cut_offset_inliers_and_intervals() {
    let (Some(est), Some(gt)) = (data("f_dataset-MH01_mono.txt"), data("MH_01_easy.txt")) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let e = dir.path().join("est.txt");
    seconds_copy(&est, &e);
    let (e, r) = (e.to_str().unwrap(), gt.to_str().unwrap());
    let o = bin(&[
        "align",
        e,
        r,
        "--skip-init",
        "auto",
        "--estimate-offset",
        "--body-from-cam",
        T_BS,
        "--json",
    ]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let b = &v["beyond"];
    let start = b["fit_start"].as_u64().unwrap();
    assert!(start > 0 && start as usize == b["stages"]["stable_start"].as_u64().unwrap() as usize);
    assert!(b["skip_reason"].as_str().unwrap().contains("dropped"));
    assert!(b["offset"].as_f64().unwrap().abs() < 0.05);
    let s = v["scale"].as_f64().unwrap();
    let iv = b["intervals"]["scale"].as_array().unwrap();
    assert!(iv[0].as_f64().unwrap() < s && s < iv[1].as_f64().unwrap());
    // The extrinsic lowers the error against the body ground truth.
    let plain = bin(&["align", e, r, "--json"]);
    let p: serde_json::Value = serde_json::from_slice(&plain.stdout).unwrap();
    let with = bin(&["align", e, r, "--json", "--body-from-cam", T_BS]);
    let w: serde_json::Value = serde_json::from_slice(&with.stdout).unwrap();
    let (before, after) = (
        p["ape"]["rmse"].as_f64().unwrap(),
        w["ape"]["rmse"].as_f64().unwrap(),
    );
    eprintln!("APE rmse without the extrinsic {before:.5} m, with {after:.5} m");
    assert!(after < 0.8 * before);
    let text = bin(&["align", e, r, "--robust"]);
    assert!(String::from_utf8_lossy(&text.stdout).contains("robust fit:"));
}

#[test]
fn bad_beyond_options_are_usage_errors() {
    for args in [
        vec!["align", "a", "b", "--skip-init", "sometimes"],
        vec!["align", "a", "b", "--body-from-cam", "1,2,3"],
        vec!["align", "a", "b", "--inlier-threshold", "0.1"],
        vec!["align", "a", "b", "--confidence", "2"],
    ] {
        let o = bin(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        assert!(!String::from_utf8_lossy(&o.stderr).contains("panicked"));
    }
}
