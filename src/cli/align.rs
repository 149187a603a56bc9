//! `slam2world align EST REF`: associate two trajectory files by time, fit
//! `T_ref_est` (Sim(3), or SE(3) with `--no-scale`) and print it with the
//! absolute position error statistics (as `evo_ape … -as`).

use std::io::Write;
use std::path::{Path, PathBuf};

use clap::{Args, ValueEnum};

use crate::align::extended::align_trajectories_extended;
use crate::align::handeye::{estimate_body_from_cam_trajectories, HandEye};
use crate::align::AlignMethod;
use crate::error::{Error, Result};
use crate::trajectory::{Trajectory, TrajectoryAlignOptions};

/// Trajectory file formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Format {
    /// `timestamp tx ty tz qx qy qz qw` (seconds).
    Tum,
    /// EuRoC ground truth CSV: `ns, x, y, z, qw, qx, qy, qz, …`.
    Euroc,
}

/// Rotation solvers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Method {
    /// Horn's quaternion method.
    Horn,
    /// Umeyama's SVD method.
    Umeyama,
}

/// Options of `slam2world align`.
#[derive(Args, Debug)]
pub struct AlignArgs {
    /// Estimated (SLAM) trajectory file.
    #[arg(value_name = "EST")]
    est: PathBuf,
    /// Reference (ground truth, IMU) trajectory file.
    #[arg(value_name = "REF")]
    reference: PathBuf,
    /// Format of EST (and of REF unless --ref-format is given).
    #[arg(long, value_enum, default_value = "tum")]
    format: Format,
    /// Format of REF (default: the same as --format).
    #[arg(long, value_enum)]
    ref_format: Option<Format>,
    /// Largest time difference of a matched pair, seconds.
    #[arg(long, default_value_t = 0.01, value_name = "S", allow_negative_numbers = true, value_parser = non_negative)]
    max_diff: f64,
    /// Seconds added to the EST stamps before matching.
    #[arg(long, default_value_t = 0.0, value_name = "S", allow_negative_numbers = true, value_parser = finite)]
    offset: f64,
    /// Fit SE(3) (scale fixed to 1) instead of Sim(3).
    #[arg(long)]
    no_scale: bool,
    /// Fit only the first N matched pairs (the error is still over all pairs).
    #[arg(long, value_name = "N")]
    n_to_align: Option<usize>,
    /// Rotation solver.
    #[arg(long, value_enum, default_value = "horn")]
    method: Method,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
    /// Also estimate the camera–body extrinsic T_body_cam (hand-eye calibration
    /// with scale): both files need orientations, and the motion rotations about
    /// two axes at least.
    #[arg(long, conflicts_with_all = ["no_scale", "body_from_cam"])]
    estimate_body_from_cam: bool,
    #[command(flatten)]
    beyond: super::beyond::BeyondArgs,
}

/// clap parser: a finite number of seconds.
pub(crate) fn finite(s: &str) -> std::result::Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!("expected a finite number of seconds, got {s:?}")),
    }
}

/// clap parser: a finite number of seconds, `>= 0`.
pub(crate) fn non_negative(s: &str) -> std::result::Result<f64, String> {
    match finite(s) {
        Ok(v) if v >= 0.0 => Ok(v),
        _ => Err(format!("expected a number of seconds >= 0, got {s:?}")),
    }
}

/// Reads a trajectory file in the given format.
pub(crate) fn read(path: &Path, format: Format) -> Result<Trajectory> {
    match format {
        Format::Tum => Trajectory::read_tum(path),
        Format::Euroc => Trajectory::read_euroc(path),
    }
}

