//! ROS 1 bag read + decode throughput.
//!
//! - `rosbag_poses`: 1e6 `geometry_msgs/PoseStamped` in an lz4 bag (768 KiB
//!   chunks, as `rosbag record` writes), scanned with the PoseStamped decoder
//!   as the mapping (messages/s). The bag is kept at
//!   `target/bench-data/poses_1e6_lz4.bag` for `benches/rosbag_peer.py`, which
//!   times the Python `rosbags` reader + deserialiser on it and prints the ratio.
//!   `read_log_pose_stamped_lz4` is the same bag through `io::read_log` (the
//!   reference trajectory built, sorted and checked).
//! - `rosbag_keyframes_{lz4,bz2}`: bags of 640×480 LSD-SLAM keyframes scanned
//!   with the keyframe decoder, keeping a copy of each point cloud (`scan_decode`)
//!   or only looking at it (`scan_decode_borrow`: the container's own cost),
//!   through `io::read_log` (`read_log`: the clouds split straight from the
//!   decompressed chunk into the keyframes' arrays), beside plain parallel
//!   decompression of the same chunks (the limit), in decompressed bytes/s.
//!
//! The bags are written here by a small ROS 1 writer (test support only: the
//! correctness tests read bags written by `rosbags`). `cargo test` runs each
//! bench once on small sizes.

use std::collections::BTreeMap;
use std::hint::black_box;
use std::io::{Read, Write};
use std::path::Path;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use rayon::prelude::*;
use slam2world::io::log::{read_log, ReadOptions};
use slam2world::io::mcap::decode::{keyframe_ros1, pose_sample, MessageKind};
use slam2world::io::rosbag::Ros1Bag;

fn field(out: &mut Vec<u8>, name: &str, value: &[u8]) {
    out.extend_from_slice(&((name.len() + 1 + value.len()) as u32).to_le_bytes());
    out.extend_from_slice(name.as_bytes());
    out.push(b'=');
    out.extend_from_slice(value);
}

fn record(out: &mut Vec<u8>, fields: &[(&str, &[u8])], data: &[u8]) {
    let mut h = Vec::new();
    for (n, v) in fields {
        field(&mut h, n, v);
    }
    out.extend_from_slice(&(h.len() as u32).to_le_bytes());
    out.extend_from_slice(&h);
    out.extend_from_slice(&(data.len() as u32).to_le_bytes());
    out.extend_from_slice(data);
}

fn time(ns: u64) -> [u8; 8] {
    let mut t = [0u8; 8];
    t[..4].copy_from_slice(&((ns / 1_000_000_000) as u32).to_le_bytes());
    t[4..].copy_from_slice(&((ns % 1_000_000_000) as u32).to_le_bytes());
    t
}

/// (chunk offset, first and last time in ns, (connection, messages) in the chunk).
type ChunkInfo = (u64, u64, u64, Vec<(u32, u32)>);

/// A minimal ROS 1 bag writer (bag header, chunks, index data, connections,
/// chunk infos), enough for the benches.
struct BagWriter {
    out: Vec<u8>,
    compression: &'static str,
    threshold: usize,
    conns: Vec<(String, String)>,
    chunk: Vec<u8>,
    index: BTreeMap<u32, Vec<(u64, u32)>>,
    range: (u64, u64),
    infos: Vec<ChunkInfo>,
    /// (compressed chunk data, uncompressed size), for the plain-decompression peer.
    chunks: Vec<(Vec<u8>, usize)>,
}

impl BagWriter {
    fn new(compression: &'static str, threshold: usize) -> Self {
        let mut out = b"#ROSBAG V2.0\n".to_vec();
        record(
            &mut out,
            &[
                ("op", &[3]),
                ("index_pos", &[0; 8]),
                ("conn_count", &[0; 4]),
                ("chunk_count", &[0; 4]),
            ],
            &[b' '; 64],
        );
        BagWriter {
            out,
            compression,
            threshold,
            conns: Vec::new(),
            chunk: Vec::new(),
            index: BTreeMap::new(),
            range: (u64::MAX, 0),
            infos: Vec::new(),
            chunks: Vec::new(),
        }
    }

