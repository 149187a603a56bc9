//! Never destroy, never hang, never blow up (issue 17), through the binary:
//! outputs that are inputs refused; FIFOs, devices and links not replaced; a
//! failed re-run (file size limit) leaves the previous outputs intact; stale
//! outputs of a set removed; SIGINT/SIGTERM leave no temporary file and no
//! partial output; one readable line for paths that are no log, long lines,
//! bytes that are not text.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::Duration;

use nalgebra::{UnitQuaternion, Vector3};
use slam2world::trajectory::Trajectory;

use crate::common::{bin as run, stderr};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_slam2world"))
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// One line of reasonable length, naming `what`.
fn one_line_naming(o: &Output, what: &str) -> String {
    let e = stderr(o);
    assert_eq!(e.trim_end().lines().count(), 1, "{e}");
    assert!(e.len() < 400, "{e}");
    assert!(e.contains(what), "{what} not in {e}");
    e
}

/// Entries of `dir`, sorted (temporary files show here).
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// EST (SLAM frame, scale 1/3) and REF (metric) trajectory files and a SLAM-frame cloud.
fn trajectory_inputs(dir: &Path) -> (PathBuf, PathBuf, PathBuf) {
    let t: Vec<f64> = (0..60).map(|i| 0.1 * i as f64).collect();
    let p: Vec<Vector3<f64>> = t
        .iter()
        .map(|&s| Vector3::new(s.sin(), (0.7 * s).cos(), 0.2 * s))
        .collect();
    let q = vec![UnitQuaternion::identity(); t.len()];
    let est = Trajectory::try_new(
        t.clone(),
        p.iter().map(|v| v / 3.0).collect(),
        Some(q.clone()),
    )
    .unwrap();
    let reference = Trajectory::try_new(t, p, Some(q)).unwrap();
    let (e, r, c) = (dir.join("est.txt"), dir.join("ref.txt"), dir.join("in.ply"));
    slam2world::io::text::write_tum(&est, &e).unwrap();
    slam2world::io::text::write_tum(&reference, &r).unwrap();
    let pts: Vec<f32> = (0..30).map(|i| i as f32 * 0.1).collect();
    slam2world::io::ply::write_ply_parts(&c, &pts, None).unwrap();
    (e, r, c)
}

fn transform_cloud(cloud: &Path, est: &Path, reference: &Path, out: &Path) -> Output {
    run(&[
        "transform-cloud",
        s(cloud),
        "--align",
        s(est),
        s(reference),
        "-o",
        s(out),
    ])
}

