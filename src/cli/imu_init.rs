//! `slam2world imu-init KEYFRAMES IMU`: metric scale, gravity direction and
//! IMU biases of SLAM keyframes (`T_slam_cam`, a TUM or EuRoC trajectory file)
//! from raw IMU samples (EuRoC `imu0/data.csv`), with their uncertainty; and,
//! with `--reference`, a consistency check against a pose-based Horn fit.

use std::path::PathBuf;

use clap::Args;
use nalgebra::Vector3;

use super::align::format;
use super::args::{finite, non_negative, parse_transform, positive, print, print_json};
use crate::align::trajectories::{align_trajectories, TrajectoryAlignOptions};
use crate::defaults;
use crate::error::Result;
use crate::geometry::Sim3;
use crate::imu::{imu_initialize, ImuAlignment, ImuInitOptions};
use crate::io::text::{read_euroc_imu, TrajectoryFormat};
use crate::pipeline::report::{ImuInitReport, ReferenceCheck};
use crate::trajectory::Trajectory;

/// Options of `slam2world imu-init`.
#[derive(Args, Debug)]
pub struct ImuInitArgs {
    /// SLAM keyframe trajectory (`T_slam_cam`, orientations required).
    #[arg(value_name = "KEYFRAMES")]
    keyframes: PathBuf,
    /// Raw IMU samples, EuRoC imu0/data.csv (ns; gyro rad/s; accel m/s²).
    #[arg(value_name = "IMU")]
    imu: PathBuf,
    /// Format of KEYFRAMES: tum or euroc.
    #[arg(long, value_name = "tum|euroc", default_value = "tum", value_parser = format)]
    format: TrajectoryFormat,
    /// `T_imu_cam`: 16 numbers (a row-major 4×4 matrix) or 7 (tx ty tz qx qy qz
    /// qw), metres (EuRoC / Kalibr `T_BS` of the camera); identity by default.
    #[arg(long, value_name = "NUMBERS", allow_hyphen_values = true)]
    imu_from_cam: Option<String>,
    /// Seconds added to the keyframe stamps to get IMU-clock times.
    #[arg(long, default_value_t = 0.0, value_name = "S", allow_negative_numbers = true, value_parser = finite)]
    time_offset: f64,
    /// Magnitude of gravity, m/s².
    #[arg(long, default_value_t = defaults::GRAVITY, value_name = "G", value_parser = positive)]
    gravity: f64,
    /// Keep the accelerometer bias at zero instead of estimating it.
    #[arg(long)]
    no_accel_bias: bool,
    /// Noise of a keyframe position, metres.
    #[arg(long, default_value_t = defaults::KEYFRAME_POSITION_SIGMA, value_name = "M", value_parser = non_negative)]
    keyframe_position_sigma: f64,
    /// Noise of a keyframe orientation, rad.
    #[arg(long, default_value_t = defaults::KEYFRAME_ROTATION_SIGMA, value_name = "RAD", value_parser = non_negative)]
    keyframe_rotation_sigma: f64,
    /// Shortest interval between two keyframes used, seconds.
    #[arg(long, default_value_t = defaults::MIN_INTERVAL, value_name = "S", value_parser = non_negative)]
    min_interval: f64,
    /// Use only keyframes from this many seconds after the first one.
    #[arg(long, default_value_t = 0.0, value_name = "S", value_parser = non_negative)]
    start: f64,
    /// Use only keyframes within this many seconds of --start.
    #[arg(long, value_name = "S", value_parser = non_negative)]
    window: Option<f64>,
    /// A metric, gravity-aligned pose file of the same motion (ground truth,
    /// motion capture): the report adds the pose-based Horn fit for comparison.
    #[arg(long, value_name = "REF")]
    reference: Option<PathBuf>,
    /// Format of REF: tum or euroc.
    #[arg(long, value_name = "tum|euroc", default_value = "euroc", value_parser = format)]
    ref_format: TrajectoryFormat,
    /// Largest time difference of a matched keyframe/reference pair, seconds.
    #[arg(long, default_value_t = defaults::MAX_DIFF, value_name = "S", value_parser = non_negative)]
    max_diff: f64,
    /// Print one JSON object instead of text (schema: `slam2world schema imu-init`).
    #[arg(long)]
    json: bool,
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

/// The pose-based comparison: Horn fit scale and gravity direction.
fn check(
    kf: &Trajectory,
    reference: &Trajectory,
    a: &ImuAlignment,
    max_diff: f64,
) -> Result<ReferenceCheck> {
    let opts = TrajectoryAlignOptions {
        max_diff,
        ..TrajectoryAlignOptions::default()
    };
    let fit = align_trajectories(kf, reference, &opts)?;
    let t = fit.transform();
    let g_ref = t.rotation.inverse() * Vector3::new(0.0, 0.0, -1.0);
    let cos = a.gravity_slam.normalize().dot(&g_ref).clamp(-1.0, 1.0);
    Ok(ReferenceCheck {
        n_pairs: fit.pairs.len(),
        horn_scale: t.scale,
        scale_difference: a.scale / t.scale - 1.0,
        gravity_angle_deg: cos.acos().to_degrees(),
        ape_rmse: fit.ape.rmse,
    })
}

/// Runs the command; prints to stdout.
pub fn run(args: ImuInitArgs) -> Result<()> {
    let imu_from_cam = match &args.imu_from_cam {
        Some(s) => parse_transform("--imu-from-cam", s)?,
        None => Sim3::identity(),
    };
    let keyframes = cut(&args.format.read(&args.keyframes)?, args.start, args.window)?;
    let imu = read_euroc_imu(&args.imu)?;
    let opts = ImuInitOptions {
        imu_from_cam,
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
            &args.ref_format.read(p)?,
            &a,
            args.max_diff,
        )?),
        None => None,
    };
    if args.json {
        let report = ImuInitReport::of(
            args.keyframes.display().to_string(),
            args.imu.display().to_string(),
            &a,
            chk,
        );
        return print_json(&report);
    }
    print(&text(&a, chk.as_ref()))
}

fn text(a: &ImuAlignment, chk: Option<&ReferenceCheck>) -> String {
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
