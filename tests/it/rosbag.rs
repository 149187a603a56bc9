//! ROS bag readers against bags written by the independent Python `rosbags`
//! package (`tests/data/rosbag/make_fixtures.py`), against real bags in
//! `../shared/data` (skipped when absent), and against damaged input.

use crate::common::{self, fixture, index_pos, without_index_pos};

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Deserialize;

use slam2world::io::container::{detect, Container, ContainerError};
use slam2world::io::log::{read_log, ReadOptions};
use slam2world::io::mcap::decode::{pose_sample, MessageKind};
use slam2world::io::messages::{ChannelInfo, Inventory, MappedScan, MessageSource, ReadMode};
use slam2world::io::rosbag::{BagError, Ros1Bag, Ros2Bag, Ros2Compression, Ros2Storage};
use slam2world::io::AnyContainer;
use slam2world::Error;

/// One message as the fixture script wrote it.
#[derive(Debug, Deserialize, PartialEq, Eq, Clone)]
struct Expected {
    topic: String,
    #[serde(rename = "type")]
    ty: String,
    time: u64,
    data: String,
}

/// `(topic, type with /msg/, time ns, bytes)` of each message.
type Rec = (String, String, u64, Vec<u8>);

fn unhex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
        .collect()
}

fn expected(name: &str) -> Vec<Rec> {
    let text = std::fs::read_to_string(fixture(name)).unwrap();
    let rows: Vec<Expected> = serde_json::from_str(&text).unwrap();
    rows.into_iter()
        .map(|r| (r.topic, r.ty, r.time, unhex(&r.data)))
        .collect()
}

/// ROS 1 type names have no `/msg/`: compare in the ROS 2 spelling.
fn ros2_name(ty: &str) -> String {
    match ty.split_once('/') {
        Some((pkg, rest)) if !rest.starts_with("msg/") => format!("{pkg}/msg/{rest}"),
        _ => ty.to_string(),
    }
}

/// Every message with its bytes, in the order the reader gives them.
fn records(scan: &MappedScan<Vec<u8>>) -> Vec<Rec> {
    scan.messages
        .iter()
        .map(|m| {
            let c = &scan.channels[&m.channel_id];
            assert_eq!(m.log_time, m.publish_time);
            assert_eq!(m.sequence, 0);
            (
                c.topic.clone(),
                ros2_name(&c.schema_name),
                m.log_time,
                m.value.clone(),
            )
        })
        .collect()
}

fn scan_all(source: &impl MessageSource) -> MappedScan<Vec<u8>> {
    source
        .scan_map(|_| true, |_, m| m.data.to_vec())
        .expect("the bag reads")
}

fn reason(e: &Error) -> &BagError {
    match e {
        Error::Bag { reason, .. } => reason,
        other => panic!("expected Error::Bag, got {other:?}"),
    }
}

fn by_topic(channels: &BTreeMap<u16, ChannelInfo>) -> BTreeMap<String, ChannelInfo> {
    channels
        .values()
        .map(|c| (c.topic.clone(), c.clone()))
        .collect()
}

const ROS1: [&str; 3] = ["ros1_none.bag", "ros1_bz2.bag", "ros1_lz4.bag"];

#[test]
fn ros1_bags_hold_what_rosbags_wrote() {
    let want = expected("ros1_expected.json");
    assert_eq!(want.len(), 100);
    for name in ROS1 {
        let bag = Ros1Bag::open(fixture(name)).unwrap();
        assert_eq!(bag.mode(), ReadMode::Indexed, "{name}");
        assert!(bag.header().chunk_count > 5, "{name}: several chunks");
        let scan = scan_all(&bag);
        assert_eq!(scan.mode, ReadMode::Indexed);
        assert_eq!(scan.profile, "ros1");
        assert_eq!(records(&scan), want, "{name}");
        let topics = by_topic(&scan.channels);
        let kf = &topics["/lsd_slam/keyframes"];
        assert_eq!(kf.schema_name, "lsd_slam_viewer/keyframeMsg");
        assert_eq!(kf.message_encoding, "ros1");
        assert_eq!(kf.schema_encoding, "ros1msg");
        let def = String::from_utf8(kf.schema_data.clone()).unwrap();
        assert!(def.contains("float32[7] camToWorld"), "{def}");
        let md5 = &kf.metadata["md5sum"];
        assert!(md5.len() == 32 && md5.bytes().all(|b| b.is_ascii_hexdigit()));
        assert_eq!(topics["/lsd_slam/graph"].metadata["callerid"], "/lsd");
        assert_eq!(topics["/imu0"].schema_name, "sensor_msgs/Imu");
        assert_eq!(bag.channels().unwrap(), scan.channels);
    }
}

#[test]
fn ros1_compressions_give_identical_scans() {
    let scans: Vec<_> = ROS1
        .iter()
        .map(|n| scan_all(&Ros1Bag::open(fixture(n)).unwrap()))
        .collect();
    for s in &scans[1..] {
        assert_eq!(s.channels, scans[0].channels);
        assert_eq!(records(s), records(&scans[0]));
    }
}