/// A small simulated log (keyframes, reference poses, IMU).
fn simulated_log(path: &Path) {
    let o = run(&[
        "simulate",
        "-o",
        s(path),
        "--reduced",
        "16",
        "--set",
        "n_keyframes=6",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn an_output_that_is_an_input_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (est, reference, cloud) = trajectory_inputs(d);
    let before = std::fs::read(&cloud).unwrap();
    // The cloud, by its own name and through `..`.
    let o = transform_cloud(&cloud, &est, &reference, &cloud);
    assert_eq!(o.status.code(), Some(1));
    one_line_naming(&o, "is the input");
    std::fs::create_dir(d.join("sub")).unwrap();
    let o = transform_cloud(&cloud, &est, &reference, &d.join("sub/../in.ply"));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    // The trajectory, and a hard link of it.
    let o = transform_cloud(&cloud, &est, &reference, &est);
    one_line_naming(&o, "est.txt");
    std::fs::hard_link(&reference, d.join("link.txt")).unwrap();
    let o = transform_cloud(&cloud, &est, &reference, &d.join("link.txt"));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert_eq!(std::fs::read(&cloud).unwrap(), before);
    // A real output still works.
    let o = transform_cloud(&cloud, &est, &reference, &d.join("world.ply"));
    assert!(o.status.success(), "{}", stderr(&o));

    // convert d/world.mcap -o d: the log would be replaced by the output world.mcap.
    let log = d.join("world.mcap");
    simulated_log(&log);
    let before = std::fs::read(&log).unwrap();
    let o = run(&["convert", s(&log), "-o", s(d), "-q"]);
    assert_eq!(o.status.code(), Some(1));
    one_line_naming(&o, "is the input");
    assert_eq!(std::fs::read(&log).unwrap(), before);

    // simulate -o s.mcap --truth s.mcap: one file for two outputs.
    let sm = d.join("s.mcap");
    let o = run(&[
        "simulate",
        "-o",
        s(&sm),
        "--truth",
        s(&sm),
        "--reduced",
        "16",
    ]);
    assert_eq!(o.status.code(), Some(1));
    one_line_naming(&o, "s.mcap");
    assert!(!sm.exists());
}

#[test]
fn fifos_devices_and_links_are_not_replaced() {
    use std::os::unix::fs::FileTypeExt;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (est, reference, cloud) = trajectory_inputs(d);

    // /dev/null: written through, still a character device.
    let o = transform_cloud(&cloud, &est, &reference, Path::new("/dev/null"));
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::metadata("/dev/null")
        .unwrap()
        .file_type()
        .is_char_device());

    // A FIFO with a reader gets the PLY; without one, a clear error; it stays a FIFO.
    let fifo = d.join("out.ply");
    let c = std::ffi::CString::new(s(&fifo)).unwrap();
    // SAFETY: mkfifo with a valid NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o644) }, 0);
    let o = transform_cloud(&cloud, &est, &reference, &fifo);
    assert_eq!(o.status.code(), Some(1));
    one_line_naming(&o, "FIFO");
    let f2 = fifo.clone();
    let reader = std::thread::spawn(move || {
        // Opening for reading blocks until the writer opens: retry the writer below.
        std::fs::read(&f2).unwrap()
    });
    let mut out = None;
    for _ in 0..200 {
        std::thread::sleep(Duration::from_millis(25));
        let o = transform_cloud(&cloud, &est, &reference, &fifo);
        if o.status.success() {
            out = Some(o);
            break;
        }
    }
    assert!(out.is_some(), "the FIFO was never written");
    let got = reader.join().unwrap();
    assert!(got.starts_with(b"ply\n"), "{:?}", &got[..got.len().min(16)]);
    assert!(std::fs::symlink_metadata(&fifo)
        .unwrap()
        .file_type()
        .is_fifo());

    // A symbolic link: followed, its target replaced, the link kept.
    let target = d.join("target.ply");
    std::fs::write(&target, b"old").unwrap();
    let link = d.join("link.ply");
    std::os::unix::fs::symlink("target.ply", &link).unwrap();
    let o = transform_cloud(&cloud, &est, &reference, &link);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    assert!(std::fs::read(&target).unwrap().starts_with(b"ply\n"));
    // No temporary file left anywhere.
    assert!(
        names(d).iter().all(|n| !n.contains("slam2world-tmp")),
        "{:?}",
        names(d)
    );
}

/// Runs `args` with a file size limit of `bytes` (SIGXFSZ ignored: writes fail with EFBIG).
fn run_with_fsize(args: &[&str], bytes: u64) -> Output {
    use std::os::unix::process::CommandExt;
    let mut cmd = bin();
    cmd.args(args);
    // SAFETY: signal and setrlimit are async-signal-safe.
    unsafe {
        cmd.pre_exec(move || {
            libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
            let lim = libc::rlimit {
                rlim_cur: bytes,
                rlim_max: bytes,
            };
            if libc::setrlimit(libc::RLIMIT_FSIZE, &lim) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    cmd.output().unwrap()
}

#[test]
fn a_failed_rerun_leaves_the_previous_outputs_and_stale_ones_go() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let log = d.join("run.mcap");
    simulated_log(&log);
    let out = d.join("out");
    let o = run(&["convert", s(&log), "-o", s(&out), "-q", "--octree", "0.5"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let first: Vec<(String, Vec<u8>)> = names(&out)
        .into_iter()
        .map(|n| {
            let b = std::fs::read(out.join(&n)).unwrap();
            (n, b)
        })
        .collect();
    assert_eq!(
        first.iter().map(|f| f.0.as_str()).collect::<Vec<_>>(),
        [
            "cloud.ply",
            "map.bt",
            "report.html",
            "report.json",
            "trajectory.txt",
            "world.mcap"
        ]
    );
    // Disk full (a file size limit below one keyframe's pixels): exit 1, naming
    // the temporary folder the keyframes' pixels go to (the first file written)
    // and the keyframe (the first to fail: the pixels are set aside from
    // several threads, so under load not always keyframe 0); every previous
    // output as it was; no temporary file.
    let o = run_with_fsize(&["convert", s(&log), "-o", s(&out), "-q"], 4096);
    assert_eq!(o.status.code(), Some(1));
    let e = one_line_naming(&o, "File too large");
    assert!(
        e.contains("temporary folder (TMPDIR)") && e.contains("(keyframe "),
        "{e}"
    );
    assert!(!e.contains("slam2world-tmp"), "{e}");
    let again: Vec<(String, Vec<u8>)> = names(&out)
        .into_iter()
        .map(|n| {
            let b = std::fs::read(out.join(&n)).unwrap();
            (n, b)
        })
        .collect();
    assert_eq!(again, first);
    // A good run without --octree replaces the set: map.bt is removed, and said so.
    let o = run(&["convert", s(&log), "-o", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("removed"));
    assert_eq!(
        names(&out),
        [
            "cloud.ply",
            "report.html",
            "report.json",
            "trajectory.txt",
            "world.mcap"
        ]
    );
    // -o naming a file is an output folder that is a file.
    let o = run(&["convert", s(&log), "-o", s(&log), "-q"]);
    assert_eq!(o.status.code(), Some(1));
    one_line_naming(&o, "output folder is a file");
    // A disk-full PLY is a file error naming the output.
    let (est, reference, cloud) = trajectory_inputs(d);
    let big: Vec<f32> = (0..30_000).map(|i| i as f32).collect();
    slam2world::io::ply::write_ply_parts(&cloud, &big, None).unwrap();
    let o = run_with_fsize(
        &[
            "transform-cloud",
            s(&cloud),
            "--align",
            s(&est),
            s(&reference),
            "-o",
            s(&d.join("w.ply")),
        ],
        8192,
    );
    assert_eq!(o.status.code(), Some(1));
    one_line_naming(&o, "w.ply");
    assert!(!d.join("w.ply").exists());
    assert!(names(d).iter().all(|n| !n.contains("slam2world-tmp")));
}

#[test]
#[ignore = "slow: make test runs it"]
fn sigint_and_sigterm_leave_no_temporary_and_no_partial_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (sig, code) in [(libc::SIGINT, 130), (libc::SIGTERM, 143)] {
        let out = d.join("sim.mcap");
        std::fs::write(&out, b"previous").unwrap();
        // A paper-size simulation: seconds of work before it writes.
        let child = bin()
            .args(["simulate", "-o", s(&out)])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_millis(700));
        // SAFETY: kill with the pid of our own child.
        unsafe { libc::kill(child.id() as i32, sig) };
        let o = child.wait_with_output().unwrap();
        assert_eq!(o.status.code(), Some(code), "{}", stderr(&o));
        one_line_naming(&o, "interrupted by");
        assert_eq!(std::fs::read(&out).unwrap(), b"previous");
        assert_eq!(names(d), ["sim.mcap"], "temporary or partial files left");
    }
    // A temporary file of a killed (SIGKILL) run is removed by the next run.
    let stale = d.join(".x.ply.slam2world-tmp-4194305-0");
    std::fs::write(&stale, b"half").unwrap();
    let (est, reference, cloud) = trajectory_inputs(d);
    let o = transform_cloud(&cloud, &est, &reference, &d.join("x.ply"));
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stale.exists());
}

#[test]
fn paths_that_are_no_log_and_files_that_are_no_text_say_what_they_are() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("o");
    for (log, what) in [(s(d), "folder"), ("/dev/null", "character device")] {
        let o = run(&["convert", log, "-o", s(&out), "-q"]);
        assert_eq!(o.status.code(), Some(1));
        let e = one_line_naming(&o, what);
        assert!(!e.contains("os error 19"), "{e}");
        let o = run(&["inspect", log]);
        assert_eq!(o.status.code(), Some(1));
        let e = one_line_naming(&o, what);
        assert!(!e.contains("os error 19"), "{e}");
    }
    // /dev/zero as a trajectory: a format error at once, not a growing buffer.
    let (est, reference, _) = trajectory_inputs(d);
    let o = run(&["align", "/dev/zero", s(&reference)]);
    assert_eq!(o.status.code(), Some(1));
    one_line_naming(&o, "longer than");
    let o = run(&["align", s(&est), "/dev/zero", "--ref-format", "euroc"]);
    one_line_naming(&o, "longer than");
    // Bytes that are not UTF-8: a format error naming the file and line.
    let bad = d.join("latin1.txt");
    std::fs::write(&bad, b"# caf\xe9\n1 0 0 0 0 0 0 1\n").unwrap();
    let o = run(&["align", s(&bad), s(&reference)]);
    let e = one_line_naming(&o, "latin1.txt:1");
    assert!(e.contains("UTF-8"), "{e}");
    // A 200 KB token is cut in the message.
    let long = d.join("long.txt");
    std::fs::write(&long, format!("1 {} 0 0 0 0 0 1\n", "x".repeat(60_000))).unwrap();
    let o = run(&["align", s(&long), s(&reference)]);
    one_line_naming(&o, "characters)");
    // An empty cloud is refused like an empty PLY.
    let empty = d.join("empty.txt");
    std::fs::write(&empty, "# no points\n").unwrap();
    let o = transform_cloud(&empty, &est, &reference, &d.join("w.ply"));
    assert_eq!(o.status.code(), Some(1));
    one_line_naming(&o, "no points");
    // A PLY that declares no vertices is an empty cloud: carried over, it stays one.
    let none = d.join("none.ply");
    slam2world::io::ply::write_ply(&none, &slam2world::cloud::PointCloud::default()).unwrap();
    let out = d.join("none_world.ply");
    let o = transform_cloud(&none, &est, &reference, &out);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(slam2world::io::ply::read_ply(&out).unwrap().is_empty());
    // --max-offset beyond the data: the argument named, the number short.
    let o = run(&[
        "align",
        s(&est),
        s(&reference),
        "--estimate-offset",
        "--max-offset",
        "1e300",
    ]);
    assert_eq!(o.status.code(), Some(1));
    let e = one_line_naming(&o, "max_offset");
    assert!(e.contains("1e300"), "{e}");
}

#[test]
fn non_finite_points_are_dropped_counted_and_named() {
    use slam2world::cloud::PointFilter;
    use slam2world::pipeline::{convert, ConvertOptions, Recording};
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("run.mcap");
    simulated_log(&log);
    let mut rec = Recording::from(slam2world::io::read_mcap(&log, &Default::default()).unwrap());
    // An inverse depth so small that 1/idepth overflows f32.
    let kf = &mut rec.keyframes[2];
    let id = kf.id;
    let w = kf.camera.width as usize;
    for px in [w + 1, w + 2, 2 * w + 3] {
        kf.idepth[px] = 1e-40;
    }
    let opts = ConvertOptions {
        filter: PointFilter::none(),
        map: Some(slam2world::map::MapParams {
            resolution: 0.5,
            prob_hit: 0.7,
            prob_miss: 0.4,
            clamp_min: 0.1192,
            clamp_max: 0.971,
            max_range: None,
        }),
        ..ConvertOptions::default()
    };
    let c = convert(&rec, &opts).unwrap();
    assert_eq!(c.report.points_non_finite, 3);
    assert_eq!(c.report.non_finite_keyframes, vec![id]);
    assert!(c.cloud.points.iter().all(|v| v.is_finite()));
    assert_eq!(c.cloud.len(), c.report.points);
    // world.mcap gets finite points only; a stamp MCAP cannot hold is named, short.
    let out = dir.path().join("out");
    c.write_all(&out, slam2world::io::mcap::WorldFlavor::Foxglove)
        .unwrap();
    let back = slam2world::io::ply::read_ply(out.join("cloud.ply")).unwrap();
    assert!(back.points.iter().all(|v| v.is_finite()));
    let mut late = c.clone();
    *late.slam_trajectory.timestamps.last_mut().unwrap() = 1e300;
    let e = late
        .write_world_mcap(
            dir.path().join("w.mcap"),
            slam2world::io::mcap::WorldFlavor::Foxglove,
        )
        .unwrap_err()
        .to_string();
    assert!(e.contains("1e300") && e.len() < 300, "{e}");
    assert!(e.contains("keyframe"), "{e}");
}

#[test]
fn an_mcap_whose_summary_lost_a_chunk_index_is_read_whole() {
    // A log with a chunk index per chunk (small chunks), then the summary's
    // last chunk index dropped: the Statistics record disagrees, so the reader
    // scans the file and finds every pose.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("idx.mcap");
    let mut w = mcap::WriteOptions::new()
        .chunk_size(Some(2048))
        .compression(None)
        .create(std::io::BufWriter::new(
            std::fs::File::create(&path).unwrap(),
        ))
        .unwrap();
    let schema = w
        .add_schema(
            "geometry_msgs/PoseStamped",
            "ros1msg",
            b"std_msgs/Header header\ngeometry_msgs/Pose pose\n",
        )
        .unwrap();
    let ch = w
        .add_channel(schema, "/pose", "ros1", &Default::default())
        .unwrap();
    let n = 300u32;
    for i in 0..n {
        let t = 1.0 + 0.01 * i as f64;
        let data = slam2world::io::mcap::write::pose_stamped_ros1(
            i,
            t,
            "world",
            [i as f64, 0.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        );
        let ns = (t * 1e9) as u64;
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: ch,
                sequence: i,
                log_time: ns,
                publish_time: ns,
            },
            &data,
        )
        .unwrap();
    }
    w.finish().unwrap();
    drop(w);
    let full = slam2world::io::read_mcap(&path, &Default::default()).unwrap();
    assert_eq!(full.reference.as_ref().unwrap().len(), n as usize);
    assert!(full.indexed);
    // Drop the last ChunkIndex record of the summary (opcode 0x08).
    let mut bytes = std::fs::read(&path).unwrap();
    let foot = bytes.len() - 8 - 29;
    let summary_start = u64::from_le_bytes(bytes[foot + 9..foot + 17].try_into().unwrap()) as usize;
    let mut pos = summary_start;
    let mut last = None;
    while pos < foot {
        let len = u64::from_le_bytes(bytes[pos + 1..pos + 9].try_into().unwrap()) as usize;
        if bytes[pos] == 0x08 {
            last = Some((pos, 9 + len));
        }
        pos += 9 + len;
    }
    let (at, len) = last.expect("a chunk index");
    // Overwrite it with a record of an unknown opcode of the same size (skipped by readers).
    bytes[at] = 0x7f;
    let _ = len;
    std::fs::write(&path, &bytes).unwrap();
    let log = slam2world::io::read_mcap(&path, &Default::default()).unwrap();
    assert_eq!(log.reference.as_ref().unwrap().len(), n as usize);
    assert!(!log.indexed, "read by a linear scan");
}

#[test]
fn fit_refusals_name_the_argument_or_the_repeated_stamps() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let log = d.join("run.mcap");
    simulated_log(&log);
    let out = d.join("o");
    // --skip-init beyond the matched pairs: how many there were and what was asked.
    let o = run(&[
        "convert",
        s(&log),
        "-o",
        s(&out),
        "-q",
        "--skip-init",
        "99999",
    ]);
    assert_eq!(o.status.code(), Some(1));
    let e = one_line_naming(&o, "99999");
    assert!(e.contains("start-up cut"), "{e}");
    assert!(!e.contains("0 keyframe stamps match"), "{e}");
    assert!(!out.exists());
    // --max-offset beyond the reference's span: the argument named.
    let o = run(&[
        "convert",
        s(&log),
        "-o",
        s(&out),
        "-q",
        "--estimate-offset",
        "--max-offset",
        "1e300",
    ]);
    assert_eq!(o.status.code(), Some(1));
    one_line_naming(&o, "max_offset");
    // Every stamp the same on both sides: the stamps repeat, not "points coincide".
    let (_, reference, _) = trajectory_inputs(d);
    let text = std::fs::read_to_string(&reference).unwrap();
    let same: String = text
        .lines()
        .map(|l| match l.split_once(' ') {
            Some((_, rest)) if !l.starts_with('#') => format!("1.0 {rest}\n"),
            _ => format!("{l}\n"),
        })
        .collect();
    let dup = d.join("same.txt");
    std::fs::write(&dup, same).unwrap();
    let o = run(&["align", s(&dup), s(&dup)]);
    assert_eq!(o.status.code(), Some(1));
    let e = one_line_naming(&o, "the stamps repeat");
    assert!(!e.contains("coincide"), "{e}");
}

