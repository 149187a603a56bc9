//! `slam2world convert LOG.mcap -o OUTDIR`: `world.mcap`, `cloud.ply`, `report.json`,
//! and with `--octree RES` the occupancy map `map.bt` (its occupied voxels also
//! in `world.mcap`).

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use crate::cloud::PointFilter;
use crate::error::Result;
use crate::io::mcap::{read_mcap, ReadOptions, WorldFlavor};
use crate::pipeline::{convert, ConvertOptions, CLOUD_PLY, MAP_BT, REPORT_JSON, WORLD_MCAP};
use crate::trajectory::TrajectoryAlignOptions;

/// Arguments of `convert`.
#[derive(Args, Debug)]
pub struct ConvertArgs {
    /// The MCAP log (LSD-SLAM keyframes + reference poses).
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
    /// Raw IMU topic (`sensor_msgs/Imu`; default: found by schema). Without a
    /// reference pose topic, `T_world_slam` comes from the IMU (metric scale and
    /// gravity from preintegration); with one, the report compares both.
    #[arg(long)]
    pub imu_topic: Option<String>,
    /// `T_imu_cam` as 16 comma-separated numbers (row-major 4×4, metres).
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    pub imu_from_cam: Option<String>,
    /// Magnitude of gravity for the IMU path, m/s².
    #[arg(long, default_value_t = 9.81)]
    pub gravity: f64,
    /// TF parent frame, when the reference is a tf2_msgs/TFMessage topic.
    #[arg(long)]
    pub tf_parent: Option<String>,
    /// TF child frame, when the reference is a tf2_msgs/TFMessage topic.
    #[arg(long)]
    pub tf_child: Option<String>,
    /// Largest keyframe–reference time difference of a pair, seconds.
    #[arg(long, default_value_t = 0.01)]
    pub max_diff: f64,
    /// Seconds added to the keyframe stamps before matching.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub offset: f64,
    /// Fit on the first N pairs only (the residuals still cover all pairs).
    #[arg(long)]
    pub n_to_align: Option<usize>,
    /// Keep every pixel with a positive inverse depth (no viewer filters).
    #[arg(long)]
    pub no_filter: bool,
    /// Build an occupancy octree with this voxel edge (metres): writes `map.bt`
    /// (OctoMap) and the occupied voxels into `world.mcap`.
    #[arg(long, value_name = "RES", allow_hyphen_values = true)]
    pub octree: Option<f64>,
    /// Octree rays longer than this (metres) only clear space.
    #[arg(
        long,
        value_name = "M",
        requires = "octree",
        allow_hyphen_values = true
    )]
    pub octree_max_range: Option<f64>,
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
    #[command(flatten)]
    pub beyond: super::beyond::BeyondArgs,
}

/// Runs the conversion and writes the three outputs.
pub fn run(args: &ConvertArgs) -> Result<()> {
    let target = if args.quiet {
        ProgressDrawTarget::hidden()
    } else {
        // Draws only when stderr is a terminal.
        ProgressDrawTarget::stderr()
    };
    let bar = ProgressBar::with_draw_target(Some(4), target);
    if let Ok(style) = ProgressStyle::with_template("{spinner} [{pos}/{len}] {msg} ({elapsed})") {
        bar.set_style(style);
    }
    let opts = ConvertOptions {
        read: ReadOptions {
            keyframe_topic: args.keyframe_topic.clone(),
            graph_topic: args.graph_topic.clone(),
            pose_topic: args.pose_topic.clone(),
            imu_topic: args.imu_topic.clone(),
            tf_parent: args.tf_parent.clone(),
            tf_child: args.tf_child.clone(),
        },
        align: TrajectoryAlignOptions {
            max_diff: args.max_diff,
            offset: args.offset,
            first_n: args.n_to_align,
            ..TrajectoryAlignOptions::default()
        },
        filter: if args.no_filter {
            PointFilter::none()
        } else {
            PointFilter::default()
        },
        imu: crate::imu::ImuInitOptions {
            imu_from_cam: match &args.imu_from_cam {
                Some(m) => super::imu_init::parse_matrix(m)?,
                None => crate::geometry::Sim3::identity(),
            },
            gravity: args.gravity,
            ..crate::imu::ImuInitOptions::default()
        },
        octree_resolution: args.octree,
        octree_max_range: args.octree_max_range,
        beyond: args.beyond.options(),
        compare_windowed: args
            .compare_windowed
            .map(crate::align::windowed::Window::Poses),
        windowed_cloud: args.windowed_cloud,
    };
    // Bad octree parameters fail before the log is read.
    opts.check()?;
    bar.set_message("reading the log");
    let t = Instant::now();
    let log = read_mcap(&args.log, &opts.read)?;
    let read_s = t.elapsed().as_secs_f64();
    bar.inc(1);
    bar.set_message(if opts.octree_resolution.is_some() {
        "aligning, backprojecting and building the octree"
    } else {
        "aligning and backprojecting"
    });
    let mut c = convert(&log, &opts)?;
    c.report.timing.read_s = read_s;
    bar.inc(2);
    bar.set_message("writing");
    let flavor = if args.ros2 {
        WorldFlavor::Ros2
    } else {
        WorldFlavor::Foxglove
    };
    c.write_all(&args.output, flavor)?;
    bar.inc(1);
    bar.finish_and_clear();
    if !args.quiet {
        let r = &c.report;
        let t = &r.t_world_slam;
        println!(
            "{} keyframes, {} matched ({} dropped), fit on {}",
            r.keyframes,
            r.frames_used,
            r.frames_dropped.len(),
            r.pairs_fitted
        );
        println!(
            "T_world_slam: scale {:.6}, translation {:?}, quaternion xyzw {:?}",
            t.scale, t.translation, t.quaternion_xyzw
        );
        println!(
            "APE rmse {:.4} m (mean {:.4}, max {:.4}); {} points",
            r.ape.rmse, r.ape.mean, r.ape.max, r.points
        );
        if let Some(imu) = &r.imu {
            println!("{}", imu_summary(imu));
        }
        if let Some(o) = &r.octree {
            println!(
                "octree {} m: {} occupied and {} free leaves, {} nodes, {:.1} MiB, {:.3} s",
                o.resolution,
                o.leaves_occupied,
                o.leaves_free,
                o.nodes,
                o.memory_bytes as f64 / (1024.0 * 1024.0),
                o.time_s
            );
        }
        for name in [WORLD_MCAP, CLOUD_PLY, REPORT_JSON] {
            println!("wrote {}", args.output.join(name).display());
        }
        if c.octree.is_some() {
            println!("wrote {}", args.output.join(MAP_BT).display());
        }
    }
    Ok(())
}

/// One line on the inertial initialisation.
fn imu_summary(r: &crate::imu::convert::ImuReport) -> String {
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