fn write_tmp(dir: &tempfile::TempDir, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.path().join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

#[test]
fn unclosed_bags_scan_like_closed_ones() {
    let dir = tempfile::tempdir().unwrap();
    for name in ROS1 {
        let closed = Ros1Bag::open(fixture(name)).unwrap();
        let closed_scan = scan_all(&closed);
        let bytes = std::fs::read(fixture(name)).unwrap();
        let zeroed = without_index_pos(&bytes);
        let mut cut = zeroed.clone();
        cut.truncate(index_pos(&bytes));
        let garbage_index = {
            // The index cut in the middle of a record: unreadable, so read linearly.
            let mut b = bytes.clone();
            b.truncate(index_pos(&bytes) + 7);
            b
        };
        for (what, variant) in [
            ("index_pos 0", zeroed),
            ("index cut off", cut),
            ("index damaged", garbage_index),
        ] {
            let p = write_tmp(&dir, "unclosed.bag", &variant);
            let bag = Ros1Bag::open(&p).unwrap();
            assert_eq!(bag.mode(), ReadMode::Linear, "{name}: {what}");
            if what == "index damaged" {
                // A linear scan meets the cut record at the end: refused, with its place.
                let e = bag.scan_map(|_| true, |_, _| ()).unwrap_err();
                assert!(matches!(reason(&e), BagError::Truncated { .. }), "{e}");
                continue;
            }
            let scan = scan_all(&bag);
            assert_eq!(scan.mode, ReadMode::Linear);
            assert_eq!(scan.channels, closed_scan.channels, "{name}: {what}");
            assert_eq!(records(&scan), records(&closed_scan), "{name}: {what}");
            assert_eq!(bag.channels().unwrap(), closed_scan.channels);
            // Only the pose topic, mapped through the PoseStamped decoder.
            let poses = bag
                .scan_map(
                    |c| c.topic == "/vicon/pose",
                    |_, m| pose_sample(MessageKind::PoseStamped, "ros1", m.data).ok(),
                )
                .unwrap();
            assert_eq!(poses.messages.len(), 40);
            assert!(poses.messages.iter().all(|m| m.value.is_some()));
        }
    }
}

fn counts(inv: &Inventory) -> BTreeMap<String, (u64, Option<(u64, u64)>)> {
    inv.channels
        .iter()
        .map(|c| (c.channel.topic.clone(), (c.count, c.time_range)))
        .collect()
}

fn expected_counts(recs: &[Rec]) -> BTreeMap<String, (u64, Option<(u64, u64)>)> {
    let mut out: BTreeMap<String, (u64, Option<(u64, u64)>)> = BTreeMap::new();
    for (topic, _, t, _) in recs {
        let e = out.entry(topic.clone()).or_insert((0, None));
        e.0 += 1;
        e.1 = Some(match e.1 {
            None => (*t, *t),
            Some((lo, hi)) => (lo.min(*t), hi.max(*t)),
        });
    }
    out
}

#[test]
fn ros1_inventory_comes_from_the_index() {
    let want = expected_counts(&expected("ros1_expected.json"));
    let dir = tempfile::tempdir().unwrap();
    for name in ROS1 {
        let inv = Ros1Bag::open(fixture(name)).unwrap().inventory().unwrap();
        assert!(inv.from_index, "{name}");
        assert_eq!(inv.mode, ReadMode::Indexed);
        assert_eq!(counts(&inv), want, "{name}");
        let bytes = std::fs::read(fixture(name)).unwrap();
        let p = write_tmp(&dir, "unclosed.bag", &without_index_pos(&bytes));
        let inv = Ros1Bag::open(&p).unwrap().inventory().unwrap();
        assert!(!inv.from_index);
        assert_eq!(inv.mode, ReadMode::Linear);
        assert_eq!(counts(&inv), want, "{name}, unclosed");
    }
}

#[test]
fn ros1_wanted_topics_only() {
    let bag = Ros1Bag::open(fixture("ros1_lz4.bag")).unwrap();
    let want = expected("ros1_expected.json");
    let scan = bag
        .scan_map(
            |c| c.topic == "/vicon/pose",
            |_, m| pose_sample(MessageKind::PoseStamped, "ros1", m.data).unwrap(),
        )
        .unwrap();
    let times: Vec<u64> = scan.messages.iter().map(|m| m.log_time).collect();
    let want_times: Vec<u64> = want
        .iter()
        .filter(|r| r.0 == "/vicon/pose")
        .map(|r| r.2)
        .collect();
    assert_eq!(times, want_times);
    // The header stamp is 1 µs before the record time in the fixture.
    for m in &scan.messages {
        let (stamp, p, q) = m.value;
        assert!((stamp - (m.log_time - 1_000) as f64 * 1e-9).abs() < 1e-6);
        assert!(p.iter().all(|v| v.is_finite()));
        let n: f64 = q.iter().map(|v| v * v).sum();
        assert!((n - 1.0).abs() < 1e-9);
    }
}

const ROS2: [(&str, Ros2Storage, Ros2Compression); 6] = [
    (
        "ros2_sqlite3_none",
        Ros2Storage::Sqlite3,
        Ros2Compression::None,
    ),
    (
        "ros2_sqlite3_file",
        Ros2Storage::Sqlite3,
        Ros2Compression::File,
    ),
    (
        "ros2_sqlite3_message",
        Ros2Storage::Sqlite3,
        Ros2Compression::Message,
    ),
    ("ros2_mcap_none", Ros2Storage::Mcap, Ros2Compression::None),
    ("ros2_mcap_file", Ros2Storage::Mcap, Ros2Compression::File),
    (
        "ros2_mcap_message",
        Ros2Storage::Mcap,
        Ros2Compression::Message,
    ),
];

#[test]
fn ros2_bags_hold_what_rosbags_wrote() {
    let want = expected("ros2_expected.json");
    for (name, storage, compression) in ROS2 {
        let bag = Ros2Bag::open(fixture(name)).unwrap();
        assert!(bag.is_folder());
        assert_eq!(bag.storage(), storage, "{name}");
        assert_eq!(bag.compression(), compression, "{name}");
        let scan = scan_all(&bag);
        assert_eq!(scan.profile, "ros2");
        assert_eq!(records(&scan), want, "{name}");
        let topics = by_topic(&scan.channels);
        for (topic, ty) in [
            ("/pose", "geometry_msgs/msg/PoseStamped"),
            ("/odom", "nav_msgs/msg/Odometry"),
            ("/tf", "tf2_msgs/msg/TFMessage"),
            ("/imu", "sensor_msgs/msg/Imu"),
        ] {
            let c = &topics[topic];
            assert_eq!(c.schema_name, ty);
            assert_eq!(c.message_encoding, "cdr");
            assert_eq!(c.schema_encoding, "ros2msg");
            if storage == Ros2Storage::Sqlite3 {
                assert!(c.schema_data.is_empty());
            }
        }
        assert_eq!(bag.channels().unwrap(), scan.channels, "{name}");
        // The same decoder as the MCAP path.
        let poses = bag
            .scan_map(
                |c| c.topic == "/odom",
                |_, m| pose_sample(MessageKind::Odometry, "cdr", m.data).unwrap(),
            )
            .unwrap();
        assert_eq!(poses.messages.len(), 15);
        for m in &poses.messages {
            // The fixture stamps each header with its record time.
            assert!((m.value.0 - m.log_time as f64 * 1e-9).abs() < 1e-6);
        }
        let inv = bag.inventory().unwrap();
        assert_eq!(counts(&inv), expected_counts(&want), "{name}");
        assert_eq!(
            inv.from_index,
            storage == Ros2Storage::Sqlite3 && compression != Ros2Compression::File
        );
        // One pass that counts every topic and maps only the wanted ones (the
        // `.db3` path of read_log) gives the two separate passes' answers.
        let (counted, inv2) = bag
            .scan_counted(
                |c| c.topic == "/odom",
                |_, m| pose_sample(MessageKind::Odometry, "cdr", m.data).unwrap(),
            )
            .unwrap();
        assert_eq!(inv2, inv, "{name}");
        assert_eq!(counted.channels, scan.channels, "{name}");
        assert_eq!(counted.mode, poses.mode, "{name}");
        let key = |s: &MappedScan<_>| {
            s.messages
                .iter()
                .map(|m| (m.channel_id, m.log_time, m.value))
                .collect::<Vec<_>>()
        };
        assert_eq!(key(&counted), key(&poses), "{name}");
    }
}

#[test]
fn ros2_single_files_and_the_yaml_path() {
    let want = expected("ros2_expected.json");
    for file in [
        "ros2_sqlite3_none/ros2_sqlite3_none.db3",
        "ros2_mcap_none/ros2_mcap_none.mcap",
        "ros2_sqlite3_none/metadata.yaml",
    ] {
        let bag = Ros2Bag::open(fixture(file)).unwrap();
        assert_eq!(bag.is_folder(), file.ends_with(".yaml"), "{file}");
        assert_eq!(records(&scan_all(&bag)), want, "{file}");
    }
    let db3 = fixture("ros2_sqlite3_none/ros2_sqlite3_none.db3");
    assert_eq!(detect(&db3).unwrap(), Container::Ros2Sqlite);
    let any = AnyContainer::open(&db3).unwrap();
    assert_eq!(any.kind(), Container::Ros2Sqlite);
    assert_eq!(records(&scan_all(&any)), want);
}

#[test]
fn detect_tells_containers_apart() {
    assert_eq!(detect(fixture("ros1_bz2.bag")).unwrap(), Container::Ros1Bag);
    assert_eq!(
        detect(fixture("ros2_mcap_none")).unwrap(),
        Container::Ros2Folder
    );
    assert_eq!(
        detect(fixture("ros2_mcap_none/ros2_mcap_none.mcap")).unwrap(),
        Container::Mcap
    );
    let dir = tempfile::tempdir().unwrap();
    let container = |p: &Path| match detect(p) {
        Err(Error::Container { reason, .. }) => reason,
        other => panic!("{}: expected Error::Container, got {other:?}", p.display()),
    };
    assert!(matches!(container(dir.path()), ContainerError::NoMetadata));
    let empty = write_tmp(&dir, "empty.bag", b"");
    assert!(matches!(container(&empty), ContainerError::Empty));
    let old = write_tmp(&dir, "old.bag", b"#ROSBAG V1.2\nsomething");
    assert!(matches!(container(&old), ContainerError::BagVersion { version } if version == "1.2"));
    let text = write_tmp(&dir, "notes.txt", b"hello world, no magic here");
    assert!(matches!(container(&text), ContainerError::Unknown { .. }));
    assert!(matches!(
        container(Path::new("/dev/null")),
        ContainerError::NotAFile {
            kind: "character device"
        }
    ));
    #[cfg(target_os = "linux")]
    {
        let fifo = dir.path().join("pipe");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: a valid NUL-terminated path; mkfifo only creates the node.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        assert!(matches!(
            container(&fifo),
            ContainerError::NotAFile { kind: "FIFO" }
        ));
    }
    assert!(matches!(
        detect(dir.path().join("missing.bag")),
        Err(Error::Io { .. })
    ));
    for name in ROS1 {
        let any = AnyContainer::open(fixture(name)).unwrap();
        assert_eq!(any.kind(), Container::Ros1Bag);
    }
    let any = AnyContainer::open(fixture("ros2_mcap_file")).unwrap();
    assert_eq!(any.kind(), Container::Ros2Folder);
    assert!(any.inventory().unwrap().channels.len() == 4);
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

fn open_err(p: &Path) -> Error {
    match Ros1Bag::open(p) {
        Err(e) => e,
        Ok(bag) => bag
            .scan_map(|_| true, |_, _| ())
            .expect_err("the damaged bag is refused"),
    }
}

#[test]
fn damaged_ros1_bags_are_refused_with_their_place() {
    let dir = tempfile::tempdir().unwrap();
    let lz4 = std::fs::read(fixture("ros1_lz4.bag")).unwrap();
    // Truncated inside the chunks: the index is gone, the linear scan meets the cut.
    let p = write_tmp(&dir, "cut.bag", &lz4[..lz4.len() / 2]);
    let e = open_err(&p);
    assert!(matches!(reason(&e), BagError::Truncated { .. }), "{e}");
    assert!(e.to_string().contains("cut.bag (byte "), "{e}");
    // Truncated inside the bag header.
    let p = write_tmp(&dir, "short.bag", &lz4[..40]);
    let e = Ros1Bag::open(&p).unwrap_err();
    assert!(matches!(reason(&e), BagError::Truncated { .. }), "{e}");
    // Another version line; no version line.
    let mut v = lz4.clone();
    v[9..12].copy_from_slice(b"1.2");
    let p = write_tmp(&dir, "v12.bag", &v);
    let e = Ros1Bag::open(&p).unwrap_err();
    assert!(matches!(reason(&e), BagError::UnsupportedVersion { version } if version == "1.2"));
    let p = write_tmp(&dir, "x.bag", b"PK\x03\x04 not a bag at all");
    assert!(matches!(
        reason(&Ros1Bag::open(&p).unwrap_err()),
        BagError::NotABag { .. }
    ));
    // A chunk whose data length runs past the end of the file.
    let none = std::fs::read(fixture("ros1_none.bag")).unwrap();
    let chunk = first_chunk(&none);
    let (len_at, _) = data_of(&none, chunk);
    let mut b = none.clone();
    b[len_at..len_at + 4].copy_from_slice(&0xfff0_0000u32.to_le_bytes());
    let p = write_tmp(&dir, "long.bag", &b);
    let e = open_err(&p);
    match reason(&e) {
        BagError::Truncated {
            what: "record data",
            needed,
            available,
        } => assert!(needed > available),
        other => panic!("{other:?}"),
    }
    assert!(matches!(e, Error::Bag { offset: Some(o), .. } if o == chunk as u64));
    // bz2 and lz4 chunks that do not decompress.
    for (name, compression) in [("ros1_bz2.bag", "bz2"), ("ros1_lz4.bag", "lz4")] {
        let bytes = std::fs::read(fixture(name)).unwrap();
        let (_, data) = data_of(&bytes, first_chunk(&bytes));
        let mut b = bytes.clone();
        b[data..data + 4].copy_from_slice(b"\0\0\0\0"); // the stream's magic
        let p = write_tmp(&dir, "bad.bag", &b);
        let e = open_err(&p);
        assert!(
            matches!(reason(&e), BagError::Decompress { compression: c, .. } if *c == compression),
            "{name}: {e}"
        );
        // Damage in the middle of the compressed stream: still a typed error.
        let mut b = bytes.clone();
        for k in 0..16 {
            b[data + 40 + k] ^= 0x5a;
        }
        let p = write_tmp(&dir, "bad.bag", &b);
        assert!(matches!(open_err(&p), Error::Bag { .. }));
    }
    // A declared chunk size beyond the limit.
    let mut b = none.clone();
    let key = b"size=";
    let at = chunk + b[chunk..].windows(5).position(|w| w == key).unwrap() + 5;
    b[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    let p = write_tmp(&dir, "huge.bag", &b);
    let e = open_err(&p);
    assert!(
        matches!(reason(&e), BagError::ChunkTooLarge { size, .. } if *size == u32::MAX as u64),
        "{e}"
    );
}

/// Offset of the value of field `name` in the header of the first record of
/// the uncompressed chunk at `chunk` whose op is `op`.
fn field_in_chunk(bytes: &[u8], chunk: usize, op: u8, name: &[u8]) -> usize {
    let (_, data) = data_of(bytes, chunk);
    let mut pos = data;
    loop {
        let hl = u32::from_le_bytes(bytes[pos..pos + 4].try_into().unwrap()) as usize;
        let header = &bytes[pos + 4..pos + 4 + hl];
        let mut f = 0;
        let (mut found_op, mut at) = (None, None);
        while f < header.len() {
            let len = u32::from_le_bytes(header[f..f + 4].try_into().unwrap()) as usize;
            let field = &header[f + 4..f + 4 + len];
            let eq = field.iter().position(|&b| b == b'=').unwrap();
            if &field[..eq] == b"op" {
                found_op = Some(field[eq + 1]);
            }
            if &field[..eq] == name {
                at = Some(pos + 4 + f + 4 + eq + 1);
            }
            f += 4 + len;
        }
        if found_op == Some(op) {
            return at.unwrap();
        }
        let dl = u32::from_le_bytes(bytes[pos + 4 + hl..pos + 8 + hl].try_into().unwrap());
        pos += 8 + hl + dl as usize;
    }
}

#[test]
fn ros1_connection_ids_are_checked() {
    let dir = tempfile::tempdir().unwrap();
    let none = std::fs::read(fixture("ros1_none.bag")).unwrap();
    let chunk = first_chunk(&none);
    // A connection id beyond the 16-bit channel ids (here and in the index).
    let mut b = none.clone();
    let at = field_in_chunk(&b, chunk, 7, b"conn");
    b[at..at + 4].copy_from_slice(&70_000u32.to_le_bytes());
    let p = write_tmp(&dir, "conn.bag", &b);
    let e = open_err(&p);
    assert!(
        matches!(reason(&e), BagError::TooManyConnections { conn: 70_000 }),
        "{e}"
    );
    // A message of a connection that nothing defines.
    let mut b = none.clone();
    let at = field_in_chunk(&b, chunk, 2, b"conn");
    b[at..at + 4].copy_from_slice(&9u32.to_le_bytes());
    let p = write_tmp(&dir, "orphan.bag", &b);
    let e = open_err(&p);
    assert!(
        matches!(
            reason(&e),
            BagError::UnknownConnection { conn: 9, index: 0 }
        ),
        "{e}"
    );
    assert!(matches!(e, Error::Bag { offset: Some(o), .. } if o == chunk as u64));
}

/// Copies a fixture folder into `dir`.
fn copy_folder(name: &str, dir: &tempfile::TempDir) -> PathBuf {
    let to = dir.path().join(name);
    std::fs::create_dir_all(&to).unwrap();
    for e in std::fs::read_dir(fixture(name)).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
    }
    to
}

#[test]
fn damaged_ros2_bags_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    // An SQLite database without the rosbag2 tables.
    let db = dir.path().join("other.db3");
    {
        let c = rusqlite::Connection::open(&db).unwrap();
        c.execute_batch("CREATE TABLE things(id INTEGER PRIMARY KEY, name TEXT);")
            .unwrap();
    }
    let bag = Ros2Bag::open(&db).unwrap();
    let e = bag.scan_map(|_| true, |_, _| ()).unwrap_err();
    assert!(
        matches!(reason(&e), BagError::MissingTable { missing: "topics", found } if found == &["things"]),
        "{e}"
    );
    // metadata.yaml naming a file that is not there.
    let f = copy_folder("ros2_sqlite3_none", &dir);
    std::fs::remove_file(f.join("ros2_sqlite3_none.db3")).unwrap();
    let e = Ros2Bag::open(&f).unwrap_err();
    assert!(
        matches!(reason(&e), BagError::MissingFile { file } if file.ends_with("ros2_sqlite3_none.db3"))
    );
    // Garbage metadata.yaml; metadata of another storage; no metadata at all.
    std::fs::write(
        f.join("metadata.yaml"),
        "rosbag2_bagfile_information: {version: [",
    )
    .unwrap();
    let e = Ros2Bag::open(&f).unwrap_err();
    assert!(
        matches!(reason(&e), BagError::Metadata { line: 1.., .. }),
        "{e}"
    );
    std::fs::write(f.join("metadata.yaml"), "\x00\x01 binary").unwrap();
    assert!(matches!(
        reason(&Ros2Bag::open(&f).unwrap_err()),
        BagError::Metadata { .. }
    ));
    std::fs::write(
        f.join("metadata.yaml"),
        "rosbag2_bagfile_information:\n  storage_identifier: leveldb\n  relative_file_paths: []\n",
    )
    .unwrap();
    assert!(matches!(
        reason(&Ros2Bag::open(&f).unwrap_err()),
        BagError::UnsupportedStorage { found } if found == "leveldb"
    ));
    std::fs::write(
        f.join("metadata.yaml"),
        "rosbag2_bagfile_information:\n  storage_identifier: sqlite3\n  compression_format: lz4\n  compression_mode: FILE\n",
    )
    .unwrap();
    assert!(matches!(
        reason(&Ros2Bag::open(&f).unwrap_err()),
        BagError::UnsupportedCompression { .. }
    ));
    std::fs::remove_file(f.join("metadata.yaml")).unwrap();
    assert!(matches!(
        reason(&Ros2Bag::open(&f).unwrap_err()),
        BagError::NoMetadata
    ));
    // A per-message compressed bag with one message that is no zstd frame.
    let f = copy_folder("ros2_sqlite3_message", &dir);
    {
        let c = rusqlite::Connection::open(f.join("ros2_sqlite3_message.db3")).unwrap();
        c.execute("UPDATE messages SET data = X'00112233' WHERE id = 5", [])
            .unwrap();
    }
    let e = Ros2Bag::open(&f)
        .unwrap()
        .scan_map(|_| true, |_, _| ())
        .unwrap_err();
    assert!(matches!(reason(&e), BagError::MessageData { .. }), "{e}");
    // A message row of a topic the topics table does not list.
    let f = copy_folder("ros2_sqlite3_none", &dir);
    {
        let c = rusqlite::Connection::open(f.join("ros2_sqlite3_none.db3")).unwrap();
        c.execute("UPDATE messages SET topic_id = 99 WHERE id = 3", [])
            .unwrap();
    }
    let bag = Ros2Bag::open(&f).unwrap();
    let e = bag.inventory().unwrap_err();
    assert!(
        matches!(
            reason(&e),
            BagError::UnknownTopic {
                topic_id: 99,
                row: 3
            }
        ),
        "{e}"
    );
    let e = bag.scan_counted(|_| true, |_, _| ()).unwrap_err();
    assert!(
        matches!(reason(&e), BagError::UnknownTopic { row: 3, .. }),
        "{e}"
    );
    let e = read_log(&f, &ReadOptions::default()).unwrap_err();
    assert!(
        matches!(reason(&e), BagError::UnknownTopic { row: 3, .. }),
        "{e}"
    );
    // scan_map queries the rows of the wanted topics only: the others still read.
    let scan = bag.scan_map(|_| true, |_, _| ()).unwrap();
    assert_eq!(
        scan.messages.len(),
        expected("ros2_expected.json").len() - 1
    );
    // A FILE-mode bag whose file is not zstd.
    let f = copy_folder("ros2_mcap_file", &dir);
    std::fs::write(f.join("ros2_mcap_file.mcap.zstd"), b"not zstd").unwrap();
    let e = Ros2Bag::open(&f).unwrap().channels().unwrap_err();
    assert!(
        matches!(
            reason(&e),
            BagError::Decompress {
                compression: "zstd",
                ..
            }
        ),
        "{e}"
    );
}

/// One mutation of a bag: bytes flipped, a length field rewritten, a cut, or
/// bytes inserted.
fn mutate(rng: &mut ChaCha8Rng, bytes: &[u8]) -> Vec<u8> {
    let mut b = bytes.to_vec();
    match rng.random_range(0..4) {
        0 => {
            for _ in 0..rng.random_range(1..8) {
                let i = rng.random_range(0..b.len());
                b[i] ^= 1 << rng.random_range(0..8);
            }
        }
        1 => {
            // A little-endian u32 somewhere (record and field lengths are u32).
            let i = rng.random_range(13..b.len() - 4);
            let v: u32 = match rng.random_range(0..4) {
                0 => 0,
                1 => u32::MAX,
                2 => rng.random_range(0..256),
                _ => rng.random(),
            };
            b[i..i + 4].copy_from_slice(&v.to_le_bytes());
        }
        2 => b.truncate(rng.random_range(0..b.len())),
        _ => {
            let i = rng.random_range(0..b.len());
            let n = rng.random_range(1..16);
            let junk: Vec<u8> = (0..n).map(|_| rng.random()).collect();
            b.splice(i..i, junk);
        }
    }
    b
}

#[test]
#[ignore = "slow: make test runs it"]
fn mutated_ros1_bags_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let sources: Vec<Vec<u8>> = ROS1
        .iter()
        .map(|n| std::fs::read(fixture(n)).unwrap())
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(14);
    let (mut ok, mut refused, mut panics) = (0, 0, Vec::new());
    for i in 0..2000 {
        let b = mutate(&mut rng, &sources[i % sources.len()]);
        let p = write_tmp(&dir, "m.bag", &b);
        let outcome = std::panic::catch_unwind(|| -> slam2world::Result<usize> {
            let bag = Ros1Bag::open(&p)?;
            let n = bag.scan_map(|_| true, |_, m| m.data.len())?.messages.len();
            bag.inventory()?;
            bag.channels()?;
            Ok(n)
        });
        match outcome {
            Ok(Ok(n)) => {
                // A mutated bag may still read; never more messages than bytes.
                assert!(n <= b.len());
                ok += 1;
            }
            Ok(Err(Error::Bag { .. })) => refused += 1,
            Ok(Err(other)) => panic!("mutant {i}: not a bag error: {other:?}"),
            Err(_) => panics.push(i),
        }
    }
    eprintln!("2000 mutants: {ok} read, {refused} refused");
    assert!(panics.is_empty(), "mutants that panicked: {panics:?}");
    assert!(ok > 100 && refused > 100, "ok {ok}, refused {refused}");
}

