//! MCAP reading and writing: the conformance suite, round trips through our
//! writers, real logs, and bad input.

use std::path::{Path, PathBuf};

use nalgebra::{UnitQuaternion, Vector3};
use slam2world::error::WireError;
use slam2world::io::mcap::{
    write_slam_log, write_world_mcap, McapFile, ReadMode, SlamLogOptions, WorldFlavor, WorldScene,
};
use slam2world::io::{read_mcap, ReadOptions};
use slam2world::{Error, ImuSamples, Keyframe, PinholeCamera, Sim3, Trajectory};

fn data_dir(folder: &str) -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data")
        .join(folder);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("skipped: real data not present at {}", p.display());
        None
    }
}

fn json_u64(v: &serde_json::Value) -> u64 {
    v.as_str().and_then(|s| s.parse().ok()).unwrap()
}

/// (channel_id, sequence, log_time, publish_time, data) of every Message record the JSON lists.
fn expected_messages(json: &Path) -> Vec<(u16, u32, u64, u64, Vec<u8>)> {
    let text = std::fs::read_to_string(json).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let mut out = Vec::new();
    for r in v["records"].as_array().unwrap() {
        if r["type"] != "Message" {
            continue;
        }
        let mut m = (0u16, 0u32, 0u64, 0u64, Vec::new());
        for f in r["fields"].as_array().unwrap() {
            let name = f[0].as_str().unwrap();
            let val = &f[1];
            match name {
                "channel_id" => m.0 = json_u64(val) as u16,
                "sequence" => m.1 = json_u64(val) as u32,
                "log_time" => m.2 = json_u64(val),
                "publish_time" => m.3 = json_u64(val),
                "data" => {
                    m.4 = val
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(|b| json_u64(b) as u8)
                        .collect()
                }
                _ => {}
            }
        }
        out.push(m);
    }
    out
}

#[test]
fn conformance_suite_yields_exactly_the_listed_messages() {
    let Some(root) = data_dir("mcap_conformance") else {
        return;
    };
    let mut files = 0;
    let mut indexed = 0;
    let mut messages = 0;
    for group in std::fs::read_dir(&root).unwrap() {
        let group = group.unwrap().path();
        if !group.is_dir() {
            continue;
        }
        for entry in std::fs::read_dir(&group).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().and_then(|e| e.to_str()) != Some("mcap") {
                continue;
            }
            let expected = expected_messages(&path.with_extension("json"));
            let file = McapFile::open(&path).unwrap();
            let scan = file
                .scan(|_| true)
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            let got: Vec<_> = scan
                .messages()
                .iter()
                .map(|m| {
                    (
                        m.channel_id,
                        m.sequence,
                        m.log_time,
                        m.publish_time,
                        m.data.to_vec(),
                    )
                })
                .collect();
            assert_eq!(got, expected, "{}", path.display());
            // The mapping reader (read_mcap's path) sees the same messages.
            let mapped = file
                .scan_map(|_| true, |_, m| m.data.to_vec())
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            let got_mapped: Vec<_> = mapped
                .messages
                .into_iter()
                .map(|m| {
                    (
                        m.channel_id,
                        m.sequence,
                        m.log_time,
                        m.publish_time,
                        m.value,
                    )
                })
                .collect();
            assert_eq!(got_mapped, expected, "scan_map {}", path.display());
            files += 1;
            messages += got.len();
            if scan.mode == ReadMode::Indexed {
                indexed += 1;
            }
        }
    }
    assert_eq!(files, 416);
    assert!(messages > 0);
    // Files with a chunk index and repeated channels are read through the index.
    assert!(
        indexed > 0 && indexed < files,
        "indexed {indexed} of {files}"
    );
}

