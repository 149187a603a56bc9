//! `--dof`, `--anchor`, `--association`, `--max-tilt` and the fit-quality
//! refusals through the command line, as a user runs them: `align` (text and
//! JSON), `transform-cloud`; exit 1 with one line for refused fits.

use crate::common::{bin, data, stderr};
use std::path::{Path, PathBuf};

/// TUM files: a gravity-aligned path (`ref`) and the estimate `est` with
/// `ref = T · est`, `T` a yaw, a translation, a scale 2 and a tilt of
/// `tilt_deg` about x; `noise` (metres) added to the estimate per axis by a
/// fixed pattern.
fn files(dir: &Path, tilt_deg: f64, noise: f64) -> (PathBuf, PathBuf) {
    let (est, reference) = (dir.join("est.txt"), dir.join("ref.txt"));
    let (mut e, mut r) = (String::new(), String::new());
    let (c, s) = (0.6f64.cos(), 0.6f64.sin());
    let (ct, st) = (tilt_deg.to_radians().cos(), tilt_deg.to_radians().sin());
    for i in 0..60 {
        let t = i as f64 * 0.1;
        let p = [3.0 * (0.5 * t).cos(), 2.0 * (0.7 * t).sin(), 0.2 * t];
        // est = (Rx(tilt)ᵀ · Rz(0.6)ᵀ · (p − (1, 2, 3))) / 2 + noise
        let q = [p[0] - 1.0, p[1] - 2.0, p[2] - 3.0];
        let z = [c * q[0] + s * q[1], -s * q[0] + c * q[1], q[2]];
        let x = [z[0], ct * z[1] + st * z[2], -st * z[1] + ct * z[2]];
        let wiggle = noise * ((i * 7 % 5) as f64 - 2.0);
        e += &format!(
            "{t} {} {} {} 0 0 0 1\n",
            x[0] / 2.0 + wiggle,
            x[1] / 2.0 - wiggle,
            x[2] / 2.0
        );
        r += &format!("{t} {} {} {} 0 0 0 1\n", p[0], p[1], p[2]);
    }
    std::fs::write(&est, e).unwrap();
    std::fs::write(&reference, r).unwrap();
    (est, reference)
}

fn first_position(path: &Path) -> [f64; 3] {
    let text = std::fs::read_to_string(path).unwrap();
    let v: Vec<f64> = text
        .lines()
        .next()
        .unwrap()
        .split_whitespace()
        .map(|x| x.parse().unwrap())
        .collect();
    [v[1], v[2], v[3]]
}

fn json(args: &[&str]) -> serde_json::Value {
    let o = bin(args);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    serde_json::from_slice(&o.stdout).unwrap()
}

fn apply(v: &serde_json::Value, p: [f64; 3]) -> [f64; 3] {
    let m = &v["rotation"];
    let (s, t) = (v["scale"].as_f64().unwrap(), &v["translation"]);
    std::array::from_fn(|i| {
        s * (0..3)
            .map(|j| m[i][j].as_f64().unwrap() * p[j])
            .sum::<f64>()
            + t[i].as_f64().unwrap()
    })
}

#[test]
fn anchor_first_puts_the_first_pose_on_its_reference() {
    let dir = tempfile::tempdir().unwrap();
    let (est, reference) = files(dir.path(), 0.0, 0.01);
    let (e, r) = (est.to_str().unwrap(), reference.to_str().unwrap());
    let (p0, q0) = (first_position(&est), first_position(&reference));
    for dof in ["sim3", "se3", "4dof", "scale+4dof"] {
        let free = json(&["align", e, r, "--json", "--dof", dof]);
        let pinned = json(&["align", e, r, "--json", "--dof", dof, "--anchor", "first"]);
        let err = |v: &serde_json::Value| {
            let a = apply(v, p0);
            (0..3).map(|i| (a[i] - q0[i]).powi(2)).sum::<f64>().sqrt()
        };
        assert!(err(&pinned) < 1e-9, "{dof}: {}", err(&pinned));
        assert!(err(&free) > 1e-4, "{dof}: {}", err(&free));
        assert!(pinned["ape"]["min"].as_f64().unwrap() < 1e-9);
        assert_eq!(pinned["fit"]["dof"], dof);
        assert_eq!(pinned["fit"]["anchor"], "first");
        assert_eq!(pinned["fit"]["association"], "evo");
        assert!(
            pinned["fit"]["dof_diagnostics"]["yaw_determinacy"]
                .as_f64()
                .unwrap()
                > 0.9
        );
        assert_eq!(pinned["with_scale"], dof == "sim3" || dof == "scale+4dof");
    }
    // The text names the dof and what it adds.
    let o = bin(&["align", e, r, "--dof", "4dof", "--anchor", "first"]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("T_ref_est (4 DoF: translation + yaw)"),
        "{text}"
    );
    assert!(
        text.contains("fit: dof 4dof, anchor first, association evo"),
        "{text}"
    );
    // The wiggle tilts the Sim(3) fit a little; the 4-DoF fit went through.
    let tilt: f64 = text
        .split("gravity tilt of the Sim(3) fit: ")
        .nth(1)
        .and_then(|rest| rest.split(" deg").next())
        .and_then(|x| x.parse().ok())
        .unwrap_or_else(|| panic!("{text}"));
    assert!(tilt < 2.0, "{text}");
}