/// A `.db3` of 512-byte pages with a table b-tree three levels deep and rows
/// whose data spills over chains of overflow pages: more page structure per
/// byte than rosbags' files for [`mutated_db3_files_never_panic`].
fn deep_db3(path: &Path) {
    let c = rusqlite::Connection::open(path).unwrap();
    c.execute_batch(
        "PRAGMA page_size = 512;
         CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, \
         serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
         CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, \
         timestamp INTEGER NOT NULL, data BLOB NOT NULL);
         INSERT INTO topics VALUES (1, '/a', 'std_msgs/msg/String', 'cdr', '');
         BEGIN;",
    )
    .unwrap();
    for k in 0..1500i64 {
        let len = if k % 40 == 0 { 1300 } else { 8 + k % 20 } as usize;
        c.execute(
            "INSERT INTO messages VALUES (?1, 1, ?2, ?3)",
            rusqlite::params![k + 1, k * 1000, vec![k as u8; len]],
        )
        .unwrap();
    }
    c.execute_batch("COMMIT").unwrap();
}

#[test]
#[ignore = "slow: make test runs it"]
fn mutated_db3_files_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let deep = dir.path().join("deep.db3");
    deep_db3(&deep);
    let sources: Vec<Vec<u8>> = [
        fixture("ros2_sqlite3_none/ros2_sqlite3_none.db3"),
        fixture("ros2_sqlite3_message/ros2_sqlite3_message.db3"),
        deep,
    ]
    .iter()
    .map(|p| std::fs::read(p).unwrap())
    .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(20);
    let (mut ok, mut refused, mut panics) = (0, 0, Vec::new());
    for i in 0..1500 {
        let src = &sources[i % sources.len()];
        let b = if rng.random_bool(0.5) {
            mutate(&mut rng, src)
        } else {
            // A big-endian field of a page header (type, cell count, cell
            // offsets, right-most child) or of a cell pointer set to an
            // extreme value: where SQLite keeps its lengths and page numbers.
            let mut b = src.clone();
            let page_size = usize::from(u16::from_be_bytes([b[16], b[17]]));
            let page = rng.random_range(0..b.len() / page_size);
            let head = if page == 0 { 100 } else { 0 };
            let at = page * page_size + head + rng.random_range(0..24);
            let v: u32 = match rng.random_range(0..4) {
                0 => 0,
                1 => u32::MAX,
                2 => rng.random_range(0..(b.len() / page_size) as u32 + 2),
                _ => rng.random(),
            };
            let n = if rng.random_bool(0.5) { 2 } else { 4 };
            b[at..at + n].copy_from_slice(&v.to_be_bytes()[4 - n..]);
            b
        };
        let p = write_tmp(&dir, "m.db3", &b);
        let outcome = std::panic::catch_unwind(|| -> slam2world::Result<usize> {
            let bag = Ros2Bag::open(&p)?;
            let n = bag.scan_map(|_| true, |_, m| m.data.len())?.messages.len();
            bag.inventory()?;
            Ok(n)
        });
        match outcome {
            Ok(Ok(n)) => {
                assert!(n <= b.len());
                ok += 1;
            }
            Ok(Err(Error::Bag { .. } | Error::Container { .. })) => refused += 1,
            Ok(Err(other)) => panic!("mutant {i}: not a bag error: {other:?}"),
            Err(_) => panics.push(i),
        }
    }
    eprintln!("1500 mutants: {ok} read, {refused} refused");
    assert!(panics.is_empty(), "mutants that panicked: {panics:?}");
    assert!(ok > 100 && refused > 100, "ok {ok}, refused {refused}");
}

