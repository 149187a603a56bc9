//! The bounded-memory conversion (`convert_path_bounded`, what the CLI's
//! `convert` runs): keyframe pixels, raw IMU, reference poses and the world
//! cloud on disk, a batch of keyframes in memory at a time, and the very
//! outputs of the in-memory conversion.

use crate::common;

use std::path::Path;

use nalgebra::{UnitQuaternion, Vector3};
use slam2world::cloud::PointFilter;
use slam2world::io::mcap::WorldFlavor;
use slam2world::io::mcap::{write_slam_log, McapFile, SlamLogOptions};
use slam2world::map::MapParams;
use slam2world::pipeline::{convert_path, convert_path_bounded, Conversion, ConvertOptions};
use slam2world::{Keyframe, PinholeCamera, Sim3, Trajectory};

fn octree() -> MapParams {
    MapParams {
        resolution: 0.2,
        prob_hit: 0.7,
        prob_miss: 0.4,
        clamp_min: 0.1192,
        clamp_max: 0.971,
        max_range: Some(8.0),
    }
}

/// The report without what differs run to run (timings) or between the two
/// paths by design (`stream`).
fn report_core(dir: &Path) -> serde_json::Value {
    let mut r: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap();
    let o = r.as_object_mut().unwrap();
    o.remove("timing");
    o.remove("stream");
    if let Some(t) = o.get_mut("octree").and_then(|v| v.as_object_mut()) {
        t.remove("time_s");
    }
    r
}

/// Every output of `a` and `b` equal: byte for byte, the report but for its
/// timings, the page's figures.
fn same_outputs(a: &Path, b: &Path) {
    let mut names: Vec<String> = std::fs::read_dir(a)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    let mut other: Vec<String> = std::fs::read_dir(b)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    other.sort();
    assert_eq!(names, other);
    for name in &names {
        match name.as_str() {
            "report.json" => assert_eq!(report_core(a), report_core(b)),
            "report.html" => {
                let figures = |d: &Path| {
                    let html = std::fs::read_to_string(d.join(name)).unwrap();
                    let start = html.find("\"figures\"").expect("the page's figures");
                    let end = html[start..].find("</script>").unwrap();
                    html[start..start + end].to_string()
                };
                assert!(figures(a) == figures(b), "report.html figures differ");
            }
            // world.mcap byte for byte (its writer lays the file out the
            // same for the same messages), and its messages as read back.
            "world.mcap" => {
                assert!(messages(&a.join(name)) == messages(&b.join(name)));
                assert!(
                    std::fs::read(a.join(name)).unwrap() == std::fs::read(b.join(name)).unwrap(),
                    "world.mcap differs"
                );
            }
            _ => assert!(
                std::fs::read(a.join(name)).unwrap() == std::fs::read(b.join(name)).unwrap(),
                "{name} differs"
            ),
        }
    }
}

/// Every message of an MCAP file in file order: topic, schema, log time, bytes.
fn messages(path: &Path) -> Vec<(String, String, u64, Vec<u8>)> {
    let f = McapFile::open(path).unwrap();
    let scan = f.scan(|_| true).unwrap();
    let channels = f.channels().unwrap();
    scan.iter()
        .map(|m| {
            let c = &channels[&m.channel_id];
            (
                c.topic.clone(),
                c.schema_name.clone(),
                m.log_time,
                m.data.to_vec(),
            )
        })
        .collect()
}

fn both(log: &Path, opts: &ConvertOptions, out: &Path) -> (Conversion, Conversion) {
    let mem = convert_path(log, opts).unwrap();
    let bounded = convert_path_bounded(log, opts).unwrap();
    assert!(bounded.cloud.is_empty() && bounded.cloud_file.is_some());
    assert!(mem.cloud_file.is_none() && mem.report.stream.is_none());
    let (a, b) = (out.join("memory"), out.join("bounded"));
    mem.write_all(&a, WorldFlavor::Foxglove).unwrap();
    bounded.write_all(&b, WorldFlavor::Foxglove).unwrap();
    same_outputs(&a, &b);
    (mem, bounded)
}

#[test]
#[ignore = "slow: make test runs it"]
fn the_bounded_conversion_writes_the_in_memory_outputs_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("sim.mcap");
    let o = common::bin(&["simulate", "-o", log.to_str().unwrap(), "--reduced", "4"]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let opts = ConvertOptions {
        map: Some(octree()),
        ..ConvertOptions::default()
    };
    let (mem, bounded) = both(&log, &opts, dir.path());
    assert_eq!(mem.report.points, bounded.report.points);
    // The bounded conversion's reference waited on disk, and its writers read
    // it there (the outputs above are the same).
    assert!(mem.reference.is_some() && mem.reference_on_disk.is_none());
    let on_disk = bounded
        .reference_on_disk
        .as_ref()
        .expect("reference on disk");
    assert!(bounded.reference.is_none());
    let back = on_disk.load().unwrap();
    let r = mem.reference.as_ref().unwrap();
    assert_eq!(back.timestamps, r.timestamps);
    assert_eq!(back.positions, r.positions);
    assert_eq!(back.orientations, r.orientations);
    assert!(mem.report.points > 10_000, "{}", mem.report.points);
    let s = bounded.report.stream.as_ref().unwrap();
    // A batch of keyframes at a time, never the whole log.
    assert!(s.max_keyframes_in_memory <= s.batch_keyframes);
    assert!(s.max_keyframes_in_memory < mem.report.keyframes);
    assert_eq!(s.cloud_bytes, 15 * mem.report.points as u64);
    assert!(s.pixel_bytes > 0);
}

