//! `read_log`, `inspect`, `convert` and `align LOG --est-topic --ref-topic`
//! over every container: the bags written by the independent `rosbags`
//! package (`tests/data/rosbag/`), damaged copies of them, and the real bags
//! in `../shared/data` (skipped when absent). The equality of a bag's
//! conversion with that of the MCAP log of the same messages is checked in
//! `tests/python/test_bags.py`, where both are written by independent writers.

use crate::common::{self, fixture, index_pos, without_index_pos};

use std::path::{Path, PathBuf};

use slam2world::io::container::Container;
use slam2world::io::log::{inspect_log, read_log, Log, LogError, ReadOptions};
use slam2world::io::rosbag::BagError;
use slam2world::Error;

const ROS1: [&str; 3] = ["ros1_none.bag", "ros1_bz2.bag", "ros1_lz4.bag"];
const ROS2: [&str; 6] = [
    "ros2_sqlite3_none",
    "ros2_sqlite3_file",
    "ros2_sqlite3_message",
    "ros2_mcap_none",
    "ros2_mcap_file",
    "ros2_mcap_message",
];

/// Everything a log gives, as exact text (floats print their shortest
/// round-trip form, so equal text is equal bits).
fn content(log: &Log) -> String {
    format!(
        "{:?}\n{:?}\n{:?}\n{:?}\n{:?} {:?} {:?} {:?} {:?}\n{} {} {}",
        log.keyframes,
        log.frames,
        log.reference,
        log.imu,
        log.keyframe_topic,
        log.graph_topic,
        log.est_topic,
        log.reference_topic,
        log.imu_topic,
        log.keyframe_messages,
        log.graph_messages,
        log.graph_updates,
    )
}

/// The reason of an [`Error::Log`].
fn log_reason(e: &Error) -> Option<&LogError> {
    match e {
        Error::Log { reason, .. } => Some(reason),
        _ => None,
    }
}

fn opts(f: impl FnOnce(&mut ReadOptions)) -> ReadOptions {
    let mut o = ReadOptions::default();
    f(&mut o);
    o
}

#[test]
fn ros1_bags_read_the_same_in_every_compression() {
    let logs: Vec<Log> = ROS1
        .iter()
        .map(|n| read_log(fixture(n), &ReadOptions::default()).unwrap())
        .collect();
    let first = &logs[0];
    // What make_fixtures.py wrote: 16 keyframe messages (4 live frames, 3
    // refinements) of 9 ids, 4 graph messages, 40 poses, 40 IMU samples.
    let ids: Vec<i32> = first.keyframes.iter().map(|k| k.id).collect();
    assert_eq!(ids, (0..9).collect::<Vec<_>>());
    assert_eq!(first.keyframe_messages, 16);
    assert_eq!(first.graph_messages, 4);
    // Graphs of 3, 5, 7 and 9 ids, each sent when all its ids had arrived.
    assert_eq!(first.graph_updates, 3 + 5 + 7 + 9);
    assert_eq!(first.reference.as_ref().unwrap().len(), 40);
    assert_eq!(first.imu.as_ref().unwrap().len(), 40);
    assert_eq!(first.reference_topic.as_deref(), Some("/vicon/pose"));
    assert_eq!(first.container, Some(Container::Ros1Bag));
    assert!(first.indexed);
    // Counts from the index: every topic, with its time range.
    let counts: Vec<(&str, u64)> = first
        .topics
        .iter()
        .map(|t| (t.topic.as_str(), t.count))
        .collect();
    for want in [
        ("/vicon/pose", 40),
        ("/imu0", 40),
        ("/lsd_slam/keyframes", 16),
        ("/lsd_slam/graph", 4),
    ] {
        assert!(counts.contains(&want), "{counts:?}");
    }
    for log in &logs[1..] {
        assert_eq!(content(log), content(first));
    }
}

#[test]
fn an_unclosed_ros1_bag_reads_like_the_closed_one() {
    let dir = tempfile::tempdir().unwrap();
    for name in ROS1 {
        let closed = read_log(fixture(name), &ReadOptions::default()).unwrap();
        let bytes = std::fs::read(fixture(name)).unwrap();
        let mut cut = without_index_pos(&bytes);
        cut.truncate(index_pos(&bytes));
        for (what, variant) in [
            ("index_pos 0", without_index_pos(&bytes)),
            ("no index", cut),
        ] {
            let p = dir.path().join("unclosed.bag");
            std::fs::write(&p, &variant).unwrap();
            let log = read_log(&p, &ReadOptions::default()).unwrap();
            assert!(!log.indexed, "{name}: {what}");
            assert_eq!(content(&log), content(&closed), "{name}: {what}");
            let a: Vec<_> = log.topics.iter().map(|t| (&t.topic, t.count)).collect();
            let b: Vec<_> = closed.topics.iter().map(|t| (&t.topic, t.count)).collect();
            assert_eq!(a, b, "{name}: {what}");
        }
    }
}

