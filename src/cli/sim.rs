//! `slam2world simulate`, `slam2world evaluate` and `slam2world demo`: the
//! paper's synthetic experiment from the command line.
//!
//! - `simulate -o sim.mcap`: the log a LSD-SLAM user records (ros1
//!   `keyframeMsg`, one `keyframeGraphMsg`, `PoseStamped` reference, `Imu`),
//!   the truth in the log's metadata (record `slam2world`, key `truth`) and in
//!   a sidecar `sim.truth.json` that also holds the tracked frames.
//! - `evaluate --truth sim.truth.json --cloud world.ply --transform ...`:
//!   scores a converted cloud and an estimated `T_world_slam`.
//! - `demo -o DIR`: simulate the paper-size run, align, convert, score, write
//!   the outputs and the figures, print a summary.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;
use nalgebra::Vector3;

use super::args::print;
use crate::align::trajectories::align_trajectories;
use crate::cloud::backproject;
use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::io::atomic::write_bytes_atomic;
use crate::io::atomic::OutputSet;
use crate::io::mcap::write::{write_slam_log_live_into, LiveLog};
use crate::io::mcap::{SlamLogOptions, WorldFlavor};
use crate::io::read_mcap;
use crate::map::{MapParams, VoxelState};
use crate::pipeline::outputs::HtmlOptions;
use crate::pipeline::report::{
    to_json_bytes, DemoAlignment, DemoReport, DemoSeconds, DemoTruth, EvaluateReport, FramesReport,
    SceneReport, SimStages, TransformReport, TruthReport,
};
use crate::pipeline::{convert, ConvertOptions, Recording};
use crate::sim::evaluate::{ape, point_distances, transform_error, ErrorStats};
use crate::sim::{simulate, CameraPath, Scene, SimConfig, Simulation};
use crate::trajectory::{scale_factors, Trajectory};

/// Options shared by `simulate` and `demo`: which run.
#[derive(Args, Debug, Clone)]
pub struct RunArgs {
    /// Seed of every random stream (same seed, same output).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Divide frames, keyframes, stage boundaries, path length and image size by K.
    #[arg(long, default_value_t = 1, value_name = "K", value_parser = clap::value_parser!(u32).range(1..))]
    reduced: u32,
    /// Switch every error off (no scale wander, no noise).
    #[arg(long)]
    noiseless: bool,
    /// Run SEED of the scenario family instead of the paper's run: stage lengths, rates,
    /// noise and start-up drawn from ranges that cover real systems (see `sim::scenario`).
    #[arg(long, value_name = "SEED", conflicts_with_all = ["seed", "reduced"])]
    scenario: Option<u64>,
    /// Set a simulation parameter (a `SimConfig` field), e.g. `--set scale_drift=0.001`.
    #[arg(long = "set", value_name = "NAME=VALUE")]
    set: Vec<String>,
}

impl RunArgs {
    fn config(&self) -> Result<SimConfig> {
        let mut cfg = match self.scenario {
            Some(seed) => SimConfig::scenario(seed),
            None => SimConfig {
                seed: self.seed,
                ..SimConfig::default()
            }
            .reduced(self.reduced as usize),
        };
        if self.noiseless {
            cfg = cfg.noiseless();
        }
        for s in &self.set {
            let (name, value) = s.split_once('=').ok_or_else(|| {
                Error::invalid("--set", format!("expected NAME=VALUE, got {s:?}"))
            })?;
            let v: f64 = value
                .trim()
                .parse()
                .map_err(|_| Error::invalid(name.trim(), format!("not a number: {value:?}")))?;
            cfg.set(name.trim(), v)?;
        }
        cfg.validate()?;
        Ok(cfg)
    }
}

/// Options of `slam2world simulate`.
#[derive(Args, Debug)]
pub struct SimulateArgs {
    /// The MCAP log to write.
    #[arg(short, long, value_name = "LOG.mcap")]
    output: PathBuf,
    /// Where to write the truth (default: the log's name with `.truth.json`).
    #[arg(long, value_name = "FILE")]
    truth: Option<PathBuf>,
    /// Leave the reference pose topic out (keyframes and raw IMU only: the
    /// log of the inertial path).
    #[arg(long)]
    no_reference: bool,
    /// Leave the raw IMU topic out (with `--no-reference`: keyframes alone,
    /// the log of a camera with no second sensor).
    #[arg(long)]
    no_imu: bool,
    #[command(flatten)]
    run: RunArgs,
}