fn test_keyframes(n: usize, w: u32, h: u32) -> Vec<Keyframe> {
    let cam =
        PinholeCamera::try_new(w as f64, w as f64, w as f64 / 2.0, h as f64 / 2.0, w, h).unwrap();
    (0..n)
        .map(|i| {
            let pose = Sim3::try_new(
                UnitQuaternion::from_euler_angles(0.1 * i as f64, 0.05, -0.02),
                Vector3::new(i as f64 * 0.25, 0.5, -0.125),
                1.0 + 0.125 * i as f64,
            )
            .unwrap();
            let npx = (w * h) as usize;
            let idepth = (0..npx).map(|p| 0.5 + (p % 7) as f32 * 0.125).collect();
            let var = (0..npx).map(|p| 1e-4 * (p % 3) as f32).collect();
            let color = (0..3 * npx).map(|p| (p % 251) as u8).collect();
            Keyframe::try_new(
                i as i32,
                10.0 + i as f64,
                pose,
                cam,
                idepth,
                Some(var),
                Some(color),
            )
            .unwrap()
        })
        .collect()
}

fn test_reference(n: usize) -> Trajectory {
    let t = (0..n).map(|i| 10.0 + 0.01 * i as f64).collect();
    let p = (0..n)
        .map(|i| Vector3::new(i as f64 * 0.01, (i as f64 * 0.1).sin(), 1.5))
        .collect();
    let q = (0..n)
        .map(|i| UnitQuaternion::from_euler_angles(0.0, 0.0, 0.01 * i as f64))
        .collect();
    Trajectory::try_new(t, p, Some(q)).unwrap()
}

fn test_imu(n: usize) -> ImuSamples {
    ImuSamples::try_new(
        (0..n).map(|i| 10.0 + 0.005 * i as f64).collect(),
        (0..n)
            .map(|i| Vector3::new(0.01 * i as f64, 0.0, -0.5))
            .collect(),
        (0..n).map(|_| Vector3::new(0.0, 0.1, 9.81)).collect(),
    )
    .unwrap()
}

fn round_trip(compression: Option<mcap::Compression>) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("slam.mcap");
    let kfs = test_keyframes(4, 8, 6);
    let reference = test_reference(50);
    let imu = test_imu(80);
    let options = SlamLogOptions {
        compression,
        ..SlamLogOptions::default()
    };
    let md = vec![("seed".to_string(), "7".to_string())];
    write_slam_log(&path, &kfs, Some(&reference), Some(&imu), &md, &options).unwrap();
    let log = read_mcap(&path, &ReadOptions::default()).unwrap();
    assert_eq!(log.keyframes.len(), kfs.len());
    for (a, b) in log.keyframes.iter().zip(&kfs) {
        assert_eq!(a.id, b.id);
        assert_eq!(a.timestamp, b.timestamp);
        assert_eq!(a.idepth, b.idepth);
        assert_eq!(a.idepth_var, b.idepth_var);
        assert_eq!(a.color, b.color);
        assert_eq!(a.camera, b.camera);
        // camToWorld travels as f32
        assert!((a.pose.translation - b.pose.translation).norm() < 1e-6);
        assert!((a.pose.scale - b.pose.scale).abs() < 1e-6);
        assert!(a.pose.rotation.angle_to(&b.pose.rotation) < 1e-6);
    }
    assert_eq!(log.graph_messages, 1);
    assert_eq!(log.graph_updates, kfs.len());
    let r = log.reference.unwrap();
    assert_eq!(r.len(), reference.len());
    for i in 0..r.len() {
        assert!((r.timestamps[i] - reference.timestamps[i]).abs() < 1e-9);
        assert_eq!(r.positions[i], reference.positions[i]);
    }
    let s = log.imu.unwrap();
    assert_eq!(s.len(), imu.len());
    assert_eq!(s.gyro, imu.gyro);
    assert_eq!(s.accel, imu.accel);
    // Sized from the summary's message counts as the scan began: no
    // vector grew past what it holds.
    assert_eq!(r.timestamps.capacity(), r.len());
    assert_eq!(r.positions.capacity(), r.len());
    assert_eq!(s.timestamps.capacity(), s.len());
    assert_eq!(s.accel.capacity(), s.len());
}