    fn connection_record(out: &mut Vec<u8>, id: u32, topic: &str, ty: &str) {
        let mut data = Vec::new();
        field(&mut data, "topic", topic.as_bytes());
        field(&mut data, "type", ty.as_bytes());
        field(&mut data, "md5sum", b"00000000000000000000000000000000");
        field(&mut data, "message_definition", b"");
        record(
            out,
            &[
                ("op", &[7]),
                ("conn", &id.to_le_bytes()),
                ("topic", topic.as_bytes()),
            ],
            &data,
        );
    }

    fn add_connection(&mut self, topic: &str, ty: &str) -> u32 {
        let id = self.conns.len() as u32;
        Self::connection_record(&mut self.chunk, id, topic, ty);
        self.conns.push((topic.into(), ty.into()));
        id
    }

    fn write(&mut self, conn: u32, ns: u64, data: &[u8]) {
        let offset = self.chunk.len() as u32;
        self.index.entry(conn).or_default().push((ns, offset));
        self.range = (self.range.0.min(ns), self.range.1.max(ns));
        record(
            &mut self.chunk,
            &[
                ("op", &[2]),
                ("conn", &conn.to_le_bytes()),
                ("time", &time(ns)),
            ],
            data,
        );
        if self.chunk.len() >= self.threshold {
            self.flush();
        }
    }

    fn flush(&mut self) {
        if self.chunk.is_empty() {
            return;
        }
        let raw = std::mem::take(&mut self.chunk);
        let data = match self.compression {
            "lz4" => {
                let mut e = lz4::EncoderBuilder::new()
                    .level(1)
                    .build(Vec::new())
                    .unwrap();
                e.write_all(&raw).unwrap();
                let (v, r) = e.finish();
                r.unwrap();
                v
            }
            "bz2" => {
                let mut e = bzip2::write::BzEncoder::new(Vec::new(), bzip2::Compression::new(6));
                e.write_all(&raw).unwrap();
                e.finish().unwrap()
            }
            _ => raw.clone(),
        };
        let pos = self.out.len() as u64;
        record(
            &mut self.out,
            &[
                ("op", &[5]),
                ("compression", self.compression.as_bytes()),
                ("size", &(raw.len() as u32).to_le_bytes()),
            ],
            &data,
        );
        self.chunks.push((data, raw.len()));
        let mut counts = Vec::new();
        for (conn, entries) in std::mem::take(&mut self.index) {
            let mut d = Vec::with_capacity(entries.len() * 12);
            for (ns, off) in &entries {
                d.extend_from_slice(&time(*ns));
                d.extend_from_slice(&off.to_le_bytes());
            }
            record(
                &mut self.out,
                &[
                    ("op", &[4]),
                    ("ver", &1u32.to_le_bytes()),
                    ("conn", &conn.to_le_bytes()),
                    ("count", &(entries.len() as u32).to_le_bytes()),
                ],
                &d,
            );
            counts.push((conn, entries.len() as u32));
        }
        let (lo, hi) = std::mem::replace(&mut self.range, (u64::MAX, 0));
        self.infos.push((pos, lo, hi, counts));
    }

    /// Writes the index and returns the bag and its chunks.
    fn finish(mut self) -> (Vec<u8>, Vec<(Vec<u8>, usize)>) {
        self.flush();
        let index_pos = self.out.len() as u64;
        for (id, (topic, ty)) in self.conns.iter().enumerate() {
            Self::connection_record(&mut self.out, id as u32, topic, ty);
        }
        for (pos, lo, hi, counts) in &self.infos {
            let mut d = Vec::new();
            for (c, n) in counts {
                d.extend_from_slice(&c.to_le_bytes());
                d.extend_from_slice(&n.to_le_bytes());
            }
            record(
                &mut self.out,
                &[
                    ("op", &[6]),
                    ("ver", &1u32.to_le_bytes()),
                    ("chunk_pos", &pos.to_le_bytes()),
                    ("start_time", &time(*lo)),
                    ("end_time", &time(*hi)),
                    ("count", &(counts.len() as u32).to_le_bytes()),
                ],
                &d,
            );
        }
        // Patch the bag header: the three fixed-size fields after "op=\x03".
        let mut header = Vec::new();
        record(
            &mut header,
            &[
                ("op", &[3]),
                ("index_pos", &index_pos.to_le_bytes()),
                ("conn_count", &(self.conns.len() as u32).to_le_bytes()),
                ("chunk_count", &(self.infos.len() as u32).to_le_bytes()),
            ],
            &[b' '; 64],
        );
        self.out[13..13 + header.len()].copy_from_slice(&header);
        (self.out, self.chunks)
    }
}