// --- real bags in ../shared/data -------------------------------------------------

fn topic_counts(source: &impl MessageSource) -> BTreeMap<String, (String, u64)> {
    let scan = source.scan_map(|_| true, |_, _| ()).unwrap();
    let mut out: BTreeMap<String, (String, u64)> = scan
        .channels
        .values()
        .map(|c| (c.topic.clone(), (c.schema_name.clone(), 0)))
        .collect();
    for m in &scan.messages {
        out.get_mut(&scan.channels[&m.channel_id].topic).unwrap().1 += 1;
    }
    out
}

fn inventory_counts(inv: &Inventory) -> BTreeMap<String, (String, u64)> {
    inv.channels
        .iter()
        .map(|c| {
            (
                c.channel.topic.clone(),
                (c.channel.schema_name.clone(), c.count),
            )
        })
        .collect()
}

fn owned(rows: &[(&str, &str, u64)]) -> BTreeMap<String, (String, u64)> {
    rows.iter()
        .map(|(t, ty, n)| (t.to_string(), (ty.to_string(), *n)))
        .collect()
}

#[test]
fn husky_bag_reads_as_its_provenance_says() {
    let Some(p) = common::data("ros1_husky_gps", "test1.bag") else {
        return;
    };
    let bag = Ros1Bag::open(&p).unwrap();
    let want = owned(&[
        ("/imu/data", "sensor_msgs/Imu", 11865),
        ("/husky_velocity_controller/odom", "nav_msgs/Odometry", 3952),
        ("/fix", "sensor_msgs/NavSatFix", 989),
    ]);
    let inv = bag.inventory().unwrap();
    assert!(inv.from_index);
    let got = inventory_counts(&inv);
    for (topic, v) in &want {
        assert_eq!(got.get(topic), Some(v), "{topic}");
    }
    assert_eq!(topic_counts(&bag), got);
    let lo = inv
        .channels
        .iter()
        .filter_map(|c| c.time_range)
        .map(|r| r.0)
        .min()
        .unwrap();
    let hi = inv
        .channels
        .iter()
        .filter_map(|c| c.time_range)
        .map(|r| r.1)
        .max()
        .unwrap();
    assert!((lo as f64 * 1e-9 - 1432235498.025).abs() < 0.01, "{lo}");
    assert!((hi as f64 * 1e-9 - 1432235893.332).abs() < 0.01, "{hi}");
    let odom = bag
        .scan_map(
            |c| c.topic == "/husky_velocity_controller/odom",
            |_, m| pose_sample(MessageKind::Odometry, "ros1", m.data).is_ok(),
        )
        .unwrap();
    assert!(odom.messages.iter().all(|m| m.value));
}

