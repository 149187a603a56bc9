//! `slam2world align EST REF`: associate two trajectory files by time, fit
//! `T_ref_est` (Sim(3); SE(3) with `--no-scale`; `--dof` for the others) and
//! print it with the absolute position error statistics (as `evo_ape … -as`).
//! `slam2world align LOG --est-topic T --ref-topic T` does the same with two
//! pose topics of one log of any container (as `evo_ape bag LOG REF EST`).
//! A REF of GNSS fixes (`align EST FIXES`, `align LOG --est-topic T
//! --gnss-topic G`) is fitted in ENU at `--origin`, as `convert` fits it.

use std::path::{Path, PathBuf};

use clap::Args;

use super::ape_plot;
use super::args::{
    finite, fit_text, gnss_format, gnss_text, print, print_json, time_unit, FitArgs, GnssFitArgs,
};
use crate::align::dof::Dof;
use crate::align::handeye::estimate_body_from_cam_trajectories;
use crate::align::trajectories::align_trajectories_weighted;
use crate::error::{Error, Result};
use crate::geo::GnssFixes;
use crate::geometry::Sim3;
use crate::io::atomic::OutputSet;
use crate::io::colmap::image_name_time;
use crate::io::gnss::{read_gnss, GnssFormat};
use crate::io::kitti::{self, read_kitti, read_times, KittiStamps};
use crate::io::log::{read_log, ReadOptions};
use crate::io::text::{euroc_bytes, match_time_units, tum_bytes, TimeUnit, TrajectoryFormat};
use crate::io::transforms::{read_dataparser, read_transforms, Transforms};
use crate::pipeline::figures::FigureData;
use crate::pipeline::gnss;
use crate::pipeline::html::{write_html, Page, Summary};
use crate::pipeline::report::{
    AlignReport, ApeReport, FitReport, HandEyeReport, TimeUnitsReport, TransformReport,
};
use crate::trajectory::Trajectory;

/// clap parser of a trajectory format.
pub(crate) fn format(s: &str) -> std::result::Result<TrajectoryFormat, String> {
    s.parse().map_err(|e: crate::Error| e.to_string())
}

