//! `slam2world imu-init KEYFRAMES IMU`: metric scale, gravity direction and
//! IMU biases of SLAM keyframes (`T_slam_cam`, a TUM or EuRoC trajectory file)
//! from raw IMU samples (EuRoC `imu0/data.csv`), with their uncertainty; and,
//! with `--reference`, a consistency check against a pose-based Horn fit.

use std::io::Write;
use std::path::{Path, PathBuf};

use clap::Args;
use nalgebra::{Matrix4, Vector3};

use super::align::Format;
use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::imu::{imu_initialize, ImuAlignment, ImuInitOptions, ImuSamples};
use crate::trajectory::{align_trajectories, Trajectory, TrajectoryAlignOptions};

/// Options of `slam2world imu-init`.
#[derive(Args, Debug)]
pub struct ImuInitArgs {
    /// SLAM keyframe trajectory (`T_slam_cam`, orientations required).
    #[arg(value_name = "KEYFRAMES")]
    keyframes: PathBuf,
    /// Raw IMU samples, EuRoC imu0/data.csv (ns; gyro rad/s; accel m/s²).
    #[arg(value_name = "IMU")]
    imu: PathBuf,
    /// Format of KEYFRAMES.
    #[arg(long, value_enum, default_value = "tum")]
    format: Format,
    /// `T_imu_cam` as 16 comma-separated numbers, a row-major 4×4 matrix in
    /// metres (EuRoC / Kalibr `T_BS` of the camera); identity by default.
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    imu_from_cam: Option<String>,
    /// Seconds added to the keyframe stamps to get IMU-clock times.
    #[arg(
        long,
        default_value_t = 0.0,
        value_name = "S",
        allow_negative_numbers = true
    )]
    time_offset: f64,
    /// Magnitude of gravity, m/s².
    #[arg(long, default_value_t = 9.81, value_name = "G")]
    gravity: f64,
    /// Keep the accelerometer bias at zero instead of estimating it.
    #[arg(long)]
    no_accel_bias: bool,
    /// Noise of a keyframe position, metres.
    #[arg(long, default_value_t = 0.01, value_name = "M")]
    keyframe_position_sigma: f64,
    /// Noise of a keyframe orientation, rad.
    #[arg(long, default_value_t = 2e-3, value_name = "RAD")]
    keyframe_rotation_sigma: f64,
    /// Shortest interval between two keyframes used, seconds.
    #[arg(long, default_value_t = 0.5, value_name = "S")]
    min_interval: f64,
    /// Use only keyframes from this many seconds after the first one.
    #[arg(long, default_value_t = 0.0, value_name = "S")]
    start: f64,
    /// Use only keyframes within this many seconds of --start.
    #[arg(long, value_name = "S")]
    window: Option<f64>,
    /// A metric, gravity-aligned pose file of the same motion (ground truth,
    /// motion capture): the report adds the pose-based Horn fit for comparison.
    #[arg(long, value_name = "REF")]
    reference: Option<PathBuf>,
    /// Format of REF.
    #[arg(long, value_enum, default_value = "euroc")]
    ref_format: Format,
    /// Largest time difference of a matched keyframe/reference pair, seconds.
    #[arg(long, default_value_t = 0.01, value_name = "S")]
    max_diff: f64,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
}

fn read(path: &Path, format: Format) -> Result<Trajectory> {
    match format {
        Format::Tum => Trajectory::read_tum(path),
        Format::Euroc => Trajectory::read_euroc(path),
    }
}

pub(crate) fn parse_matrix(s: &str) -> Result<Sim3> {
    let v: std::result::Result<Vec<f64>, _> =
        s.split(',').map(|f| f.trim().parse::<f64>()).collect();
    let v = v.map_err(|_| Error::invalid("--imu-from-cam", format!("not numbers: {s:?}")))?;
    if v.len() != 16 {
        return Err(Error::invalid(
            "--imu-from-cam",
            format!("expected 16 numbers (row-major 4×4), got {}", v.len()),
        ));
    }
    Sim3::from_matrix(&Matrix4::from_row_slice(&v))
}