#[test]
fn ros2_bags_read_the_same_in_every_storage() {
    let logs: Vec<Log> = ROS2
        .iter()
        .map(|n| read_log(fixture(n), &opts(|o| o.est_topic = Some("/odom".into()))).unwrap())
        .collect();
    let first = &logs[0];
    assert!(first.keyframes.is_empty(), "no keyframes with est_topic");
    assert_eq!(first.frames.as_ref().unwrap().len(), 15);
    assert_eq!(first.est_topic.as_deref(), Some("/odom"));
    // The estimate's topic is never the reference: the first other pose type.
    assert_eq!(first.reference_topic.as_deref(), Some("/pose"));
    assert_eq!(first.reference.as_ref().unwrap().len(), 15);
    assert_eq!(first.imu.as_ref().unwrap().len(), 30);
    assert_eq!(first.container, Some(Container::Ros2Folder));
    for (name, log) in ROS2.iter().zip(&logs) {
        assert_eq!(content(log), content(first), "{name}");
    }
    // A TF reference, narrowed to its one frame pair; the single .db3 alone.
    let tf = opts(|o| {
        o.est_topic = Some("/odom".into());
        o.pose_topic = Some("/tf".into());
        o.tf_parent = Some("odom".into());
    });
    let a = read_log(fixture("ros2_sqlite3_none"), &tf).unwrap();
    let db3 = fixture("ros2_sqlite3_none/ros2_sqlite3_none.db3");
    let b = read_log(&db3, &tf).unwrap();
    assert_eq!(a.reference.as_ref().unwrap().len(), 15);
    assert_eq!(content(&a), content(&b));
    assert_eq!(b.container, Some(Container::Ros2Sqlite));
    let wrong = opts(|o| {
        o.pose_topic = Some("/tf".into());
        o.tf_parent = Some("nowhere".into());
    });
    let e = read_log(&db3, &wrong).unwrap_err();
    let Error::Log { path, reason } = &e else {
        panic!("{e:?}")
    };
    match reason.as_ref() {
        LogError::NoTransform { topic, parent, .. } => {
            assert_eq!(path, &db3);
            assert_eq!(
                (topic.as_str(), parent.as_deref()),
                ("/tf", Some("nowhere"))
            );
        }
        other => panic!("{other:?}"),
    }
}

/// A copy of a fixture folder in `dir`.
fn copy_folder(name: &str, dir: &Path) -> PathBuf {
    let to = dir.join(name);
    std::fs::create_dir_all(&to).unwrap();
    for e in std::fs::read_dir(fixture(name)).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
    }
    to
}

