//! `slam2world convert INPUT -o OUTDIR`: `world.mcap`, `cloud.ply`,
//! `trajectory.txt`, `report.json`, `report.html`, with `--octree RES` the
//! occupancy map `map.bt` (its occupied voxels also in `world.mcap` and the
//! page), with `--grid Z_MIN Z_MAX` its 2-D projection (`map.pgm`,
//! `map.yaml`, `map_height.npy`, a grid channel in `world.mcap`), and for a
//! COLMAP model the model in metres (`model/`).
//!
//! INPUT is a log (MCAP, ROS 1 bag, rosbag2 folder or .db3) or a
//! reconstruction (COLMAP / GLOMAP model folder, DROID-SLAM folder, TUM-order
//! trajectory file with its PLY), told apart by its contents; a
//! reconstruction takes its metric reference from `--reference` (poses by
//! time, or positions by image name).

use std::path::PathBuf;

use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use super::args::{
    finite, gnss_text, non_negative, parse_transform, positive, print, time_unit, FitArgs, GnssArgs,
};
use crate::cloud::PointFilter;
use crate::defaults;
use crate::error::{Error, Result};
use crate::io::colmap::ColmapFormat;
use crate::io::droid::DepthFilter;
use crate::io::log::ReadOptions;
use crate::io::mcap::WorldFlavor;
use crate::io::text::TimeUnit;
use crate::map::{GridParams, MapParams};
use crate::pipeline::gnss::WithGnss;
use crate::pipeline::native::ReferenceFormat;
use crate::pipeline::outputs::output_set;
use crate::pipeline::prior::{DistanceSpec, HeightSpec, PriorOptions};
use crate::pipeline::reconstruction::{open_input, ReconstructionOptions, ReferenceSpec};
use crate::pipeline::report::{ImuReport, PriorReport, Report, TextInfoReport};
use crate::pipeline::{convert_source_bounded, ConvertOptions};

fn reference_format(s: &str) -> std::result::Result<ReferenceFormat, String> {
    s.parse().map_err(|e: Error| e.to_string())
}

fn camera_height(s: &str) -> std::result::Result<HeightSpec, String> {
    s.parse().map_err(|e: Error| e.to_string())
}

fn colmap_format(s: &str) -> std::result::Result<ColmapFormat, String> {
    ColmapFormat::parse(s).map_err(|e| e.to_string())
}