/// Keyframes with `start ≤ t − t_first ≤ start + window`.
fn cut(t: &Trajectory, start: f64, window: Option<f64>) -> Result<Trajectory> {
    let Some(&t0) = t.timestamps.first() else {
        return Ok(t.clone());
    };
    let end = window.map_or(f64::INFINITY, |w| start + w);
    let keep: Vec<usize> = (0..t.len())
        .filter(|&i| {
            let d = t.timestamps[i] - t0;
            d >= start && d <= end
        })
        .collect();
    Trajectory::try_new(
        keep.iter().map(|&i| t.timestamps[i]).collect(),
        keep.iter().map(|&i| t.positions[i]).collect(),
        t.orientations
            .as_ref()
            .map(|o| keep.iter().map(|&i| o[i]).collect()),
    )
}

fn v3(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

/// The pose-based comparison: Horn fit scale and gravity direction.
struct Check {
    n_pairs: usize,
    horn_scale: f64,
    scale_difference: f64,
    gravity_angle_deg: f64,
    ape_rmse: f64,
}

fn check(
    kf: &Trajectory,
    reference: &Trajectory,
    a: &ImuAlignment,
    max_diff: f64,
) -> Result<Check> {
    let opts = TrajectoryAlignOptions {
        max_diff,
        ..TrajectoryAlignOptions::default()
    };
    let fit = align_trajectories(kf, reference, &opts)?;
    let t = fit.alignment.transform;
    let g_ref = t.rotation.inverse() * Vector3::new(0.0, 0.0, -1.0);
    let cos = a.gravity_slam.normalize().dot(&g_ref).clamp(-1.0, 1.0);
    Ok(Check {
        n_pairs: fit.pairs.len(),
        horn_scale: t.scale,
        scale_difference: a.scale / t.scale - 1.0,
        gravity_angle_deg: cos.acos().to_degrees(),
        ape_rmse: fit.ape.rmse,
    })
}

/// Runs the command; prints to stdout.
pub fn run(args: ImuInitArgs) -> Result<()> {
    let keyframes = cut(
        &read(&args.keyframes, args.format)?,
        args.start,
        args.window,
    )?;
    let imu = ImuSamples::read_euroc(&args.imu)?;
    let opts = ImuInitOptions {
        imu_from_cam: match &args.imu_from_cam {
            Some(s) => parse_matrix(s)?,
            None => Sim3::identity(),
        },
        time_offset: args.time_offset,
        gravity: args.gravity,
        estimate_accel_bias: !args.no_accel_bias,
        keyframe_position_sigma: args.keyframe_position_sigma,
        keyframe_rotation_sigma: args.keyframe_rotation_sigma,
        min_interval: args.min_interval,
        ..ImuInitOptions::default()
    };
    let a = imu_initialize(&keyframes, &imu, &opts)?;
    let chk = match &args.reference {
        Some(p) => Some(check(
            &keyframes,
            &read(p, args.ref_format)?,
            &a,
            args.max_diff,
        )?),
        None => None,
    };
    let text = if args.json {
        json(&args, &a, chk.as_ref())
    } else {
        text(&a, chk.as_ref())
    };
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|_| out.flush())
        .map_err(|e| Error::io("<stdout>", e))
}

