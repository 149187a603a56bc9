//! `slam2world follow LOG.mcap -o OUT/`: the online conversion of a log that
//! is still being written.
//!
//! The file is read as it grows (MCAP needs no summary to be read: the
//! `mcap` crate's sans-io `LinearReader` is fed the new bytes at every poll,
//! chunks decompressed as they complete); every message goes into a
//! [`Session`] in log order. After every keyframe the outputs in `OUT/` are
//! replaced as one set of atomic renames — `report.json` (stage, transform,
//! timing), and once the transform is known `map.bt`, `world.mcap` (the
//! transform, the world cloud bounded for a viewer, the keyframe path, the
//! reference path, the occupied voxels, the 2-D grid and the session's state
//! as JSON on `/slam2world/state`: [`SessionWorld`], a rolling file, the
//! latest state) and with `--grid` nav2's `map.pgm` + `map.yaml` +
//! `map_height.npy` — so that a reader never sees a half-written file. One
//! status line per keyframe goes to stdout (stage, scale, rmse, points,
//! latency). It stops at the end of the log (the MCAP footer), after
//! `--idle-timeout` seconds without growth, or on Ctrl-C (exit 130, the last
//! complete outputs left as they were); at the end of the log the map is made
//! exact ([`Session::finish`]) and written once more.
//!
//! With `--serve [HOST:]PORT` each world goes to the clients of a Foxglove
//! WebSocket ([`WorldServer::live`]) before it is written, and the final
//! one is served after the end until Ctrl-C (exit 0).

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use clap::Args;

use super::args::{finite, non_negative, positive, print};
use crate::cloud::PointFilter;
use crate::defaults;
use crate::error::{Error, Result};
use crate::io::atomic::OutputSet;
use crate::io::mcap::WorldFlavor;
use crate::io::messages::decode::MessageKind;
use crate::io::nav2::{write_nav2_into, Nav2Files};
use crate::live::{ServeOptions, WorldServer, WsSource};
use crate::map::{GridParams, MapParams};
use crate::pipeline::live_world::SessionWorld;
use crate::pipeline::outputs::{
    MAP_BT, MAP_HEIGHT_NPY, MAP_PGM, MAP_YAML, REPORT_JSON, WORLD_MCAP,
};
use crate::pipeline::report::{to_json_bytes, FollowReport};
use crate::pipeline::session::{LogFeed, Pushed, Session, SessionOptions, UpdateTiming};

fn serve_at(s: &str) -> std::result::Result<ServeOptions, String> {
    s.parse().map_err(|e: Error| e.to_string())
}

fn camera_height(s: &str) -> std::result::Result<crate::pipeline::prior::HeightSpec, String> {
    s.parse().map_err(|e: crate::error::Error| e.to_string())
}