#[test]
fn zstd_round_trip() {
    round_trip(Some(mcap::Compression::Zstd));
}

#[test]
fn lz4_round_trip() {
    round_trip(Some(mcap::Compression::Lz4));
}

#[test]
fn uncompressed_round_trip() {
    round_trip(None);
}

#[test]
fn slam_log_is_deterministic() {
    let dir = tempfile::tempdir().unwrap();
    let kfs = test_keyframes(3, 4, 4);
    let r = test_reference(20);
    let imu = test_imu(20);
    let md = vec![("a".to_string(), "b".to_string())];
    let opts = SlamLogOptions::default();
    let a = dir.path().join("a.mcap");
    let b = dir.path().join("b.mcap");
    write_slam_log(&a, &kfs, Some(&r), Some(&imu), &md, &opts).unwrap();
    write_slam_log(&b, &kfs, Some(&r), Some(&imu), &md, &opts).unwrap();
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
}

#[test]
fn nav2_sim_yields_its_odometry() {
    let Some(dir) = data_dir("mcap_nav2_sim") else {
        return;
    };
    let path = dir.join("nav2_turtlebot.mcap");
    let opts = ReadOptions {
        pose_topic: Some("/odom".into()),
        ..ReadOptions::default()
    };
    let log = read_mcap(&path, &opts).unwrap();
    let r = log.reference.unwrap();
    assert_eq!(r.len(), 2639);
    let span = r.timestamps[r.len() - 1] - r.timestamps[0];
    assert!(span > 90.0 && span < 100.0, "span {span}");
    // The default pick is PoseWithCovarianceStamped (/amcl_pose), 135 messages.
    let log = read_mcap(&path, &ReadOptions::default()).unwrap();
    assert_eq!(log.reference_topic.as_deref(), Some("/amcl_pose"));
    assert_eq!(log.reference.unwrap().len(), 135);
    let odom = log.topics.iter().find(|t| t.topic == "/odom").unwrap();
    assert_eq!(odom.count, 2639);
    // TF: one parent/child pair, the most frequent unless named.
    let opts = ReadOptions {
        pose_topic: Some("/tf".into()),
        tf_parent: Some("odom".into()),
        tf_child: Some("base_link".into()),
        ..ReadOptions::default()
    };
    let log = read_mcap(&path, &opts).unwrap();
    assert_eq!(log.reference.unwrap().len(), 2639);
    // Without frames, the most frequent pair (odom → base_link) is taken.
    let opts = ReadOptions {
        pose_topic: Some("/tf".into()),
        ..ReadOptions::default()
    };
    assert_eq!(
        read_mcap(&path, &opts).unwrap().reference.unwrap().len(),
        2639
    );
}

fn expect_mcap_error(r: slam2world::Result<impl std::fmt::Debug>, words: &[&str]) {
    match r {
        Err(e @ Error::Mcap { .. }) => {
            let msg = e.to_string();
            for w in words {
                assert!(msg.contains(w), "{msg:?} lacks {w:?}");
            }
        }
        other => panic!("expected an MCAP error with {words:?}, got {other:?}"),
    }
}

/// A decode error of message `index` of `topic`, whose cause `cause` accepts.
fn expect_decode_error(
    r: slam2world::Result<impl std::fmt::Debug>,
    want_topic: &str,
    want_index: usize,
    cause: impl Fn(&slam2world::error::WireError) -> bool,
) {
    match r {
        Err(Error::Decode {
            topic,
            index,
            source,
            ..
        }) => {
            assert_eq!((topic.as_str(), index), (want_topic, want_index));
            assert!(cause(&source), "unexpected cause {source:?}");
        }
        other => panic!("expected a decode error of {want_topic} {want_index}, got {other:?}"),
    }
}

fn written_log(dir: &Path, compression: Option<mcap::Compression>) -> PathBuf {
    let path = dir.join("log.mcap");
    let opts = SlamLogOptions {
        compression,
        ..SlamLogOptions::default()
    };
    write_slam_log(
        &path,
        &test_keyframes(2, 4, 4),
        Some(&test_reference(10)),
        None,
        &[],
        &opts,
    )
    .unwrap();
    path
}