/// Options of `slam2world align`.
#[derive(Args, Debug)]
pub struct AlignArgs {
    /// Estimated (SLAM) trajectory file; with --est-topic, the log (MCAP, ROS 1
    /// bag, rosbag2 folder or .db3) holding both topics.
    #[arg(value_name = "EST|LOG")]
    est: PathBuf,
    /// Reference (ground truth, IMU) trajectory file (none with --est-topic).
    #[arg(value_name = "REF", required_unless_present = "est_topic")]
    reference: Option<PathBuf>,
    /// The estimate's pose topic in LOG (PoseStamped, Odometry, TransformStamped, TF, …).
    #[arg(
        long,
        value_name = "TOPIC",
        requires = "log_reference",
        conflicts_with = "reference"
    )]
    est_topic: Option<String>,
    /// The reference's pose topic in LOG.
    #[arg(
        long,
        value_name = "TOPIC",
        requires = "est_topic",
        group = "log_reference"
    )]
    ref_topic: Option<String>,
    /// The reference's GNSS topic in LOG (`sensor_msgs/NavSatFix`,
    /// `foxglove.LocationFix`): the fit is then in ENU at `--origin`.
    #[arg(
        long,
        value_name = "TOPIC",
        requires = "est_topic",
        group = "log_reference"
    )]
    gnss_topic: Option<String>,
    /// TF parent frame of the reference, when --ref-topic is a tf2_msgs/TFMessage topic.
    #[arg(long, requires = "ref_topic")]
    tf_parent: Option<String>,
    /// TF child frame of the reference, when --ref-topic is a tf2_msgs/TFMessage topic.
    #[arg(long, requires = "ref_topic")]
    tf_child: Option<String>,
    /// Format of EST (and of REF unless --ref-format is given): tum, euroc,
    /// kitti or transforms (nerfstudio / instant-ngp `transforms.json`;
    /// default: transforms for JSON, kitti when the first pose line holds 12
    /// numbers, else tum).
    #[arg(long, value_name = "tum|euroc|kitti|transforms", value_parser = format)]
    format: Option<TrajectoryFormat>,
    /// Format of REF (default: GNSS fixes when REF holds NMEA sentences or
    /// `time, lat, lon, alt[, covariance]` rows, transforms for JSON, kitti
    /// when its first line holds 12 numbers, else the same as --format). Two
    /// `transforms.json` pair their frames by file name.
    #[arg(long, value_name = "tum|euroc|kitti|transforms", value_parser = format, conflicts_with = "gnss_format")]
    ref_format: Option<TrajectoryFormat>,
    /// Stamps of a KITTI EST: a `times.txt` (seconds, one a line, one a pose).
    /// Without stamps two KITTI files pair by index, as evo pairs them.
    #[arg(long, value_name = "PATH", conflicts_with_all = ["est_rate", "est_topic"])]
    est_times: Option<PathBuf>,
    /// Stamps of a KITTI REF: a `times.txt`.
    #[arg(long, value_name = "PATH", conflicts_with_all = ["ref_rate", "est_topic"])]
    ref_times: Option<PathBuf>,
    /// Stamps of a KITTI EST from its frame rate: pose i at i / HZ seconds.
    #[arg(long, value_name = "HZ", value_parser = finite, conflicts_with = "est_topic")]
    est_rate: Option<f64>,
    /// Stamps of a KITTI REF from its frame rate.
    #[arg(long, value_name = "HZ", value_parser = finite, conflicts_with = "est_topic")]
    ref_rate: Option<f64>,
    /// REF is a file of GNSS fixes in this format (default: found from its
    /// first lines): CSV / TXT `time, lat, lon, alt[, covariance]` (degrees;
    /// metres above the WGS84 ellipsoid) or NMEA (GGA, with GST accuracy).
    #[arg(long, value_name = "csv|nmea", value_parser = gnss_format)]
    gnss_format: Option<GnssFormat>,
    /// Metres added to every height of a GNSS REF file (the geoid
    /// separation, for heights above mean sea level).
    #[arg(long, value_name = "M", default_value_t = 0.0, allow_hyphen_values = true, value_parser = finite)]
    geoid_offset: f64,
    /// Unit of EST's stamps (default: found from the stamps, against REF's).
    #[arg(long, value_name = "s|ms|us|ns", value_parser = time_unit, conflicts_with = "est_topic")]
    est_time_unit: Option<TimeUnit>,
    /// Unit of REF's stamps (default: found from the stamps, against EST's;
    /// nanoseconds for --ref-format euroc).
    #[arg(long, value_name = "s|ms|us|ns", value_parser = time_unit, conflicts_with = "est_topic")]
    ref_time_unit: Option<TimeUnit>,
    /// Print one JSON object instead of text (schema: `slam2world schema align`).
    #[arg(long)]
    json: bool,
    /// Also estimate the camera–body extrinsic T_body_cam (hand-eye calibration
    /// with scale): both files need orientations, and the motion rotations about
    /// two axes at least.
    #[arg(long, conflicts_with_all = ["no_scale", "body_from_cam"])]
    estimate_body_from_cam: bool,
    /// Draw evo_ape's figures as PNG: the paths in the plane of most motion
    /// (the estimate coloured by APE) and the APE over time (`ape_map.png`,
    /// `ape_raw.png` unless --save-plot names them).
    #[arg(long)]
    plot: bool,
    /// Where the figures go: PATH `ape.png` gives `ape_map.png` and
    /// `ape_raw.png` beside it (implies --plot).
    #[arg(long, value_name = "PATH")]
    save_plot: Option<PathBuf>,
    /// Also write the report page (self-contained HTML: summary, paths in 3-D,
    /// p_k with the start-up stages, APE over time and its histogram).
    #[arg(long, value_name = "PATH")]
    html: Option<PathBuf>,
    /// Write the estimate carried into the reference frame by the fit
    /// (every EST pose, `T_ref_est · T_est_cam`), in EST's format and stamp
    /// unit unless --output-format names another, atomically.
    #[arg(short, long, value_name = "PATH")]
    output: Option<PathBuf>,
    /// Format of --output: tum, euroc, kitti, or transforms for a
    /// `transforms.json` EST (written back with every other key kept;
    /// default: EST's format; tum for a topic of a log).
    #[arg(long, value_name = "tum|euroc|kitti|transforms", value_parser = format, requires = "output")]
    output_format: Option<TrajectoryFormat>,
    /// Write the fitted T_ref_est: PATH.json as JSON (quaternion, translation,
    /// scale and the 4×4 matrix), any other name as the 4×4 matrix [sR t; 0 1]
    /// in 4 lines of 4 numbers (numpy.loadtxt reads it).
    #[arg(long, value_name = "PATH")]
    save_transform: Option<PathBuf>,
    /// A nerfstudio model's `dataparser_transforms.json` (IN, made for EST's
    /// scene), written as OUT for the scene carried by the fit: the training
    /// frame stays the same, so the model still fits the metric scene and
    /// its exports come out in metres.
    #[arg(long, num_args = 2, value_names = ["IN", "OUT"])]
    dataparser_transforms: Vec<PathBuf>,
    #[command(flatten)]
    fit: FitArgs,
    #[command(flatten)]
    gnss: GnssFitArgs,
}