#[test]
fn a_type_without_a_decoder_is_named_with_file_and_topic() {
    let dir = tempfile::tempdir().unwrap();
    let f = copy_folder("ros2_sqlite3_none", dir.path());
    let db3 = f.join("ros2_sqlite3_none.db3");
    {
        let c = rusqlite::Connection::open(&db3).unwrap();
        c.execute(
            "UPDATE topics SET type = 'sensor_msgs/msg/Temperature' WHERE name = '/imu'",
            [],
        )
        .unwrap();
    }
    // Not asked for: the other topics still read, the unknown one is listed.
    let log = read_log(&f, &ReadOptions::default()).unwrap();
    assert!(log.imu.is_none());
    let fix = log.topics.iter().find(|t| t.topic == "/imu").unwrap();
    assert_eq!((fix.kind, fix.count), (None, 30));
    // Asked for: a typed error naming the file, the topic and the type.
    let e = read_log(&f, &opts(|o| o.imu_topic = Some("/imu".into()))).unwrap_err();
    let Error::Log { path, reason } = &e else {
        panic!("{e:?}")
    };
    assert_eq!(path, &f);
    match reason.as_ref() {
        LogError::UnknownType {
            role,
            topic,
            type_name,
            ..
        } => {
            assert_eq!(
                (*role, topic.as_str(), type_name.as_str()),
                ("imu", "/imu", "sensor_msgs/msg/Temperature")
            );
        }
        other => panic!("{other:?}"),
    }
    let text = e.to_string();
    assert!(
        text.contains("ros2_sqlite3_none") && text.contains("Temperature"),
        "{text}"
    );
    // A known type in the wrong role, and a topic that is not there.
    let e = read_log(&f, &opts(|o| o.pose_topic = Some("/imu".into()))).unwrap_err();
    assert!(
        matches!(
            log_reason(&e),
            Some(LogError::UnknownType { role: "pose", .. })
        ),
        "{e:?}"
    );
    let e = read_log(&f, &opts(|o| o.imu_topic = Some("/odom".into()))).unwrap_err();
    assert!(
        matches!(log_reason(&e), Some(LogError::WrongType { role: "imu", topic, .. }) if topic == "/odom"),
        "{e:?}"
    );
    // A name without its leading `/` finds the topic (ROS resolves `odom` as `/odom`).
    let e = read_log(&f, &opts(|o| o.imu_topic = Some("odom".into()))).unwrap_err();
    assert!(
        matches!(log_reason(&e), Some(LogError::WrongType { role: "imu", topic, .. }) if topic == "odom"),
        "{e:?}"
    );
    let e = read_log(&f, &opts(|o| o.pose_topic = Some("/gps".into()))).unwrap_err();
    assert!(
        matches!(log_reason(&e), Some(LogError::NoTopic { topic, topics, .. })
            if topic == "/gps" && topics.len() == 4),
        "{e:?}"
    );
}

/// Offset of the first chunk record (right after the bag header record).
fn first_chunk(bytes: &[u8]) -> usize {
    let hl = u32::from_le_bytes(bytes[13..17].try_into().unwrap()) as usize;
    let dl = u32::from_le_bytes(bytes[17 + hl..21 + hl].try_into().unwrap()) as usize;
    21 + hl + dl
}

/// `(offset of the data length field, offset of the data)` of the record at `pos`.
fn data_of(bytes: &[u8], pos: usize) -> (usize, usize) {
    let hl = u32::from_le_bytes(bytes[pos..pos + 4].try_into().unwrap()) as usize;
    (pos + 4 + hl, pos + 8 + hl)
}