/// Arguments of `follow`.
#[derive(Args, Debug)]
pub struct FollowArgs {
    /// The MCAP log being written (LSD-SLAM keyframes, live frames, graph,
    /// reference poses), or a running Foxglove WebSocket server
    /// (`ws://HOST:PORT`: the SDK's, `foxglove_bridge`) publishing them.
    pub log: PathBuf,
    /// Output folder (created when missing).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Seconds between polls of the file for new bytes.
    #[arg(long, value_name = "S", default_value_t = 0.05, value_parser = positive)]
    pub poll: f64,
    /// Stop after this many seconds without the file growing (the writer
    /// gone without closing the log).
    #[arg(long, value_name = "S", default_value_t = 10.0, value_parser = positive)]
    pub idle_timeout: f64,
    /// Octree voxel edge, metres.
    #[arg(long, value_name = "RES", default_value_t = defaults::DEMO_OCTREE_RESOLUTION, value_parser = positive)]
    pub octree: f64,
    /// Octree rays longer than this (metres) only clear space.
    #[arg(long, value_name = "M", default_value_t = 10.0, value_parser = positive)]
    pub octree_max_range: f64,
    /// Also write the 2-D grid of the voxels between Z_MIN and Z_MAX (metres).
    #[arg(long, num_args = 2, value_names = ["Z_MIN", "Z_MAX"], allow_hyphen_values = true, value_parser = finite)]
    pub grid: Option<Vec<f64>>,
    /// Association window, seconds.
    #[arg(long, default_value_t = defaults::MAX_DIFF, value_parser = non_negative)]
    pub max_diff: f64,
    /// Seconds of stable stage seen before the transform is given.
    #[arg(long, value_name = "S", default_value_t = crate::pipeline::session::STABLE_HOLD_S, value_parser = non_negative)]
    pub stable_hold: f64,
    /// The cameras' height over the ground, for a log with no reference:
    /// metres at every pose (`1.2`) or at the first (`first:0.95`);
    /// `T_world_slam` comes from the ground plane of the keyframes so far as
    /// soon as one is supported.
    #[arg(long, value_name = "M|first:M", allow_hyphen_values = true, value_parser = camera_height)]
    pub camera_height: Option<crate::pipeline::prior::HeightSpec>,
    /// Write ROS 2 messages into world.mcap instead of Foxglove schemas.
    #[arg(long)]
    pub ros2: bool,
    /// Most points of world.mcap's cloud, sent whole at every keyframe with
    /// --serve (16 bytes a point: lower it for a slow link).
    #[arg(long, value_name = "N", default_value_t = defaults::LIVE_MAX_POINTS, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub live_points: usize,
    /// Serve the world on a Foxglove WebSocket as it grows (`PORT` on this
    /// machine, or `HOST:PORT`; 0: a free port, printed), and the final one
    /// once the log ends, until Ctrl-C.
    #[arg(long, value_name = "[HOST:]PORT", value_parser = serve_at)]
    pub serve: Option<ServeOptions>,
    /// No status lines.
    #[arg(short, long)]
    pub quiet: bool,
}

/// The names `follow` writes (a stale one of an earlier run is removed).
const NAMES: &[&str] = &[
    REPORT_JSON,
    MAP_BT,
    WORLD_MCAP,
    MAP_PGM,
    MAP_YAML,
    MAP_HEIGHT_NPY,
];

/// A channel as the follower knows it.
struct Chan {
    topic: String,
    encoding: String,
    kind: Option<MessageKind>,
}

/// The growing file and the reader fed from it.
struct Tail {
    file: File,
    offset: u64,
    reader: mcap::sans_io::LinearReader,
}

impl Tail {
    fn open(path: &Path) -> Result<Tail> {
        let file = File::open(path).map_err(|e| Error::io(path, e))?;
        Ok(Tail {
            file,
            offset: 0,
            reader: mcap::sans_io::LinearReader::new(),
        })
    }

    /// Reads up to `want` new bytes into the reader; the number read (0: the
    /// file has not grown).
    fn feed(&mut self, path: &Path, want: usize) -> Result<usize> {
        let len = self.file.metadata().map_err(|e| Error::io(path, e))?.len();
        if len < self.offset {
            return Err(Error::Mcap {
                path: path.to_path_buf(),
                reason: format!("the file shrank to {len} bytes while it was followed"),
            });
        }
        let n = ((len - self.offset) as usize).min(want.max(1 << 16));
        if n == 0 {
            return Ok(0);
        }
        self.file
            .seek(SeekFrom::Start(self.offset))
            .map_err(|e| Error::io(path, e))?;
        let buf = self.reader.insert(n);
        let got = self.file.read(buf).map_err(|e| Error::io(path, e))?;
        self.reader.notify_read(got);
        self.offset += got as u64;
        Ok(got)
    }
}

