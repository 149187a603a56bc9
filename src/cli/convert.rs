//! `slam2world convert LOG -o OUTDIR`: `world.mcap`, `cloud.ply`, `report.json`,
//! `report.html`, and with `--octree RES` the occupancy map `map.bt` (its
//! occupied voxels also in `world.mcap` and the page).

use std::path::PathBuf;

use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use super::args::{finite, parse_transform, positive, print, FitArgs};
use crate::cloud::PointFilter;
use crate::defaults;
use crate::error::Result;
use crate::io::log::ReadOptions;
use crate::io::mcap::WorldFlavor;
use crate::map::MapParams;
use crate::pipeline::outputs::output_set;
use crate::pipeline::report::ImuReport;
use crate::pipeline::{convert_source, source, ConvertOptions};

/// Arguments of `convert`.
#[derive(Args, Debug)]
pub struct ConvertArgs {
    /// The log with LSD-SLAM keyframes and reference poses or raw IMU: MCAP,
    /// ROS 1 bag, rosbag2 folder or .db3 (found from the bytes).
    pub log: PathBuf,
    /// Output folder (created when missing).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Keyframe topic (default: found by schema `lsd_slam_viewer/keyframeMsg`).
    #[arg(long)]
    pub keyframe_topic: Option<String>,
    /// Keyframe graph topic (default: found by schema).
    #[arg(long)]
    pub graph_topic: Option<String>,
    /// Reference pose topic (default: the first pose schema found).
    #[arg(long)]
    pub pose_topic: Option<String>,
    /// SLAM poses without depth (any pose type) instead of keyframes: the
    /// estimate's topic, for logs without LSD-SLAM keyframes.
    #[arg(long)]
    pub est_topic: Option<String>,
    /// Raw IMU topic (`sensor_msgs/Imu`; default: found by schema). Without a
    /// reference pose topic, `T_world_slam` comes from the IMU (metric scale and
    /// gravity from preintegration); with one, the report compares both.
    #[arg(long)]
    pub imu_topic: Option<String>,
    /// `T_imu_cam`: 16 numbers (row-major 4×4) or 7 (tx ty tz qx qy qz qw), metres.
    #[arg(long, value_name = "NUMBERS", allow_hyphen_values = true)]
    pub imu_from_cam: Option<String>,
    /// Magnitude of gravity for the IMU path, m/s².
    #[arg(long, default_value_t = defaults::GRAVITY, value_parser = positive)]
    pub gravity: f64,
    /// TF parent frame, when the reference is a tf2_msgs/TFMessage topic.
    #[arg(long)]
    pub tf_parent: Option<String>,
    /// TF child frame, when the reference is a tf2_msgs/TFMessage topic.
    #[arg(long)]
    pub tf_child: Option<String>,
    /// Keep every pixel with a positive inverse depth (no viewer filters).
    #[arg(long)]
    pub no_filter: bool,
    /// Build an occupancy octree with this voxel edge (metres): writes `map.bt`
    /// (OctoMap) and the occupied voxels into `world.mcap`.
    #[arg(long, value_name = "RES", allow_hyphen_values = true, value_parser = finite)]
    pub octree: Option<f64>,
    /// Octree rays longer than this (metres) only clear space.
    #[arg(long, value_name = "M", requires = "octree", allow_hyphen_values = true, value_parser = finite)]
    pub octree_max_range: Option<f64>,
    /// OctoMap's probability of a ray's end voxel being occupied.
    #[arg(long, value_name = "P", requires = "octree", default_value_t = defaults::PROB_HIT)]
    pub prob_hit: f64,
    /// OctoMap's probability of a crossed voxel being occupied.
    #[arg(long, value_name = "P", requires = "octree", default_value_t = defaults::PROB_MISS)]
    pub prob_miss: f64,
    /// OctoMap's lower clamping threshold.
    #[arg(long, value_name = "P", requires = "octree", default_value_t = defaults::CLAMP_MIN)]
    pub clamp_min: f64,
    /// OctoMap's upper clamping threshold.
    #[arg(long, value_name = "P", requires = "octree", default_value_t = defaults::CLAMP_MAX)]
    pub clamp_max: f64,
    /// Write ROS 2 PointCloud2 + TFMessage instead of Foxglove schemas.
    #[arg(long)]
    pub ros2: bool,
    /// No progress bar and no summary.
    #[arg(short, long)]
    pub quiet: bool,
    /// Also fit a windowed Sim(3) over N matched keyframes and compare it with
    /// the single Sim(3) in the report.
    #[arg(long, value_name = "N")]
    pub compare_windowed: Option<usize>,
    /// Carry each keyframe with the windowed Sim(3) at its time (cloud, map,
    /// world poses) instead of the single one: for SLAM whose scale drifts.
    #[arg(long, requires = "compare_windowed")]
    pub windowed_cloud: bool,
    /// Also write a Rerun recording of the outputs (cloud, paths, voxels,
    /// T_world_slam): runs `python -m slam2world.rerun`, which needs Python
    /// ($SLAM2WORLD_PYTHON, else python3) with slam2world and rerun-sdk.
    #[arg(long, value_name = "PATH")]
    pub rrd: Option<PathBuf>,
    /// Association and fit options.
    #[command(flatten)]
    pub fit: FitArgs,
}