/// Runs the command; prints to stdout.
pub fn run(args: AlignArgs) -> Result<()> {
    let opts = args.fit.options();
    opts.check()?;
    // The outputs are none of the inputs: refused before the work.
    let dataparser = match args.dataparser_transforms.as_slice() {
        [input, output] => Some((read_dataparser(input)?, output)),
        _ => None,
    };
    let mut outputs = OutputSet::new().with_inputs(
        [
            Some(&args.est),
            args.reference.as_ref(),
            args.est_times.as_ref(),
            args.ref_times.as_ref(),
            args.dataparser_transforms.first(),
        ]
        .into_iter()
        .flatten(),
    );
    let dataparser_out = dataparser.as_ref().map(|d| d.1);
    for path in [
        args.output.as_ref(),
        args.save_transform.as_ref(),
        dataparser_out,
    ]
    .into_iter()
    .flatten()
    {
        outputs.check_output(path)?;
    }
    let Inputs {
        est,
        reference,
        est_name,
        ref_name,
        time_units,
        est_format,
        est_unit,
        est_scene,
    } = inputs(&args, opts.offset)?;
    // Fixes are the reference in ENU at the origin, interpolated at the
    // estimate's stamps, weighted and with the lever arm, as `convert` fits them.
    let (reference, gnss) = match reference {
        Reference::Poses(r) => (std::sync::Arc::new(r), None),
        Reference::Fixes(fixes, source) => {
            if args.estimate_body_from_cam {
                return Err(Error::invalid(
                    "--estimate-body-from-cam",
                    "needs the reference's orientations, and GNSS fixes have none",
                ));
            }
            let mut g = gnss::reference(
                &fixes,
                &est,
                &args.gnss.options(),
                opts.offset,
                opts.estimate_offset.is_none(),
                opts.body_from_cam.as_ref(),
            )?;
            match source {
                FixSource::File(p) => g.report.file = Some(p),
                FixSource::Topic(t) => g.report.topic = Some(t),
            }
            (g.trajectory.clone(), Some(g))
        }
    };
    let (fit_opts, weights) = match &gnss {
        Some(g) => g.fit_options(&opts),
        None => (opts.clone(), None),
    };
    let r = align_trajectories_weighted(&est, &reference, weights, &fit_opts)?;
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
        est: est_name,
        reference: ref_name,
        n_est: est.len(),
        n_ref: reference.len(),
        n_pairs: r.pairs.len(),
        n_fitted: r.alignment.residuals.len(),
        max_diff: opts.max_diff,
        offset: opts.offset,
        time_units,
        with_scale: r.dof.has_scale(),
        scale: t.scale,
        rotation: std::array::from_fn(|i| std::array::from_fn(|j| rot[(i, j)])),
        quaternion_xyzw: t.quaternion_xyzw(),
        translation: [t.translation.x, t.translation.y, t.translation.z],
        fit_rmse: r.alignment.rmse,
        ape: ApeReport::from(&r.ape),
        fit: FitReport::of(&r, args.fit.confidence),
        body_from_cam_estimate: hand_eye.as_ref().map(|(he, n)| HandEyeReport::of(he, *n)),
        gnss: gnss.map(|g| g.report),
    };
    let mut written = String::new();
    if let Some(path) = &args.output {
        let format = args.output_format.unwrap_or(est_format);
        outputs.write_bytes(
            path,
            &aligned_bytes(&est, est_scene.as_ref(), &t, format, est_unit)?,
        )?;
        written += &format!(
            "wrote {} (EST in the reference frame, {format:?})\n",
            path.display()
        );
    }
    if let Some(path) = &args.save_transform {
        outputs.write_bytes(path, &transform_bytes(path, &t)?)?;
        written += &format!("wrote {} (T_ref_est)\n", path.display());
    }
    if let Some((d, path)) = &dataparser {
        outputs.write_bytes(path, &d.carried_bytes(&t)?)?;
        written += &format!(
            "wrote {} (the model's dataparser transform)\n",
            path.display()
        );
    }
    outputs.commit()?;
    if args.plot || args.save_plot.is_some() {
        let save = args
            .save_plot
            .clone()
            .unwrap_or_else(|| PathBuf::from("ape.png"));
        let (map, raw) = ape_plot::figure_paths(&save);
        ape_plot::write_ape_figures(&est, &reference, &r, &map, &raw)?;
        written += &format!("wrote {} and {}\n", map.display(), raw.display());
    }
    if let Some(path) = &args.html {
        let figures = FigureData::of_alignment(&est, &reference, &r)?;
        let title = args.est.display().to_string();
        let page = Page {
            title: &title,
            summary: Summary::Align(&report),
            demo: None,
            figures: &figures,
        };
        write_html(path, &page)?;
        written += &format!("wrote {}\n", path.display());
    }
    if args.json {
        // stdout holds the JSON alone; what was written goes to stderr.
        eprint!("{written}");
        return print_json(&report);
    }
    print(&(text(&report) + &written))
}