#[test]
fn truncated_file_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = written_log(dir.path(), Some(mcap::Compression::Zstd));
    let bytes = std::fs::read(&path).unwrap();
    for cut in [bytes.len() - 3, bytes.len() / 2, 20] {
        let p = dir.path().join("cut.mcap");
        std::fs::write(&p, &bytes[..cut]).unwrap();
        expect_mcap_error(
            read_mcap(&p, &ReadOptions::default()),
            &["cut.mcap", "truncated"],
        );
    }
}

#[test]
fn bad_magic_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.mcap");
    std::fs::write(&p, b"\x89MCAQ0\r\nxxxxxxxxxxxxxxxxxxxx").unwrap();
    expect_mcap_error(
        read_mcap(&p, &ReadOptions::default()),
        &["bad.mcap", "magic"],
    );
    std::fs::write(&p, b"").unwrap();
    expect_mcap_error(read_mcap(&p, &ReadOptions::default()), &["magic"]);
}

#[test]
fn crc_mismatch_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = written_log(dir.path(), None);
    let mut bytes = std::fs::read(&path).unwrap();
    // Flip one byte inside the keyframe point cloud (inside the uncompressed chunk).
    let i = bytes.len() / 3;
    bytes[i] ^= 0x5a;
    let p = dir.path().join("crc.mcap");
    std::fs::write(&p, &bytes).unwrap();
    expect_mcap_error(
        read_mcap(&p, &ReadOptions::default()),
        &["crc.mcap", "chunk"],
    );
    let msg = read_mcap(&p, &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(msg.to_lowercase().contains("crc"), "{msg}");
}

#[test]
fn unknown_or_mismatched_topic_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = written_log(dir.path(), None);
    let opts = ReadOptions {
        pose_topic: Some("/nope".into()),
        ..ReadOptions::default()
    };
    expect_mcap_error(read_mcap(&path, &opts), &["/nope", "not in the log"]);
    let opts = ReadOptions {
        pose_topic: Some("/lsd_slam/keyframes".into()),
        ..ReadOptions::default()
    };
    expect_mcap_error(
        read_mcap(&path, &opts),
        &["/lsd_slam/keyframes", "lsd_slam_viewer/keyframeMsg", "pose"],
    );
}