fn pose_stamped(i: u64, ns: u64) -> Vec<u8> {
    let mut m = Vec::with_capacity(80);
    m.extend_from_slice(&(i as u32).to_le_bytes());
    m.extend_from_slice(&time(ns));
    m.extend_from_slice(&5u32.to_le_bytes());
    m.extend_from_slice(b"world");
    let a = i as f64 * 1e-4;
    for v in [
        a.sin(),
        a.cos(),
        1.0,
        0.0,
        0.0,
        (a / 2.0).sin(),
        (a / 2.0).cos(),
    ] {
        m.extend_from_slice(&f64::to_le_bytes(v));
    }
    m
}

/// An LSD-SLAM keyframeMsg of `w`×`h` with about a quarter of the pixels set.
fn keyframe_msg(i: usize, w: u32, h: u32) -> Vec<u8> {
    let n = (w * h) as usize;
    let mut m = Vec::with_capacity(69 + 12 * n);
    m.extend_from_slice(&(i as i32).to_le_bytes());
    m.extend_from_slice(&(1.0 + i as f64).to_le_bytes());
    m.push(1);
    for v in [0.0f32, 0.0, 0.0, 1.0, 0.1 * i as f32, 0.0, 0.0] {
        m.extend_from_slice(&v.to_le_bytes());
    }
    for v in [525.0f32, 525.0, 319.5, 239.5] {
        m.extend_from_slice(&v.to_le_bytes());
    }
    m.extend_from_slice(&h.to_le_bytes());
    m.extend_from_slice(&w.to_le_bytes());
    m.extend_from_slice(&((12 * n) as u32).to_le_bytes());
    let mut state = 0x9e3779b97f4a7c15u64 ^ i as u64;
    for p in 0..n {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let (x, y) = (p % w as usize, p / w as usize);
        let (id, var) = if state % 4 == 0 {
            (
                0.5 + (state >> 40) as f32 / (1u64 << 24) as f32,
                1e-4 * ((state >> 20) & 0xff) as f32 / 255.0,
            )
        } else {
            (0.0, 0.0)
        };
        m.extend_from_slice(&id.to_le_bytes());
        m.extend_from_slice(&var.to_le_bytes());
        m.extend_from_slice(&[(x / 3) as u8, (y / 2) as u8, ((x + y) / 5) as u8, 255]);
    }
    m
}

fn decompress(compression: &str, data: &[u8], size: usize) -> usize {
    let mut out = Vec::with_capacity(size);
    match compression {
        "lz4" => {
            lz4::Decoder::new(data)
                .unwrap()
                .read_to_end(&mut out)
                .unwrap();
        }
        _ => {
            bzip2::bufread::BzDecoder::new(data)
                .read_to_end(&mut out)
                .unwrap();
        }
    }
    out.len()
}

