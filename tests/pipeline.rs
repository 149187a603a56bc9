//! `convert`: a LSD-SLAM log with a known `T_world_slam` gives that transform
//! back, a world cloud in world coordinates, and the three outputs.

use std::path::Path;

use nalgebra::{UnitQuaternion, Vector3};
use slam2world::cloud::{backproject, PointFilter};
use slam2world::io::mcap::{write_slam_log, McapFile, SlamLogOptions};
use slam2world::pipeline::{convert_file, ConvertOptions};
use slam2world::{Keyframe, PinholeCamera, Sim3, Trajectory};

fn truth() -> Sim3 {
    Sim3::try_new(
        UnitQuaternion::from_euler_angles(0.3, -0.2, 1.1),
        Vector3::new(4.0, -1.0, 0.5),
        2.5,
    )
    .unwrap()
}

/// Keyframes on a curve (SLAM frame) and the reference `T_world_slam · T_slam_cam`.
fn scene(n: usize) -> (Vec<Keyframe>, Trajectory) {
    let cam = PinholeCamera::try_new(8.0, 8.0, 3.5, 2.5, 8, 6).unwrap();
    let t = truth();
    let mut kfs = Vec::new();
    let mut times = Vec::new();
    let mut pos = Vec::new();
    let mut rot = Vec::new();
    for i in 0..n {
        let a = i as f64 * 0.4;
        let pose = Sim3::try_new(
            UnitQuaternion::from_euler_angles(0.05 * a, 0.1 * a, 0.0),
            Vector3::new(a.cos(), a.sin(), 0.2 * a),
            1.0,
        )
        .unwrap();
        // f32 round trip, as the message carries it
        let pose = Sim3::from_lsd_slam(&pose.to_lsd_slam().map(|v| v as f32 as f64)).unwrap();
        let npx = 48;
        let idepth = (0..npx).map(|p| 0.5 + 0.01 * p as f32).collect();
        let kf =
            Keyframe::try_new(i as i32, 5.0 + i as f64, pose, cam, idepth, None, None).unwrap();
        let w = t * pose;
        times.push(5.0 + i as f64);
        pos.push(w.translation);
        rot.push(w.rotation);
        kfs.push(kf);
    }
    (kfs, Trajectory::try_new(times, pos, Some(rot)).unwrap())
}

fn write_log(dir: &Path) -> std::path::PathBuf {
    let (kfs, reference) = scene(8);
    let path = dir.join("lsd.mcap");
    write_slam_log(
        &path,
        &kfs,
        Some(&reference),
        None,
        &[],
        &SlamLogOptions::default(),
    )
    .unwrap();
    path
}

fn opts() -> ConvertOptions {
    ConvertOptions {
        filter: PointFilter::none(),
        ..ConvertOptions::default()
    }
}

#[test]
fn convert_recovers_the_transform_and_the_world_cloud() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_log(dir.path());
    let c = convert_file(&path, &opts()).unwrap();
    let t = c.transform();
    let want = truth();
    assert!((t.scale - want.scale).abs() < 1e-4, "scale {}", t.scale);
    assert!((t.translation - want.translation).norm() < 1e-4);
    assert!(t.rotation.angle_to(&want.rotation) < 1e-5);
    assert_eq!(c.report.frames_used, 8);
    assert!(c.report.frames_dropped.is_empty());
    assert!(c.report.ape.rmse < 1e-4);
    // The world cloud is the SLAM cloud carried by the true transform.
    let (kfs, _) = scene(8);
    let slam_cloud = backproject(&kfs, &PointFilter::none(), None).unwrap();
    assert_eq!(c.cloud.len(), 8 * 48);
    assert_eq!(c.cloud.len(), slam_cloud.len());
    for (w, s) in c
        .cloud
        .points
        .chunks_exact(3)
        .zip(slam_cloud.points.chunks_exact(3))
    {
        let p = want.transform_point(&Vector3::new(s[0] as f64, s[1] as f64, s[2] as f64));
        let d = (p - Vector3::new(w[0] as f64, w[1] as f64, w[2] as f64)).norm();
        assert!(d < 1e-3, "{d}");
    }
    let out = dir.path().join("out");
    c.write_all(&out, slam2world::io::mcap::WorldFlavor::Foxglove)
        .unwrap();
    for f in ["world.mcap", "cloud.ply", "report.json"] {
        assert!(out.join(f).exists(), "{f}");
    }
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["points"], 8 * 48);
    assert_eq!(report["frames_used"], 8);
    let scale = report["t_world_slam"]["scale"].as_f64().unwrap();
    assert!((scale - 2.5).abs() < 1e-4);
    let world = McapFile::open(out.join("world.mcap")).unwrap();
    let names: Vec<String> = world
        .channels()
        .unwrap()
        .values()
        .map(|c| c.schema_name.clone())
        .collect();
    assert!(
        names.iter().any(|n| n == "foxglove.PointCloud"),
        "{names:?}"
    );
}

#[test]
fn cli_convert_writes_outputs_and_fails_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_log(dir.path());
    let out = dir.path().join("out");
    let run = |args: &[&str]| {
        let mut v = vec!["slam2world", "convert"];
        v.extend_from_slice(args);
        slam2world::cli::main_with_args(v)
    };
    let code = run(&[
        path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--quiet",
        "--no-filter",
    ]);
    assert_eq!(code, 0);
    assert!(out.join("world.mcap").exists() && out.join("cloud.ply").exists());

    // No reference pose within max_diff: exit 1, nothing written.
    let out2 = dir.path().join("out2");
    let code = run(&[
        path.to_str().unwrap(),
        "-o",
        out2.to_str().unwrap(),
        "--quiet",
        "--offset",
        "100",
    ]);
    assert_eq!(code, 1);
    assert!(!out2.join("world.mcap").exists());
    let err = slam2world::pipeline::convert_file(
        &path,
        &ConvertOptions {
            align: slam2world::trajectory::TrajectoryAlignOptions {
                offset: 100.0,
                ..Default::default()
            },
            ..opts()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("lsd.mcap")
            && err.contains("/lsd_slam/keyframes")
            && err.contains("/ground_truth/pose"),
        "{err}"
    );

    // A damaged log: exit 1, nothing written.
    let bad = dir.path().join("bad.mcap");
    std::fs::write(&bad, b"\x89MCAP0\r\n\x01\x02").unwrap();
    let out3 = dir.path().join("out3");
    assert_eq!(
        run(&[bad.to_str().unwrap(), "-o", out3.to_str().unwrap(), "-q"]),
        1
    );
    assert!(!out3.exists());
    // Usage error: exit 2.
    assert_eq!(run(&[bad.to_str().unwrap()]), 2);
}