/// Options of `slam2world evaluate`.
#[derive(Args, Debug)]
pub struct EvaluateArgs {
    /// The truth written by `simulate` (or `demo`).
    #[arg(long, value_name = "FILE")]
    truth: PathBuf,
    /// The converted cloud (world frame, metres), PLY.
    #[arg(long, value_name = "CLOUD.ply")]
    cloud: PathBuf,
    /// The estimated T_world_slam: `qx,qy,qz,qw,tx,ty,tz,s`, or a JSON file with a
    /// `t_world_slam` object (`quaternion_xyzw`, `translation`, `scale`).
    #[arg(long, value_name = "T")]
    transform: String,
    /// Write the scores as JSON here (they are printed in any case).
    #[arg(short, long, value_name = "FILE")]
    output: Option<PathBuf>,
}

/// Options of `slam2world demo`.
#[derive(Args, Debug)]
pub struct DemoArgs {
    /// Output folder (created).
    #[arg(short, long, default_value = "slam2world-demo", value_name = "DIR")]
    output: PathBuf,
    /// Skip the figures (they need Python with slam2world and matplotlib).
    #[arg(long)]
    no_plots: bool,
    /// Python interpreter for the figures (default: $SLAM2WORLD_PYTHON, else python3).
    #[arg(long, value_name = "EXE")]
    python: Option<PathBuf>,
    /// Voxel edge of the occupancy octree (`map.bt`, `octree.png`), metres.
    #[arg(long, value_name = "RES", default_value_t = crate::defaults::DEMO_OCTREE_RESOLUTION, value_parser = super::args::positive)]
    octree: f64,
    #[command(flatten)]
    run: RunArgs,
}

/// A transform given in a JSON file: the fields of [`TransformReport`] that
/// define it (a `report.json`, `demo.json` or truth file has them under
/// `t_world_slam`).
#[derive(serde::Deserialize)]
struct TransformSpec {
    quaternion_xyzw: [f64; 4],
    translation: [f64; 3],
    scale: f64,
}

/// A JSON file holding a transform: under `t_world_slam`, or as the object itself.
#[derive(serde::Deserialize)]
#[serde(untagged)]
enum TransformFile {
    Field { t_world_slam: TransformSpec },
    Bare(TransformSpec),
}

impl TransformSpec {
    fn to_sim3(&self) -> Result<Sim3> {
        Sim3::from_quaternion_xyzw(self.quaternion_xyzw, self.translation.into(), self.scale)
    }
}

/// The truth of a run (`frames`: also the tracked SLAM frames).
fn truth_report(sim: &Simulation, frames: bool) -> TruthReport {
    let scene = &sim.truth.scene;
    TruthReport {
        t_world_slam: TransformReport::from(&sim.truth.t_world_slam),
        config: sim.config.clone(),
        stages: SimStages {
            converge_start: sim.config.converge_start,
            stable_start: sim.config.stable_start,
        },
        scene: SceneReport {
            plane_half: scene.plane_half,
            cube_min: scene.cube_min.iter().map(|c| [c.x, c.y, c.z]).collect(),
            cube_size: scene.cube_size,
            gravity: [0.0, 0.0, -crate::sim::scene::GRAVITY],
        },
        keyframe_frames: sim.truth.keyframe_frames.clone(),
        true_path_length: sim.config.path_length,
        slam_frames: frames.then(|| {
            let f = &sim.slam_frames;
            FramesReport {
                timestamps: f.timestamps.clone(),
                positions: f.positions.iter().map(|p| [p.x, p.y, p.z]).collect(),
                orientations_xyzw: f
                    .orientations
                    .as_ref()
                    .map(|o| o.iter().map(|q| [q.i, q.j, q.k, q.w]).collect()),
            }
        }),
    }
}

/// Topic of the simulated log's live frames (LSD-SLAM's).
pub const LIVE_TOPIC: &str = "/lsd_slam/liveframes";

/// Seconds between the simulated log's graph messages.
pub const GRAPH_PERIOD: f64 = 5.0;

