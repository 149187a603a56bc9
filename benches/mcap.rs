//! MCAP read + decode throughput.
//!
//! - `poses`: a log of small ros1 `geometry_msgs/PoseStamped` messages (zstd
//!   chunks), read into a reference trajectory (messages/s). The Python peer
//!   (`mcap` + `mcap-ros1-support`) is timed by `benches/compare.py --only mcap`.
//! - `keyframes`: a zstd log of 640×480 LSD-SLAM keyframes read into keyframes
//!   (decompressed bytes/s), beside plain single-threaded zstd decompression of
//!   the same chunks (the peer, the limit).
//!
//! - `world`: `world.mcap` of a cloud of `S2W_BENCH_WORLD_POINTS` points
//!   (default 4,194,304: one full cloud message, 64 MiB), written a piece at a
//!   time by slam2world's writer, beside the `mcap` crate's writer given the
//!   same message built whole in memory (the peer: what `world.mcap` was
//!   written with before; same zstd level, one thread).
//!
//! Sizes: poses 1e3 … `S2W_BENCH_POSES` (default 1e6) and `S2W_BENCH_KEYFRAMES` (default 16);
//! `cargo test` runs each once on small sizes.

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use nalgebra::{UnitQuaternion, Vector3};
use slam2world::io::mcap::write::foxglove_point_cloud;
use slam2world::io::mcap::{
    write_slam_log, write_world_mcap, SlamLogOptions, WorldFlavor, WorldScene,
};
use slam2world::io::spill::CloudRef;
use slam2world::io::{read_mcap, ReadOptions};
use slam2world::{Keyframe, PinholeCamera, Sim3, Trajectory};

/// `default` under `cargo bench`; a small size when `cargo test` runs the bench once.
fn env_usize(name: &str, default: usize) -> usize {
    let benchmarking = std::env::args().any(|a| a == "--bench");
    let default = if benchmarking {
        default
    } else {
        default.div_ceil(1000).max(2)
    };
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse::<f64>().ok())
        .map_or(default, |v| v as usize)
}

fn pose_log(path: &Path, n: usize) {
    let t: Vec<f64> = (0..n).map(|i| 1000.0 + i as f64 * 0.001).collect();
    let p = (0..n)
        .map(|i| Vector3::new((i as f64 * 1e-3).sin(), (i as f64 * 1e-3).cos(), 1.0))
        .collect();
    let q = (0..n)
        .map(|i| UnitQuaternion::from_euler_angles(0.0, 0.0, i as f64 * 1e-4))
        .collect();
    let r = Trajectory::try_new(t, p, Some(q)).expect("valid trajectory");
    write_slam_log(path, &[], Some(&r), None, &[], &SlamLogOptions::default())
        .expect("bench log written");
}

/// A semi-dense 640×480 keyframe: about a quarter of the pixels have depth.
fn keyframe(i: usize) -> Keyframe {
    let (w, h) = (640u32, 480u32);
    let cam = PinholeCamera::try_new(525.0, 525.0, 319.5, 239.5, w, h).expect("camera");
    let n = (w * h) as usize;
    let mut idepth = vec![0.0f32; n];
    let mut var = vec![0.0f32; n];
    let mut color = vec![0u8; 3 * n];
    let mut state = 0x9e3779b97f4a7c15u64 ^ i as u64;
    for p in 0..n {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let (x, y) = (p % w as usize, p / w as usize);
        color[3 * p] = (x / 3) as u8;
        color[3 * p + 1] = (y / 2) as u8;
        color[3 * p + 2] = ((x + y) / 5) as u8;
        if state % 4 == 0 {
            idepth[p] = 0.5 + (state >> 40) as f32 / (1u64 << 24) as f32;
            var[p] = 1e-4 * ((state >> 20) & 0xff) as f32 / 255.0;
        }
    }
    let pose = Sim3::try_new(
        UnitQuaternion::from_euler_angles(0.0, 0.01 * i as f64, 0.0),
        Vector3::new(0.1 * i as f64, 0.0, 0.0),
        1.0,
    )
    .expect("pose");
    Keyframe::try_new(
        i as i32,
        1.0 + i as f64,
        pose,
        cam,
        idepth,
        Some(var),
        Some(color),
    )
    .expect("keyframe")
}