/// Runs `follow`.
pub fn run(args: &FollowArgs) -> Result<()> {
    let opts = SessionOptions {
        align: crate::align::trajectories::TrajectoryAlignOptions {
            max_diff: args.max_diff,
            ..Default::default()
        },
        map: MapParams {
            max_range: Some(args.octree_max_range),
            ..MapParams::new(args.octree)
        },
        stable_hold: args.stable_hold,
        rebuild_tolerance: 0.5 * args.octree,
        camera_height: args.camera_height.clone(),
        ..SessionOptions::default()
    };
    let grid = args.grid.as_ref().map(|z| GridParams::new(z[0], z[1]));
    if let Some(g) = &grid {
        g.check()?;
    }
    let mut feed = LogFeed::new(opts)?;
    let url = ws_url(&args.log);
    // Refuse a bad output folder (a file, the log's own folder entry) first.
    let set = OutputSet::folder(&args.output, NAMES)?;
    match url {
        Some(_) => set,
        None => set.with_inputs([&args.log]),
    }
    .check_output(&args.output.join(REPORT_JSON))?;
    let server = match &args.serve {
        Some(at) => {
            let s = WorldServer::live(&args.output.join(WORLD_MCAP), at)?;
            print(&format!(
                "serving {} on {} as it is written; open it in Foxglove (Open connection, \
                 Foxglove WebSocket)\n",
                s.path().display(),
                s.url()
            ))?;
            Some(s)
        }
        None => None,
    };
    // Served: a keyframe's points go out before the ground refit it may
    // call for.
    feed.session.defer_refits(server.is_some());
    let mut run = Follower {
        args,
        feed,
        report: FollowReport::new(&args.log),
        keyframes: 0,
        server,
        world: SessionWorld::new(
            PointFilter::default(),
            args.live_points,
            grid,
            if args.ros2 {
                WorldFlavor::Ros2
            } else {
                WorldFlavor::Foxglove
            },
        ),
    };
    let end = match url {
        Some(u) => run.follow_ws(u)?,
        None => run.follow_file()?,
    };
    run.finish(end)
}

/// The URL of a live source: `LOG` given as `ws://…`.
fn ws_url(log: &Path) -> Option<&str> {
    log.to_str().filter(|s| s.starts_with("ws://"))
}

/// One follow run: the session fed message by message, the outputs written
/// after every keyframe.
struct Follower<'a> {
    args: &'a FollowArgs,
    feed: LogFeed,
    report: FollowReport,
    keyframes: usize,
    server: Option<WorldServer>,
    world: SessionWorld,
}