#[test]
fn evo_example_bag_reads_as_its_provenance_says() {
    let Some(p) = common::data("evo_ros1_example_bag", "ROS_example.bag") else {
        return;
    };
    let bag = Ros1Bag::open(&p).unwrap();
    let inv = bag.inventory().unwrap();
    let got = inventory_counts(&inv);
    let names: Vec<&String> = got.keys().collect();
    let find = |needle: &str| {
        got.iter()
            .find(|(t, _)| t.trim_start_matches('/') == needle)
            .unwrap_or_else(|| panic!("no topic {needle} in {names:?}"))
            .1
    };
    assert_eq!(
        find("groundtruth"),
        &("geometry_msgs/PoseStamped".into(), 12765)
    );
    assert_eq!(
        find("ORB-SLAM"),
        &("geometry_msgs/PoseStamped".into(), 8362)
    );
    assert_eq!(find("S-PTAM"), &("geometry_msgs/PoseStamped".into(), 5439));
    let poses = bag
        .scan_map(
            |_| true,
            |_, m| pose_sample(MessageKind::PoseStamped, "ros1", m.data).ok(),
        )
        .unwrap();
    assert_eq!(poses.messages.len(), 12765 + 8362 + 5439);
    // Header stamps equal the record stamps (< 1 µs), as PROVENANCE.md says.
    for m in &poses.messages {
        let (stamp, _, _) = m.value.expect("every PoseStamped decodes");
        assert!((stamp - m.log_time as f64 * 1e-9).abs() < 1e-5);
    }
    assert!(poses
        .messages
        .windows(2)
        .all(|w| w[0].log_time <= w[1].log_time));
}

