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

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;
use nalgebra::Vector3;
use serde_json::{json, Value};

use crate::cloud::backproject;
use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::io::atomic::write_bytes_atomic;
use crate::io::mcap::{read_mcap, write_slam_log, SlamLogOptions, WorldFlavor};
use crate::pipeline::{convert, ConvertOptions};
use crate::sim::evaluate::{ape, point_distances, transform_error, ErrorStats};
use crate::sim::{simulate, CameraPath, Scene, SimConfig, Simulation};
use crate::trajectory::{align_trajectories, scale_factors, Trajectory};

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
    /// Set a simulation parameter (a `SimConfig` field), e.g. `--set scale_drift=0.001`.
    #[arg(long = "set", value_name = "NAME=VALUE")]
    set: Vec<String>,
}

impl RunArgs {
    fn config(&self) -> Result<SimConfig> {
        let mut cfg = SimConfig {
            seed: self.seed,
            ..SimConfig::default()
        }
        .reduced(self.reduced as usize);
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
    #[command(flatten)]
    run: RunArgs,
}

fn sim3_json(t: &Sim3) -> Value {
    json!({
        "quaternion_xyzw": t.quaternion_xyzw(),
        "translation": [t.translation.x, t.translation.y, t.translation.z],
        "scale": t.scale,
    })
}

fn sim3_from_json(v: &Value, path: &Path) -> Result<Sim3> {
    let bad = |what: &str| {
        Error::parse(
            path,
            0,
            format!("t_world_slam: missing or malformed {what}"),
        )
    };
    let nums = |key: &str, n: usize| -> Result<Vec<f64>> {
        let a = v
            .get(key)
            .and_then(Value::as_array)
            .ok_or_else(|| bad(key))?;
        let out: Vec<f64> = a.iter().filter_map(Value::as_f64).collect();
        if out.len() != n {
            return Err(bad(key));
        }
        Ok(out)
    };
    let q = nums("quaternion_xyzw", 4)?;
    let t = nums("translation", 3)?;
    let s = v
        .get("scale")
        .and_then(Value::as_f64)
        .ok_or_else(|| bad("scale"))?;
    Sim3::from_quaternion_xyzw([q[0], q[1], q[2], q[3]], Vector3::new(t[0], t[1], t[2]), s)
}

/// The truth of a run as JSON (`frames`: also the tracked SLAM frames).
fn truth_json(sim: &Simulation, frames: bool) -> Value {
    let scene = &sim.truth.scene;
    let mut v = json!({
        "t_world_slam": sim3_json(&sim.truth.t_world_slam),
        "config": sim.config.to_json(),
        "stages": {
            "converge_start": sim.config.converge_start,
            "stable_start": sim.config.stable_start,
        },
        "scene": {
            "plane_half": scene.plane_half,
            "cube_min": scene.cube_min.iter().map(|c| [c.x, c.y, c.z]).collect::<Vec<_>>(),
            "cube_size": scene.cube_size,
            "gravity": [0.0, 0.0, -crate::sim::scene::GRAVITY],
        },
        "keyframe_frames": sim.truth.keyframe_frames,
        "true_path_length": sim.config.path_length,
    });
    if frames {
        let f = &sim.slam_frames;
        v["slam_frames"] = json!({
            "timestamps": f.timestamps,
            "positions": f.positions.iter().map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>(),
            "orientations_xyzw": f.orientations.as_ref().map(|o| {
                o.iter().map(|q| [q.i, q.j, q.k, q.w]).collect::<Vec<_>>()
            }),
        });
    }
    v
}

fn json_bytes(v: &Value) -> Result<Vec<u8>> {
    let mut b = serde_json::to_vec_pretty(v).map_err(|e| Error::invalid("json", e.to_string()))?;
    b.push(b'\n');
    Ok(b)
}

fn truth_path_for(log: &Path) -> PathBuf {
    log.with_extension("truth.json")
}

/// Writes the simulated log and its truth.
fn write_log(sim: &Simulation, log: &Path, truth: &Path) -> Result<()> {
    let truth_meta = serde_json::to_string(&truth_json(sim, false))
        .map_err(|e| Error::invalid("json", e.to_string()))?;
    write_slam_log(
        log,
        &sim.keyframes,
        Some(&sim.reference),
        Some(&sim.imu),
        &[("truth".to_string(), truth_meta)],
        &SlamLogOptions::default(),
    )?;
    write_bytes_atomic(truth, &json_bytes(&truth_json(sim, true))?)
}

/// `slam2world simulate`.
pub fn run_simulate(args: &SimulateArgs) -> Result<()> {
    let cfg = args.run.config()?;
    let sim = simulate(&cfg)?;
    let truth = args
        .truth
        .clone()
        .unwrap_or_else(|| truth_path_for(&args.output));
    write_log(&sim, &args.output, &truth)?;
    println!(
        "wrote {} ({} keyframes, {} reference poses, {} IMU samples) and {}",
        args.output.display(),
        sim.keyframes.len(),
        sim.reference.len(),
        sim.imu.len(),
        truth.display()
    );
    Ok(())
}

fn stats_json(s: &ErrorStats) -> Value {
    json!({"n": s.n, "mean": s.mean, "median": s.median, "rmse": s.rmse, "p95": s.p95, "max": s.max})
}

/// `slam2world evaluate`.
pub fn run_evaluate(args: &EvaluateArgs) -> Result<()> {
    let text = std::fs::read_to_string(&args.truth).map_err(|e| Error::io(&args.truth, e))?;
    let truth: Value = serde_json::from_str(&text)
        .map_err(|e| Error::parse(&args.truth, e.line(), e.to_string()))?;
    let t_true = sim3_from_json(&truth["t_world_slam"], &args.truth)?;
    let est = parse_transform(&args.transform)?;
    let cloud = crate::io::ply::read_ply(&args.cloud)?;
    let scene = Scene::paper()?;
    let d = point_distances(&scene, &cloud.points)?;
    let mut out = json!({
        "cloud": stats_json(&ErrorStats::from_values("points", &d)?),
        "transform": serde_json::to_value(transform_error(&est, &t_true)).map_err(|e| Error::invalid("json", e.to_string()))?,
    });
    // APE of the tracked frames of the stable stage, when the truth holds them.
    let cfg = &truth["config"];
    if let (Some(frames), Some(n), Some(fps), Some(len), Some(stable)) = (
        truth.get("slam_frames"),
        cfg["n_frames"].as_u64(),
        cfg["fps"].as_f64(),
        cfg["path_length"].as_f64(),
        truth["stages"]["stable_start"].as_u64(),
    ) {
        let path = CameraPath::paper(n as f64 / fps, len)?;
        let ts: Vec<f64> = frames["timestamps"]
            .as_array()
            .map(|a| a.iter().filter_map(Value::as_f64).collect())
            .unwrap_or_default();
        let ps: Vec<Vector3<f64>> = frames["positions"]
            .as_array()
            .map(|a| {
                a.iter()
                    .filter_map(|p| {
                        let p = p.as_array()?;
                        Some(Vector3::new(
                            p.first()?.as_f64()?,
                            p.get(1)?.as_f64()?,
                            p.get(2)?.as_f64()?,
                        ))
                    })
                    .collect()
            })
            .unwrap_or_default();
        if ts.len() == ps.len() && (stable as usize) < ts.len() {
            let k = stable as usize;
            let traj = Trajectory::try_new(ts[k..].to_vec(), ps[k..].to_vec(), None)?;
            out["ape_stable_frames"] = stats_json(&ape(&traj, &est, &path)?);
        }
    }
    let bytes = json_bytes(&out)?;
    if let Some(o) = &args.output {
        write_bytes_atomic(o, &bytes)?;
    }
    std::io::stdout()
        .write_all(&bytes)
        .map_err(|e| Error::io("<stdout>", e))?;
    Ok(())
}

fn parse_transform(s: &str) -> Result<Sim3> {
    let p = Path::new(s);
    if p.is_file() {
        let text = std::fs::read_to_string(p).map_err(|e| Error::io(p, e))?;
        let v: Value =
            serde_json::from_str(&text).map_err(|e| Error::parse(p, e.line(), e.to_string()))?;
        let inner = v.get("t_world_slam").unwrap_or(&v);
        return sim3_from_json(inner, p);
    }
    let nums: Vec<f64> = s
        .split([',', ' '])
        .filter(|t| !t.is_empty())
        .map(|t| {
            t.parse::<f64>()
                .map_err(|_| Error::invalid("--transform", format!("not a number: {t:?}")))
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
    write_log(&sim, &log_path, &truth_file)?;
    let t_log = t0.elapsed().as_secs_f64() - t_sim;

    // Convert it: read, associate, align (keyframes vs reference), backproject, write.
    let opts = ConvertOptions::default();
    let log = read_mcap(&log_path, &opts.read)?;
    let conv = convert(&log, &opts)?;
    conv.write_all(dir, WorldFlavor::Foxglove)?;
    let est = conv.transform();
    let cloud = &conv.cloud;
    // The same keyframes through the same filter, carried with the true transform:
    // SLAM's own depth error, the yardstick of the alignment.
    let cloud_true = backproject(&log.keyframes, &opts.filter, Some(&sim.truth.t_world_slam))?;
    let t_convert = t0.elapsed().as_secs_f64() - t_sim - t_log;

    // For comparison: every tracked frame, start-up included (the paper's warning), and
    // the tracked frames of the stable stage only.
    let all_frames = align_trajectories(&sim.slam_frames, &sim.reference, &opts.align)?;
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

    let files = [
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
    let mut names = serde_json::Map::new();
    for (key, name, bytes) in &files {
        write_bytes_atomic(&dir.join(name), bytes)?;
        names.insert((*key).into(), json!(name));
    }
    let report = json!({
        "t_world_slam": sim3_json(&est),
        "truth": {
            "t_world_slam": sim3_json(&sim.truth.t_world_slam),
            "scale": sim.truth.t_world_slam.scale,
        },
        "transform_error": serde_json::to_value(terr).map_err(|e| Error::invalid("json", e.to_string()))?,
        "cloud_error": stats_json(&err),
        "cloud_error_true_transform": stats_json(&err_true),
        "ape_keyframes": stats_json(&ape_kf),
        "alignment": {
            "fit": "keyframes vs reference (the convert pipeline, report.json)",
            "pairs": conv.alignment.trajectory.pairs.len(),
            "rmse": conv.alignment.trajectory.ape.rmse,
            "scale_error_all_frames": all_frames.alignment.transform.scale / sim.truth.t_world_slam.scale - 1.0,
            "scale_error_stable_frames": stable_fit.alignment.transform.scale / sim.truth.t_world_slam.scale - 1.0,
        },
        "stages": {"converge_start": cfg.converge_start, "stable_start": cfg.stable_start},
        "scene": truth_json(&sim, false)["scene"].clone(),
        "config": cfg.to_json(),
        "files": Value::Object(names),
        "seconds": {"simulate": t_sim, "write_log": t_log, "convert": t_convert, "score": t_score},
    });
    write_bytes_atomic(&dir.join("demo.json"), &json_bytes(&report)?)?;

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
        100.0 * (all_frames.alignment.transform.scale / sim.truth.t_world_slam.scale - 1.0),
        100.0 * (stable_fit.alignment.transform.scale / sim.truth.t_world_slam.scale - 1.0),
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
    match plots {
        Some(Ok(())) => {
            println!("  figures: paths.png, scale_factors.png, cloud.png, error_histogram.png")
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
        t_convert,
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
        let j = sim3_json(&t);
        let back = sim3_from_json(&j, Path::new("x")).unwrap();
        assert!((back.matrix() - t.matrix()).amax() < 1e-12);
        assert!(sim3_from_json(&json!({"scale": 1.0}), Path::new("x")).is_err());
    }
}
