//! `convert`: a LSD-SLAM log with a known `T_world_slam` gives that transform
//! back, a world cloud in world coordinates, and the three outputs.

use std::path::Path;

use nalgebra::{UnitQuaternion, Vector3};
use slam2world::cloud::{backproject, PointFilter};
use slam2world::io::mcap::{write_slam_log, McapFile, SlamLogOptions};
use slam2world::pipeline::{convert_path, ConvertOptions};
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
    let c = convert_path(&path, &opts()).unwrap();
    let t = c.transform();
    let want = truth();
    assert!((t.scale - want.scale).abs() < 1e-4, "scale {}", t.scale);
    assert!((t.translation - want.translation).norm() < 1e-4);
    assert!(t.rotation.angle_to(&want.rotation) < 1e-5);
    assert_eq!(c.report.frames_used, 8);
    assert!(c.report.frames_dropped.is_empty());
    assert!(c.report.ape.as_ref().unwrap().rmse < 1e-4);
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
    let err = slam2world::pipeline::convert_path(
        &path,
        &ConvertOptions {
            align: slam2world::align::trajectories::TrajectoryAlignOptions {
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

/// A cube's centre and size (metres).
type Cube = ([f64; 3], [f64; 3]);

/// The `(centre, size)` of every cube of a `foxglove.SceneUpdate`, and the
/// number of entities it holds.
fn scene_update_cubes(data: &[u8]) -> (usize, Vec<Cube>) {
    use slam2world::io::mcap::wire::pb_fields;
    let fields = |b: &[u8]| -> Vec<(u32, Vec<u8>, u64)> {
        pb_fields(b)
            .map(|f| {
                let (n, v) = f.unwrap();
                match v.as_bytes() {
                    Ok(b) => (n, b.to_vec(), 0),
                    Err(_) => (n, Vec::new(), v.as_u64().unwrap()),
                }
            })
            .collect()
    };
    let vec3 = |b: &[u8]| {
        let mut v = [0.0; 3];
        for (n, _, bits) in fields(b) {
            v[n as usize - 1] = f64::from_bits(bits);
        }
        v
    };
    let mut entities = 0;
    let mut cubes = Vec::new();
    for (n, entity, _) in fields(data) {
        assert_eq!(n, 2, "a SceneUpdate holds entities only");
        entities += 1;
        for (n, cube, _) in fields(&entity) {
            if n != 8 {
                continue;
            }
            let (mut centre, mut size) = ([f64::NAN; 3], [f64::NAN; 3]);
            for (n, b, _) in fields(&cube) {
                match n {
                    1 => {
                        for (n, b, _) in fields(&b) {
                            if n == 1 {
                                centre = vec3(&b);
                            }
                        }
                    }
                    2 => size = vec3(&b),
                    _ => {}
                }
            }
            cubes.push((centre, size));
        }
    }
    (entities, cubes)
}

#[test]
fn convert_with_an_octree_writes_map_bt_and_the_occupied_voxels() {
    use slam2world::io::mcap::WorldFlavor;
    use slam2world::map::{MapParams, OccupancyMap, VoxelState};
    let dir = tempfile::tempdir().unwrap();
    let path = write_log(dir.path());
    let res = 0.2;
    let o = ConvertOptions {
        map: Some(slam2world::map::MapParams::new(res)),
        ..opts()
    };
    let c = convert_path(&path, &o).unwrap();
    let map = c.octree.as_ref().expect("an octree");
    assert_eq!(map.resolution(), res);

    // The same map, built here scan by scan from the camera centres
    // T_world_slam · T_slam_cam of the fitted transform.
    let log = slam2world::io::read_mcap(&path, &Default::default()).unwrap();
    let t = c.transform();
    let mut want = OccupancyMap::try_new(MapParams::new(res)).unwrap();
    for kf in &log.keyframes {
        let pts: Vec<f32> = c
            .cloud
            .points
            .chunks_exact(3)
            .zip(&c.cloud.keyframe_ids)
            .filter(|(_, id)| **id == kf.id)
            .flat_map(|(p, _)| p.iter().copied())
            .collect();
        let o = (t * kf.pose).translation;
        want.insert_scan(&pts, [o.x as f32, o.y as f32, o.z as f32])
            .unwrap();
    }
    assert!(*map == want, "the octree differs from scan-wise insertion");

    // Occupied voxels are where the converted points are: each holds a point,
    // and most points lie in an occupied voxel.
    let point_keys: std::collections::HashSet<_> = c
        .cloud
        .points
        .chunks_exact(3)
        .map(|p| map.key_of([p[0] as f64, p[1] as f64, p[2] as f64]).unwrap())
        .collect();
    let occupied = map.voxel_centers(VoxelState::Occupied);
    assert!(occupied.len() > 50, "{} occupied voxels", occupied.len());
    for v in &occupied {
        assert!(point_keys.contains(&map.key_of(*v).unwrap()), "{v:?}");
    }
    let in_occupied = c
        .cloud
        .points
        .chunks_exact(3)
        .filter(|p| map.state([p[0] as f64, p[1] as f64, p[2] as f64]) == VoxelState::Occupied)
        .count();
    assert!(
        2 * in_occupied > c.cloud.len(),
        "{in_occupied} of {} points in occupied voxels",
        c.cloud.len()
    );
    // Free space between the cameras and the points.
    assert!(!map.voxel_centers(VoxelState::Free).is_empty());

    // The report's section.
    let leaves = map.leaves(VoxelState::Occupied);
    let r = c.report.octree.as_ref().unwrap();
    assert_eq!(r.leaves_occupied, leaves.len());
    assert_eq!(r.leaves_free, map.leaves(VoxelState::Free).len());
    assert_eq!((r.scans, r.points), (8, c.cloud.len()));
    assert!(r.memory_bytes > 0 && r.nodes == map.num_nodes());

    // The CLI writes map.bt, which reads back with the same classification.
    let out = dir.path().join("out");
    let run = |args: &[&str]| {
        let mut v = vec!["slam2world", "convert", path.to_str().unwrap(), "-q"];
        v.extend_from_slice(args);
        slam2world::cli::main_with_args(v)
    };
    let code = run(&[
        "-o",
        out.to_str().unwrap(),
        "--no-filter",
        "--octree",
        "0.2",
    ]);
    assert_eq!(code, 0);
    let back = OccupancyMap::read_bt(&out.join("map.bt"), MapParams::new(1.0)).unwrap();
    assert_eq!(back.resolution(), res);
    let key_set = |m: &OccupancyMap, s| {
        let mut k: Vec<_> = m
            .voxel_centers(s)
            .into_iter()
            .map(|p| m.key_of(p).unwrap())
            .collect();
        k.sort_unstable();
        k
    };
    for s in [VoxelState::Occupied, VoxelState::Free] {
        assert_eq!(key_set(&back, s), key_set(map, s), "{s:?}");
    }
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["octree"]["resolution"], 0.2);
    assert_eq!(report["octree"]["leaves_occupied"], leaves.len());

    // world.mcap: one SceneUpdate whose cubes are the occupied leaves.
    let world = McapFile::open(out.join("world.mcap")).unwrap();
    let scan = world
        .scan(|ch| ch.schema_name == "foxglove.SceneUpdate")
        .unwrap();
    let ch: Vec<_> = scan
        .channels
        .values()
        .filter(|ch| ch.schema_name == "foxglove.SceneUpdate")
        .collect();
    assert_eq!(ch.len(), 1);
    assert_eq!(
        (ch[0].topic.as_str(), ch[0].message_encoding.as_str()),
        ("/slam2world/octomap", "protobuf")
    );
    assert_eq!(scan.len(), 1);
    let (entities, cubes) = scene_update_cubes(scan.get(0).unwrap().data);
    assert_eq!(entities, 1);
    assert_eq!(cubes.len(), leaves.len());
    let mut got: Vec<_> = cubes
        .iter()
        .map(|(c, s)| {
            assert!(s[0] == s[1] && s[1] == s[2], "{s:?}");
            (map.key_of(*c).unwrap(), s[0])
        })
        .collect();
    let mut expected: Vec<_> = leaves
        .iter()
        .map(|(c, s)| (map.key_of(*c).unwrap(), *s))
        .collect();
    got.sort_by(|a, b| a.partial_cmp(b).unwrap());
    expected.sort_by(|a, b| a.partial_cmp(b).unwrap());
    assert_eq!(got, expected);

    // The ROS 2 flavour carries the leaf centres as a PointCloud2.
    let out_ros2 = dir.path().join("out_ros2");
    c.write_all(&out_ros2, WorldFlavor::Ros2).unwrap();
    let world = McapFile::open(out_ros2.join("world.mcap")).unwrap();
    assert!(world
        .channels()
        .unwrap()
        .values()
        .any(|ch| ch.topic == "/slam2world/octomap"
            && ch.schema_name == "sensor_msgs/msg/PointCloud2"));
    assert!(out_ros2.join("map.bt").exists());

    // Bad octree arguments: a bad resolution is a core error (exit 1, nothing
    // written); a max range without --octree is a usage error (exit 2).
    let out2 = dir.path().join("out2");
    assert_eq!(run(&["-o", out2.to_str().unwrap(), "--octree", "0"]), 1);
    assert_eq!(run(&["-o", out2.to_str().unwrap(), "--octree", "-1"]), 1);
    assert!(!out2.exists());
    assert_eq!(
        run(&["-o", out2.to_str().unwrap(), "--octree-max-range", "5"]),
        2
    );
    // Without an octree there is no map.bt and no octree section.
    let none = convert_path(&path, &opts()).unwrap();
    assert!(none.octree.is_none() && none.report.octree.is_none());
    assert!(none.write_bt(dir.path().join("x.bt")).is_err());
}