#[test]
fn keyframes_out_of_id_order_give_the_in_memory_octree() {
    // The octree inserts keyframes in id order: the bounded path sweeps
    // again in that order when they did not arrive in it.
    let cam = PinholeCamera::try_new(40.0, 40.0, 19.5, 14.5, 40, 30).unwrap();
    let truth = Sim3::try_new(
        UnitQuaternion::from_euler_angles(0.3, -0.2, 1.1),
        Vector3::new(4.0, -1.0, 0.5),
        2.5,
    )
    .unwrap();
    let (mut kfs, mut times, mut pos, mut rot) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for i in 0..40 {
        let a = i as f64 * 0.15;
        let pose = Sim3::try_new(
            UnitQuaternion::from_euler_angles(0.05 * a, 0.1 * a, 0.0),
            Vector3::new(a.cos(), a.sin(), 0.2 * a),
            1.0,
        )
        .unwrap();
        let pose = Sim3::from_lsd_slam(&pose.to_lsd_slam().map(|v| v as f32 as f64)).unwrap();
        let n = 40 * 30;
        let idepth = (0..n).map(|p| 0.3 + 0.0005 * p as f32).collect();
        let var = vec![1e-4; n];
        let color = (0..3 * n).map(|p| (p % 256) as u8).collect();
        // Ids in no order: 37, 14, 31, ...
        let id = (i * 23) % 40;
        let kf = Keyframe::try_new(
            id,
            5.0 + i as f64,
            pose,
            cam,
            idepth,
            Some(var),
            Some(color),
        )
        .unwrap();
        let w = truth * pose;
        times.push(5.0 + i as f64);
        pos.push(w.translation);
        rot.push(w.rotation);
        kfs.push(kf);
    }
    let reference = Trajectory::try_new(times, pos, Some(rot)).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("shuffled.mcap");
    write_slam_log(
        &log,
        &kfs,
        Some(&reference),
        None,
        &[],
        &SlamLogOptions::default(),
    )
    .unwrap();
    let opts = ConvertOptions {
        filter: PointFilter::none(),
        map: Some(octree()),
        ..ConvertOptions::default()
    };
    let (mem, bounded) = both(&log, &opts, dir.path());
    assert_eq!(
        mem.octree.unwrap().to_bt_bytes(),
        bounded.octree.unwrap().to_bt_bytes()
    );
}

#[test]
#[ignore = "slow: make test runs it"]
fn the_inertial_path_reads_its_imu_back_from_disk_to_the_same_outputs() {
    // Without a reference the raw IMU is what the world frame comes from:
    // a bounded read leaves it on disk and the fit reads it back.
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("imu.mcap");
    let o = common::bin(&[
        "simulate",
        "-o",
        log.to_str().unwrap(),
        "--reduced",
        "4",
        "--no-reference",
    ]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let read = slam2world::io::log::read_log_spilled(&log, &Default::default()).unwrap();
    assert!(read.imu.is_none() && read.reference.is_none());
    assert!(read.imu_on_disk.as_ref().is_some_and(|i| i.len() > 1000));
    let (mem, bounded) = both(&log, &ConvertOptions::default(), dir.path());
    assert!(mem.world.poses().is_none(), "the IMU gives the world frame");
    assert_eq!(
        mem.transform().scale.to_bits(),
        bounded.transform().scale.to_bits()
    );
    assert_eq!(mem.report.points, bounded.report.points);
}

#[test]
#[ignore = "slow: make test runs it"]
fn a_reference_file_replaces_the_log_reference_left_on_disk() {
    use slam2world::pipeline::reconstruction::{open_input, ReferenceSpec};
    // The log's reference, every other pose, written as a TUM file: given as
    // the reference, it is the one fitted and written, in both paths.
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("sim.mcap");
    let o = common::bin(&["simulate", "-o", log.to_str().unwrap(), "--reduced", "4"]);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let own = slam2world::io::read_log(&log, &Default::default())
        .unwrap()
        .reference
        .unwrap();
    let keep: Vec<usize> = (0..own.len()).step_by(2).collect();
    let half = Trajectory::try_new(
        keep.iter().map(|&i| own.timestamps[i]).collect(),
        keep.iter().map(|&i| own.positions[i]).collect(),
        own.orientations
            .as_ref()
            .map(|q| keep.iter().map(|&i| q[i]).collect()),
    )
    .unwrap();
    let tum = dir.path().join("ref.tum");
    slam2world::io::text::write_tum(&half, &tum).unwrap();
    let spec = ReferenceSpec {
        path: tum,
        format: None,
        time_unit: None,
    };
    let opts = ConvertOptions::default();
    let src = open_input(&log, &opts.read, &Default::default(), Some(&spec)).unwrap();
    let mem = slam2world::pipeline::convert_source(&*src, &opts).unwrap();
    let bounded = slam2world::pipeline::convert_source_bounded(&*src, &opts).unwrap();
    for c in [&mem, &bounded] {
        assert_eq!(c.report.reference_poses, half.len());
        assert!(c.reference_on_disk.is_none());
        assert_eq!(c.reference.as_ref().unwrap().len(), half.len());
    }
    assert_eq!(
        mem.transform().scale.to_bits(),
        bounded.transform().scale.to_bits()
    );
}