/// A log with one channel carrying hand-made payloads.
fn custom_log(
    path: &Path,
    schema: (&str, &str, &[u8]),
    encoding: &str,
    topic: &str,
    payloads: &[Vec<u8>],
) {
    let f = std::fs::File::create(path).unwrap();
    let mut w = mcap::WriteOptions::new()
        .create(std::io::BufWriter::new(f))
        .unwrap();
    let sid = w.add_schema(schema.0, schema.1, schema.2).unwrap();
    let cid = w
        .add_channel(sid, topic, encoding, &Default::default())
        .unwrap();
    for (i, p) in payloads.iter().enumerate() {
        let h = mcap::records::MessageHeader {
            channel_id: cid,
            sequence: i as u32,
            log_time: i as u64,
            publish_time: i as u64,
        };
        w.write_to_known_channel(&h, p).unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn keyframe_pointcloud_of_wrong_size_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let kf = &test_keyframes(1, 4, 4)[0];
    let mut msg = slam2world::io::mcap::write::keyframe_msg_ros1(kf);
    // Drop the last point but keep the length field consistent with the bytes.
    msg.truncate(msg.len() - 12);
    let len = (4 * 4 * 12 - 12) as u32;
    msg[65..69].copy_from_slice(&len.to_le_bytes());
    let p = dir.path().join("kf.mcap");
    custom_log(
        &p,
        slam2world::io::mcap::schemas::ROS1_KEYFRAME,
        "ros1",
        "/lsd_slam/keyframes",
        &[msg],
    );
    let r = read_mcap(&p, &ReadOptions::default());
    assert!(format!("{:?}", r.as_ref().err()).contains("180 bytes"));
    expect_decode_error(r, "/lsd_slam/keyframes", 0, |e| {
        // The point cloud's length field is at byte 65 of the message.
        matches!(e, WireError::Malformed { offset: 65, what } if what.contains("192"))
    });
}

#[test]
fn nan_poses_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("nan.mcap");
    let good =
        slam2world::io::mcap::write::pose_stamped_ros1(0, 1.0, "w", [0.0; 3], [0.0, 0.0, 0.0, 1.0]);
    let bad = slam2world::io::mcap::write::pose_stamped_ros1(
        1,
        2.0,
        "w",
        [f64::NAN, 0.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    );
    custom_log(
        &p,
        slam2world::io::mcap::schemas::ROS1_POSE_STAMPED,
        "ros1",
        "/gt",
        &[good, bad],
    );
    expect_decode_error(
        read_mcap(&p, &ReadOptions::default()),
        "/gt",
        1,
        |e| matches!(e, WireError::Value { what } if what.contains("non-finite")),
    );

    // A keyframe with a NaN camToWorld.
    let kf = &test_keyframes(1, 4, 4)[0];
    let mut msg = slam2world::io::mcap::write::keyframe_msg_ros1(kf);
    msg[13..17].copy_from_slice(&f32::NAN.to_le_bytes());
    let p = dir.path().join("nankf.mcap");
    custom_log(
        &p,
        slam2world::io::mcap::schemas::ROS1_KEYFRAME,
        "ros1",
        "/kf",
        &[msg],
    );
    expect_mcap_error(
        read_mcap(&p, &ReadOptions::default()),
        &["nankf.mcap", "/kf", "keyframe 0", "non-finite"],
    );
}

#[test]
fn graph_messages_give_poses_to_the_keyframes_before_them() {
    use slam2world::io::mcap::write::{graph_msg_ros1_poses, keyframe_msg_ros1_at};
    let kfs = test_keyframes(2, 4, 4);
    let pose = |x: f64| Sim3::try_new(UnitQuaternion::identity(), Vector3::new(x, 0.0, 0.0), 1.0);
    let (a, b, c) = (pose(1.0).unwrap(), pose(2.0).unwrap(), pose(3.0).unwrap());
    // In log order: keyframe 0; graph 0 (ids 0 and 1: 1 not seen yet);
    // keyframe 1; graph 1 (both); keyframe 0 again (its own pose again);
    // graph 2 (id 1 alone).
    let k = |i: usize, p: &Sim3| (true, keyframe_msg_ros1_at(&kfs[i], p));
    let g = |poses: &[(i32, Sim3)]| (false, graph_msg_ros1_poses(poses));
    let own0 = pose(9.0).unwrap();
    let messages = [
        k(0, &kfs[0].pose),
        g(&[(0, a), (1, a)]),
        k(1, &kfs[1].pose),
        g(&[(0, b), (1, b)]),
        k(0, &own0),
        g(&[(1, c)]),
    ];
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("graph.mcap");
    {
        let f = std::fs::File::create(&p).unwrap();
        let mut w = mcap::WriteOptions::new()
            .create(std::io::BufWriter::new(f))
            .unwrap();
        let (kn, ke, kd) = slam2world::io::mcap::schemas::ROS1_KEYFRAME;
        let (gn, ge, gd) = slam2world::io::mcap::schemas::ROS1_KEYFRAME_GRAPH;
        let ks = w.add_schema(kn, ke, kd).unwrap();
        let gs = w.add_schema(gn, ge, gd).unwrap();
        let kc = w
            .add_channel(ks, "/lsd_slam/keyframes", "ros1", &Default::default())
            .unwrap();
        let gc = w
            .add_channel(gs, "/lsd_slam/graph", "ros1", &Default::default())
            .unwrap();
        for (i, (is_kf, data)) in messages.iter().enumerate() {
            let h = mcap::records::MessageHeader {
                channel_id: if *is_kf { kc } else { gc },
                sequence: i as u32,
                log_time: i as u64,
                publish_time: i as u64,
            };
            w.write_to_known_channel(&h, data).unwrap();
        }
        w.finish().unwrap();
    }
    let log = read_mcap(&p, &ReadOptions::default()).unwrap();
    assert_eq!((log.keyframe_messages, log.graph_messages), (3, 3));
    // Graph 0 finds keyframe 0; graph 1 both; graph 2 keyframe 1.
    assert_eq!(log.graph_updates, 1 + 2 + 1);
    let x: Vec<f64> = log.keyframes.iter().map(|k| k.pose.translation.x).collect();
    // Keyframe 0: its second version came after every graph that named it.
    // Keyframe 1: the last graph.
    assert!((x[0] - own0.translation.x).abs() < 1e-6, "{x:?}");
    assert!((x[1] - c.translation.x).abs() < 1e-6, "{x:?}");
}

#[test]
fn bad_imu_messages_are_refused_by_index() {
    use slam2world::io::mcap::write::imu_ros1;
    let dir = tempfile::tempdir().unwrap();
    let good = |i: u32| imu_ros1(i, f64::from(i), "imu", [0.0; 3], [0.0, 0.0, 9.81]);
    let nan = imu_ros1(2, 2.0, "imu", [0.0, f64::NAN, 0.0], [0.0, 0.0, 9.81]);
    let cases: [(&str, Vec<Vec<u8>>, usize, bool); 2] = [
        // A finite sample after a non-finite one does not hide it.
        ("nan.mcap", vec![good(0), good(1), nan, good(3)], 2, true),
        (
            "short.mcap",
            vec![good(0), vec![1, 2, 3], good(2)],
            1,
            false,
        ),
    ];
    for (name, messages, index, non_finite) in cases {
        let p = dir.path().join(name);
        custom_log(
            &p,
            slam2world::io::mcap::schemas::ROS1_IMU,
            "ros1",
            "/imu0",
            &messages,
        );
        // The same error at the same index when the samples go to disk as
        // they are read (a bounded read), before anything is converted.
        for r in [
            read_mcap(&p, &ReadOptions::default()),
            slam2world::io::log::read_log_spilled(&p, &ReadOptions::default()),
        ] {
            expect_decode_error(r, "/imu0", index, |e| match e {
                WireError::Value { what } => non_finite && what.contains("non-finite IMU sample"),
                WireError::Truncated { .. } => !non_finite,
                _ => false,
            });
        }
    }
    // Samples out of order are read by time, the first of a repeated stamp kept.
    let p = dir.path().join("order.mcap");
    let messages = vec![
        good(2),
        good(0),
        imu_ros1(9, 1.0, "imu", [1.0; 3], [0.0, 0.0, 9.81]),
        imu_ros1(10, 1.0, "imu", [2.0; 3], [0.0, 0.0, 9.81]),
    ];
    custom_log(
        &p,
        slam2world::io::mcap::schemas::ROS1_IMU,
        "ros1",
        "/imu0",
        &messages,
    );
    let imu = read_mcap(&p, &ReadOptions::default()).unwrap().imu.unwrap();
    assert_eq!(imu.timestamps, vec![0.0, 1.0, 2.0]);
    assert_eq!(imu.gyro[1].x, 1.0);
    // Read bounded, the samples wait on disk and come back the same.
    let log = slam2world::io::log::read_log_spilled(&p, &ReadOptions::default()).unwrap();
    assert!(log.imu.is_none());
    let on_disk = log.imu_on_disk.expect("the IMU on disk");
    assert_eq!(on_disk.len(), 4);
    let back = on_disk.load().unwrap();
    assert_eq!(back.timestamps, imu.timestamps);
    assert_eq!(back.gyro, imu.gyro);
    assert_eq!(back.accel, imu.accel);
}

#[test]
fn short_pose_message_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("short.mcap");
    custom_log(
        &p,
        slam2world::io::mcap::schemas::ROS1_POSE_STAMPED,
        "ros1",
        "/gt",
        &[vec![1, 2, 3]],
    );
    let r = read_mcap(&p, &ReadOptions::default());
    let msg = format!("{}", r.as_ref().unwrap_err());
    assert!(
        msg.contains("short.mcap") && msg.contains("too short"),
        "{msg}"
    );
    // PoseStamped starts with the header's u32 seq: 4 bytes needed at 0, 3 there.
    expect_decode_error(r, "/gt", 0, |e| {
        *e == WireError::Truncated {
            offset: 0,
            need: 4,
            len: 3,
        }
    });
}