#[test]
fn evo_tf_example_is_the_same_as_ros1_and_ros2() {
    let (Some(bag1), Some(folder)) = (
        common::data("evo_tf_example", "tf_example.bag"),
        common::data("evo_tf_example", "tf_example"),
    ) else {
        return;
    };
    let want = owned(&[
        ("/tf_static", "tf2_msgs/msg/TFMessage", 1),
        ("/tf", "tf2_msgs/msg/TFMessage", 517),
    ]);
    let ros1 = Ros1Bag::open(&bag1).unwrap();
    let ros2 = Ros2Bag::open(&folder).unwrap();
    let db3 = Ros2Bag::open(folder.join("tf_example.db3")).unwrap();
    let spelled = |m: BTreeMap<String, (String, u64)>| -> BTreeMap<String, (String, u64)> {
        m.into_iter()
            .map(|(t, (ty, n))| (t, (ros2_name(&ty), n)))
            .collect()
    };
    assert_eq!(spelled(topic_counts(&ros1)), want);
    assert_eq!(spelled(inventory_counts(&ros1.inventory().unwrap())), want);
    assert_eq!(topic_counts(&ros2), want);
    assert_eq!(inventory_counts(&db3.inventory().unwrap()), want);
    let times = |s: &dyn Fn() -> Vec<u64>| s();
    let t1 = times(&|| {
        ros1.scan_map(|_| true, |_, _| ())
            .unwrap()
            .messages
            .iter()
            .map(|m| m.log_time)
            .collect()
    });
    let t2 = times(&|| {
        ros2.scan_map(|_| true, |_, _| ())
            .unwrap()
            .messages
            .iter()
            .map(|m| m.log_time)
            .collect()
    });
    assert_eq!(t1.len(), 518);
    assert_eq!(t1, t2);
    let lo = *t1.first().unwrap() as f64 * 1e-9;
    let hi = *t1.last().unwrap() as f64 * 1e-9;
    assert!((lo - 1714741164.112).abs() < 0.01 && (hi - 1714741215.797).abs() < 0.01);
}

