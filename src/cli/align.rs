//! `slam2world align EST REF`: associate two trajectory files by time, fit
//! `T_ref_est` (Sim(3); SE(3) with `--no-scale`; `--dof` for the others) and
//! print it with the absolute position error statistics (as `evo_ape … -as`).

use std::path::PathBuf;

use clap::Args;

use super::args::{fit_text, print, print_json, FitArgs};
use crate::align::dof::Dof;
use crate::align::handeye::estimate_body_from_cam_trajectories;
use crate::align::trajectories::align_trajectories;
use crate::error::Result;
use crate::io::text::TrajectoryFormat;
use crate::pipeline::report::{AlignReport, ApeReport, FitReport, HandEyeReport};

/// clap parser of a trajectory format.
pub(crate) fn format(s: &str) -> std::result::Result<TrajectoryFormat, String> {
    s.parse().map_err(|e: crate::Error| e.to_string())
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
    /// Format of EST (and of REF unless --ref-format is given): tum or euroc.
    #[arg(long, value_name = "tum|euroc", default_value = "tum", value_parser = format)]
    format: TrajectoryFormat,
    /// Format of REF (default: the same as --format).
    #[arg(long, value_name = "tum|euroc", value_parser = format)]
    ref_format: Option<TrajectoryFormat>,
    /// Print one JSON object instead of text (schema: `slam2world schema align`).
    #[arg(long)]
    json: bool,
    /// Also estimate the camera–body extrinsic T_body_cam (hand-eye calibration
    /// with scale): both files need orientations, and the motion rotations about
    /// two axes at least.
    #[arg(long, conflicts_with_all = ["no_scale", "body_from_cam"])]
    estimate_body_from_cam: bool,
    #[command(flatten)]
    fit: FitArgs,
}

/// Runs the command; prints to stdout.
pub fn run(args: AlignArgs) -> Result<()> {
    let opts = args.fit.options();
    opts.check()?;
    let est = args.format.read(&args.est)?;
    let reference = args
        .ref_format
        .unwrap_or(args.format)
        .read(&args.reference)?;
    let r = align_trajectories(&est, &reference, &opts)?;
    // The extrinsic at the offset the fit used (given plus estimated).
    let hand_eye = if args.estimate_body_from_cam {
        Some(estimate_body_from_cam_trajectories(
            &est,
            &reference,
            opts.max_diff,
            r.offset,
        )?)
    } else {
        None
    };
    let t = r.transform();
    let rot = t.rotation_matrix();
    let report = AlignReport {
        est: args.est.display().to_string(),
        reference: args.reference.display().to_string(),
        n_est: est.len(),
        n_ref: reference.len(),
        n_pairs: r.pairs.len(),
        n_fitted: r.alignment.residuals.len(),
        max_diff: opts.max_diff,
        offset: opts.offset,
        with_scale: r.dof.has_scale(),
        scale: t.scale,
        rotation: std::array::from_fn(|i| std::array::from_fn(|j| rot[(i, j)])),
        quaternion_xyzw: t.quaternion_xyzw(),
        translation: [t.translation.x, t.translation.y, t.translation.z],
        fit_rmse: r.alignment.rmse,
        ape: ApeReport::from(&r.ape),
        fit: FitReport::of(&r, args.fit.confidence),
        body_from_cam_estimate: hand_eye.as_ref().map(|(he, n)| HandEyeReport::of(he, *n)),
    };
    if args.json {
        return print_json(&report);
    }
    print(&text(&report))
}

/// The report as the text `align` prints.
fn text(r: &AlignReport) -> String {
    let q = r.quaternion_xyzw;
    let a = &r.ape;
    let mut s = format!(
        "matched {} pairs of {} EST and {} REF poses (max_diff {} s, offset {} s); fitted {}\n",
        r.n_pairs, r.n_est, r.n_ref, r.max_diff, r.offset, r.n_fitted
    );
    s += &format!(
        "T_ref_est ({}):\n",
        match r.fit.dof {
            Dof::Sim3 => "Sim(3)",
            Dof::Se3 => "SE(3)",
            Dof::FourDof => "4 DoF: translation + yaw",
            Dof::ScaleFourDof => "5 DoF: translation + yaw + scale",
        }
    );
    s += &format!("  scale        {:.12}\n", r.scale);
    s += &format!(
        "  quaternion   [{:.9}, {:.9}, {:.9}, {:.9}]  (x, y, z, w)\n",
        q[0], q[1], q[2], q[3]
    );
    for (i, row) in r.rotation.iter().enumerate() {
        s += &format!(
            "  {}  [{:12.9}, {:12.9}, {:12.9}]\n",
            if i == 0 { "rotation   " } else { "           " },
            row[0],
            row[1],
            row[2]
        );
    }
    let t = r.translation;
    s += &format!("  translation  [{:.9}, {:.9}, {:.9}]\n", t[0], t[1], t[2]);
    s += &format!(
        "APE (m) over {} pairs: rmse {:.6}  mean {:.6}  median {:.6}  std {:.6}  min {:.6}  max {:.6}\n",
        a.n_pairs, a.rmse, a.mean, a.median, a.std, a.min, a.max
    );
    s += &fit_text(&r.fit);
    if let Some(he) = &r.body_from_cam_estimate {
        let b = he.translation;
        let q = he.quaternion_xyzw;
        s += &format!(
            "T_body_cam (estimated with T_ref_est over {} pairs; scale {:.9}):\n  \
             translation  [{:.6}, {:.6}, {:.6}]\n  \
             quaternion   [{:.9}, {:.9}, {:.9}, {:.9}]  (x, y, z, w)\n  \
             fit: position rmse {:.6} m, rotation rmse {:.4} deg\n",
            he.n_pairs,
            he.scale,
            b[0],
            b[1],
            b[2],
            q[0],
            q[1],
            q[2],
            q[3],
            he.position_rmse,
            he.rotation_rmse_deg
        );
    }
    s
}