#[test]
fn world_mcap_reads_back() {
    let dir = tempfile::tempdir().unwrap();
    let points: Vec<f32> = (0..30).map(|i| i as f32 * 0.5).collect();
    let colors: Vec<u8> = (0..30).map(|i| i as u8).collect();
    let r = test_reference(5);
    for flavor in [WorldFlavor::Foxglove, WorldFlavor::Ros2] {
        let path = dir.path().join(format!("world-{flavor:?}.mcap"));
        let scene = WorldScene {
            cloud: slam2world::io::spill::CloudRef::Memory(&points, Some(&colors)),
            t_world_slam: Sim3::identity(),
            slam_trajectory: Some(&r),
            reference: Some((&r).into()),
            stamp: 12.5,
            world_frame: "world",
            slam_frame: "slam",
            frames: &[],
        };
        write_world_mcap(&path, &scene, flavor).unwrap();
        let file = McapFile::open(&path).unwrap();
        let scan = file.scan(|_| true).unwrap();
        let names: Vec<&str> = scan
            .channels
            .values()
            .map(|c| c.schema_name.as_str())
            .collect();
        match flavor {
            WorldFlavor::Foxglove => {
                assert!(names.contains(&"foxglove.PointCloud"));
                assert!(names.contains(&"foxglove.FrameTransform"));
                assert!(names.contains(&"foxglove.PosesInFrame"));
                // The reference comes back through the PosesInFrame decoder (last pose).
                let log = read_mcap(
                    &path,
                    &ReadOptions {
                        pose_topic: Some("/world/reference".into()),
                        ..ReadOptions::default()
                    },
                )
                .unwrap();
                let back = log.reference.unwrap();
                assert_eq!(back.positions[0], r.positions[r.len() - 1]);
            }
            WorldFlavor::Ros2 => {
                assert!(names.contains(&"sensor_msgs/msg/PointCloud2"));
                assert!(names.contains(&"tf2_msgs/msg/TFMessage"));
            }
        }
    }
    // No temporary file is left beside the outputs.
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(left.len(), 2);
}