/// A `.db3` of `n` rows on two topics, written through SQL: rowid gaps, stamps
/// out of rowid order, each row's data its row number (8 bytes, zstd when
/// `zstd`). Returns `(row number, topic, stamp)` of the rows written.
fn big_db3(path: &Path, n: i64, zstd: bool) -> Vec<(i64, i64, i64)> {
    let c = rusqlite::Connection::open(path).unwrap();
    c.execute_batch(
        "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, \
         serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
         CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, \
         timestamp INTEGER NOT NULL, data BLOB NOT NULL);
         INSERT INTO topics VALUES (1, '/a', 'std_msgs/msg/UInt64', 'cdr', '');
         INSERT INTO topics VALUES (2, '/b', 'std_msgs/msg/UInt64', 'cdr', '');
         BEGIN;",
    )
    .unwrap();
    let mut rows = Vec::new();
    {
        let mut ins = c
            .prepare("INSERT INTO messages VALUES (?1, ?2, ?3, ?4)")
            .unwrap();
        for k in 0..n {
            // Every 7th rowid skipped; runs of 3 rows per topic; every 1000th
            // stamp earlier than the rows before it.
            let id = k + k / 7 + 1;
            let topic = 1 + (k / 3) % 2;
            let stamp = if k % 1000 == 999 { k - 500 } else { k } * 1000;
            let data = if zstd {
                zstd::bulk::compress(&(k as u64).to_le_bytes(), 1).unwrap()
            } else {
                (k as u64).to_le_bytes().to_vec()
            };
            ins.execute(rusqlite::params![id, topic, stamp, data])
                .unwrap();
            rows.push((k, topic, stamp));
        }
    }
    c.execute_batch("COMMIT;").unwrap();
    rows
}