/// Runs the command; prints to stdout.
pub fn run(args: AlignArgs) -> Result<()> {
    let est = read(&args.est, args.format)?;
    let reference = read(&args.reference, args.ref_format.unwrap_or(args.format))?;
    let opts = TrajectoryAlignOptions {
        max_diff: args.max_diff,
        offset: args.offset,
        scale: !args.no_scale,
        first_n: args.n_to_align,
        method: match args.method {
            Method::Horn => AlignMethod::Horn,
            Method::Umeyama => AlignMethod::Umeyama,
        },
    };
    let ext = align_trajectories_extended(&est, &reference, &opts, &args.beyond.options())?;
    // The extrinsic at the offset the fit used (given plus estimated).
    let hand_eye = if args.estimate_body_from_cam {
        Some(estimate_body_from_cam_trajectories(
            &est,
            &reference,
            args.max_diff,
            ext.offset,
        )?)
    } else {
        None
    };
    let r = &ext.trajectory;
    let t = r.alignment.transform;
    let q = t.quaternion_xyzw();
    let rot = t.rotation_matrix();
    let ape = r.ape;
    let text = if args.json {
        let rows = |m: &nalgebra::Matrix3<f64>| -> Vec<[f64; 3]> {
            (0..3).map(|i| [m[(i, 0)], m[(i, 1)], m[(i, 2)]]).collect()
        };
        let v = serde_json::json!({
            "est": args.est.display().to_string(),
            "ref": args.reference.display().to_string(),
            "n_est": est.len(),
            "n_ref": reference.len(),
            "n_pairs": r.pairs.len(),
            "n_fitted": r.alignment.residuals.len(),
            "max_diff": args.max_diff,
            "offset": args.offset,
            "with_scale": !args.no_scale,
            "scale": t.scale,
            "rotation": rows(&rot),
            "quaternion_xyzw": q,
            "translation": [t.translation.x, t.translation.y, t.translation.z],
            "fit_rmse": r.alignment.rmse,
            "ape": {
                "rmse": ape.rmse, "mean": ape.mean, "median": ape.median, "std": ape.std,
                "min": ape.min, "max": ape.max, "n_pairs": ape.n_pairs,
            },
        });
        let mut v = v;
        v["beyond"] = super::beyond::report_json(&ext, args.beyond.confidence);
        if let Some((he, n)) = &hand_eye {
            v["body_from_cam_estimate"] = hand_eye_json(he, *n);
        }
        format!("{v}\n")
    } else {
        let mut s = String::new();
        s += &format!(
            "matched {} pairs of {} EST and {} REF poses (max_diff {} s, offset {} s); fitted {}\n",
            r.pairs.len(),
            est.len(),
            reference.len(),
            args.max_diff,
            args.offset,
            r.alignment.residuals.len()
        );
        s += &format!(
            "T_ref_est ({}):\n",
            if args.no_scale { "SE(3)" } else { "Sim(3)" }
        );
        s += &format!("  scale        {:.12}\n", t.scale);
        s += &format!(
            "  quaternion   [{:.9}, {:.9}, {:.9}, {:.9}]  (x, y, z, w)\n",
            q[0], q[1], q[2], q[3]
        );
        for i in 0..3 {
            s += &format!(
                "  {}  [{:12.9}, {:12.9}, {:12.9}]\n",
                if i == 0 { "rotation   " } else { "           " },
                rot[(i, 0)],
                rot[(i, 1)],
                rot[(i, 2)]
            );
        }
        s += &format!(
            "  translation  [{:.9}, {:.9}, {:.9}]\n",
            t.translation.x, t.translation.y, t.translation.z
        );
        s += &format!(
            "APE (m) over {} pairs: rmse {:.6}  mean {:.6}  median {:.6}  std {:.6}  min {:.6}  max {:.6}\n",
            ape.n_pairs, ape.rmse, ape.mean, ape.median, ape.std, ape.min, ape.max
        );
        s += &super::beyond::report_text(&ext, args.beyond.confidence);
        if let Some((he, n)) = &hand_eye {
            s += &hand_eye_text(he, *n);
        }
        s
    };
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|_| out.flush())
        .map_err(|e| Error::io("<stdout>", e))
}

/// The estimated extrinsic as JSON: `T_body_cam` and how well it fits.
fn hand_eye_json(he: &HandEye, n_pairs: usize) -> serde_json::Value {
    let b = &he.body_from_cam;
    let w = &he.alignment.transform;
    serde_json::json!({
        "translation": [b.translation.x, b.translation.y, b.translation.z],
        "quaternion_xyzw": b.quaternion_xyzw(),
        "scale": w.scale,
        "world_from_slam_translation": [w.translation.x, w.translation.y, w.translation.z],
        "world_from_slam_quaternion_xyzw": w.quaternion_xyzw(),
        "position_rmse": he.alignment.rmse,
        "rotation_rmse_deg": he.rotation_rmse.to_degrees(),
        "n_pairs": n_pairs,
    })
}

/// The estimated extrinsic as text lines.
fn hand_eye_text(he: &HandEye, n_pairs: usize) -> String {
    let b = &he.body_from_cam;
    let q = b.quaternion_xyzw();
    format!(
        "T_body_cam (estimated with T_ref_est over {n_pairs} pairs; scale {:.9}):\n  \
         translation  [{:.6}, {:.6}, {:.6}]\n  \
         quaternion   [{:.9}, {:.9}, {:.9}, {:.9}]  (x, y, z, w)\n  \
         fit: position rmse {:.6} m, rotation rmse {:.4} deg\n",
        he.alignment.transform.scale,
        b.translation.x,
        b.translation.y,
        b.translation.z,
        q[0],
        q[1],
        q[2],
        q[3],
        he.alignment.rmse,
        he.rotation_rmse.to_degrees()
    )
}