fn truth_path_for(log: &Path) -> PathBuf {
    log.with_extension("truth.json")
}

/// Writes the simulated log (with the reference poses when `reference`, the
/// raw IMU when `imu`) and its truth, both or neither.
fn write_log(sim: &Simulation, log: &Path, truth: &Path, reference: bool, imu: bool) -> Result<()> {
    let truth_meta = serde_json::to_string(&truth_report(sim, false))
        .map_err(|e| Error::invalid("json", e.to_string()))?;
    let mut set = OutputSet::new();
    let first_poses = sim.first_published_poses()?;
    let live = LiveLog {
        topic: LIVE_TOPIC,
        frames: &sim.slam_frames,
        camera: sim.camera,
        first_poses: &first_poses,
        republish: false,
        graph_period: Some(GRAPH_PERIOD),
    };
    write_slam_log_live_into(
        &mut set,
        log,
        &sim.keyframes,
        Some(&live),
        reference.then_some(&sim.reference),
        imu.then_some(&sim.imu),
        &[("truth".to_string(), truth_meta)],
        &SlamLogOptions::default(),
    )?;
    set.write_bytes(truth, &to_json_bytes(&truth_report(sim, true))?)?;
    set.commit().map(|_| ())
}

/// `slam2world simulate`.
pub fn run_simulate(args: &SimulateArgs) -> Result<()> {
    let cfg = args.run.config()?;
    let truth = args
        .truth
        .clone()
        .unwrap_or_else(|| truth_path_for(&args.output));
    // Two outputs, never one file: refused before the work.
    let probe = OutputSet::new();
    probe.check_output(&args.output)?;
    probe.check_output(&truth)?;
    if crate::io::atomic::same_output(&args.output, &truth)? {
        return Err(Error::Output {
            path: truth,
            reason: format!(
                "is the log output {} too: the truth needs a file of its own",
                args.output.display()
            ),
        });
    }
    let sim = simulate(&cfg)?;
    write_log(&sim, &args.output, &truth, !args.no_reference, !args.no_imu)?;
    println!(
        "wrote {} ({} keyframes, {} reference poses, {} IMU samples) and {}",
        args.output.display(),
        sim.keyframes.len(),
        if args.no_reference {
            0
        } else {
            sim.reference.len()
        },
        if args.no_imu { 0 } else { sim.imu.len() },
        truth.display()
    );
    Ok(())
}

/// `slam2world evaluate`.
pub fn run_evaluate(args: &EvaluateArgs) -> Result<()> {
    let text = std::fs::read_to_string(&args.truth).map_err(|e| Error::io(&args.truth, e))?;
    let truth: TruthReport = serde_json::from_str(&text)
        .map_err(|e| Error::parse(&args.truth, e.line(), e.to_string()))?;
    let t_true = truth.t_world_slam.to_sim3()?;
    let est = parse_transform(&args.transform)?;
    let cloud = crate::io::ply::read_ply(&args.cloud)?;
    let scene = Scene::paper()?;
    let d = point_distances(&scene, &cloud.points)?;
    // APE of the tracked frames of the stable stage, when the truth holds them.
    let cfg = &truth.config;
    let ape_stable_frames = match &truth.slam_frames {
        Some(f)
            if f.timestamps.len() == f.positions.len()
                && truth.stages.stable_start < f.timestamps.len() =>
        {
            let path = CameraPath::with_heights(
                cfg.n_frames as f64 / cfg.fps,
                cfg.path_length,
                cfg.path_heights(),
            )?;
            let k = truth.stages.stable_start;
            let traj = Trajectory::try_new(
                f.timestamps[k..].to_vec(),
                f.positions[k..].iter().map(|&p| Vector3::from(p)).collect(),
                None,
            )?;
            Some(ape(&traj, &est, &path)?)
        }
        _ => None,
    };
    let report = EvaluateReport {
        cloud: ErrorStats::from_values("points", &d)?,
        transform: transform_error(&est, &t_true),
        ape_stable_frames,
    };
    let bytes = to_json_bytes(&report)?;
    if let Some(o) = &args.output {
        write_bytes_atomic(o, &bytes)?;
    }
    print(&String::from_utf8_lossy(&bytes))
}