#[test]
#[ignore = "slow: make test runs it"]
fn db3_scans_split_into_ranges_keep_order_counts_and_error_places() {
    let dir = tempfile::tempdir().unwrap();
    // Two ranges or more on a machine of two threads or more.
    let n = 100_000;
    let path = dir.path().join("big.db3");
    let rows = big_db3(&path, n, false);
    let bag = Ros2Bag::open(&path).unwrap();
    let row_of = |_: &ChannelInfo, m: &slam2world::io::messages::RawMessage<'_>| {
        u64::from_le_bytes(m.data.try_into().unwrap())
    };
    // The wanted topic's rows by stamp, ties in row order (a stable sort).
    let mut want: Vec<(u64, u64)> = rows
        .iter()
        .filter(|r| r.1 == 1)
        .map(|&(k, _, t)| (t as u64, k as u64))
        .collect();
    want.sort_by_key(|r| r.0);
    let got = |s: &MappedScan<u64>| {
        s.messages
            .iter()
            .map(|m| (m.log_time, m.value))
            .collect::<Vec<_>>()
    };
    let scan = bag.scan_map(|c| c.topic == "/a", row_of).unwrap();
    assert_eq!(got(&scan), want);
    let (counted, inv) = bag.scan_counted(|c| c.topic == "/a", row_of).unwrap();
    assert_eq!(got(&counted), want);
    assert_eq!(inv, bag.inventory().unwrap());
    for (topic, id) in [("/a", 1), ("/b", 2)] {
        let c = inv
            .channels
            .iter()
            .find(|c| c.channel.topic == topic)
            .unwrap();
        let mine: Vec<u64> = rows
            .iter()
            .filter(|r| r.1 == id)
            .map(|r| r.2 as u64)
            .collect();
        assert_eq!(c.count, mine.len() as u64, "{topic}");
        let lo = *mine.iter().min().unwrap();
        let hi = *mine.iter().max().unwrap();
        assert_eq!(c.time_range, Some((lo, hi)), "{topic}");
    }
    // A row of an unlisted topic late in the file is found, with its rowid.
    let late = n + n / 7 - 10;
    {
        let c = rusqlite::Connection::open(&path).unwrap();
        c.execute("UPDATE messages SET topic_id = 9 WHERE id = ?1", [late])
            .unwrap();
    }
    let e = bag.scan_counted(|_| true, row_of).unwrap_err();
    assert!(
        matches!(reason(&e), BagError::UnknownTopic { topic_id: 9, row } if *row == late),
        "{e}"
    );
    // Per-message zstd: a message that is no zstd frame in the file's second
    // half is named by its index among the wanted messages of the whole file.
    let folder = dir.path().join("message");
    std::fs::create_dir_all(&folder).unwrap();
    let rows = big_db3(&folder.join("message.db3"), n, true);
    let yaml = std::fs::read_to_string(fixture("ros2_sqlite3_message").join("metadata.yaml"))
        .unwrap()
        .replace("ros2_sqlite3_message.db3", "message.db3");
    std::fs::write(folder.join("metadata.yaml"), yaml).unwrap();
    let bag = Ros2Bag::open(&folder).unwrap();
    assert_eq!(bag.compression(), Ros2Compression::Message);
    let (counted, _) = bag.scan_counted(|c| c.topic == "/b", row_of).unwrap();
    assert_eq!(
        counted.messages.len(),
        rows.iter().filter(|r| r.1 == 2).count()
    );
    let bad = 75_000;
    {
        let c = rusqlite::Connection::open(folder.join("message.db3")).unwrap();
        c.execute(
            "UPDATE messages SET data = X'00112233' WHERE id = ?1",
            [bad + bad / 7 + 1],
        )
        .unwrap();
    }
    let before = rows[..bad as usize].iter().filter(|r| r.1 == 1).count() as u64;
    assert_eq!(rows[bad as usize].1, 1);
    for e in [
        bag.scan_counted(|c| c.topic == "/a", row_of).unwrap_err(),
        bag.scan_map(|c| c.topic == "/a", row_of).unwrap_err(),
    ] {
        assert!(
            matches!(reason(&e), BagError::MessageData { index, topic, .. }
                if *index == before && topic == "/a"),
            "{e}"
        );
    }
}

#[test]
fn db3_rowids_across_the_whole_i64_range_are_read() {
    // Rowids at both ends of i64 (SQLite allows negative ones): the range split
    // neither overflows nor loses a row.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("wide.db3");
    big_db3(&path, 10, false);
    {
        let c = rusqlite::Connection::open(&path).unwrap();
        c.execute(
            "UPDATE messages SET id = -9223372036854775808 WHERE id = 1",
            [],
        )
        .unwrap();
        c.execute(
            "UPDATE messages SET id = 9223372036854775807 WHERE id = 2",
            [],
        )
        .unwrap();
    }
    let bag = Ros2Bag::open(&path).unwrap();
    let (scan, inv) = bag.scan_counted(|_| true, |_, m| m.data.len()).unwrap();
    assert_eq!(scan.messages.len(), 10);
    assert_eq!(inv.channels.iter().map(|c| c.count).sum::<u64>(), 10);
    assert_eq!(
        bag.scan_map(|_| true, |_, _| ()).unwrap().messages.len(),
        10
    );
}