impl Follower<'_> {
    /// One message of `topic` (`kind` read from its schema name); `source`
    /// names the input in an error.
    fn message(
        &mut self,
        topic: &str,
        kind: Option<MessageKind>,
        encoding: &str,
        data: &[u8],
        source: &Path,
    ) -> Result<()> {
        let pushed = self
            .feed
            .push(topic, kind, encoding, data)
            .map_err(|e| Error::Mcap {
                path: source.to_path_buf(),
                reason: e.to_string(),
            })?;
        if let Pushed::Keyframe {
            id,
            decode_s,
            timing,
        } = pushed
        {
            self.keyframes += 1;
            let latency = self.updated(id, decode_s, &timing)?;
            if !self.args.quiet {
                status_line(&self.feed.session, id, latency)?;
            }
        }
        if self.feed.session.has_deferred() {
            // The ground refit the keyframe called for, after its points
            // went out (--serve), and the world again.
            let timing = self.feed.session.catch_up()?;
            self.updated(self.report.last_keyframe, 0.0, &timing)?;
        }
        Ok(())
    }

    /// After an update of the session for keyframe `id`: the report brought
    /// up to it and the world published; returns the update's latency.
    fn updated(&mut self, id: i32, decode_s: f64, timing: &UpdateTiming) -> Result<f64> {
        let latency = decode_s + timing.total_s();
        self.report
            .update(&self.feed.session, id, decode_s, timing, latency);
        self.publish()?;
        Ok(latency)
    }

    /// Hands the world of the session as it stands to the clients with
    /// `--serve`, then writes the outputs.
    fn publish(&mut self) -> Result<()> {
        write_outputs(
            self.args,
            &self.feed.session,
            &self.report,
            &mut self.world,
            self.server.as_ref(),
        )
    }

    /// Follows the growing MCAP file; returns why it ended.
    fn follow_file(&mut self) -> Result<String> {
        let args = self.args;
        // Wait for the file to appear (the writer may start after us).
        let t_start = Instant::now();
        while !args.log.exists() {
            crate::interrupt::check()?;
            if t_start.elapsed().as_secs_f64() > args.idle_timeout {
                return Err(Error::io(
                    &args.log,
                    std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
                ));
            }
            std::thread::sleep(Duration::from_secs_f64(args.poll));
        }
        let mut tail = Tail::open(&args.log)?;
        let mut schemas: std::collections::HashMap<u16, String> = Default::default();
        let mut chans: std::collections::HashMap<u16, Chan> = Default::default();
        let mut last_growth = Instant::now();
        loop {
            crate::interrupt::check()?;
            let event = match tail.reader.next_event() {
                None => return Ok("idle timeout".into()),
                Some(e) => e.map_err(|e| Error::Mcap {
                    path: args.log.clone(),
                    reason: e.to_string(),
                })?,
            };
            let (opcode, data) = match event {
                mcap::sans_io::LinearReadEvent::ReadRequest(n) => {
                    loop {
                        if tail.feed(&args.log, n)? > 0 {
                            last_growth = Instant::now();
                            break;
                        }
                        crate::interrupt::check()?;
                        if last_growth.elapsed().as_secs_f64() > args.idle_timeout {
                            return Ok("idle timeout".into());
                        }
                        std::thread::sleep(Duration::from_secs_f64(args.poll));
                    }
                    continue;
                }
                mcap::sans_io::LinearReadEvent::Record { opcode, data } => (opcode, data.to_vec()),
            };
            let record = mcap::parse_record(opcode, &data).map_err(|e| Error::Mcap {
                path: args.log.clone(),
                reason: e.to_string(),
            })?;
            use mcap::records::Record;
            match record {
                Record::Schema { header, .. } => {
                    schemas.insert(header.id, header.name);
                }
                Record::Channel(c) => {
                    let name = schemas.get(&c.schema_id).cloned().unwrap_or_default();
                    chans.insert(
                        c.id,
                        Chan {
                            topic: c.topic,
                            encoding: c.message_encoding,
                            kind: MessageKind::from_schema(&name),
                        },
                    );
                }
                Record::Message { header, data } => {
                    let Some(ch) = chans.get(&header.channel_id) else {
                        continue;
                    };
                    let (topic, kind, encoding) = (ch.topic.clone(), ch.kind, ch.encoding.clone());
                    self.message(&topic, kind, &encoding, &data, &args.log)?;
                }
                Record::Footer(_) | Record::DataEnd(_) => return Ok("end of log".into()),
                _ => {}
            }
        }
    }

    /// Follows a Foxglove WebSocket server at `url`: its channels that
    /// slam2world reads subscribed, their messages fed as they come. A lost
    /// connection is tried again with back-off (0.1 s doubling to 2 s, what
    /// came meanwhile is lost, and the report counts the losses) until
    /// `--idle-timeout` passes without a message; returns why it ended.
    fn follow_ws(&mut self, url: &str) -> Result<String> {
        let args = self.args;
        let idle = Duration::from_secs_f64(args.idle_timeout);
        let wait = Duration::from_secs_f64(args.poll.clamp(0.001, 1.0));
        let mut last_message = Instant::now();
        let mut source: Option<WsSource> = None;
        let mut backoff = Duration::from_millis(100);
        loop {
            crate::interrupt::check()?;
            if last_message.elapsed() > idle {
                return Ok(match source {
                    Some(_) => "idle timeout".into(),
                    None => format!(
                        "server gone ({} connection{} lost)",
                        self.report.disconnections,
                        if self.report.disconnections == 1 {
                            ""
                        } else {
                            "s"
                        }
                    ),
                });
            }
            let Some(src) = source.as_mut() else {
                match WsSource::connect(url, idle.min(Duration::from_secs(5))) {
                    Ok(mut s) => {
                        s.set_wait(wait)?;
                        if !args.quiet {
                            print(&format!("follow: connected to {url}\n"))?;
                        }
                        source = Some(s);
                        backoff = Duration::from_millis(100);
                    }
                    Err(e) if self.report.disconnections == 0 && self.keyframes == 0 => {
                        // Never connected: the server may start after us,
                        // within the idle timeout.
                        if last_message.elapsed() + backoff > idle {
                            return Err(e);
                        }
                        std::thread::sleep(backoff);
                        backoff = (backoff * 2).min(Duration::from_secs(2));
                    }
                    Err(_) => {
                        std::thread::sleep(backoff);
                        backoff = (backoff * 2).min(Duration::from_secs(2));
                    }
                }
                continue;
            };
            match src.recv() {
                Ok(Some(m)) => {
                    last_message = Instant::now();
                    let source_name = PathBuf::from(format!("{url} {}", m.channel.topic));
                    self.message(
                        &m.channel.topic,
                        m.channel.kind,
                        &m.channel.encoding,
                        &m.data,
                        &source_name,
                    )?;
                }
                Ok(None) => {}
                Err(e) => {
                    self.report.disconnections += 1;
                    eprintln!(
                        "slam2world: follow: connection lost after {} messages ({e}); \
                         trying again, what the server sends meanwhile is lost",
                        src.received
                    );
                    source = None;
                }
            }
        }
    }

    /// The end: the map made exact, the outputs written once more, the
    /// final world served until Ctrl-C with `--serve`.
    fn finish(mut self, end: String) -> Result<()> {
        let args = self.args;
        let timing = self.feed.session.finish()?;
        self.report
            .update(&self.feed.session, -1, 0.0, &timing, 0.0);
        self.report.finished = true;
        self.report.end = end;
        self.publish()?;
        let session = &self.feed.session;
        if !args.quiet {
            let s = session.state();
            print(&format!(
                "follow: {} keyframes, {} live frames, stage {} ({}); {}\n",
                self.keyframes,
                s.frames,
                s.stage.name(),
                self.report.end,
                match session.transform() {
                    Ok(t) => format!(
                        "T_world_slam scale {:.6}, rmse {:.4} m over {} pairs",
                        t.transform.scale, t.rmse, t.pairs
                    ),
                    Err(e) => format!("no transform: {e}"),
                }
            ))?;
        }
        if let Some(s) = self.server.take() {
            print(&format!(
                "follow: serving the final world on {} until Ctrl-C\n",
                s.url()
            ))?;
            while crate::interrupt::pending_signal().is_none() {
                std::thread::sleep(Duration::from_millis(100));
            }
            s.stop();
        }
        Ok(())
    }
}