fn parse_transform(s: &str) -> Result<Sim3> {
    let p = Path::new(s);
    if p.is_file() {
        let text = std::fs::read_to_string(p).map_err(|e| Error::io(p, e))?;
        let file: TransformFile = serde_json::from_str(&text).map_err(|_| {
            Error::parse(
                p,
                0,
                "expected a t_world_slam object (quaternion_xyzw, translation, scale), alone or as a field",
            )
        })?;
        return match file {
            TransformFile::Field { t_world_slam } => t_world_slam.to_sim3(),
            TransformFile::Bare(t) => t.to_sim3(),
        };
    }
    let nums: Vec<f64> = s
        .split([',', ' '])
        .filter(|t| !t.is_empty())
        .map(|t| {
            t.parse::<f64>().map_err(|_| {
                Error::invalid(
                    "--transform",
                    format!("not a number: {}", crate::error::cut(t)),
                )
            })
        })
        .collect::<Result<_>>()?;
    if nums.len() != 8 {
        return Err(Error::invalid(
            "--transform",
            format!(
                "expected qx,qy,qz,qw,tx,ty,tz,s (8 numbers) or a JSON file, got {} numbers",
                nums.len()
            ),
        ));
    }
    Sim3::from_quaternion_xyzw(
        [nums[0], nums[1], nums[2], nums[3]],
        Vector3::new(nums[4], nums[5], nums[6]),
        nums[7],
    )
}

/// Little-endian raw arrays for the figure script.
fn raw_f64(v: impl IntoIterator<Item = f64>) -> Vec<u8> {
    v.into_iter().flat_map(f64::to_le_bytes).collect()
}

fn raw_f32(v: impl IntoIterator<Item = f32>) -> Vec<u8> {
    v.into_iter().flat_map(f32::to_le_bytes).collect()
}

fn vec3s(v: &[Vector3<f64>]) -> impl Iterator<Item = f64> + '_ {
    v.iter().flat_map(|p| [p.x, p.y, p.z])
}