/// The estimate carried by `t` (every pose) as `format` writes it; TUM
/// stamps in `unit`, the one EST was written in.
fn aligned_bytes(
    est: &Trajectory,
    scene: Option<&Transforms>,
    t: &Sim3,
    format: TrajectoryFormat,
    unit: TimeUnit,
) -> Result<Vec<u8>> {
    let mut aligned = est.transformed(t);
    match format {
        TrajectoryFormat::Transforms => match scene {
            Some(s) => s.carried_bytes(t),
            None => Err(Error::invalid(
                "--output-format",
                "transforms needs EST to be a transforms.json (its other keys are written back)",
            )),
        },
        TrajectoryFormat::Tum => {
            aligned.timestamps = unit.written(&aligned.timestamps);
            tum_bytes(&aligned)
        }
        TrajectoryFormat::Euroc => euroc_bytes(&aligned),
        TrajectoryFormat::Kitti => kitti::kitti_bytes(&aligned),
    }
}

/// `t` as `--save-transform` writes it: JSON for a `.json` path (the
/// reports' transform: quaternion, translation, scale, matrix), else the
/// 4×4 matrix as 4 lines of 4 numbers (the shortest form that reads back
/// exactly).
fn transform_bytes(path: &Path, t: &Sim3) -> Result<Vec<u8>> {
    let json = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    if json {
        let mut v = serde_json::to_vec_pretty(&TransformReport::from(t))
            .map_err(|e| Error::invalid("--save-transform", e.to_string()))?;
        v.push(b'\n');
        return Ok(v);
    }
    let m = t.matrix();
    let rows: Vec<String> = (0..4)
        .map(|r| {
            let row: Vec<String> = (0..4).map(|c| m[(r, c)].to_string()).collect();
            row.join(" ") + "\n"
        })
        .collect();
    Ok(rows.concat().into_bytes())
}

/// What `align` fits: the estimate and the reference, with the names the
/// report gives them (`LOG:TOPIC` for topics) and, for two files, the units
/// of their stamps.
struct Inputs {
    est: Trajectory,
    reference: Reference,
    est_name: String,
    ref_name: String,
    time_units: Option<TimeUnitsReport>,
    /// EST's format (TUM for a topic of a log): `--output`'s default.
    est_format: TrajectoryFormat,
    /// The unit EST's stamps were read in (seconds for a topic).
    est_unit: TimeUnit,
    /// EST's scene, when it is a `transforms.json` (written back by `--output`).
    est_scene: Option<Transforms>,
}

/// The reference: poses, or GNSS fixes (which `gnss::reference` turns into
/// ENU positions at the estimate's stamps).
enum Reference {
    Poses(Trajectory),
    Fixes(GnssFixes, FixSource),
}

/// Where the fixes came from (the report names it).
enum FixSource {
    File(PathBuf),
    Topic(String),
}