/// A zstd MCAP of `n` poses in chunks of about `chunk` bytes.
fn zstd_pose_log(path: &Path, n: u32, chunk: u64) {
    let mut w = mcap::WriteOptions::new()
        .chunk_size(Some(chunk))
        .compression(Some(mcap::Compression::Zstd))
        .create(std::io::BufWriter::new(
            std::fs::File::create(path).unwrap(),
        ))
        .unwrap();
    let schema = w
        .add_schema(
            "geometry_msgs/PoseStamped",
            "ros1msg",
            b"std_msgs/Header header\ngeometry_msgs/Pose pose\n",
        )
        .unwrap();
    let ch = w
        .add_channel(schema, "/pose", "ros1", &Default::default())
        .unwrap();
    for i in 0..n {
        let t = 1.0 + 0.01 * i as f64;
        let data = slam2world::io::mcap::write::pose_stamped_ros1(
            i,
            t,
            "world",
            [i as f64, 0.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        );
        let ns = (t * 1e9) as u64;
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: ch,
                sequence: i,
                log_time: ns,
                publish_time: ns,
            },
            &data,
        )
        .unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn an_mcap_chunk_that_declares_gigabytes_is_refused_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bomb.mcap");
    zstd_pose_log(&path, 2000, 1 << 20);
    assert!(slam2world::io::read_mcap(&path, &Default::default()).is_ok());
    // Every chunk (opcode 0x06) and chunk index (0x08) declares 2.5 GB uncompressed.
    let mut bytes = std::fs::read(&path).unwrap();
    let huge = 2_500_000_000u64.to_le_bytes();
    let mut pos = 8;
    let mut patched = 0;
    while pos + 9 <= bytes.len() - 8 {
        let op = bytes[pos];
        let len = u64::from_le_bytes(bytes[pos + 1..pos + 9].try_into().unwrap()) as usize;
        let body = pos + 9;
        if op == 0x06 {
            bytes[body + 16..body + 24].copy_from_slice(&huge);
            patched += 1;
        } else if op == 0x08 {
            // After the fixed 32 bytes, the offsets map, the index length and the
            // compression string: compressed size, then uncompressed size.
            let map_len = u32::from_le_bytes(bytes[body + 32..body + 36].try_into().unwrap());
            let c = body + 36 + map_len as usize + 8;
            let s_len = u32::from_le_bytes(bytes[c..c + 4].try_into().unwrap()) as usize;
            let u = c + 4 + s_len + 8;
            bytes[u..u + 8].copy_from_slice(&huge);
        }
        pos = body + len;
    }
    assert!(patched >= 1);
    assert!(bytes.len() < 200_000, "{}", bytes.len());
    std::fs::write(&path, &bytes).unwrap();
    let e = slam2world::io::read_mcap(&path, &Default::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("2500000000") && e.contains("bomb.mcap"), "{e}");
    assert!(e.len() < 400 && !e.contains('\n'), "{e}");
    let e = slam2world::io::inspect_mcap(&path).map(|_| ()).unwrap_err();
    assert!(e.to_string().contains("2500000000"), "{e}");
}

#[test]
fn an_mcap_truncated_while_it_is_read_is_an_error_not_sigbus() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("live.mcap");
    zstd_pose_log(&path, 20_000, 64 << 10);
    let len = std::fs::metadata(&path).unwrap().len();
    assert!(len > 256 << 10, "{len}");
    let file = slam2world::io::mcap::McapFile::open(&path).unwrap();
    // The writer (or a copy) cuts the file after it was opened and mapped.
    std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .unwrap()
        .set_len(len / 3)
        .unwrap();
    let e = match file.scan(|_| true) {
        Ok(_) => panic!("a scan of a shrunk file succeeded"),
        Err(e) => e.to_string(),
    };
    assert!(e.contains("shrank") && e.contains("live.mcap"), "{e}");
}