/// A damaged input: what it is, its path, how it is read, and the test of the
/// error `read_log` must give.
type Damaged = (&'static str, PathBuf, ReadOptions, fn(&Error) -> bool);

/// Damaged inputs, each with the error `read_log` must give.
fn damaged(dir: &Path) -> Vec<Damaged> {
    let mut out: Vec<Damaged> = Vec::new();
    let write = |name: &str, bytes: &[u8]| {
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    };
    let none = std::fs::read(fixture("ros1_none.bag")).unwrap();
    let lz4 = std::fs::read(fixture("ros1_lz4.bag")).unwrap();
    let bz2 = std::fs::read(fixture("ros1_bz2.bag")).unwrap();
    let d = ReadOptions::default();
    out.push((
        "truncated bag",
        write("cut.bag", &lz4[..lz4.len() / 2]),
        d.clone(),
        |e| {
            matches!(
                e,
                Error::Bag {
                    reason: BagError::Truncated { .. },
                    offset: Some(_),
                    ..
                }
            )
        },
    ));
    let mut v = lz4.clone();
    v[9..12].copy_from_slice(b"1.2");
    out.push(
        ("wrong version line", write("v12.bag", &v), d.clone(), |e| {
            matches!(e, Error::Container { .. }) && e.to_string().contains("1.2")
        }),
    );
    let chunk = first_chunk(&none);
    let (len_at, _) = data_of(&none, chunk);
    let mut b = none.clone();
    b[len_at..len_at + 4].copy_from_slice(&0xfff0_0000u32.to_le_bytes());
    out.push((
        "chunk past the file",
        write("long.bag", &b),
        d.clone(),
        |e| {
            matches!(
                e,
                Error::Bag {
                    reason: BagError::Truncated {
                        what: "record data",
                        ..
                    },
                    ..
                }
            )
        },
    ));
    for (name, bytes) in [("bad_lz4.bag", &lz4), ("bad_bz2.bag", &bz2)] {
        let (_, data) = data_of(bytes, first_chunk(bytes));
        let mut b = bytes.clone();
        b[data..data + 4].copy_from_slice(b"\0\0\0\0");
        out.push((
            "chunk that does not decompress",
            write(name, &b),
            d.clone(),
            |e| {
                matches!(
                    e,
                    Error::Bag {
                        reason: BagError::Decompress { .. },
                        ..
                    }
                )
            },
        ));
    }
    let db = dir.join("other.db3");
    {
        let c = rusqlite::Connection::open(&db).unwrap();
        c.execute_batch("CREATE TABLE things(id INTEGER PRIMARY KEY, name TEXT);")
            .unwrap();
    }
    out.push(("SQLite without the rosbag2 tables", db, d.clone(), |e| {
        matches!(
            e,
            Error::Bag {
                reason: BagError::MissingTable { .. },
                ..
            }
        )
    }));
    let f = copy_folder("ros2_sqlite3_none", dir);
    std::fs::remove_file(f.join("ros2_sqlite3_none.db3")).unwrap();
    out.push(("metadata.yaml naming a missing file", f, d.clone(), |e| {
        matches!(
            e,
            Error::Bag {
                reason: BagError::MissingFile { .. },
                ..
            }
        )
    }));
    let g = dir.join("unknown_type");
    std::fs::create_dir_all(&g).unwrap();
    let f = copy_folder("ros2_sqlite3_none", &g);
    {
        let c = rusqlite::Connection::open(f.join("ros2_sqlite3_none.db3")).unwrap();
        c.execute(
            "UPDATE topics SET type = 'sensor_msgs/msg/Temperature' WHERE name = '/pose'",
            [],
        )
        .unwrap();
    }
    out.push((
        "unknown message type",
        f,
        opts(|o| o.pose_topic = Some("/pose".into())),
        |e| matches!(log_reason(e), Some(LogError::UnknownType { .. })),
    ));
    out
}

#[test]
fn damaged_logs_are_typed_errors_and_convert_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    for (what, path, options, expected) in damaged(dir.path()) {
        let e = read_log(&path, &options).unwrap_err();
        assert!(expected(&e), "{what}: {e:?}");
        // The message names the file.
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        assert!(e.to_string().contains(&name), "{what}: {e}");
        // The CLI: exit 1, one line naming the file, no output written.
        let out = dir.path().join(format!("out_{name}"));
        let mut args = vec![
            "convert".to_string(),
            path.display().to_string(),
            "-o".into(),
            out.display().to_string(),
            "--quiet".into(),
        ];
        if let Some(t) = &options.pose_topic {
            args.extend(["--pose-topic".into(), t.clone()]);
        }
        let argv: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = common::bin(&argv);
        assert_eq!(o.status.code(), Some(1), "{what}");
        let err = common::stderr(&o);
        assert!(
            err.contains(&name) && err.lines().count() == 1,
            "{what}: {err}"
        );
        let written: Vec<_> = std::fs::read_dir(&out)
            .map(|d| d.map(|e| e.unwrap().file_name()).collect())
            .unwrap_or_default();
        assert!(written.is_empty(), "{what}: {written:?}");
        // inspect reads the index alone where there is one: a damaged chunk or
        // an unknown type is no error there.
        let o = common::bin(&["inspect", &path.display().to_string()]);
        let listed = ["unknown message type", "chunk that does not decompress"];
        let code = if listed.contains(&what) { 0 } else { 1 };
        assert_eq!(o.status.code(), Some(code), "inspect, {what}");
    }
}