/// A trajectory file and the unit its stamps were read in: TUM stamps as
/// they are written (seconds; every row kept, as evo reads them), EuRoC's
/// nanoseconds, a KITTI file's from `times` / `rate` (seconds) or its pose
/// index (`indexed`).
struct Read {
    trajectory: Trajectory,
    unit: TimeUnit,
    /// The stamps are the poses' index (a KITTI file without stamps).
    indexed: bool,
    /// `unit` is the format's (EuRoC nanoseconds; a KITTI rate or index),
    /// not to be found from the values.
    known: bool,
    /// The scene, when the file is a `transforms.json`.
    scene: Option<Transforms>,
}

/// Reads `path` as `format`; `times` and `rate` (the `--*-times`,
/// `--*-rate` of `side`) give a KITTI file its stamps.
fn read_as_written(
    format: TrajectoryFormat,
    path: &Path,
    times: Option<&Path>,
    rate: Option<f64>,
    side: &str,
) -> Result<Read> {
    if format != TrajectoryFormat::Kitti && (times.is_some() || rate.is_some()) {
        return Err(Error::invalid(
            format!("--{side}-times/--{side}-rate"),
            format!(
                "give stamps to KITTI files only; {} is read as {format:?} (stamps in the file)",
                path.display()
            ),
        ));
    }
    let read = |trajectory, unit, known| Read {
        trajectory,
        unit,
        indexed: false,
        known,
        scene: None,
    };
    Ok(match format {
        TrajectoryFormat::Tum => read(format.read(path)?, TimeUnit::Seconds, false),
        TrajectoryFormat::Euroc => read(format.read(path)?, TimeUnit::Nanoseconds, true),
        TrajectoryFormat::Kitti => {
            let stamps = match (times, rate) {
                (Some(t), _) => KittiStamps::Times(read_times(t)?),
                (None, Some(r)) => KittiStamps::Rate(r),
                (None, None) => KittiStamps::Index,
            };
            let indexed = stamps == KittiStamps::Index;
            Read {
                known: !matches!(stamps, KittiStamps::Times(_)),
                trajectory: read_kitti(path, &stamps)?,
                unit: TimeUnit::Seconds,
                indexed,
                scene: None,
            }
        }
        TrajectoryFormat::Transforms => {
            let scene = read_transforms(path)?;
            // Frames named by stamps are timed by them; else the frame order.
            let indexed = scene
                .frames
                .iter()
                .any(|f| image_name_time(&f.file_path).is_none());
            Read {
                trajectory: scene.trajectory()?,
                unit: TimeUnit::Seconds,
                indexed,
                // Seconds: the names' stamps or the frame order.
                known: true,
                scene: Some(scene),
            }
        }
    })
}

/// REF's poses restamped to pair with EST's by file name
/// ([`Transforms::key`]): each REF frame takes the stamp of the EST frame of
/// its name; frames of no shared name are left out. Fewer than three shared
/// names, or a name twice in one scene, is an error.
fn paired_by_name(
    est: &Transforms,
    est_traj: &Trajectory,
    r: &Transforms,
    ref_path: &Path,
) -> Result<Trajectory> {
    let (stamps, frames) = est.stamped();
    let mut by_key = std::collections::HashMap::new();
    for (t, f) in stamps.iter().zip(&frames) {
        if by_key.insert(Transforms::key(&f.file_path), *t).is_some() {
            return Err(Error::invalid(
                "EST",
                format!("two frames named {}: frames pair by file name", f.file_path),
            ));
        }
    }
    let ref_traj = r.trajectory()?;
    let (_, ref_frames) = r.stamped();
    let mut rows: Vec<(f64, usize)> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for (i, f) in ref_frames.iter().enumerate() {
        let key = Transforms::key(&f.file_path);
        if !seen.insert(key) {
            return Err(Error::invalid(
                "REF",
                format!("two frames named {}: frames pair by file name", f.file_path),
            ));
        }
        if let Some(&t) = by_key.get(key) {
            rows.push((t, i));
        }
    }
    if rows.len() < 3 {
        return Err(Error::invalid(
            "EST/REF",
            format!(
                "{} of the {} frames of {} share a file name with the {} of EST: two \
                 transforms.json pair by file name, and a fit needs 3",
                rows.len(),
                ref_frames.len(),
                ref_path.display(),
                est_traj.len()
            ),
        ));
    }
    rows.sort_by(|a, b| a.0.total_cmp(&b.0));
    let o = ref_traj.orientations.as_ref();
    Trajectory::try_new(
        rows.iter().map(|r| r.0).collect(),
        rows.iter().map(|r| ref_traj.positions[r.1]).collect(),
        o.map(|o| rows.iter().map(|r| o[r.1]).collect()),
    )
}