impl ConvertArgs {
    /// The core options these flags ask for.
    pub fn options(&self) -> Result<ConvertOptions> {
        let imu_from_cam = match &self.imu_from_cam {
            Some(m) => parse_transform("--imu-from-cam", m)?,
            None => crate::geometry::Sim3::identity(),
        };
        Ok(ConvertOptions {
            read: ReadOptions {
                keyframe_topic: self.keyframe_topic.clone(),
                graph_topic: self.graph_topic.clone(),
                pose_topic: self.pose_topic.clone(),
                imu_topic: self.imu_topic.clone(),
                tf_parent: self.tf_parent.clone(),
                tf_child: self.tf_child.clone(),
                est_topic: self.est_topic.clone(),
            },
            align: self.fit.options(),
            filter: if self.no_filter {
                PointFilter::none()
            } else {
                PointFilter::default()
            },
            imu: crate::imu::ImuInitOptions {
                imu_from_cam,
                gravity: self.gravity,
                ..crate::imu::ImuInitOptions::default()
            },
            map: self.octree.map(|resolution| MapParams {
                resolution,
                prob_hit: self.prob_hit,
                prob_miss: self.prob_miss,
                clamp_min: self.clamp_min,
                clamp_max: self.clamp_max,
                max_range: self.octree_max_range,
            }),
            compare_windowed: self
                .compare_windowed
                .map(crate::align::windowed::Window::Poses),
            windowed_cloud: self.windowed_cloud,
            confidence: self.fit.confidence,
        })
    }
}