/// `slam2world demo`.
pub fn run_demo(args: &DemoArgs) -> Result<()> {
    let t0 = Instant::now();
    let cfg = args.run.config()?;
    let dir = &args.output;
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;

    let sim = simulate(&cfg)?;
    let t_sim = t0.elapsed().as_secs_f64();

    // The log a LSD-SLAM user records, and its truth.
    let log_path = dir.join("sim.mcap");
    let truth_file = dir.join("sim.truth.json");
    write_log(&sim, &log_path, &truth_file, true, true)?;
    let t_log = t0.elapsed().as_secs_f64() - t_sim;

    // Convert it: read, associate, align (keyframes vs reference), backproject,
    // build the octree; the outputs are written once the scores are known
    // (report.html shows them).
    let opts = ConvertOptions {
        map: Some(MapParams::new(args.octree)),
        ..ConvertOptions::default()
    };
    let log = Recording::from(read_mcap(&log_path, &opts.read)?);
    let conv = convert(&log, &opts)?;
    let est = conv.transform();
    let cloud = &conv.cloud;
    // The same keyframes through the same filter, carried with the true transform:
    // SLAM's own depth error, the yardstick of the alignment.
    let cloud_true = backproject(&log.keyframes, &opts.filter, Some(&sim.truth.t_world_slam))?;
    let t_convert = t0.elapsed().as_secs_f64() - t_sim - t_log;

    // For comparison: every tracked frame, start-up included (the paper's warning), and
    // the tracked frames of the stable stage only.
    // The tracked frames as the log has them (its live frames).
    let tracked = log.live.as_ref().unwrap_or(&sim.slam_frames);
    let all_frames = align_trajectories(tracked, &sim.reference, &opts.align)?;
    let k = cfg.stable_start;
    let stable_frames = Trajectory::try_new(
        sim.slam_frames.timestamps[k..].to_vec(),
        sim.slam_frames.positions[k..].to_vec(),
        None,
    )?;
    let stable_fit = align_trajectories(&stable_frames, &sim.reference, &opts.align)?;

    // Score.
    let t1 = Instant::now();
    let scene = &sim.truth.scene;
    let d = point_distances(scene, &cloud.points)?;
    let d_true = point_distances(scene, &cloud_true.points)?;
    let err = ErrorStats::from_values("points", &d)?;
    let err_true = ErrorStats::from_values("points", &d_true)?;
    let terr = transform_error(&est, &sim.truth.t_world_slam);
    // The pipeline's keyframe trajectory is already in the world frame.
    let aligned = &conv.slam_trajectory;
    let ape_kf = ape(aligned, &Sim3::identity(), &sim.truth.path)?;
    let t_score = t1.elapsed().as_secs_f64();

    // p_k of the tracked frames against the reference at the same times.
    let ref_at = sim
        .reference
        .interpolate(&sim.slam_frames.timestamps, 0.1)?;
    let p_k = scale_factors(&sim.slam_frames.positions, &ref_at.positions)?;

    let voxels = conv
        .octree
        .as_ref()
        .map(|m| m.leaves(VoxelState::Occupied))
        .unwrap_or_default();
    let files = [
        (
            "voxels",
            "plot_data/voxels.f32",
            raw_f32(
                voxels
                    .iter()
                    .flat_map(|(c, size)| [c[0], c[1], c[2], *size].map(|v| v as f32)),
            ),
        ),
        (
            "points",
            "plot_data/points.f32",
            raw_f32(cloud.points.iter().copied()),
        ),
        (
            "distances",
            "plot_data/distances.f32",
            raw_f32(d.iter().map(|&v| v as f32)),
        ),
        (
            "distances_true_transform",
            "plot_data/distances_true.f32",
            raw_f32(d_true.iter().map(|&v| v as f32)),
        ),
        (
            "true_path",
            "plot_data/true_path.f64",
            raw_f64(vec3s(&sim.truth.camera.positions)),
        ),
        (
            "slam_path",
            "plot_data/slam_path.f64",
            raw_f64(vec3s(&sim.slam_frames.positions)),
        ),
        (
            "aligned_keyframes",
            "plot_data/aligned_keyframes.f64",
            raw_f64(vec3s(&aligned.positions)),
        ),
        (
            "scale_factors",
            "plot_data/scale_factors.f64",
            raw_f64(p_k.iter().copied()),
        ),
    ];
    // The figures' arrays, out of the way of the outputs a user opens.
    std::fs::create_dir_all(dir.join("plot_data"))
        .map_err(|e| Error::io(dir.join("plot_data"), e))?;
    let mut names = BTreeMap::new();
    for (key, name, bytes) in &files {
        write_bytes_atomic(&dir.join(name), bytes)?;
        names.insert((*key).to_string(), (*name).to_string());
    }
    let fit = conv
        .world
        .poses()
        .map(|p| &p.alignment)
        .ok_or_else(|| Error::invalid("demo", "the simulated log has reference poses"))?;
    let truth = truth_report(&sim, false);
    let mut report = DemoReport {
        t_world_slam: TransformReport::from(&est),
        truth: DemoTruth {
            t_world_slam: truth.t_world_slam,
            scale: sim.truth.t_world_slam.scale,
        },
        transform_error: terr,
        cloud_error: err,
        cloud_error_true_transform: err_true,
        ape_keyframes: ape_kf,
        alignment: DemoAlignment {
            fit: "keyframes vs reference (the convert pipeline, report.json)".into(),
            pairs: fit.pairs.len(),
            rmse: fit.ape.rmse,
            scale_error_all_frames: all_frames.transform().scale / sim.truth.t_world_slam.scale
                - 1.0,
            scale_error_stable_frames: stable_fit.transform().scale / sim.truth.t_world_slam.scale
                - 1.0,
        },
        stages: truth.stages,
        scene: truth.scene,
        config: cfg.clone(),
        files: names,
        seconds: DemoSeconds {
            simulate: t_sim,
            write_log: t_log,
            convert: t_convert,
            score: t_score,
        },
    };
    let t2 = Instant::now();
    let html = HtmlOptions {
        demo: Some(&report),
        ..HtmlOptions::default()
    };
    conv.write_all_html(dir, WorldFlavor::Foxglove, conv.octree.as_ref(), &html)?;
    report.seconds.convert += t2.elapsed().as_secs_f64();
    write_bytes_atomic(&dir.join("demo.json"), &to_json_bytes(&report)?)?;

    let plots = if args.no_plots {
        None
    } else {
        Some(make_plots(args, dir))
    };

    let slam_len: f64 = sim
        .slam_frames
        .positions
        .windows(2)
        .map(|w| (w[1] - w[0]).norm())
        .sum();
    println!(
        "slam2world demo: the paper's synthetic experiment (seed {})",
        cfg.seed
    );
    println!(
        "  frames {} at {} Hz, keyframes {}, {}x{} px; true path {:.2} m, SLAM path {:.2} units",
        cfg.n_frames,
        cfg.fps,
        sim.keyframes.len(),
        cfg.width,
        cfg.height,
        cfg.path_length,
        slam_len
    );
    println!(
        "  T_world_slam: scale {:.4} (true {:.4}), scale error {:+.3} %, rotation error {:.3} deg, gravity error {:.3} deg",
        est.scale,
        sim.truth.t_world_slam.scale,
        100.0 * terr.scale_error,
        terr.rotation_error_deg,
        terr.gravity_error_deg
    );
    println!(
        "  fit on all tracked frames (start-up included): scale error {:+.2} %; stable frames only: {:+.3} %",
        100.0 * report.alignment.scale_error_all_frames,
        100.0 * report.alignment.scale_error_stable_frames,
    );
    println!(
        "  cloud: {} points, distance to the true surfaces median {:.1} mm, rmse {:.1} mm, p95 {:.1} mm (true transform: median {:.1} mm, ratio {:.3})",
        err.n,
        1e3 * err.median,
        1e3 * err.rmse,
        1e3 * err.p95,
        1e3 * err_true.median,
        err.rmse / err_true.rmse
    );
    println!("  keyframe APE rmse {:.1} mm", 1e3 * ape_kf.rmse);
    if let Some(o) = &conv.report.octree {
        println!(
            "  octree {} m: {} occupied and {} free leaves (map.bt); report.html",
            o.resolution, o.leaves_occupied, o.leaves_free
        );
    }
    match plots {
        Some(Ok(())) => {
            println!("  figures: paths.png, scale_factors.png, cloud.png, error_histogram.png, octree.png")
        }
        Some(Err(e)) => println!("  figures skipped: {e}"),
        None => {}
    }
    println!(
        "  wrote {} in {:.1} s (simulate {:.1} s, log {:.1} s, convert {:.1} s, score {:.1} s)",
        dir.display(),
        t0.elapsed().as_secs_f64(),
        t_sim,
        t_log,
        report.seconds.convert,
        t_score
    );
    Ok(())
}