/// Two KITTI files without stamps pair by index (as many poses in each);
/// one without stamps beside stamped poses cannot be paired.
fn check_indexed(est: &Read, r: &Read, est_path: &Path, ref_path: &Path) -> Result<()> {
    let (n, m) = (est.trajectory.len(), r.trajectory.len());
    match (est.indexed, r.indexed) {
        (true, true) if n != m => Err(Error::invalid(
            "EST/REF",
            format!(
                "{} has {n} poses and {} has {m}: files without stamps (KITTI, a \
                 transforms.json timed by its frame order) pair by index and need as many \
                 poses (or give KITTI files --est-times/--ref-times)",
                est_path.display(),
                ref_path.display()
            ),
        )),
        (true, false) | (false, true) => {
            let (side, path, read) = if est.indexed {
                ("est", est_path, est)
            } else {
                ("ref", ref_path, r)
            };
            Err(unstamped(read, path, side, "the other side's stamps"))
        }
        _ => Ok(()),
    }
}

/// The error of a file without stamps (`side` its flags' prefix) that was
/// to pair with `what` by time.
fn unstamped(read: &Read, path: &Path, side: &str, what: &str) -> Error {
    if read.scene.is_some() {
        return Error::invalid(
            "EST/REF",
            format!(
                "{}: no frame's file name is a stamp, so its frames are timed by their order \
                 and cannot pair with {what}; it pairs with another transforms.json of the \
                 same images (by file name) or by index with KITTI poses without stamps",
                path.display()
            ),
        );
    }
    Error::invalid(
        format!("--{side}-times"),
        format!(
            "{} is a KITTI file without stamps: give --{side}-times times.txt or --{side}-rate \
             HZ to pair it with {what}",
            path.display()
        ),
    )
}

/// `t`, read in `read`, with its stamps in seconds of `unit`.
fn in_unit(mut t: Trajectory, read: TimeUnit, unit: TimeUnit) -> Trajectory {
    read.reread(&mut t.timestamps, unit);
    t
}