/// A small deterministic mutation fuzz on stable Rust (the cargo-fuzz targets
/// under fuzz/ go further): decoders and the reader return errors, never panic.
#[test]
fn mutated_inputs_never_panic() {
    use slam2world::io::mcap::decode::{self, MessageKind};
    let dir = tempfile::tempdir().unwrap();
    let kf = slam2world::io::mcap::write::keyframe_msg_ros1(&test_keyframes(1, 3, 2)[0]);
    let pose = slam2world::io::mcap::write::pose_stamped_ros1(
        3,
        1.5,
        "world",
        [1.0, 2.0, 3.0],
        [0.0, 0.0, 0.0, 1.0],
    );
    let imu = slam2world::io::mcap::write::imu_ros1(1, 2.0, "imu", [0.1; 3], [9.8; 3]);
    let graph = slam2world::io::mcap::write::graph_msg_ros1(&test_keyframes(2, 2, 2));
    let seeds = [kf, pose, imu, graph];
    let kinds = [
        MessageKind::PoseStamped,
        MessageKind::PoseWithCovarianceStamped,
        MessageKind::Odometry,
        MessageKind::PoseInFrame,
        MessageKind::PosesInFrame,
        MessageKind::Tf,
    ];
    let mut state = 0x2545f4914f6cdd1du64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    for round in 0..3000 {
        let mut m = seeds[round % seeds.len()].clone();
        for _ in 0..1 + next() % 4 {
            let i = (next() as usize) % m.len().max(1);
            match next() % 3 {
                0 if !m.is_empty() => m[i] = next() as u8,
                1 => m.truncate(i),
                _ => m.insert(i.min(m.len()), next() as u8),
            }
        }
        for k in kinds {
            for enc in ["ros1", "cdr", "protobuf", "json"] {
                let _ = decode::poses(k, enc, &m);
                let _ = decode::pose_sample(k, enc, &m);
            }
        }
        let _ = decode::imu("ros1", &m);
        let _ = decode::imu("cdr", &m);
        if let Ok(k) = decode::keyframe_ros1(&m) {
            let _ = decode::split_pointcloud(k.pointcloud);
        }
        let _ = decode::graph_ros1(&m);
    }
    // Whole files: flip bytes of a small zstd log and read it.
    let path = written_log(dir.path(), Some(mcap::Compression::Zstd));
    let bytes = std::fs::read(&path).unwrap();
    let p = dir.path().join("mutated.mcap");
    for _ in 0..300 {
        let mut b = bytes.clone();
        for _ in 0..1 + next() % 3 {
            let i = (next() as usize) % b.len();
            b[i] = next() as u8;
        }
        std::fs::write(&p, &b).unwrap();
        let _ = read_mcap(&p, &ReadOptions::default());
    }
}