#[test]
fn inspect_lists_every_container() {
    for (name, container, topic, ty, count) in [
        (
            "ros1_lz4.bag",
            "ros1 bag",
            "/lsd_slam/keyframes",
            "lsd_slam_viewer/keyframeMsg",
            16,
        ),
        (
            "ros2_sqlite3_none",
            "rosbag2 folder",
            "/odom",
            "nav_msgs/msg/Odometry",
            15,
        ),
        (
            "ros2_sqlite3_none/ros2_sqlite3_none.db3",
            "rosbag2 db3",
            "/imu",
            "sensor_msgs/msg/Imu",
            30,
        ),
        (
            "ros2_mcap_message",
            "rosbag2 folder",
            "/tf",
            "tf2_msgs/msg/TFMessage",
            15,
        ),
        (
            "ros2_mcap_none/ros2_mcap_none.mcap",
            "mcap",
            "/pose",
            "geometry_msgs/msg/PoseStamped",
            15,
        ),
    ] {
        let p = fixture(name);
        let i = inspect_log(&p).unwrap();
        assert_eq!(i.container.name(), container);
        let t = i.topics.iter().find(|t| t.topic == topic).unwrap();
        assert_eq!((t.schema_name.as_str(), t.count), (ty, count), "{name}");
        assert!(t.kind.is_some() && t.time_range.is_some());
        let o = common::bin(&["inspect", p.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(0), "{name}: {}", common::stderr(&o));
        let text = String::from_utf8(o.stdout).unwrap();
        assert!(text.contains(&format!("container: {container}")), "{text}");
        let line = text.lines().find(|l| l.starts_with(topic)).unwrap();
        assert!(
            line.contains(ty) && line.contains(&format!(" {count} ")),
            "{line}"
        );
    }
    // The index of a closed ROS 1 bag gives the counts without a chunk read.
    let i = inspect_log(fixture("ros1_bz2.bag")).unwrap();
    assert!(i.from_index);
    assert!(i
        .picks
        .contains(&("keyframes", "/lsd_slam/keyframes".to_string())));
}

fn json(o: &std::process::Output) -> serde_json::Value {
    assert_eq!(o.status.code(), Some(0), "{}", common::stderr(o));
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn align_of_two_topics_equals_align_of_their_files() {
    let dir = tempfile::tempdir().unwrap();
    let bag = fixture("ros2_sqlite3_none");
    let log = read_log(
        &bag,
        &opts(|o| {
            o.est_topic = Some("/odom".into());
            o.pose_topic = Some("/pose".into());
        }),
    )
    .unwrap();
    let est = dir.path().join("est.txt");
    let gt = dir.path().join("gt.txt");
    slam2world::io::text::write_tum(log.frames.as_ref().unwrap(), &est).unwrap();
    slam2world::io::text::write_tum(log.reference.as_ref().unwrap(), &gt).unwrap();
    let b = bag.to_str().unwrap();
    let topics = json(&common::bin(&[
        "align",
        b,
        "--est-topic",
        "/odom",
        "--ref-topic",
        "/pose",
        "--json",
        "--max-diff",
        "0.01",
        // the fixture's poses are random: the fit-quality refusals would refuse them
        "--no-fit-checks",
    ]));
    let files = json(&common::bin(&[
        "align",
        est.to_str().unwrap(),
        gt.to_str().unwrap(),
        "--json",
        "--no-fit-checks",
    ]));
    assert_eq!(topics["est"], format!("{b}:/odom"));
    assert_eq!(topics["ref"], format!("{b}:/pose"));
    for key in [
        "n_pairs",
        "scale",
        "translation",
        "quaternion_xyzw",
        "ape",
        "fit_rmse",
    ] {
        // TUM files keep 9 decimals of the stamps and poses: the same pairs,
        // the same fit to the precision of the files.
        let (a, f) = (&topics[key], &files[key]);
        match (a.as_f64(), f.as_f64()) {
            (Some(x), Some(y)) => assert!((x - y).abs() < 1e-6, "{key}: {x} {y}"),
            _ if a.is_array() => {
                for (x, y) in a.as_array().unwrap().iter().zip(f.as_array().unwrap()) {
                    assert!(
                        (x.as_f64().unwrap() - y.as_f64().unwrap()).abs() < 1e-6,
                        "{key}"
                    );
                }
            }
            _ if a.is_object() => assert_eq!(a["n_pairs"], f["n_pairs"], "{key}"),
            _ => assert_eq!(a, f, "{key}"),
        }
    }
    // Usage: a topic without the other, or a REF file beside the topics, exit 2.
    assert_eq!(
        common::bin(&["align", b, "--est-topic", "/odom"])
            .status
            .code(),
        Some(2)
    );
    assert_eq!(
        common::bin(&[
            "align",
            b,
            "x.txt",
            "--est-topic",
            "/odom",
            "--ref-topic",
            "/pose"
        ])
        .status
        .code(),
        Some(2)
    );
    // A topic that is not there: exit 1 naming it.
    let o = common::bin(&["align", b, "--est-topic", "/nope", "--ref-topic", "/pose"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(common::stderr(&o).contains("/nope"));
}

// --- real bags in ../shared/data ----------------------------------------------

#[test]
fn real_bags_read_through_read_log() {
    if let Some(p) = common::data("ros1_husky_gps", "test1.bag") {
        let log = read_log(&p, &ReadOptions::default()).unwrap();
        // Odometry is the only pose type; the IMU at 30 Hz; NavSatFix is listed, not read.
        assert_eq!(
            log.reference_topic.as_deref(),
            Some("/husky_velocity_controller/odom")
        );
        assert_eq!(log.reference.as_ref().unwrap().len(), 3952);
        assert_eq!(log.imu.as_ref().unwrap().len(), 11865);
        let fix = log.topics.iter().find(|t| t.topic == "/fix").unwrap();
        assert_eq!(
            (fix.schema_name.as_str(), fix.count),
            ("sensor_msgs/NavSatFix", 989)
        );
    }
    if let Some(p) = common::data("ros1_husky_gps", "test1.bag") {
        // Naming the GNSS topic makes it the reference: no pose topic is read.
        let log = read_log(&p, &opts(|o| o.gnss_topic = Some("/fix".into()))).unwrap();
        assert_eq!(log.gnss_topic.as_deref(), Some("/fix"));
        assert!(log.reference.is_none() && log.reference_topic.is_none());
        let fixes = log.gnss.unwrap();
        // PROVENANCE.md: 989 fixes, status SBAS throughout, diag (0.81, 0.81, 3.24) m².
        assert_eq!((fixes.len(), fixes.dropped_no_fix), (989, 0));
        assert_eq!(fixes.covariance[0].unwrap()[(2, 2)], 3.24);
        assert!(fixes.lat.iter().all(|l| (42.3757..42.3772).contains(l)));
        // One reference per conversion: a pose topic and a GNSS topic both named.
        let both = opts(|o| {
            o.gnss_topic = Some("/fix".into());
            o.pose_topic = Some("/husky_velocity_controller/odom".into());
        });
        assert!(matches!(
            read_log(&p, &both),
            Err(Error::InvalidArgument { .. })
        ));
        // A GNSS topic of another type is named with its type.
        let wrong = opts(|o| o.gnss_topic = Some("/imu/data".into()));
        assert!(matches!(
            log_reason(&read_log(&p, &wrong).unwrap_err()),
            Some(LogError::WrongType { .. })
        ));
    }
    if let (Some(bag), Some(folder)) = (
        common::data("evo_tf_example", "tf_example.bag"),
        common::data("evo_tf_example", "tf_example"),
    ) {
        // The same /tf recording as ROS 1 and as ROS 2: the same reference.
        let a = read_log(&bag, &ReadOptions::default()).unwrap();
        let b = read_log(&folder, &ReadOptions::default()).unwrap();
        let ra = a.reference.unwrap();
        let rb = b.reference.unwrap();
        assert!(ra.len() > 100);
        assert_eq!(format!("{ra:?}"), format!("{rb:?}"));
        assert_eq!(a.reference_topic.as_deref(), Some("/tf"));
    }
}

/// Mutated bags through the whole assembly (decoders included): a result or a
/// typed error, never a panic (the stable-Rust counterpart of the fuzz target).
#[test]
#[ignore = "slow: make test runs it"]
fn mutated_bags_through_read_log_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let sources: Vec<Vec<u8>> = ROS1
        .iter()
        .map(|n| std::fs::read(fixture(n)).unwrap())
        .collect();
    // xorshift: deterministic mutants.
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let p = dir.path().join("m.bag");
    let (mut ok, mut refused) = (0, 0);
    for i in 0..600 {
        let mut b = sources[i % 3].clone();
        match next() % 3 {
            0 => {
                for _ in 0..1 + next() % 8 {
                    let k = (next() as usize) % b.len();
                    b[k] ^= 1 << (next() % 8);
                }
            }
            1 => {
                let k = 13 + (next() as usize) % (b.len() - 17);
                let v =
                    [0u32, u32::MAX, (next() % 256) as u32, next() as u32][(next() % 4) as usize];
                b[k..k + 4].copy_from_slice(&v.to_le_bytes());
            }
            _ => b.truncate((next() as usize) % b.len()),
        }
        std::fs::write(&p, &b).unwrap();
        let r = std::panic::catch_unwind(|| read_log(&p, &ReadOptions::default()));
        match r {
            Ok(Ok(_)) => ok += 1,
            Ok(Err(
                Error::Bag { .. }
                | Error::Decode { .. }
                | Error::Log { .. }
                | Error::Container { .. }
                | Error::Mcap { .. },
            )) => refused += 1,
            Ok(Err(other)) => panic!("mutant {i}: unexpected error {other:?}"),
            Err(_) => panic!("mutant {i} panicked"),
        }
    }
    assert!(ok > 20 && refused > 20, "ok {ok}, refused {refused}");
}