/// Arguments of `convert`.
#[derive(Args, Debug)]
pub struct ConvertArgs {
    /// The input: a log (LSD-SLAM keyframes and reference poses or raw IMU;
    /// MCAP, ROS 1 bag, rosbag2 folder or .db3, found from the bytes) or a
    /// reconstruction (COLMAP/GLOMAP model folder, DROID-SLAM folder,
    /// trajectory file: DPVO, MASt3R-SLAM, DSO, ORB-SLAM3).
    pub log: PathBuf,
    /// Metric reference file: poses by time (TUM order, any time unit; EuRoC
    /// CSV) or positions by image name (`name x y z`, COLMAP model_aligner's).
    #[arg(long, value_name = "REF")]
    pub reference: Option<PathBuf>,
    /// Format of the reference (default: detected from its first lines).
    #[arg(long, value_name = "names|tum|euroc", requires = "reference", value_parser = reference_format)]
    pub reference_format: Option<ReferenceFormat>,
    /// Unit of the reference's stamps (default: detected; EuRoC: ns).
    #[arg(long, value_name = "s|ms|us|ns", requires = "reference", value_parser = time_unit)]
    pub reference_time_unit: Option<TimeUnit>,
    /// Unit of the stamps of a trajectory input (default: detected).
    #[arg(long, value_name = "s|ms|us|ns", value_parser = time_unit)]
    pub time_unit: Option<TimeUnit>,
    /// Cloud of a trajectory input, PLY or x y z text (default: the PLY of the
    /// same stem beside it).
    #[arg(long, value_name = "PLY")]
    pub cloud: Option<PathBuf>,
    /// Flavour to read when a COLMAP folder holds both `.bin` and `.txt`.
    #[arg(long, value_name = "bin|txt", value_parser = colmap_format)]
    pub colmap_format: Option<ColmapFormat>,
    /// DROID-SLAM depth filter: largest depth difference of an agreeing
    /// neighbour keyframe (depth units).
    #[arg(long, value_name = "D", default_value_t = defaults::DEPTH_THRESHOLD, value_parser = positive)]
    pub depth_threshold: f64,
    /// DROID-SLAM depth filter: neighbour keyframes that must agree.
    #[arg(long, value_name = "N", default_value_t = defaults::DEPTH_MIN_COUNT)]
    pub depth_min_count: u32,
    /// DROID-SLAM depth filter: keep disparities above this fraction of the
    /// keyframe's mean (0 keeps all).
    #[arg(long, value_name = "R", default_value_t = defaults::MIN_DISPARITY_RATIO, value_parser = non_negative)]
    pub min_disparity_ratio: f64,
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
    /// The cameras' height above the ground, for a recording with no
    /// reference sensor: metres at every pose (`1.2`), at the first pose
    /// only (`first:0.95`, a drone on the floor), or a file of `stamp height`
    /// lines. The ground plane of the SLAM cloud gives "up"; the heights
    /// give the scale. With a sensor, the report compares the two.
    #[arg(long, value_name = "M|first:M|FILE", allow_hyphen_values = true, value_parser = camera_height)]
    pub camera_height: Option<HeightSpec>,
    /// How well the camera height is known: its standard deviation, metres
    /// (the report's scale sigma counts it with the ground plane's).
    #[arg(long, value_name = "M", requires = "camera_height", value_parser = non_negative)]
    pub camera_height_sigma: Option<f64>,
    /// Two poses or map points a known distance apart (each a pose's index
    /// from 0, stamp or image name, or a map point `x,y,z` in the SLAM
    /// frame) and the distance in metres: the scale, for a recording with
    /// no reference sensor (before a camera height).
    #[arg(long, num_args = 3, value_names = ["A", "B", "METRES"], allow_hyphen_values = true)]
    pub known_distance: Option<Vec<String>>,
    /// "Up" from the plane the cameras ride in (a ground robot) instead of
    /// the ground plane of the cloud; needs a scale (`--camera-height` or
    /// `--known-distance`).
    #[arg(long)]
    pub planar_motion: bool,
    /// Magnitude of gravity for the IMU path, m/s².
    #[arg(long, default_value_t = defaults::GRAVITY, value_parser = positive)]
    pub gravity: f64,
    /// TF parent frame, when the reference is a tf2_msgs/TFMessage topic.
    #[arg(long)]
    pub tf_parent: Option<String>,
    /// TF child frame, when the reference is a tf2_msgs/TFMessage topic.
    #[arg(long)]
    pub tf_child: Option<String>,
    /// Keep every pixel with a positive inverse depth (no viewer filters, no
    /// DROID-SLAM depth filter).
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
    /// Project the octree to a 2-D occupancy grid of the voxels whose centres
    /// lie between Z_MIN and Z_MAX (metres, world z): writes nav2's `map.pgm`
    /// + `map.yaml`, `map_height.npy` and a grid channel in `world.mcap`.
    #[arg(long, num_args = 2, value_names = ["Z_MIN", "Z_MAX"], requires = "octree", allow_hyphen_values = true, value_parser = finite)]
    pub grid: Option<Vec<f64>>,
    /// Cell edge of the 2-D grid (metres; a whole multiple of the octree's
    /// resolution; default the octree's).
    #[arg(long, value_name = "R", requires = "grid", value_parser = positive)]
    pub grid_resolution: Option<f64>,
    /// Probability at or above which a grid cell is occupied in `map.pgm`.
    #[arg(long, value_name = "P", requires = "grid", default_value_t = defaults::OCCUPANCY_THRESHOLD)]
    pub grid_threshold: f64,
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
    /// The GNSS reference and the georeferenced outputs.
    #[command(flatten)]
    pub gnss: GnssArgs,
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
                gnss_topic: self.gnss.gnss_topic.clone(),
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
            grid: self.grid.as_ref().map(|z| GridParams {
                z_min: z[0],
                z_max: z[1],
                resolution: self.grid_resolution,
                occupied_threshold: self.grid_threshold,
            }),
            compare_windowed: self
                .compare_windowed
                .map(crate::align::windowed::Window::Poses),
            windowed_cloud: self.windowed_cloud,
            confidence: self.fit.confidence,
            gnss: self.gnss.options(),
            geo_outputs: self.gnss.outputs(),
            prior: self.prior()?,
        })
    }

    /// The prior these flags give, if any.
    fn prior(&self) -> Result<Option<PriorOptions>> {
        let known_distance = match self.known_distance.as_deref() {
            Some([a, b, m]) => Some(DistanceSpec {
                a: a.parse()?,
                b: b.parse()?,
                metres: m.trim().parse().map_err(|_| {
                    Error::invalid(
                        "--known-distance",
                        format!("the distance must be metres, got {m:?}"),
                    )
                })?,
            }),
            Some(other) => {
                return Err(Error::invalid(
                    "--known-distance",
                    format!("expected A B METRES, got {} values", other.len()),
                ))
            }
            None => None,
        };
        PriorOptions::from_parts(
            self.camera_height.clone(),
            self.camera_height_sigma,
            known_distance,
            self.planar_motion,
        )
    }

    /// How a reconstruction input is read.
    pub fn reconstruction_options(&self) -> ReconstructionOptions {
        ReconstructionOptions {
            time_unit: self.time_unit,
            cloud: self.cloud.clone(),
            colmap_format: self.colmap_format,
            depth_filter: (!self.no_filter).then(|| DepthFilter {
                threshold: self.depth_threshold,
                min_count: self.depth_min_count,
                min_disparity_ratio: self.min_disparity_ratio,
                ..DepthFilter::default()
            }),
        }
    }

    /// The reference file, with `--reference`.
    pub fn reference_spec(&self) -> Option<ReferenceSpec> {
        self.reference.as_ref().map(|path| ReferenceSpec {
            path: path.clone(),
            format: self.reference_format,
            time_unit: self.reference_time_unit,
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
    let inputs = [
        Some(&args.log),
        args.reference.as_ref(),
        args.cloud.as_ref(),
        args.gnss.gnss.as_ref(),
    ];
    let mut outputs = output_set(&args.output, inputs.into_iter().flatten())?;
    let src = open_input(
        &args.log,
        &opts.read,
        &args.reconstruction_options(),
        args.reference_spec().as_ref(),
    )?;
    let src: Box<dyn crate::pipeline::Source> = match args.gnss.file() {
        Some(file) => Box::new(WithGnss { inner: src, file }),
        None => src,
    };
    bar.set_message(if opts.map.is_some() {
        "reading, aligning, backprojecting and building the octree"
    } else {
        "reading, aligning and backprojecting"
    });
    // Bounded memory: keyframe pixels and the world cloud stay on disk.
    let c = convert_source_bounded(&*src, &opts)?;
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
    for w in warnings(&c.report) {
        eprintln!("slam2world: warning: {w}");
    }
    if args.quiet {
        return Ok(());
    }
    let r = &c.report;
    let t = &r.t_world_slam;
    // A reconstruction's poses are frames (images, trajectory rows), DROID-SLAM's keyframes.
    let rows = match &r.reconstruction {
        Some(x) if x.kind != "droid" => "frames",
        _ => "keyframes",
    };
    let mut s = match &r.prior {
        Some(g) if g.used_for_transform => format!(
            "{} {rows}; scale from the {}, up from the {}\n",
            r.keyframes,
            g.scale_from.replace('_', " "),
            g.up_from.replace('_', " ")
        ),
        _ => format!(
            "{} {rows}, {} matched ({} dropped), fit on {}\n",
            r.keyframes,
            r.frames_used,
            r.frames_dropped.len(),
            r.pairs_fitted
        ),
    };
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
    if let Some(g) = &r.prior {
        s += &prior_summary(g);
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
    if let Some(g) = &r.gnss {
        s += &gnss_text(g);
    }
    if let Some(g) = &r.grid {
        s += &format!(
            "grid {} m, z {} .. {} m: {} x {} cells, {} occupied, {} free, {} unknown\n",
            g.resolution,
            g.z_band[0],
            g.z_band[1],
            g.width,
            g.height,
            g.cells_occupied,
            g.cells_free,
            g.cells_unknown
        );
    }
    s += &input_summary(r);
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

/// What the trajectory reader found, as a phrase (`ns (detected), comma-separated`).
fn text_phrase(t: &TextInfoReport) -> String {
    let mut s = format!(
        "stamps in {} ({})",
        t.unit,
        if t.unit_detected { "detected" } else { "given" }
    );
    if t.delimiter == "comma" {
        s += ", comma-separated";
    }
    if t.header {
        s += ", a header line skipped";
    }
    s
}

/// Lines on how a reconstruction and its reference were read.
fn input_summary(r: &Report) -> String {
    let mut s = String::new();
    if let Some(rec) = &r.reconstruction {
        s += &format!(
            "{}{}: {} frames, stamps from {}",
            rec.kind,
            rec.flavour
                .as_ref()
                .map_or(String::new(), |f| format!(" (.{f})")),
            rec.frames,
            rec.frame_times
        );
        if let Some(t) = &rec.text {
            s += &format!("; {}", text_phrase(t));
        }
        s.push('\n');
    }
    if let Some(f) = &r.reference_file {
        s += &format!(
            "reference {} ({}{}), paired by {}",
            f.path.display(),
            f.format,
            if f.format_detected { ", detected" } else { "" },
            f.pairing
        );
        if let Some(t) = &f.text {
            s += &format!("; {}", text_phrase(t));
        }
        if let Some(n) = &f.names {
            s += &format!(
                "; {} of {} names are images of the input",
                n.matched, n.reference_names
            );
        }
        s.push('\n');
    }
    s
}

/// What a user should see even with `--quiet`: repeated stamps dropped,
/// reference names that name no image.
fn warnings(r: &Report) -> Vec<String> {
    let mut out = Vec::new();
    let repeated = |what: &str, t: &TextInfoReport| {
        (t.repeated_stamps > 0).then(|| {
            format!(
                "{what}: {} rows repeat the previous row's stamp; the first row of each stamp is kept",
                t.repeated_stamps
            )
        })
    };
    if let Some(t) = r.reconstruction.as_ref().and_then(|x| x.text.as_ref()) {
        out.extend(repeated(&r.input.display().to_string(), t));
    }
    if let Some(f) = &r.reference_file {
        if let Some(t) = &f.text {
            out.extend(repeated(&f.path.display().to_string(), t));
        }
        if let Some(n) = f.names.as_ref().filter(|n| n.unknown > 0) {
            out.push(format!(
                "{}: {} of {} names are no image of the input (e.g. {:?})",
                f.path.display(),
                n.unknown,
                n.reference_names,
                n.unknown_examples.first().map_or("", String::as_str)
            ));
        }
    }
    out
}

/// One line on the prior (ground plane, heights, known distance, planar motion).
fn prior_summary(g: &PriorReport) -> String {
    let mut s = format!(
        "prior{}: scale {:.6} from the {}, up from the {}",
        if g.used_for_transform {
            " (gives T_world_slam)"
        } else {
            ""
        },
        g.scale,
        g.scale_from.replace('_', " "),
        g.up_from.replace('_', " ")
    );
    if let Some(p) = &g.plane {
        s += &format!(
            "; ground plane {} of {} points, spread {:.3e} units",
            p.inliers, p.n_points, p.spread
        );
        if let Some(t) = p.tilt_from_cameras_deg {
            s += &format!(", {t:.2}° from the cameras' up");
        }
    }
    if let (Some(h), Some(rms)) = (g.height_scale, g.height_rms) {
        s += &format!("; heights: scale {h:.6} (rms {rms:.3} m)");
        if let Some(sigma) = g.scale_sigma {
            s += &format!(", ± {:.2} %", 100.0 * sigma);
        }
    }
    if let Some(d) = &g.known_distance {
        let end = |k: usize| match d.poses[k] {
            Some(i) => format!("pose {i}"),
            None => {
                let [x, y, z] = d.ends[k];
                format!("point ({x}, {y}, {z})")
            }
        };
        s += &format!(
            "; {} and {}: {} m over {:.4e} units",
            end(0),
            end(1),
            d.metres,
            d.slam_distance
        );
    }
    if let Some(m) = &g.planar_motion {
        s += &format!(
            "; cameras' plane: rms {:.3e} units, tilt bound {:.2}°",
            m.rms, m.tilt_bound_deg
        );
    }
    if let (Some(ds), Some(up)) = (g.scale_vs_sensor, g.up_vs_sensor_deg) {
        s += &format!("; vs the sensor: scale {:+.3} %, up {up:.3}°", 100.0 * ds);
    }
    s
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