#[test]
fn inspect_exits_0_on_a_log_and_1_on_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let path = written_log(dir.path(), Some(mcap::Compression::Lz4));
    let inv = slam2world::io::inspect_mcap(&path).unwrap();
    let topics: Vec<&str> = inv.topics.iter().map(|t| t.topic.as_str()).collect();
    assert_eq!(topics.len(), 3, "{topics:?}");
    assert!(inv
        .picks
        .iter()
        .any(|(role, t)| *role == "keyframes" && t == "/lsd_slam/keyframes"));
    let kf = inv
        .topics
        .iter()
        .find(|t| t.topic == "/lsd_slam/keyframes")
        .unwrap();
    assert_eq!(kf.count, 2);
    let code = slam2world::cli::main_with_args(["slam2world", "inspect", path.to_str().unwrap()]);
    assert_eq!(code, 0);
    let bad = dir.path().join("bad.mcap");
    std::fs::write(&bad, b"nope").unwrap();
    let code = slam2world::cli::main_with_args(["slam2world", "inspect", bad.to_str().unwrap()]);
    assert_eq!(code, 1);
}

/// Found by the cargo-fuzz target `decoders`: width·height·12 overflowed u64
/// for a header claiming a 4e9 x 4e9 image; the decoder must refuse it.
#[test]
fn keyframe_with_huge_dimensions_is_an_error_not_an_overflow() {
    let mut msg = Vec::new();
    msg.extend_from_slice(&7i32.to_le_bytes()); // id
    msg.extend_from_slice(&1.5f64.to_le_bytes()); // time
    msg.push(1); // isKeyframe
    for v in [
        0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 500.0, 500.0, 320.0, 240.0,
    ] {
        msg.extend_from_slice(&v.to_le_bytes()); // camToWorld[7], fx, fy, cx, cy
    }
    msg.extend_from_slice(&u32::MAX.to_le_bytes()); // height
    msg.extend_from_slice(&u32::MAX.to_le_bytes()); // width
    msg.extend_from_slice(&12u32.to_le_bytes()); // pointcloud length
    msg.extend_from_slice(&[0u8; 12]);
    let err = slam2world::io::mcap::decode::keyframe_ros1(&msg).unwrap_err();
    assert!(
        matches!(&err, WireError::Malformed { offset: 65, what } if what.contains("expected width·height·12")),
        "{err:?}"
    );
}