fn json(args: &ImuInitArgs, a: &ImuAlignment, chk: Option<&Check>) -> String {
    let t = a.transform;
    let d = &a.diagnostics;
    let v = serde_json::json!({
        "keyframes": args.keyframes.display().to_string(),
        "imu": args.imu.display().to_string(),
        "scale": a.scale,
        "scale_sigma": a.scale_sigma,
        "gravity_slam": v3(&a.gravity_slam),
        "gravity_sigma_deg": a.gravity_sigma.to_degrees(),
        "gyro_bias": v3(&a.gyro_bias),
        "gyro_bias_sigma": v3(&a.gyro_bias_sigma),
        "accel_bias": v3(&a.accel_bias),
        "accel_bias_sigma": v3(&a.accel_bias_sigma),
        "transform": {
            "scale": t.scale,
            "quaternion_xyzw": t.quaternion_xyzw(),
            "translation": v3(&t.translation),
        },
        "diagnostics": {
            "n_keyframes": d.n_keyframes, "n_dropped": d.n_dropped, "n_skipped": d.n_skipped,
            "duration": d.duration, "excitation": d.excitation,
            "initial_scale": d.initial_scale, "initial_gravity_norm": d.initial_gravity_norm,
            "rotation_rms": d.rotation_rms, "position_rms": d.position_rms,
            "velocity_rms": d.velocity_rms, "variance_factor": d.variance_factor,
            "relative_scale_sigma": d.relative_scale_sigma,
        },
        "reference_check": chk.map(|c| serde_json::json!({
            "n_pairs": c.n_pairs,
            "horn_scale": c.horn_scale,
            "scale_difference": c.scale_difference,
            "gravity_angle_deg": c.gravity_angle_deg,
            "ape_rmse": c.ape_rmse,
        })),
    });
    format!("{v}\n")
}

fn text(a: &ImuAlignment, chk: Option<&Check>) -> String {
    let d = &a.diagnostics;
    let t = a.transform;
    let q = t.quaternion_xyzw();
    let g = a.gravity_slam.normalize();
    let (bg, sg, ba, sa) = (
        a.gyro_bias,
        a.gyro_bias_sigma,
        a.accel_bias,
        a.accel_bias_sigma,
    );
    let mut s = format!(
        "used {} keyframes over {:.2} s ({} outside the IMU span, {} closer than min_interval); excitation {:.3} m/s²\n",
        d.n_keyframes, d.duration, d.n_dropped, d.n_skipped, d.excitation
    );
    s += &format!(
        "scale          {:.6} ± {:.6} m per SLAM unit ({:.2} %)\n",
        a.scale,
        a.scale_sigma,
        100.0 * d.relative_scale_sigma
    );
    s += &format!(
        "gravity (SLAM) [{:.6}, {:.6}, {:.6}] · {:.5} m/s², direction ± {:.4}°\n",
        g.x,
        g.y,
        g.z,
        a.gravity_slam.norm(),
        a.gravity_sigma.to_degrees()
    );
    s += &format!(
        "gyro bias      [{:.6}, {:.6}, {:.6}] ± [{:.6}, {:.6}, {:.6}] rad/s\n",
        bg.x, bg.y, bg.z, sg.x, sg.y, sg.z
    );
    s += &format!(
        "accel bias     [{:.4}, {:.4}, {:.4}] ± [{:.4}, {:.4}, {:.4}] m/s²\n",
        ba.x, ba.y, ba.z, sa.x, sa.y, sa.z
    );
    s += &format!(
        "T_world_slam   scale {:.6}, quaternion [{:.9}, {:.9}, {:.9}, {:.9}] (x, y, z, w), translation [{:.6}, {:.6}, {:.6}]\n",
        t.scale, q[0], q[1], q[2], q[3], t.translation.x, t.translation.y, t.translation.z
    );
    s += &format!(
        "fit            first-solve scale {:.6}, |g| {:.4} m/s²; residual rms {:.2e} rad, {:.2e} m, {:.2e} m/s; variance factor {:.3}\n",
        d.initial_scale, d.initial_gravity_norm, d.rotation_rms, d.position_rms, d.velocity_rms, d.variance_factor
    );
    if let Some(c) = chk {
        s += &format!(
            "reference      Horn fit over {} pairs: scale {:.6} (IMU differs by {:+.3} %), gravity directions differ by {:.4}°, APE rmse {:.4} m\n",
            c.n_pairs, c.horn_scale, 100.0 * c.scale_difference, c.gravity_angle_deg, c.ape_rmse
        );
    }
    s
}