/// Runs the conversion and writes the outputs.
pub fn run(args: &ConvertArgs) -> Result<()> {
    let target = if args.quiet {
        ProgressDrawTarget::hidden()
    } else {
        // Draws only when stderr is a terminal.
        ProgressDrawTarget::stderr()
    };
    let bar = ProgressBar::with_draw_target(Some(3), target);
    if let Ok(style) = ProgressStyle::with_template("{spinner} [{pos}/{len}] {msg} ({elapsed})") {
        bar.set_style(style);
    }
    let opts = args.options()?;
    // Bad options and a bad output folder (a file, the input's folder) fail
    // before the log is read.
    opts.check()?;
    let mut outputs = output_set(&args.output, [&args.log])?;
    let src = source::open_log(&args.log, &opts.read)?;
    bar.set_message(if opts.map.is_some() {
        "reading, aligning, backprojecting and building the octree"
    } else {
        "reading, aligning and backprojecting"
    });
    let c = convert_source(&*src, &opts)?;
    bar.inc(2);
    bar.set_message("writing");
    let flavor = if args.ros2 {
        WorldFlavor::Ros2
    } else {
        WorldFlavor::Foxglove
    };
    c.write_into(&mut outputs, flavor, c.octree.as_ref())?;
    let done = outputs.commit()?;
    if let Some(rrd) = &args.rrd {
        write_rrd(&args.output, rrd)?;
    }
    bar.inc(1);
    bar.finish_and_clear();
    if args.quiet {
        return Ok(());
    }
    let r = &c.report;
    let t = &r.t_world_slam;
    let mut s = format!(
        "{} keyframes, {} matched ({} dropped), fit on {}\n",
        r.keyframes,
        r.frames_used,
        r.frames_dropped.len(),
        r.pairs_fitted
    );
    s += &format!(
        "T_world_slam: scale {:.6}, translation {:?}, quaternion xyzw {:?}\n",
        t.scale, t.translation, t.quaternion_xyzw
    );
    match &r.ape {
        Some(a) => {
            s += &format!(
                "APE rmse {:.4} m (mean {:.4}, max {:.4}); {} points\n",
                a.rmse, a.mean, a.max, r.points
            )
        }
        None => s += &format!("{} points\n", r.points),
    }
    if let Some(imu) = &r.imu {
        s += &imu_summary(imu);
        s.push('\n');
    }
    if let Some(o) = &r.octree {
        s += &format!(
            "octree {} m: {} occupied and {} free leaves, {} nodes, {:.1} MiB, {:.3} s\n",
            o.resolution,
            o.leaves_occupied,
            o.leaves_free,
            o.nodes,
            o.memory_bytes as f64 / (1024.0 * 1024.0),
            o.time_s
        );
    }
    for p in &done.written {
        s += &format!("wrote {}\n", p.display());
    }
    for p in &done.removed {
        s += &format!(
            "removed {} (of an earlier run; not produced by this one)\n",
            p.display()
        );
    }
    if let Some(rrd) = &args.rrd {
        s += &format!("wrote {}\n", rrd.display());
    }
    print(&s)
}

/// Runs `python -m slam2world.rerun OUT -o RRD`; an error saying what is
/// missing when it cannot.
fn write_rrd(out: &std::path::Path, rrd: &std::path::Path) -> Result<()> {
    let exe = std::env::var_os("SLAM2WORLD_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("python3"));
    let why = |reason: String| {
        crate::Error::invalid(
            "--rrd",
            format!("{reason} (a Rerun recording needs Python with slam2world and rerun-sdk; the other outputs are written)"),
        )
    };
    let run = std::process::Command::new(&exe)
        .args(["-m", "slam2world.rerun"])
        .arg(out)
        .arg("-o")
        .arg(rrd)
        .output()
        .map_err(|e| why(format!("could not run {}: {e}", exe.display())))?;
    if run.status.success() {
        return Ok(());
    }
    let err = String::from_utf8_lossy(&run.stderr);
    Err(why(err.lines().last().unwrap_or("failed").to_string()))
}

/// One line on the inertial initialisation.
fn imu_summary(r: &ImuReport) -> String {
    if let Some(e) = &r.error {
        return format!("IMU: not used ({e})");
    }
    let mut s = format!(
        "IMU{}: scale {:.6} ± {:.6}, gravity direction ± {:.3}°",
        if r.used_for_transform {
            " (gives T_world_slam)"
        } else {
            ""
        },
        r.scale.map_or(f64::NAN, |v| v[0]),
        r.scale.map_or(f64::NAN, |v| v[1]),
        r.gravity_sigma_deg.unwrap_or(f64::NAN)
    );
    if let (Some(g), Some(a)) = (r.gyro_bias, r.accel_bias) {
        s += &format!(
            ", gyro bias [{:.5}, {:.5}, {:.5}] rad/s, accel bias [{:.4}, {:.4}, {:.4}] m/s²",
            g[0][0], g[0][1], g[0][2], a[0][0], a[0][1], a[0][2]
        );
    }
    if let Some(c) = &r.pose_check {
        s += &format!(
            "; vs poses: scale {:+.3} %, gravity {:.3}°",
            100.0 * c.scale_difference,
            c.gravity_angle_deg
        );
    }
    s
}