/// Runs `python -m slam2world.plot DIR`; an error string when it cannot.
fn make_plots(args: &DemoArgs, dir: &Path) -> std::result::Result<(), String> {
    let exe = args
        .python
        .clone()
        .or_else(|| std::env::var_os("SLAM2WORLD_PYTHON").map(PathBuf::from))
        .unwrap_or_else(|| PathBuf::from("python3"));
    let out = std::process::Command::new(&exe)
        .args(["-m", "slam2world.plot"])
        .arg(dir)
        .output()
        .map_err(|e| format!("could not run {}: {e}", exe.display()))?;
    if out.status.success() {
        Ok(())
    } else {
        let err = String::from_utf8_lossy(&out.stderr);
        let last = err.lines().last().unwrap_or("").to_string();
        Err(format!(
            "{} -m slam2world.plot failed: {last}",
            exe.display()
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transform_argument() {
        let t = parse_transform("0,0,0,1, 1,2,3, 15.5").unwrap();
        assert_eq!(t.scale, 15.5);
        assert_eq!(t.translation, Vector3::new(1.0, 2.0, 3.0));
        assert!(parse_transform("0,0,0,1,1,2,3").is_err());
        assert!(parse_transform("0,0,0,1,1,2,3,x").is_err());
        let spec: TransformSpec =
            serde_json::from_value(serde_json::to_value(TransformReport::from(&t)).unwrap())
                .unwrap();
        assert!((spec.to_sim3().unwrap().matrix() - t.matrix()).amax() < 1e-12);
        assert!(serde_json::from_str::<TransformSpec>(r#"{"scale": 1.0}"#).is_err());
    }
}