/// (compressed chunk bytes, uncompressed size) of every chunk of the log.
fn chunks(path: &Path) -> Vec<(Vec<u8>, usize)> {
    let bytes = std::fs::read(path).expect("log readable");
    let mut out = Vec::new();
    for rec in mcap::read::LinearReader::new(&bytes).expect("mcap") {
        if let Ok(mcap::records::Record::Chunk { header, data }) = rec {
            out.push((data.into_owned(), header.uncompressed_size as usize));
        }
    }
    out
}

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("temp dir");

    // 1e3 … S2W_BENCH_POSES messages (1e6 by default).
    let max = env_usize("S2W_BENCH_POSES", 1_000_000);
    let sizes: Vec<usize> = [1_000usize, 10_000, 100_000, 1_000_000]
        .into_iter()
        .filter(|&s| s < max)
        .chain(std::iter::once(max))
        .collect();
    let mut g = c.benchmark_group("mcap_poses");
    g.sample_size(10)
        .measurement_time(Duration::from_secs(2))
        .warm_up_time(Duration::from_millis(300));
    for n in sizes {
        let poses = dir.path().join(format!("poses_{n}.mcap"));
        pose_log(&poses, n);
        g.throughput(Throughput::Elements(n as u64));
        g.bench_with_input(
            BenchmarkId::new("read_decode_pose_stamped", n),
            &n,
            |b, _| {
                b.iter(|| {
                    let log = read_mcap(black_box(&poses), &ReadOptions::default()).expect("read");
                    black_box(log.reference.map(|r| r.len()))
                })
            },
        );
    }
    g.finish();

    let k = env_usize("S2W_BENCH_KEYFRAMES", 16);
    let kf_path = dir.path().join("keyframes.mcap");
    let kfs: Vec<Keyframe> = (0..k).map(keyframe).collect();
    write_slam_log(&kf_path, &kfs, None, None, &[], &SlamLogOptions::default()).expect("kf log");
    drop(kfs);
    let chunk_data = chunks(&kf_path);
    let total: usize = chunk_data.iter().map(|c| c.1).sum();
    let mut g = c.benchmark_group("mcap_keyframes");
    g.sample_size(10).measurement_time(Duration::from_secs(3));
    g.throughput(Throughput::Bytes(total as u64));
    g.bench_function(format!("read_decode_{k}_keyframes_640x480"), |b| {
        b.iter(|| {
            let log = read_mcap(black_box(&kf_path), &ReadOptions::default()).expect("read");
            black_box(log.keyframes.len())
        })
    });
    g.bench_function("peer_plain_zstd_decompress_one_thread", |b| {
        b.iter(|| {
            let mut sum = 0usize;
            for (data, size) in &chunk_data {
                let out = zstd::bulk::decompress(black_box(data), *size).expect("zstd");
                sum += out.len();
            }
            black_box(sum)
        })
    });
    g.finish();

    let n = env_usize("S2W_BENCH_WORLD_POINTS", 1 << 22);
    let points: Vec<f32> = (0..3 * n).map(|i| (i as f32 * 0.37).sin() * 20.0).collect();
    let colors: Vec<u8> = (0..3 * n).map(|i| (i * 7 % 256) as u8).collect();
    let scene = WorldScene {
        cloud: CloudRef::Memory(&points, Some(&colors)),
        t_world_slam: Sim3::identity(),
        slam_trajectory: None,
        reference: None,
        stamp: 10.0,
        world_frame: "world",
        slam_frame: "slam",
        frames: &[],
    };
    let world = dir.path().join("world.mcap");
    let peer = dir.path().join("peer.mcap");
    let mut g = c.benchmark_group("mcap_world");
    g.sample_size(10).measurement_time(Duration::from_secs(4));
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function(format!("write_world_mcap_{n}_points_piecewise"), |b| {
        b.iter(|| {
            write_world_mcap(black_box(&world), &scene, WorldFlavor::Foxglove).expect("write")
        })
    });
    g.bench_function("peer_mcap_crate_writer_message_built_whole", |b| {
        b.iter(|| {
            let msg = foxglove_point_cloud(10.0, "world", black_box(&points), Some(&colors));
            let file = std::io::BufWriter::new(std::fs::File::create(&peer).expect("create"));
            let mut w = mcap::WriteOptions::new()
                .compression(Some(mcap::Compression::Zstd))
                .compression_threads(0)
                .create(file)
                .expect("writer");
            let schema = w
                .add_schema("foxglove.PointCloud", "protobuf", b"")
                .expect("schema");
            let ch = w
                .add_channel(schema, "/world/cloud", "protobuf", &Default::default())
                .expect("channel");
            let header = mcap::records::MessageHeader {
                channel_id: ch,
                sequence: 0,
                log_time: 10_000_000_000,
                publish_time: 10_000_000_000,
            };
            w.write_to_known_channel(&header, &msg).expect("message");
            w.finish().expect("finish");
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
