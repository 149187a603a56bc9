//! `slam2world align EST REF`: associate two trajectory files by time, fit
//! `T_ref_est` (Sim(3); SE(3) with `--no-scale`; `--dof` for the others) and
//! print it with the absolute position error statistics (as `evo_ape … -as`).
//! `slam2world align LOG --est-topic T --ref-topic T` does the same with two
//! pose topics of one log of any container (as `evo_ape bag LOG REF EST`).
//! A REF of GNSS fixes (`align EST FIXES`, `align LOG --est-topic T
//! --gnss-topic G`) is fitted in ENU at `--origin`, as `convert` fits it.

use std::path::{Path, PathBuf};

use clap::Args;

use super::align_files::{
    aligned_bytes, check_indexed, in_unit, paired_by_name, read_as_written, transform_bytes,
    unstamped, Read,
};
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
use crate::io::gnss::{read_gnss, GnssFormat};
use crate::io::log::{read_log, ReadOptions};
use crate::io::text::{match_time_units, TimeUnit, TrajectoryFormat};
use crate::io::transforms::{read_dataparser, Dataparser, Transforms};
use crate::pipeline::figures::FigureData;
use crate::pipeline::gnss;
use crate::pipeline::html::{write_html, Page, Summary};
use crate::pipeline::report::{AlignReport, ApeReport, FitReport, HandEyeReport, TimeUnitsReport};
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
    let outputs = Outputs::check(&args)?;
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
    let mut written = outputs.write(&args, &est, est_scene.as_ref(), &t, est_format, est_unit)?;
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

/// The files `align` writes besides its report (`-o`, `--save-transform`,
/// `--dataparser-transforms`), checked before the work and written together.
struct Outputs<'a> {
    set: OutputSet,
    /// The model's dataparser transform read, and where it goes.
    dataparser: Option<(Dataparser, &'a Path)>,
}

impl<'a> Outputs<'a> {
    /// Reads the dataparser transform and checks that no output is an input.
    fn check(args: &'a AlignArgs) -> Result<Self> {
        let dataparser = match args.dataparser_transforms.as_slice() {
            [input, output] => Some((read_dataparser(input)?, output.as_path())),
            _ => None,
        };
        let inputs = [
            Some(&args.est),
            args.reference.as_ref(),
            args.est_times.as_ref(),
            args.ref_times.as_ref(),
            args.dataparser_transforms.first(),
        ];
        let set = OutputSet::new().with_inputs(inputs.into_iter().flatten());
        let outs = [
            args.output.as_deref(),
            args.save_transform.as_deref(),
            dataparser.as_ref().map(|d| d.1),
        ];
        for path in outs.into_iter().flatten() {
            set.check_output(path)?;
        }
        Ok(Outputs { set, dataparser })
    }

    /// Writes the outputs of the fit `t` and publishes them; what was
    /// written, a line each.
    fn write(
        mut self,
        args: &AlignArgs,
        est: &Trajectory,
        scene: Option<&Transforms>,
        t: &Sim3,
        est_format: TrajectoryFormat,
        est_unit: TimeUnit,
    ) -> Result<String> {
        let mut written = String::new();
        if let Some(path) = &args.output {
            let format = args.output_format.unwrap_or(est_format);
            let bytes = aligned_bytes(est, scene, t, format, est_unit)?;
            self.set.write_bytes(path, &bytes)?;
            written += &format!(
                "wrote {} (EST in the reference frame, {format:?})\n",
                path.display()
            );
        }
        if let Some(path) = &args.save_transform {
            self.set.write_bytes(path, &transform_bytes(path, t)?)?;
            written += &format!("wrote {} (T_ref_est)\n", path.display());
        }
        if let Some((d, path)) = &self.dataparser {
            self.set.write_bytes(path, &d.carried_bytes(t)?)?;
            written += &format!(
                "wrote {} (the model's dataparser transform)\n",
                path.display()
            );
        }
        self.set.commit()?;
        Ok(written)
    }
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
            // EuRoC's nanoseconds, a KITTI rate's or a scene's seconds are known.
            let est_given = args
                .est_time_unit
                .or(est_side.known.then_some(est_side.unit));
            let est_scene = est_side.scene;
            let (est, est_read) = (est_side.trajectory, est_side.unit);
            let fixes = read_gnss(reference, Some(format), args.geoid_offset)?;
            // Fix times are seconds (Unix, or of the day for NMEA without a date).
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