fn status_line(session: &Session, id: i32, latency: f64) -> Result<()> {
    let s = session.state();
    let (scale, rmse) = match session.transform() {
        Ok(t) => (
            format!("{:.6}", t.transform.scale),
            format!("{:.4}", t.rmse),
        ),
        Err(_) => ("-".into(), "-".into()),
    };
    print(&format!(
        "keyframe {id} t {:.3} s stage {} scale {scale} rmse {rmse} m points {} latency {:.1} ms\n",
        s.time,
        s.stage.name(),
        s.points,
        1e3 * latency
    ))
}

/// Replaces the outputs as one set; with `server`, its clients get the
/// world first (the files are not on the way from a keyframe to a viewer).
fn write_outputs(
    args: &FollowArgs,
    session: &Session,
    report: &FollowReport,
    world: &mut SessionWorld,
    server: Option<&WorldServer>,
) -> Result<()> {
    // report.json, and the same bytes as the state message of world.mcap.
    let report_json = to_json_bytes(report)?;
    let built = world.build(session, report_json.clone())?;
    let sent = match (&built, server) {
        (Some(w), Some(s)) => {
            let bytes = w.bytes()?;
            s.publish(bytes.clone());
            Some(bytes)
        }
        _ => None,
    };
    let mut set = OutputSet::folder(&args.output, NAMES)?.with_inputs([&args.log]);
    let path = set.path(WORLD_MCAP);
    if let Some(w) = &built {
        // Stored uncompressed while it changes at every keyframe (the bytes
        // sent, when served); the last one compressed.
        match &sent {
            Some(bytes) if !report.finished => set.write_bytes(&path, bytes)?,
            _ => w.write_into(&mut set, &path, report.finished)?,
        }
        if let Some(map) = session.map() {
            set.write_bytes(&set.path(MAP_BT), &map.to_bt_bytes())?;
        }
    }
    if let Some((g, threshold)) = built.as_ref().and_then(|w| w.grid()) {
        let files = Nav2Files {
            image: set.path(MAP_PGM),
            yaml: set.path(MAP_YAML),
            height: set.path(MAP_HEIGHT_NPY),
        };
        write_nav2_into(&mut set, g, &files, *threshold)?;
    }
    set.write_bytes(&set.path(REPORT_JSON), &report_json)?;
    set.commit().map(|_| ())
}