fn bench(c: &mut Criterion) {
    // Full sizes under `cargo bench` (criterion gets `--bench`), small ones
    // when `cargo test --all-targets` runs the bench once.
    let full = std::env::args().any(|a| a == "--bench");
    let data_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/bench-data");
    std::fs::create_dir_all(&data_dir).expect("bench data folder");

    let n: u64 = if full { 1_000_000 } else { 2_000 };
    let path = data_dir.join(if full {
        "poses_1e6_lz4.bag".to_string()
    } else {
        format!("poses_{n}_lz4.bag")
    });
    {
        let mut w = BagWriter::new("lz4", 768 * 1024);
        let conn = w.add_connection("/groundtruth", "geometry_msgs/PoseStamped");
        for i in 0..n {
            let ns = 1_500_000_000_000_000_000 + i * 5_000_000;
            w.write(conn, ns, &pose_stamped(i, ns));
        }
        std::fs::write(&path, w.finish().0).expect("pose bag written");
    }
    let mut g = c.benchmark_group("rosbag_poses");
    g.sample_size(10)
        .measurement_time(Duration::from_secs(3))
        .warm_up_time(Duration::from_millis(500));
    g.throughput(Throughput::Elements(n));
    g.bench_with_input(
        BenchmarkId::new("scan_decode_pose_stamped_lz4", n),
        &path,
        |b, path| {
            b.iter(|| {
                let bag = Ros1Bag::open(black_box(path)).expect("open");
                let scan = bag
                    .scan_map(
                        |c| c.schema_name == "geometry_msgs/PoseStamped",
                        |_, m| pose_sample(MessageKind::PoseStamped, "ros1", m.data).ok(),
                    )
                    .expect("scan");
                assert_eq!(scan.messages.len() as u64, n);
                black_box(scan.messages.len())
            })
        },
    );
    g.bench_with_input(
        BenchmarkId::new("read_log_pose_stamped_lz4", n),
        &path,
        |b, path| {
            b.iter(|| {
                let log = read_log(black_box(path), &ReadOptions::default()).expect("read_log");
                let r = log.reference.expect("a reference");
                assert_eq!(r.len() as u64, n);
                black_box(r.len())
            })
        },
    );
    g.finish();

    let (w, h) = (640u32, 480u32);
    for (compression, k) in [
        ("lz4", if full { 32 } else { 2 }),
        ("bz2", if full { 8 } else { 2 }),
    ] {
        let mut bw = BagWriter::new(compression, 768 * 1024);
        let conn = bw.add_connection("/lsd_slam/keyframes", "lsd_slam_viewer/keyframeMsg");
        for i in 0..k {
            bw.write(conn, 1_000_000_000 * (1 + i as u64), &keyframe_msg(i, w, h));
        }
        let (bytes, chunks) = bw.finish();
        let kf_path = data_dir.join(format!("keyframes_{k}_{compression}.bag"));
        std::fs::write(&kf_path, bytes).expect("keyframe bag written");
        let total: usize = chunks.iter().map(|c| c.1).sum();
        let mut g = c.benchmark_group(format!("rosbag_keyframes_{compression}"));
        g.sample_size(10)
            .measurement_time(Duration::from_secs(if full { 5 } else { 1 }));
        g.throughput(Throughput::Bytes(total as u64));
        g.bench_function(format!("scan_decode_{k}_keyframes_640x480"), |b| {
            b.iter(|| {
                let bag = Ros1Bag::open(black_box(&kf_path)).expect("open");
                let scan = bag
                    .scan_map(
                        |_| true,
                        |_, m| keyframe_ros1(m.data).map(|kf| kf.pointcloud.to_vec()).ok(),
                    )
                    .expect("scan");
                assert!(scan.messages.iter().all(|m| m.value.is_some()));
                black_box(scan.messages.len())
            })
        });
        g.bench_function(format!("scan_decode_borrow_{k}_keyframes_640x480"), |b| {
            b.iter(|| {
                let bag = Ros1Bag::open(black_box(&kf_path)).expect("open");
                let scan = bag
                    .scan_map(
                        |_| true,
                        |_, m| keyframe_ros1(m.data).map(|kf| kf.pointcloud.len()).ok(),
                    )
                    .expect("scan");
                assert!(scan.messages.iter().all(|m| m.value.is_some()));
                black_box(scan.messages.len())
            })
        });
        g.bench_function(format!("read_log_{k}_keyframes_640x480"), |b| {
            b.iter(|| {
                let log = read_log(black_box(&kf_path), &ReadOptions::default()).expect("read_log");
                assert_eq!(log.keyframes.len(), k);
                black_box(log.keyframes.len())
            })
        });
        g.bench_function("peer_plain_parallel_decompress", |b| {
            b.iter(|| {
                let sum: usize = chunks
                    .par_iter()
                    .map(|(data, size)| decompress(compression, black_box(data), *size))
                    .sum();
                assert_eq!(sum, total);
                black_box(sum)
            })
        });
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
