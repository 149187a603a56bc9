//! Seeded mutation tests of every reader: MCAP, ROS 1 bag, rosbag2 `.db3`,
//! PLY, `.bt`, TUM, EuRoC, IMU CSV, `x y z` text, COLMAP (binary and text),
//! `.npy`, and the Foxglove WebSocket client of `follow ws://` (`ws`: a case
//! is a stream of frames that a hostile server sends it — malformed JSON and
//! binary frames, huge advertised schemas, a flood of messages).
//!
//! For each reader, a few valid seed files are mutated with a seeded random
//! generator (bit flips, bytes overwritten, truncations, insertions, copied
//! regions, 4- and 8-byte fields set to extreme values: where the length
//! fields are). The cases are read by a worker process — this test binary
//! run again — under a 2 GiB address-space limit (`RLIMIT_AS`). Each case must
//! give a value or a typed error: no panic (caught and reported), no abort
//! (the worker would die), no hang (a case that runs past [`CASE_TIMEOUT`]
//! fails the test), and a peak resident memory (`VmHWM`, reset before each
//! case through `/proc/self/clear_refs`) of at most 100 × the case's size
//! plus [`FIXED_BYTES`].
//!
//! `SLAM2WORLD_MUTATION_CASES` changes the cases per reader (default 400);
//! `SLAM2WORLD_MUTATION_SECONDS=N` instead runs the MCAP reader on random
//! mutations for N seconds (the stable-Rust stand-in for the `mcap_file`
//! fuzz target, `make fuzz-stable`).

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use nalgebra::{UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use slam2world::geometry::{PinholeCamera, Sim3};
use slam2world::imu::ImuSamples;
use slam2world::keyframe::Keyframe;
use slam2world::map::{MapParams, OccupancyMap};
use slam2world::trajectory::Trajectory;

/// Longest a single case may run (debug build, 2 shared cores).
const CASE_TIMEOUT: Duration = Duration::from_secs(30);
/// The address space the worker may use.
const ADDRESS_SPACE: u64 = 2 << 30;
/// Memory a case may use whatever its size: the allocator's arenas, the
/// thread pool, a chunk buffer per thread.
const FIXED_BYTES: u64 = 160 << 20;

const READERS: [&str; 13] = [
    "mcap",
    "ros1",
    "db3",
    "ply",
    "bt",
    "tum",
    "euroc",
    "imu",
    "xyz",
    "colmap_bin",
    "colmap_txt",
    "npy",
    "ws",
];

fn cases_per_reader() -> usize {
    std::env::var("SLAM2WORLD_MUTATION_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(400)
}

// ---------------------------------------------------------------- seeds

fn trajectory(n: usize) -> Trajectory {
    let t: Vec<f64> = (0..n).map(|i| 1.0 + 0.1 * i as f64).collect();
    let p = t
        .iter()
        .map(|&s| Vector3::new(s.sin(), (0.7 * s).cos(), 0.1 * s))
        .collect();
    let q = t
        .iter()
        .map(|&s| UnitQuaternion::from_euler_angles(0.1 * s, 0.2, 0.3 * s))
        .collect();
    Trajectory::try_new(t, p, Some(q)).unwrap()
}

fn keyframes() -> Vec<Keyframe> {
    let cam = PinholeCamera::try_new(8.0, 8.0, 4.0, 3.0, 8, 6).unwrap();
    (0..4)
        .map(|i| {
            let idepth: Vec<f32> = (0..48).map(|k| 0.5 + 0.01 * (k + i) as f32).collect();
            let var = vec![1e-4f32; 48];
            let color = (0..144).map(|k| (k * 5 % 256) as u8).collect();
            let pose = Sim3::try_new(
                UnitQuaternion::from_euler_angles(0.0, 0.05 * i as f64, 0.0),
                Vector3::new(0.2 * i as f64, 0.0, 0.0),
                1.0,
            )
            .unwrap();
            Keyframe::try_new(
                i,
                1.0 + 0.5 * i as f64,
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

/// Valid files of one reader (`dir` holds them); folders for COLMAP.
fn seeds(reader: &str, dir: &Path) -> Vec<PathBuf> {
    let p = |name: &str| dir.join(name);
    match reader {
        "mcap" => {
            let traj = trajectory(40);
            let imu = ImuSamples::try_new(
                (0..60).map(|i| 1.0 + 0.05 * i as f64).collect(),
                vec![Vector3::new(0.01, 0.0, 0.0); 60],
                vec![Vector3::new(0.0, 0.0, 9.81); 60],
            )
            .unwrap();
            let log = p("log.mcap");
            slam2world::io::mcap::write_slam_log(
                &log,
                &keyframes(),
                Some(&traj),
                Some(&imu),
                &[("note".into(), "seed".into())],
                &Default::default(),
            )
            .unwrap();
            // An indexed file: summary, chunk indexes, statistics.
            let world = p("world.mcap");
            let pts: Vec<f32> = (0..300).map(|i| (i as f32 * 0.37).sin()).collect();
            let scene = slam2world::io::mcap::WorldScene {
                cloud: slam2world::io::spill::CloudRef::Memory(&pts, None),
                t_world_slam: Sim3::identity(),
                slam_trajectory: Some(&traj),
                reference: Some((&traj).into()),
                stamp: 5.0,
                world_frame: "world",
                slam_frame: "slam",
                frames: &[],
            };
            slam2world::io::mcap::write_world_mcap(
                &world,
                &scene,
                slam2world::io::mcap::WorldFlavor::Foxglove,
            )
            .unwrap();
            vec![log, world]
        }
        "ros1" => {
            let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/rosbag");
            ["ros1_none.bag", "ros1_lz4.bag", "ros1_bz2.bag"]
                .iter()
                .map(|n| root.join(n))
                .filter(|f| f.is_file())
                .collect()
        }
        "db3" => {
            let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/rosbag");
            [
                "ros2_sqlite3_none/ros2_sqlite3_none.db3",
                "ros2_sqlite3_message/ros2_sqlite3_message.db3",
            ]
            .iter()
            .map(|n| root.join(n))
            .filter(|f| f.is_file())
            .collect()
        }
        "ply" => {
            let bin = p("bin.ply");
            let pts: Vec<f32> = (0..90).map(|i| i as f32 * 0.5).collect();
            let cols: Vec<u8> = (0..90).map(|i| i as u8).collect();
            slam2world::io::ply::write_ply_parts(&bin, &pts, Some(&cols)).unwrap();
            let ascii = p("ascii.ply");
            std::fs::write(
                &ascii,
                "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\n\
                 element vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
                 property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n\
                 3 0 1 2\n1 2 3 255 0 0\n4 5 6 0 255 0\n7 8 9 0 0 255\n",
            )
            .unwrap();
            vec![bin, ascii]
        }
        "bt" => {
            let mut m = OccupancyMap::try_new(map_params()).unwrap();
            let pts: Vec<f32> = (0..60)
                .flat_map(|i| [1.0 + 0.05 * i as f32, 0.3, 0.2])
                .collect();
            m.insert_scan(&pts, [0.0, 0.0, 0.0]).unwrap();
            let f = p("map.bt");
            std::fs::write(&f, m.to_bt_bytes()).unwrap();
            vec![f]
        }
        "tum" => {
            let f = p("traj.txt");
            slam2world::io::text::write_tum(&trajectory(30), &f).unwrap();
            vec![f]
        }
        "euroc" => {
            let f = p("data.csv");
            let mut s = String::from("#timestamp, p_x, p_y, p_z, q_w, q_x, q_y, q_z\n");
            for i in 0..30u64 {
                s += &format!(
                    "{},{},{},0.5,1,0,0,0\n",
                    1_403_636_579_000_000_000 + i * 5_000_000,
                    0.1 * i as f64,
                    (i as f64).sin()
                );
            }
            std::fs::write(&f, s).unwrap();
            vec![f]
        }
        "imu" => {
            let f = p("imu.csv");
            let mut s = String::from("#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\n");
            for i in 0..40u64 {
                s += &format!(
                    "{},0.01,-0.02,0.003,0.1,0.2,9.8{}\n",
                    1_403_636_579_000_000_000 + i * 5_000_000,
                    i % 10
                );
            }
            std::fs::write(&f, s).unwrap();
            vec![f]
        }
        "xyz" => {
            let f = p("MapPoints.txt");
            let s: String = (0..40)
                .map(|i| format!("{} {} {}\n", i, 0.5 * i as f64, -0.25 * i as f64))
                .collect();
            std::fs::write(&f, s).unwrap();
            vec![f]
        }
        "colmap_txt" | "colmap_bin" => {
            let txt = p("model_txt");
            std::fs::create_dir_all(&txt).unwrap();
            std::fs::write(
                txt.join("cameras.txt"),
                "1 PINHOLE 640 480 500 500 320 240\n",
            )
            .unwrap();
            std::fs::write(
                txt.join("images.txt"),
                "1 1 0 0 0 0.1 0.2 0.3 1 a.png\n10 20 1 30 40 -1\n\
                 2 0.9 0.1 0 0 0.4 0.2 0.3 1 b.png\n11 21 1\n",
            )
            .unwrap();
            std::fs::write(
                txt.join("points3D.txt"),
                "1 1.0 2.0 3.0 255 0 0 0.5 1 0 2 0\n",
            )
            .unwrap();
            if reader == "colmap_txt" {
                return vec![txt];
            }
            let m = slam2world::io::colmap::read_colmap(&txt, None).unwrap();
            let bin = p("model_bin");
            std::fs::create_dir_all(&bin).unwrap();
            m.write(&bin, Some(slam2world::io::colmap::ColmapFormat::Binary))
                .unwrap();
            vec![bin]
        }
        "npy" => {
            let f = p("poses.npy");
            let mut header =
                String::from("{'descr': '<f4', 'fortran_order': False, 'shape': (5, 7), }");
            while (10 + header.len() + 1) % 64 != 0 {
                header.push(' ');
            }
            header.push('\n');
            let mut b = b"\x93NUMPY\x01\x00".to_vec();
            b.extend_from_slice(&(header.len() as u16).to_le_bytes());
            b.extend_from_slice(header.as_bytes());
            for i in 0..35 {
                b.extend_from_slice(&(i as f32 * 0.1).to_le_bytes());
            }
            std::fs::write(&f, b).unwrap();
            vec![f]
        }
        "ws" => {
            let advertise = r#"{"op":"advertise","channels":[{"id":7,"topic":"/gt","encoding":"ros1","schemaName":"geometry_msgs/PoseStamped","schema":"..."},{"id":8,"topic":"/kf","encoding":"ros1","schemaName":"lsd_slam_viewer/keyframeMsg","schema":"..."}]}"#;
            let pose = ws_message(1, 42, &[0u8; 60]);
            // Channels, a few messages, a withdrawal and a second advertise.
            let mut a = Vec::new();
            ws_frame(&mut a, b'T', advertise.as_bytes());
            for i in 0..4 {
                ws_frame(
                    &mut a,
                    b'B',
                    &ws_message(1 + i % 2, 42 + i as u64, &[i as u8; 60]),
                );
            }
            ws_frame(&mut a, b'T', br#"{"op":"unadvertise","channelIds":[8]}"#);
            ws_frame(&mut a, b'T', advertise.as_bytes());
            ws_frame(&mut a, b'B', &pose);
            // A huge advertised schema (1 MiB).
            let mut b = Vec::new();
            let huge = format!(
                r#"{{"op":"advertise","channels":[{{"id":1,"topic":"/gt","encoding":"ros1","schemaName":"geometry_msgs/PoseStamped","schema":"{}"}}]}}"#,
                "x".repeat(1 << 20)
            );
            ws_frame(&mut b, b'T', huge.as_bytes());
            ws_frame(&mut b, b'B', &pose);
            // A flood: 5000 messages.
            let mut c = Vec::new();
            ws_frame(&mut c, b'T', advertise.as_bytes());
            for i in 0..5000u64 {
                ws_frame(&mut c, b'B', &ws_message(1, i, &[0u8; 8]));
            }
            let names = ["frames.ws", "huge_schema.ws", "flood.ws"];
            names
                .iter()
                .zip([a, b, c])
                .map(|(n, bytes)| {
                    std::fs::write(p(n), bytes).unwrap();
                    p(n)
                })
                .collect()
        }
        other => panic!("unknown reader {other}"),
    }
}

/// A `ws` case's frame: kind (`T` text, `B` binary), length (`u32` LE), bytes.
fn ws_frame(out: &mut Vec<u8>, kind: u8, payload: &[u8]) {
    out.push(kind);
    out.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    out.extend_from_slice(payload);
}

/// A message frame of the protocol: opcode 1, subscription, log time, payload.
fn ws_message(sub: u32, t: u64, payload: &[u8]) -> Vec<u8> {
    let mut b = vec![1u8];
    b.extend_from_slice(&sub.to_le_bytes());
    b.extend_from_slice(&t.to_le_bytes());
    b.extend_from_slice(payload);
    b
}

/// The frames of a (mutated) `ws` case, read leniently: a length past the
/// end takes what is left, a kind other than `T` is a binary frame.
#[cfg(feature = "live")]
fn ws_frames(b: &[u8]) -> Vec<tungstenite::Message> {
    let mut out = Vec::new();
    let mut rest = b;
    while rest.len() >= 5 {
        let kind = rest[0];
        let n = u32::from_le_bytes([rest[1], rest[2], rest[3], rest[4]]) as usize;
        let body = &rest[5..];
        let n = n.min(body.len());
        out.push(if kind == b'T' {
            tungstenite::Message::text(String::from_utf8_lossy(&body[..n]).into_owned())
        } else {
            tungstenite::Message::binary(body[..n].to_vec())
        });
        rest = &body[n..];
    }
    out
}

/// `follow ws://`'s client against a server that sends the case's frames
/// and then goes: the messages it received, and the error it ended on (none:
/// the server went quiet for 5 s).
#[cfg(feature = "live")]
fn ws_exchange(path: &Path) -> (usize, Option<slam2world::Error>) {
    use slam2world::live::WsSource;
    let frames = ws_frames(&std::fs::read(path).unwrap());
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!("ws://{}", listener.local_addr().unwrap());
    let server = std::thread::spawn(move || {
        let Ok((stream, _)) = listener.accept() else {
            return;
        };
        let _ = stream.set_read_timeout(Some(Duration::from_secs(5)));
        let agree = |_: &tungstenite::handshake::server::Request,
                     mut r: tungstenite::handshake::server::Response| {
            r.headers_mut()
                .insert("Sec-WebSocket-Protocol", "foxglove.sdk.v1".parse().unwrap());
            Ok(r)
        };
        let Ok(mut ws) = tungstenite::accept_hdr(stream, agree) else {
            return;
        };
        for f in frames {
            if ws.send(f).is_err() {
                return;
            }
        }
        // A closing handshake (what the client sent read meanwhile), so
        // that no frame is lost to a reset.
        let _ = ws.close(None);
        while ws.read().is_ok() {}
    });
    let mut got = 0;
    let r = (|| {
        let mut src = WsSource::connect(&url, Duration::from_secs(5))?;
        src.set_wait(Duration::from_millis(50))?;
        let mut quiet = 0;
        while quiet < 100 {
            quiet = match src.recv()? {
                Some(_) => {
                    got += 1;
                    0
                }
                None => quiet + 1,
            };
        }
        Ok::<(), slam2world::Error>(())
    })();
    let _ = server.join();
    (got, r.err())
}

#[cfg(feature = "live")]
fn read_ws_case(path: &Path) -> slam2world::Result<()> {
    match ws_exchange(path) {
        (_, Some(e)) => Err(e),
        _ => Ok(()),
    }
}

/// The `ws` seeds reach the client whole: what the mutations start from.
#[cfg(feature = "live")]
#[test]
fn ws_seeds_are_received_whole() {
    let dir = tempfile::tempdir().unwrap();
    let seeds = seeds("ws", dir.path());
    let got: Vec<(usize, String)> = seeds
        .iter()
        .map(|p| {
            let (n, e) = ws_exchange(p);
            (n, e.map(|e| e.to_string()).unwrap_or_default())
        })
        .collect();
    // 4 + 1 messages of subscribed channels (the one after the withdrawal
    // re-subscribed), the huge schema's 1, the flood's 5000; each ended by
    // the server's going.
    assert_eq!(
        got.iter().map(|g| g.0).collect::<Vec<_>>(),
        [5, 1, 5000],
        "{got:?}"
    );
    assert!(got.iter().all(|g| g.1.contains("connection")), "{got:?}");
}

fn map_params() -> MapParams {
    MapParams {
        resolution: 0.1,
        prob_hit: 0.7,
        prob_miss: 0.4,
        clamp_min: 0.1192,
        clamp_max: 0.971,
        max_range: None,
    }
}

// ---------------------------------------------------------------- mutations

/// One seeded mutation of `b` (never empty unless truncated to nothing).
fn mutate(b: &mut Vec<u8>, rng: &mut ChaCha8Rng) {
    let rounds = rng.random_range(1..=3);
    for _ in 0..rounds {
        if b.is_empty() {
            b.push(rng.random());
            continue;
        }
        let at = rng.random_range(0..b.len());
        match rng.random_range(0..8) {
            0 => b[at] ^= 1 << rng.random_range(0..8),
            1 => b[at] = rng.random(),
            2 => b.truncate(at),
            3 => {
                let n = rng.random_range(1..16);
                let bytes: Vec<u8> = (0..n).map(|_| rng.random()).collect();
                b.splice(at..at, bytes);
            }
            4 => {
                // A region copied elsewhere (records repeated or overlapping).
                let len = rng.random_range(1..=64.min(b.len() - at));
                let region = b[at..at + len].to_vec();
                let to = rng.random_range(0..b.len());
                b.splice(to..to, region);
            }
            5 | 6 => {
                // A length-like field set to an extreme value.
                let values: [u64; 6] = [
                    0,
                    0xFFFF_FFFF,
                    0x7FFF_FFFF,
                    0x8000_0000,
                    u64::MAX,
                    0xD000_0000,
                ];
                let v = values[rng.random_range(0..values.len())];
                let width = if rng.random() { 4 } else { 8 };
                if at + width <= b.len() {
                    b[at..at + width].copy_from_slice(&v.to_le_bytes()[..width]);
                }
            }
            _ => {
                // A text field made huge or odd (text formats).
                let s: &[u8] = match rng.random_range(0..4) {
                    0 => b"1e308",
                    1 => b"-nan",
                    2 => b"\xff\xfe",
                    _ => b"99999999999999999999999",
                };
                b.splice(at..at, s.iter().copied());
            }
        }
    }
}

/// Writes the cases of `reader` into `dir`: `(path, bytes on disk)`.
fn make_cases(reader: &str, dir: &Path, n: usize, seed: u64) -> Vec<(PathBuf, u64)> {
    let seed_dir = dir.join("seeds");
    std::fs::create_dir_all(&seed_dir).unwrap();
    let seeds = seeds(reader, &seed_dir);
    assert!(!seeds.is_empty(), "{reader}: no seed");
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut cases = Vec::with_capacity(n);
    for i in 0..n {
        let s = &seeds[i % seeds.len()];
        let case = dir.join(format!("case-{i:04}"));
        if s.is_dir() {
            // One file of the model mutated, the others copied.
            std::fs::create_dir_all(&case).unwrap();
            let mut files: Vec<PathBuf> = std::fs::read_dir(s)
                .unwrap()
                .map(|e| e.unwrap().path())
                .collect();
            files.sort();
            let k = rng.random_range(0..files.len());
            let mut total = 0;
            for (j, f) in files.iter().enumerate() {
                let mut b = std::fs::read(f).unwrap();
                if j == k {
                    mutate(&mut b, &mut rng);
                }
                total += b.len() as u64;
                std::fs::write(case.join(f.file_name().unwrap()), &b).unwrap();
            }
            cases.push((case, total));
        } else {
            let mut b = std::fs::read(s).unwrap();
            mutate(&mut b, &mut rng);
            let case = case.with_extension(s.extension().unwrap_or_default());
            std::fs::write(&case, &b).unwrap();
            cases.push((case, b.len() as u64));
        }
    }
    cases
}

// ---------------------------------------------------------------- worker

/// Reads one case with `reader`; `Ok` whether the reader accepted or refused it.
fn read_case(reader: &str, path: &Path) -> Result<(), String> {
    use slam2world::io::messages::MessageSource;
    use slam2world::io::AnyContainer;
    let r: slam2world::Result<()> = match reader {
        "mcap" => slam2world::io::read_mcap(path, &Default::default())
            .map(|_| ())
            .and_then(|_| slam2world::io::inspect_mcap(path).map(|_| ())),
        "ros1" | "db3" => AnyContainer::open(path).and_then(|c| {
            c.inventory()?;
            c.scan_map(|_| true, |_, m| m.data.len()).map(|_| ())
        }),
        "ply" => slam2world::io::ply::read_ply(path).map(|_| ()),
        "bt" => OccupancyMap::read_bt(path, map_params()).map(|_| ()),
        "tum" => slam2world::io::text::read_tum(path)
            .map(|_| ())
            .and_then(|_| slam2world::io::text::read_trajectory(path, None).map(|_| ())),
        "euroc" => slam2world::io::text::read_euroc(path).map(|_| ()),
        "imu" => slam2world::io::text::read_euroc_imu(path).map(|_| ()),
        "xyz" => slam2world::io::ply::read_xyz_text(path).map(|_| ()),
        "colmap_bin" | "colmap_txt" => slam2world::io::colmap::read_colmap(path, None).map(|_| ()),
        "npy" => slam2world::io::npy::read_npy(path).map(|_| ()),
        #[cfg(feature = "live")]
        "ws" => read_ws_case(path),
        #[cfg(not(feature = "live"))]
        "ws" => Ok(()),
        other => return Err(format!("unknown reader {other}")),
    };
    // A typed error is an answer; its message must stay one reasonable line.
    if let Err(e) = r {
        let msg = e.to_string();
        if msg.len() > 2000 || msg.contains('\n') {
            return Err(format!(
                "error message of {} bytes: {}",
                msg.len(),
                &msg[..200.min(msg.len())]
            ));
        }
    }
    Ok(())
}

fn status_kb(field: &str) -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with(field))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// The worker's side: reads every case listed on its standard input, one
/// line each, and reports `done PATH PEAK_BYTES` (or `fail PATH WHY`).
#[test]
fn worker() {
    let Ok(reader) = std::env::var("SLAM2WORLD_MUTATION_READER") else {
        return;
    };
    let stdin = std::io::stdin();
    let mut out = std::io::stdout().lock();
    for line in stdin.lock().lines() {
        let path = PathBuf::from(line.unwrap());
        // Peak RSS reset to the current RSS (Linux `clear_refs` 5).
        let reset = std::fs::write("/proc/self/clear_refs", "5").is_ok();
        let base = status_kb("VmRSS:").unwrap_or(0);
        writeln!(out, "start {}", path.display()).unwrap();
        out.flush().unwrap();
        let r = std::panic::catch_unwind(|| read_case(&reader, &path));
        let peak = if reset {
            status_kb("VmHWM:").map(|p| p.saturating_sub(base) * 1024)
        } else {
            None
        };
        match r {
            Ok(Ok(())) => writeln!(
                out,
                "done {} {}",
                path.display(),
                peak.map_or("-".into(), |p| p.to_string())
            ),
            Ok(Err(why)) => writeln!(out, "fail {} {why}", path.display()),
            Err(p) => {
                let msg = p
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default();
                writeln!(out, "fail {} panic: {msg}", path.display())
            }
        }
        .unwrap();
        out.flush().unwrap();
    }
}

// ---------------------------------------------------------------- parent

#[derive(Debug)]
struct Outcome {
    failures: Vec<String>,
    peak_max: u64,
    done: usize,
}

/// Runs the worker on `cases` under the address-space limit; every failure named.
fn run_worker(reader: &str, cases: &[(PathBuf, u64)]) -> Outcome {
    let exe = std::env::current_exe().unwrap();
    let mut cmd = Command::new(exe);
    cmd.args([
        "mutation::worker",
        "--exact",
        "--nocapture",
        "--test-threads=1",
    ])
    .env("SLAM2WORLD_MUTATION_READER", reader)
    .env("RUST_BACKTRACE", "0")
    .stdin(Stdio::piped())
    .stdout(Stdio::piped())
    .stderr(Stdio::null());
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::process::CommandExt;
        // SAFETY: setrlimit is async-signal-safe and touches no state of the parent.
        unsafe {
            cmd.pre_exec(|| {
                let lim = libc::rlimit {
                    rlim_cur: ADDRESS_SPACE,
                    rlim_max: ADDRESS_SPACE,
                };
                if libc::setrlimit(libc::RLIMIT_AS, &lim) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            });
        }
    }
    let mut child = cmd.spawn().unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let list: String = cases
        .iter()
        .map(|(p, _)| format!("{}\n", p.display()))
        .collect();
    let writer = std::thread::spawn(move || {
        let _ = stdin.write_all(list.as_bytes());
    });
    let stdout = child.stdout.take().unwrap();
    let (tx, rx) = mpsc::channel::<String>();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines() {
            let Ok(line) = line else { break };
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let size_of = |p: &str| {
        cases
            .iter()
            .find(|(c, _)| c.to_string_lossy() == p)
            .map_or(0, |c| c.1)
    };
    let mut out = Outcome {
        failures: Vec::new(),
        peak_max: 0,
        done: 0,
    };
    let mut current: Option<String> = None;
    loop {
        match rx.recv_timeout(CASE_TIMEOUT) {
            Ok(line) => {
                if let Some(p) = line.strip_prefix("start ") {
                    current = Some(p.to_string());
                } else if let Some(rest) = line.strip_prefix("done ") {
                    let (p, peak) = rest.rsplit_once(' ').unwrap();
                    out.done += 1;
                    if let Ok(peak) = peak.parse::<u64>() {
                        out.peak_max = out.peak_max.max(peak);
                        let bound = 100 * size_of(p) + FIXED_BYTES;
                        if peak > bound {
                            out.failures.push(format!(
                                "{reader}: {p}: peak memory {peak} bytes above {bound}"
                            ));
                        }
                    }
                    current = None;
                } else if let Some(rest) = line.strip_prefix("fail ") {
                    out.done += 1;
                    out.failures.push(format!("{reader}: {rest}"));
                    current = None;
                }
            }
            Err(mpsc::RecvTimeoutError::Timeout) => {
                let _ = child.kill();
                out.failures.push(format!(
                    "{reader}: {}: no answer within {CASE_TIMEOUT:?} (hang)",
                    current.as_deref().unwrap_or("?")
                ));
                break;
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => break,
        }
    }
    let status = child.wait().unwrap();
    let _ = writer.join();
    if !status.success() && out.failures.is_empty() {
        out.failures.push(format!(
            "{reader}: the worker died ({status}) at {}",
            current.as_deref().unwrap_or("?")
        ));
    } else if let Some(c) = current {
        out.failures
            .push(format!("{reader}: the worker died ({status}) at {c}"));
    }
    out
}

#[test]
#[ignore = "slow: make test runs it"]
fn every_reader_survives_seeded_mutations() {
    if std::env::var("SLAM2WORLD_MUTATION_READER").is_ok()
        || std::env::var("SLAM2WORLD_MUTATION_SECONDS").is_ok()
    {
        return;
    }
    let n = cases_per_reader();
    let mut failures = Vec::new();
    let t0 = Instant::now();
    for (k, reader) in READERS.iter().enumerate() {
        let dir = tempfile::tempdir().unwrap();
        let cases = make_cases(reader, dir.path(), n, 17 + k as u64);
        let out = run_worker(reader, &cases);
        eprintln!(
            "{reader}: {} of {} cases read, peak {:.1} MiB above the worker's base",
            out.done,
            cases.len(),
            out.peak_max as f64 / (1 << 20) as f64
        );
        if out.failures.is_empty() {
            assert_eq!(out.done, cases.len(), "{reader}: cases left unread");
        }
        failures.extend(out.failures);
    }
    eprintln!(
        "{} readers in {:.1} s",
        READERS.len(),
        t0.elapsed().as_secs_f64()
    );
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// The bounded random-input run of the MCAP reader (`SLAM2WORLD_MUTATION_SECONDS`).
#[test]
fn mcap_random_run_for_a_while() {
    let Some(secs) = std::env::var("SLAM2WORLD_MUTATION_SECONDS")
        .ok()
        .and_then(|s| s.parse::<u64>().ok())
    else {
        return;
    };
    let t0 = Instant::now();
    let mut round = 0u64;
    let mut total = 0usize;
    while t0.elapsed() < Duration::from_secs(secs) {
        let dir = tempfile::tempdir().unwrap();
        let cases = make_cases("mcap", dir.path(), 200, 1000 + round);
        let out = run_worker("mcap", &cases);
        total += out.done;
        assert!(out.failures.is_empty(), "{}", out.failures.join("\n"));
        round += 1;
    }
    eprintln!(
        "mcap: {total} random cases in {:.0} s, no crash, no hang, memory bounded",
        t0.elapsed().as_secs_f64()
    );
}