/// The estimate and the reference, from two files (the units of their
/// stamps found against each other, [`match_time_units`]; REF poses or GNSS
/// fixes) or from two topics of a log.
fn inputs(args: &AlignArgs, offset: f64) -> Result<Inputs> {
    let Some(est_topic) = &args.est_topic else {
        let Some(reference) = &args.reference else {
            return Err(Error::invalid(
                "REF",
                "a reference file, or --est-topic and --ref-topic or --gnss-topic",
            ));
        };
        let fixes_format = match (args.gnss_format, args.ref_format) {
            (Some(f), _) => Some(f),
            (None, None) => GnssFormat::sniff_text(reference)?,
            (None, Some(_)) => None,
        };
        let est_format = TrajectoryFormat::of_file(args.format, &args.est)?;
        let est_side = read_as_written(
            est_format,
            &args.est,
            args.est_times.as_deref(),
            args.est_rate,
            "est",
        )?;
        if let Some(format) = fixes_format {
            if est_side.indexed {
                return Err(unstamped(&est_side, &args.est, "est", "GNSS fixes"));
            }
            let est_scene = est_side.scene;
            let (est, est_read) = (est_side.trajectory, est_side.unit);
            let fixes = read_gnss(reference, Some(format), args.geoid_offset)?;
            // Fix times are seconds (Unix, or of the day for NMEA without a date).
            let est_given = args.est_time_unit;
            let (est_unit, _) = match_time_units(
                &est_read.written(&est.timestamps),
                &fixes.times,
                est_given,
                Some(TimeUnit::Seconds),
                offset,
            );
            return Ok(Inputs {
                est_format,
                est_unit,
                est_scene,
                est: in_unit(est, est_read, est_unit),
                reference: Reference::Fixes(fixes, FixSource::File(reference.clone())),
                est_name: args.est.display().to_string(),
                ref_name: reference.display().to_string(),
                time_units: Some(TimeUnitsReport {
                    est: est_unit.symbol().into(),
                    reference: TimeUnit::Seconds.symbol().into(),
                    est_detected: est_given.is_none(),
                    ref_detected: false,
                    paired_by_index: false,
                }),
            });
        }
        let ref_format = TrajectoryFormat::of_reference(args.ref_format, args.format, reference)?;
        let ref_side = read_as_written(
            ref_format,
            reference,
            args.ref_times.as_deref(),
            args.ref_rate,
            "ref",
        )?;
        let (mut est_side, mut ref_side) = (est_side, ref_side);
        if let (Some(e), Some(r)) = (&est_side.scene, &ref_side.scene) {
            // Two scenes of the same images: frames pair by file name.
            ref_side.trajectory = paired_by_name(e, &est_side.trajectory, r, reference)?;
            (est_side.indexed, ref_side.indexed) = (false, false);
        }
        check_indexed(&est_side, &ref_side, &args.est, reference)?;
        // EuRoC files are nanoseconds by their format; stamps from a rate
        // or an index are seconds.
        let fixed =
            |side: &Read, given: Option<TimeUnit>| given.or(side.known.then_some(side.unit));
        let est_given = fixed(&est_side, args.est_time_unit);
        let ref_given = fixed(&ref_side, args.ref_time_unit);
        let est_scene = est_side.scene;
        let (est, est_read) = (est_side.trajectory, est_side.unit);
        let (r, ref_read) = (ref_side.trajectory, ref_side.unit);
        let (est_unit, ref_unit) = match_time_units(
            &est_read.written(&est.timestamps),
            &ref_read.written(&r.timestamps),
            est_given,
            ref_given,
            offset,
        );
        let units = TimeUnitsReport {
            est: est_unit.symbol().into(),
            reference: ref_unit.symbol().into(),
            est_detected: est_given.is_none(),
            ref_detected: ref_given.is_none(),
            paired_by_index: est_side.indexed,
        };
        return Ok(Inputs {
            est_format,
            est_unit,
            est_scene,
            est: in_unit(est, est_read, est_unit),
            reference: Reference::Poses(in_unit(r, ref_read, ref_unit)),
            est_name: args.est.display().to_string(),
            ref_name: reference.display().to_string(),
            time_units: Some(units),
        });
    };
    let log = read_log(
        &args.est,
        &ReadOptions {
            est_topic: Some(est_topic.clone()),
            pose_topic: args.ref_topic.clone(),
            gnss_topic: args.gnss_topic.clone(),
            tf_parent: args.tf_parent.clone(),
            tf_child: args.tf_child.clone(),
            ..ReadOptions::default()
        },
    )?;
    let named = |t: &str| format!("{}:{t}", args.est.display());
    let reference = match (&args.gnss_topic, log.reference, log.gnss) {
        (Some(topic), _, Some(fixes)) => Some((
            Reference::Fixes(fixes, FixSource::Topic(topic.clone())),
            topic,
        )),
        (None, Some(r), _) => args.ref_topic.as_ref().map(|t| (Reference::Poses(r), t)),
        _ => None,
    };
    match (log.frames, reference) {
        (Some(est), Some((reference, ref_topic))) => Ok(Inputs {
            est_format: TrajectoryFormat::Tum,
            est_unit: TimeUnit::Seconds,
            est_scene: None,
            est,
            reference,
            est_name: named(est_topic),
            ref_name: named(ref_topic),
            time_units: None,
        }),
        // read_log gives the topics it was asked for (or an error).
        _ => Err(Error::invalid(
            "--est-topic/--ref-topic",
            format!(
                "{}: the log gave no data for both topics",
                args.est.display()
            ),
        )),
    }
}

/// The report as the text `align` prints.
fn text(r: &AlignReport) -> String {
    let q = r.quaternion_xyzw;
    let a = &r.ape;
    let mut s = format!(
        "matched {} pairs of {} EST and {} REF poses (max_diff {} s, offset {} s); fitted {}\n",
        r.n_pairs, r.n_est, r.n_ref, r.max_diff, r.offset, r.n_fitted
    );
    if r.time_units.as_ref().is_some_and(|u| u.paired_by_index) {
        s += "paired by index: KITTI files without stamps (pose i at i s)\n";
    } else if let Some(u) = &r.time_units {
        let how = |found: bool| if found { "found" } else { "given" };
        s += &format!(
            "stamps read in {} for EST ({}), {} for REF ({})\n",
            u.est,
            how(u.est_detected),
            u.reference,
            how(u.ref_detected)
        );
    }
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
    if let Some(g) = &r.gnss {
        s += &gnss_text(g);
    }
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