#[test]
fn tilted_gravity_exits_1_with_one_line_naming_the_angle() {
    let dir = tempfile::tempdir().unwrap();
    let (est, reference) = files(dir.path(), 4.0, 0.0);
    let (e, r) = (est.to_str().unwrap(), reference.to_str().unwrap());
    let o = bin(&["align", e, r, "--dof", "4dof"]);
    assert_eq!(o.status.code(), Some(1));
    let msg = stderr(&o);
    assert_eq!(msg.lines().count(), 1, "{msg}");
    assert!(msg.contains("gravity is tilted"), "{msg}");
    assert!(msg.contains("4.000 deg"), "{msg}");
    assert!(msg.contains("2 deg a 4dof fit allows"), "{msg}");
    assert!(o.stdout.is_empty());
    // A looser limit, or none, accepts it; sim3 fits it exactly.
    for limit in ["5", "none"] {
        let o = bin(&["align", e, r, "--dof", "scale+4dof", "--max-tilt", limit]);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    }
    let v = json(&["align", e, r, "--json"]);
    assert!(v["ape"]["rmse"].as_f64().unwrap() < 1e-9);
    // Flags that contradict each other, or values out of their domain.
    let o = bin(&["align", e, r, "--dof", "scale+4dof", "--no-scale"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("scale+4dof"), "{}", stderr(&o));
    for bad in [
        vec!["--dof", "6dof"],
        vec!["--anchor", "last"],
        vec!["--association", "nearest"],
        vec!["--max-tilt", "-1"],
    ] {
        let mut args = vec!["align", e, r];
        args.extend(bad.iter().copied());
        let o = bin(&args);
        assert_eq!(o.status.code(), Some(2), "{bad:?}: {}", stderr(&o));
    }
}

#[test]
fn one_to_one_reproduces_the_tum_benchmark_end_to_end() {
    let (Some(gt), Some(est)) = (
        data("evo_tum_fr2_desk", "fr2_desk_groundtruth.txt"),
        data("evo_tum_fr2_desk", "fr2_desk_ORB.txt"),
    ) else {
        return;
    };
    let (g, e) = (gt.to_str().unwrap(), est.to_str().unwrap());
    // evaluate_ate.py fr2_desk_groundtruth.txt fr2_desk_ORB.txt (0.02 s, SE(3)).
    let v = json(&[
        "align",
        e,
        g,
        "--json",
        "--association",
        "one_to_one",
        "--max-diff",
        "0.02",
        "--dof",
        "se3",
    ]);
    assert_eq!(v["n_pairs"], 2223);
    assert!((v["ape"]["rmse"].as_f64().unwrap() - 0.008144).abs() < 5e-7);
    assert_eq!(v["fit"]["association"], "one_to_one");
    assert_eq!(v["with_scale"], false);
    // evo's rule at evo's window: evo's figure.
    let v = json(&["align", e, g, "--json", "--no-scale"]);
    assert_eq!(v["n_pairs"], 2174);
    assert!((v["ape"]["rmse"].as_f64().unwrap() - 0.008119).abs() < 5e-7);
    assert_eq!(v["fit"]["dof"], "se3");
}

#[test]
fn a_static_reference_exits_1_and_transform_cloud_takes_the_flags() {
    let dir = tempfile::tempdir().unwrap();
    let (est, reference) = files(dir.path(), 0.0, 0.01);
    let (e, r) = (est.to_str().unwrap(), reference.to_str().unwrap());
    // A receiver that stands still: the fixes scatter by a few centimetres.
    let still = dir.path().join("still.txt");
    let mut text = String::new();
    for i in 0..60 {
        let j = (i * 37 % 11) as f64 / 11.0 - 0.5;
        let k = (i * 17 % 7) as f64 / 7.0 - 0.5;
        text += &format!(
            "{} {} {} {} 0 0 0 1\n",
            i as f64 * 0.1,
            5.0 + 0.03 * j,
            0.03 * k,
            0.02 * j * k
        );
    }
    std::fs::write(&still, text).unwrap();
    let s = still.to_str().unwrap();
    let o = bin(&["align", e, s]);
    assert_eq!(o.status.code(), Some(1));
    let msg = stderr(&o);
    assert_eq!(msg.lines().count(), 1, "{msg}");
    assert!(msg.contains("the reference does not move"), "{msg}");
    let o = bin(&["align", e, s, "--no-fit-checks"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // A stated noise below the scatter's own: the reference moves enough.
    let o = bin(&["align", e, s, "--reference-noise", "0.001"]);
    assert_ne!(o.status.code(), Some(2), "{}", stderr(&o));

    // transform-cloud: the pipeline with the text-file source, every flag.
    let cloud = dir.path().join("pts.txt");
    std::fs::write(&cloud, "0 0 0\n1 0 0\n0 1 0\n").unwrap();
    let out = dir.path().join("world.ply");
    let o = bin(&[
        "transform-cloud",
        cloud.to_str().unwrap(),
        "--align",
        e,
        r,
        "-o",
        out.to_str().unwrap(),
        "--dof",
        "scale+4dof",
        "--anchor",
        "first",
        "--association",
        "one_to_one",
        "--max-tilt",
        "1",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(out.exists());
    let o = bin(&[
        "transform-cloud",
        cloud.to_str().unwrap(),
        "--align",
        e,
        s,
        "-o",
        dir.path().join("no.ply").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("does not move"), "{}", stderr(&o));
}
