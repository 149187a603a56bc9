//! [`read_log`]: a SLAM log (keyframes, graph updates, reference poses, IMU)
//! read into the crate's types from any container: an MCAP file, a ROS 1 bag,
//! a rosbag2 folder or `.db3` ([`crate::io::container::detect`] tells which
//! from the bytes). [`inspect_log`] lists what a log holds.
//!
//! The assembly is written once over [`MessageSource`]: messages are decoded
//! inside the readers' parallel chunk tasks by the decoders of
//! [`crate::io::messages::decode`] (the same for every container), keyframes
//! keep their latest version per id with the graph updates applied, the
//! reference and the IMU are sorted by time. Times in the log are `u64`
//! nanoseconds; the results are in seconds and metres.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU8, Ordering};

use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use rayon::prelude::*;

pub use crate::error::LogError;
use crate::error::{Error, Result, WireError};
use crate::geo::{GnssFix, GnssFixes, TimeBase};
use crate::geometry::{PinholeCamera, Sim3};
use crate::imu::ImuSamples;
use crate::io::container::{detect, Container};
use crate::io::mcap::reader::McapFile;
use crate::io::messages::decode::{self, KeyframeMsg, MessageKind, StampedPose};
use crate::io::messages::gnss;
use crate::io::messages::{
    ChannelCount, ChannelInfo, Inventory, MappedMessage, MappedScan, MessageSource, RawMessage,
    ReadMode, ScanInfo, ScanSink,
};
use crate::io::rosbag::{Ros1Bag, Ros2Bag, Ros2Storage};
use crate::io::spill::{
    PixelSpill, RowFile, RowSpill, SpilledKeyframes, SpilledPixels, TrajectoryFile, ROW_PIECE,
};
use crate::keyframe::Keyframe;
use crate::trajectory::Trajectory;

/// Which topics to read. `None` finds the topic by its schema (type) name.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// Topic of `lsd_slam_viewer/keyframeMsg`.
    pub keyframe_topic: Option<String>,
    /// Topic of `lsd_slam_viewer/keyframeGraphMsg`.
    pub graph_topic: Option<String>,
    /// Topic of the reference poses `T_world_body` (any supported pose type).
    pub pose_topic: Option<String>,
    /// Topic of `sensor_msgs/Imu`.
    pub imu_topic: Option<String>,
    /// For `tf2_msgs/TFMessage` references: the parent frame (the world side).
    pub tf_parent: Option<String>,
    /// For `tf2_msgs/TFMessage` references: the child frame (the body).
    pub tf_child: Option<String>,
    /// Topic of the SLAM estimate as poses without depth (`T_slam_cam`, any
    /// pose type; a TF topic gives its most frequent frame pair), as
    /// `evo_ape bag LOG REF EST` takes it. Never found by type: with it and
    /// without `keyframe_topic`, no keyframes are read, and the reference is
    /// never this topic.
    pub est_topic: Option<String>,
    /// Topic of the GNSS fixes (`sensor_msgs/NavSatFix`, `foxglove.LocationFix`).
    /// Found by type only when the log has no reference pose topic; naming it
    /// makes the fixes the reference (no pose topic is then read unless one is
    /// named too, which is refused: one reference).
    pub gnss_topic: Option<String>,
}

/// One topic of the log, as [`read_log`] and `slam2world inspect` list it.
#[derive(Clone, Debug, PartialEq)]
pub struct TopicInfo {
    /// Topic name.
    pub topic: String,
    /// Schema (type) name, e.g. `geometry_msgs/PoseStamped`; empty when schemaless.
    pub schema_name: String,
    /// Schema encoding (`ros1msg`, `ros2msg`, `protobuf`, …).
    pub schema_encoding: String,
    /// Message encoding (`ros1`, `cdr`, `protobuf`, `json`, …).
    pub message_encoding: String,
    /// Messages on the topic: from the container's index where it has one
    /// (a ROS 1 bag's index, a `.db3`'s tables), else those read (0 when an
    /// MCAP index let its chunks be skipped).
    pub count: u64,
    /// First and last log (record) time, nanoseconds.
    pub time_range: Option<(u64, u64)>,
    /// What slam2world makes of the type, when anything.
    pub kind: Option<MessageKind>,
}

/// A SLAM log: keyframes, SLAM poses, reference poses, IMU and the topic inventory.
#[derive(Clone, Debug, Default)]
pub struct Log {
    /// The file (or rosbag2 folder) read.
    pub path: PathBuf,
    /// The container, when the log was read from one ([`read_log`] sets it).
    pub container: Option<Container>,
    /// Keyframes, the latest version of each id, in order of first arrival; each
    /// pose is the latest of the keyframe message and the graph messages after it.
    /// Timestamps are the messages' own `time`.
    pub keyframes: Vec<Keyframe>,
    /// SLAM poses without depth (`T_slam_cam`, sorted by header time), from
    /// [`ReadOptions::est_topic`].
    pub frames: Option<Trajectory>,
    /// Reference poses `T_world_body`, sorted by time.
    pub reference: Option<Trajectory>,
    /// Raw IMU samples, sorted by time (samples with a repeated time dropped).
    pub imu: Option<ImuSamples>,
    /// The raw IMU samples left on disk by [`read_log_spilled`] (`imu` is
    /// then `None`).
    pub imu_on_disk: Option<std::sync::Arc<ImuOnDisk>>,
    /// The reference poses left on disk by [`read_log_spilled`] when they
    /// came in time order (`reference` is then `None`).
    pub reference_on_disk: Option<std::sync::Arc<TrajectoryFile>>,
    /// GNSS fixes in log order (their stamps are the messages' header times),
    /// those without a fix dropped and counted.
    pub gnss: Option<GnssFixes>,
    /// LSD-SLAM's live frames (`keyframeMsg` with `isKeyframe = false` on a
    /// `…liveframes` topic): the tracked `T_slam_cam` of every frame as it was
    /// published, sorted by time (a repeated time keeps its first frame);
    /// `None` when the log has none.
    pub live: Option<Trajectory>,
    /// Topic the live frames came from.
    pub live_topic: Option<String>,
    /// Topic the keyframes came from.
    pub keyframe_topic: Option<String>,
    /// Topic the graph updates came from.
    pub graph_topic: Option<String>,
    /// Topic the SLAM poses without depth came from.
    pub est_topic: Option<String>,
    /// Topic the reference came from.
    pub reference_topic: Option<String>,
    /// Topic the IMU came from.
    pub imu_topic: Option<String>,
    /// Topic the GNSS fixes came from.
    pub gnss_topic: Option<String>,
    /// Keyframe messages read (all versions) and graph messages applied.
    pub keyframe_messages: usize,
    /// Graph messages read.
    pub graph_messages: usize,
    /// Keyframe poses overwritten by graph messages.
    pub graph_updates: usize,
    /// Every topic of the log.
    pub topics: Vec<TopicInfo>,
    /// True when the log was read through its index (false: a linear scan).
    pub indexed: bool,
    /// Where the keyframes' pixels are when the log was read with them left
    /// on disk ([`read_log_spilled`]): then every keyframe of `keyframes`
    /// has empty pixel arrays, and `at[i]` holds those of keyframe `i`.
    pub pixels: Option<std::sync::Arc<SpilledKeyframes>>,
}

/// Reference pose kinds in the order they are preferred.
const POSE_KINDS: [MessageKind; 7] = [
    MessageKind::PoseStamped,
    MessageKind::PoseWithCovarianceStamped,
    MessageKind::Odometry,
    MessageKind::TransformStamped,
    MessageKind::PoseInFrame,
    MessageKind::PosesInFrame,
    MessageKind::Tf,
];

fn kind_of(c: &ChannelInfo) -> Option<MessageKind> {
    MessageKind::from_schema(&c.schema_name)
}

fn topic_info(c: &ChannelInfo, count: u64, time_range: Option<(u64, u64)>) -> TopicInfo {
    TopicInfo {
        topic: c.topic.clone(),
        schema_name: c.schema_name.clone(),
        schema_encoding: c.schema_encoding.clone(),
        message_encoding: c.message_encoding.clone(),
        count,
        time_range,
        kind: kind_of(c),
    }
}

/// Counts and time ranges per channel, as topics and as a count map;
/// `messages` yields `(channel id, log time)`.
fn topic_inventory(
    channels: &BTreeMap<u16, ChannelInfo>,
    stats: &ChannelStats,
) -> (Vec<TopicInfo>, HashMap<u16, u64>) {
    let topics = channels
        .values()
        .map(|c| {
            let (count, first, last) = stats.0[c.id as usize];
            topic_info(c, count, (count > 0).then_some((first, last)))
        })
        .collect();
    let counts = channels
        .keys()
        .map(|id| (*id, stats.0[*id as usize].0))
        .collect();
    (topics, counts)
}

/// Messages, first and last log time per channel id, counted as a scan
/// gives them.
struct ChannelStats(Vec<(u64, u64, u64)>);

impl ChannelStats {
    fn new() -> ChannelStats {
        ChannelStats(vec![(0, u64::MAX, 0); 1 << 16])
    }

    fn add(&mut self, id: u16, t: u64) {
        let s = &mut self.0[id as usize];
        s.0 += 1;
        s.1 = s.1.min(t);
        s.2 = s.2.max(t);
    }
}

/// The topics and counts of a container's inventory.
fn inventory_topics(inv: &Inventory) -> (Vec<TopicInfo>, HashMap<u16, u64>) {
    let topics = inv
        .channels
        .iter()
        .map(|c: &ChannelCount| topic_info(&c.channel, c.count, c.time_range))
        .collect();
    let counts = inv
        .channels
        .iter()
        .map(|c| (c.channel.id, c.count))
        .collect();
    (topics, counts)
}

fn kinds_text(kinds: &[MessageKind]) -> String {
    kinds
        .iter()
        .map(|k| format!("{k:?}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Picks the channel for a role: the named topic (which must exist and carry
/// one of `kinds`), else the channel of the first kind in `kinds` present (most
/// messages first, then topic name), never `exclude`.
fn choose<'c>(
    path: &Path,
    role: &'static str,
    named: Option<&str>,
    kinds: &[MessageKind],
    channels: &'c BTreeMap<u16, ChannelInfo>,
    counts: &HashMap<u16, u64>,
    exclude: Option<u16>,
) -> Result<Option<&'c ChannelInfo>> {
    if let Some(topic) = named {
        // The exact name first; else the name without a leading `/` on either side
        // (ROS resolves `x` in the root namespace as `/x`; some bags store either).
        let bare = |t: &str| t.strip_prefix('/').unwrap_or(t).to_string();
        let found = channels
            .values()
            .find(|c| c.topic == topic)
            .or_else(|| channels.values().find(|c| bare(&c.topic) == bare(topic)));
        let Some(c) = found else {
            return Err(Error::log(
                path,
                LogError::NoTopic {
                    role,
                    topic: topic.to_string(),
                    topics: channels.values().map(|c| c.topic.clone()).collect(),
                },
            ));
        };
        return match kind_of(c) {
            Some(k) if kinds.contains(&k) => Ok(Some(c)),
            Some(_) => Err(Error::log(
                path,
                LogError::WrongType {
                    role,
                    topic: topic.to_string(),
                    type_name: c.schema_name.clone(),
                    expected: kinds_text(kinds),
                },
            )),
            None => Err(Error::log(
                path,
                LogError::UnknownType {
                    role,
                    topic: topic.to_string(),
                    type_name: c.schema_name.clone(),
                    expected: kinds_text(kinds),
                },
            )),
        };
    }
    for k in kinds {
        let mut cands: Vec<&ChannelInfo> = channels
            .values()
            .filter(|c| kind_of(c) == Some(*k) && Some(c.id) != exclude)
            .collect();
        // LSD-SLAM also publishes live frames (pose only) as keyframeMsg, more often
        // than keyframes: a topic named like that comes last.
        let live = |c: &ChannelInfo| c.topic.contains("liveframe");
        cands.sort_by(|a, b| {
            let ca = counts.get(&a.id).copied().unwrap_or(0);
            let cb = counts.get(&b.id).copied().unwrap_or(0);
            live(a)
                .cmp(&live(b))
                .then(cb.cmp(&ca))
                .then_with(|| a.topic.cmp(&b.topic))
        });
        if let Some(c) = cands.first() {
            return Ok(Some(c));
        }
    }
    Ok(None)
}

fn check_encoding(path: &Path, c: &ChannelInfo, kind: MessageKind) -> Result<()> {
    if kind.encodings().contains(&c.message_encoding.as_str()) {
        Ok(())
    } else {
        Err(Error::log(
            path,
            LogError::Encoding {
                topic: c.topic.clone(),
                type_name: c.schema_name.clone(),
                encoding: c.message_encoding.clone(),
                expected: kind.encodings().join(" or "),
            },
        ))
    }
}

/// The channels each role reads.
struct Picks<'c> {
    keyframes: Option<&'c ChannelInfo>,
    /// LSD-SLAM's live frames: a second keyframe-type topic named like them.
    live: Option<&'c ChannelInfo>,
    graph: Option<&'c ChannelInfo>,
    est: Option<&'c ChannelInfo>,
    pose: Option<&'c ChannelInfo>,
    imu: Option<&'c ChannelInfo>,
    gnss: Option<&'c ChannelInfo>,
}

/// The GNSS fix kinds.
const GNSS_KINDS: [MessageKind; 2] = [MessageKind::NavSatFix, MessageKind::LocationFix];

impl<'c> Picks<'c> {
    fn all(&self) -> impl Iterator<Item = &'c ChannelInfo> {
        [
            self.keyframes,
            self.live,
            self.graph,
            self.est,
            self.pose,
            self.imu,
            self.gnss,
        ]
        .into_iter()
        .flatten()
    }
}

fn pick<'c>(
    path: &Path,
    options: &ReadOptions,
    channels: &'c BTreeMap<u16, ChannelInfo>,
    counts: &HashMap<u16, u64>,
) -> Result<Picks<'c>> {
    use MessageKind as K;
    let est = match options.est_topic.as_deref() {
        Some(t) => choose(
            path,
            "estimate",
            Some(t),
            &POSE_KINDS,
            channels,
            counts,
            None,
        )?,
        None => None,
    };
    let keyframes = if est.is_some() && options.keyframe_topic.is_none() {
        None
    } else {
        choose(
            path,
            "keyframe",
            options.keyframe_topic.as_deref(),
            &[K::Keyframe],
            channels,
            counts,
            None,
        )?
    };
    let graph = if keyframes.is_some() || options.graph_topic.is_some() {
        choose(
            path,
            "graph",
            options.graph_topic.as_deref(),
            &[K::KeyframeGraph],
            channels,
            counts,
            None,
        )?
    } else {
        None
    };
    if let (Some(p), Some(g)) = (&options.pose_topic, &options.gnss_topic) {
        return Err(Error::invalid(
            "gnss_topic",
            format!(
                "a conversion has one reference: pose topic {p:?} and GNSS topic {g:?} both named"
            ),
        ));
    }
    let pose = if options.gnss_topic.is_some() {
        None
    } else {
        choose(
            path,
            "pose",
            options.pose_topic.as_deref(),
            &POSE_KINDS,
            channels,
            counts,
            est.map(|c| c.id),
        )?
    };
    let gnss = if pose.is_none() {
        choose(
            path,
            "gnss",
            options.gnss_topic.as_deref(),
            &GNSS_KINDS,
            channels,
            counts,
            None,
        )?
    } else {
        None
    };
    let imu = choose(
        path,
        "imu",
        options.imu_topic.as_deref(),
        &[K::Imu],
        channels,
        counts,
        None,
    )?;
    // The live frames of LSD-SLAM (pose only, at frame rate): a keyframe-type
    // topic other than the keyframes', named like them.
    let live = keyframes.and_then(|k| {
        channels.values().find(|c| {
            c.id != k.id && kind_of(c) == Some(K::Keyframe) && c.topic.contains("liveframe")
        })
    });
    let picks = Picks {
        keyframes,
        live,
        graph,
        est,
        pose,
        imu,
        gnss,
    };
    for c in picks.all() {
        if let Some(k) = kind_of(c) {
            check_encoding(path, c, k)?;
        }
    }
    Ok(picks)
}

/// Whichever container `io::container::detect` found, opened.
pub enum AnyContainer {
    /// An MCAP file.
    Mcap(McapFile),
    /// A ROS 1 bag.
    Ros1(Ros1Bag),
    /// A rosbag2 folder or `.db3` file.
    Ros2(Ros2Bag),
}

impl AnyContainer {
    /// Detects the container of `path` and opens it.
    pub fn open(path: impl AsRef<Path>) -> Result<AnyContainer> {
        let path = path.as_ref();
        Ok(match detect(path)? {
            Container::Mcap => AnyContainer::Mcap(McapFile::open(path)?),
            Container::Ros1Bag => AnyContainer::Ros1(Ros1Bag::open(path)?),
            Container::Ros2Folder | Container::Ros2Sqlite => {
                AnyContainer::Ros2(Ros2Bag::open(path)?)
            }
        })
    }

    /// The kind of container.
    pub fn kind(&self) -> Container {
        match self {
            AnyContainer::Mcap(_) => Container::Mcap,
            AnyContainer::Ros1(_) => Container::Ros1Bag,
            AnyContainer::Ros2(b) if b.is_folder() => Container::Ros2Folder,
            AnyContainer::Ros2(_) => Container::Ros2Sqlite,
        }
    }
}

impl MessageSource for AnyContainer {
    fn path(&self) -> &Path {
        match self {
            AnyContainer::Mcap(f) => MessageSource::path(f),
            AnyContainer::Ros1(b) => MessageSource::path(b),
            AnyContainer::Ros2(b) => MessageSource::path(b),
        }
    }

    fn channels(&self) -> Result<BTreeMap<u16, ChannelInfo>> {
        match self {
            AnyContainer::Mcap(f) => MessageSource::channels(f),
            AnyContainer::Ros1(b) => MessageSource::channels(b),
            AnyContainer::Ros2(b) => MessageSource::channels(b),
        }
    }

    fn scan_map<T: Send + Default>(
        &self,
        want: impl Fn(&ChannelInfo) -> bool + Sync,
        map: impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync,
    ) -> Result<MappedScan<T>> {
        match self {
            AnyContainer::Mcap(f) => MessageSource::scan_map(f, want, map),
            AnyContainer::Ros1(b) => MessageSource::scan_map(b, want, map),
            AnyContainer::Ros2(b) => MessageSource::scan_map(b, want, map),
        }
    }

    fn scan_into<T: Send + Default>(
        &self,
        want: impl Fn(&ChannelInfo) -> bool + Sync,
        map: impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync,
        sink: &mut dyn ScanSink<T>,
    ) -> Result<ScanInfo> {
        match self {
            AnyContainer::Mcap(f) => MessageSource::scan_into(f, want, map, sink),
            AnyContainer::Ros1(b) => MessageSource::scan_into(b, want, map, sink),
            AnyContainer::Ros2(b) => MessageSource::scan_into(b, want, map, sink),
        }
    }

    fn inventory(&self) -> Result<Inventory> {
        match self {
            AnyContainer::Mcap(f) => f.inventory(),
            AnyContainer::Ros1(b) => b.inventory(),
            AnyContainer::Ros2(b) => b.inventory(),
        }
    }
}

/// Reads a log of any container (detected from its bytes: MCAP, ROS 1 bag,
/// rosbag2 folder or `.db3`). Keyframes come from `lsd_slam_viewer/keyframeMsg`
/// (+ graph updates), the reference from the first pose type present in the
/// order PoseStamped, PoseWithCovarianceStamped, Odometry, TransformStamped,
/// PoseInFrame, PosesInFrame, TFMessage (unless a topic is named), the IMU
/// from `sensor_msgs/Imu`; SLAM poses without depth from
/// [`ReadOptions::est_topic`] when given.
///
/// A closed ROS 1 bag's index chooses the topics and only their chunks are
/// read; a `.db3` is read once, every row counted and the rows of known
/// types decoded; otherwise every message is read and counted.
///
/// Errors: [`Error::Container`] for a path that is no log slam2world reads;
/// the readers' own ([`Error::Mcap`], [`Error::Bag`]) on damaged files;
/// [`Error::Log`] (naming the file, the topic and its type) for a named topic
/// that is missing, of a type slam2world does not decode or that cannot be
/// read in that role, and for samples that make no trajectory;
/// [`Error::Decode`] (file, topic, message index, log time, byte offset) for
/// a message that does not decode.
pub fn read_log(path: impl AsRef<Path>, options: &ReadOptions) -> Result<Log> {
    read_log_with(path.as_ref(), options, None).map(|r| r.0)
}

/// [`read_log`] with what grows with the log's length left on disk, written
/// as the log is read: the keyframes' pixels in a [`PixelSpill`]
/// ([`Log::pixels`]), the raw IMU ([`Log::imu_on_disk`]) and the reference
/// poses when they come in time order ([`Log::reference_on_disk`]). The log
/// in memory is then its keyframes' poses, live frames and fixes.
pub fn read_log_spilled(path: impl AsRef<Path>, options: &ReadOptions) -> Result<Log> {
    let spill = PixelSpill::new()?;
    let (mut log, at) = read_log_with(path.as_ref(), options, Some(&spill))?;
    log.pixels = Some(std::sync::Arc::new(SpilledKeyframes { spill, at }));
    Ok(log)
}

/// The log, and where the keyframes' pixels went when `spill` is given.
fn read_log_with(
    path: &Path,
    options: &ReadOptions,
    spill: Option<&PixelSpill>,
) -> Result<(Log, Vec<SpilledPixels>)> {
    let source = AnyContainer::open(path)?;
    let container = Some(source.kind());
    match &source {
        // A closed bag's index counts without reading messages.
        AnyContainer::Ros1(b) if b.mode() == ReadMode::Indexed => {
            read_log_spilling(&source, container, Some(b.inventory()?), options, spill)
        }
        // A .db3 is counted and read in one pass: every row counted, the rows
        // of known types decoded; the topics are chosen on those counts.
        AnyContainer::Ros2(b) if b.storage() == Ros2Storage::Sqlite3 => {
            let kinds = KindCache::new();
            let (scan, inv) = b.scan_counted(
                |c| kinds.get(c).is_some(),
                |c, m| decode_message(kinds.get(c), c, m, spill),
            )?;
            let mut gathered = Gathered::new(&kinds, spill.is_some());
            let info = scan.into_sink(&mut gathered);
            let (topics, counts) = inventory_topics(&inv);
            log_of_scan(
                MessageSource::path(b),
                info,
                gathered,
                topics,
                counts,
                container,
                options,
            )
        }
        _ => read_log_spilling(&source, container, None, options, spill),
    }
}

/// The kind of each channel, found once per channel id (the scans' tasks
/// share it).
struct KindCache(Vec<AtomicU8>);

impl KindCache {
    fn new() -> KindCache {
        KindCache((0..1 << 16).map(|_| AtomicU8::new(0)).collect())
    }

    fn get(&self, c: &ChannelInfo) -> Option<MessageKind> {
        // 0 not yet, 1 none, 2 + index in KINDS
        let slot = &self.0[c.id as usize];
        match slot.load(Ordering::Relaxed) {
            0 => {
                let k = kind_of(c);
                let code = k
                    .and_then(|k| KINDS.iter().position(|x| *x == k))
                    .map_or(1, |i| i as u8 + 2);
                slot.store(code, Ordering::Relaxed);
                k
            }
            1 => None,
            code => KINDS.get(code as usize - 2).copied(),
        }
    }

    /// The kind of channel `id` when [`KindCache::get`] has found it.
    fn cached(&self, id: u16) -> Option<MessageKind> {
        match self.0[id as usize].load(Ordering::Relaxed) {
            0 | 1 => None,
            code => KINDS.get(code as usize - 2).copied(),
        }
    }
}

/// [`read_log`] over an opened source. With `counts` (the source's
/// inventory), the topics are chosen from it and only the chosen channels
/// are read; without, every message is read, counted and (when of a known
/// type) decoded.
pub fn read_log_from<S: MessageSource>(
    source: &S,
    container: Option<Container>,
    counts: Option<Inventory>,
    options: &ReadOptions,
) -> Result<Log> {
    read_log_spilling(source, container, counts, options, None).map(|r| r.0)
}

/// [`read_log_from`], the keyframes' pixels into `spill` when given.
fn read_log_spilling<S: MessageSource>(
    source: &S,
    container: Option<Container>,
    counts: Option<Inventory>,
    options: &ReadOptions,
    spill: Option<&PixelSpill>,
) -> Result<(Log, Vec<SpilledPixels>)> {
    let path = source.path();
    let kinds = KindCache::new();
    let decode = |c: &ChannelInfo, m: &RawMessage<'_>| decode_message(kinds.get(c), c, m, spill);
    let mut gathered = Gathered::new(&kinds, spill.is_some());
    let (info, topics, counts) = match counts {
        Some(inv) => {
            // Choose from the index, then read the chosen channels alone.
            let (topics, counts) = inventory_topics(&inv);
            let channels: BTreeMap<u16, ChannelInfo> = inv
                .channels
                .into_iter()
                .map(|c| (c.channel.id, c.channel))
                .collect();
            let wanted: Vec<u16> = pick(path, options, &channels, &counts)?
                .all()
                .map(|c| c.id)
                .collect();
            let info = source.scan_into(|c| wanted.contains(&c.id), decode, &mut gathered)?;
            (info, topics, counts)
        }
        None => {
            // Every message is counted; those of a known type are decoded inside the
            // parallel chunk tasks (decompressed buffers are reused, not kept).
            let info = source.scan_into(|_| true, decode, &mut gathered)?;
            let (topics, counts) = topic_inventory(&info.channels, &gathered.stats);
            (info, topics, counts)
        }
    };
    log_of_scan(path, info, gathered, topics, counts, container, options)
}

/// The log of `path` from a scan of it (the messages of the topics it may
/// use decoded) and the counts of every topic: the topics picked, then
/// keyframes, live frames, poses, IMU and fixes assembled.
fn log_of_scan(
    path: &Path,
    scan: ScanInfo,
    gathered: Gathered<'_>,
    topics: Vec<TopicInfo>,
    counts: HashMap<u16, u64>,
    container: Option<Container>,
    options: &ReadOptions,
) -> Result<(Log, Vec<SpilledPixels>)> {
    let ch = &scan.channels;
    let picks = pick(path, options, ch, &counts)?;
    let mut log = Log {
        path: path.to_path_buf(),
        container,
        keyframe_topic: picks.keyframes.map(|c| c.topic.clone()),
        live_topic: picks.live.map(|c| c.topic.clone()),
        graph_topic: picks.graph.map(|c| c.topic.clone()),
        est_topic: picks.est.map(|c| c.topic.clone()),
        reference_topic: picks.pose.map(|c| c.topic.clone()),
        imu_topic: picks.imu.map(|c| c.topic.clone()),
        gnss_topic: picks.gnss.map(|c| c.topic.clone()),
        topics,
        indexed: scan.mode == ReadMode::Indexed,
        ..Log::default()
    };
    let Gathered {
        mut messages,
        mut poses,
        mut imu,
        graph: graph_updates,
        ..
    } = gathered;
    // The channels read by each step below, in order: once a step is done, the
    // messages no later step reads are dropped and their memory given back, so
    // that a long log's scan and what is built from it are not held together.
    let steps = [
        picks.keyframes,
        picks.graph,
        picks.live,
        picks.est,
        picks.pose,
        picks.imu,
        picks.gnss,
    ]
    .map(|c| c.map(|c| c.id));
    // The channels the messages may hold (the counted ones, then those of the
    // steps left): a step that drops none of them leaves the messages as they
    // are, one that drops all frees them without a look at each (a 1e6-pose
    // log's scan is 100 MB).
    let mut held: Vec<u16> = counts
        .iter()
        .filter(|(_, n)| **n > 0)
        .map(|(id, _)| *id)
        .collect();
    let mut keep_from = |messages: &mut Vec<Mapped>, step: usize| {
        let later = &steps[step..];
        let kept = |id: &u16| later.contains(&Some(*id));
        if held.iter().all(kept) {
            return;
        }
        let before = messages.len();
        if held.iter().any(kept) {
            messages.retain(|m| kept(&m.channel_id));
        } else {
            *messages = Vec::new();
        }
        held = later.iter().flatten().copied().collect();
        if messages.len() < before {
            messages.shrink_to_fit();
            crate::buffer::release_free_memory();
        }
    };
    keep_from(&mut messages, 0);
    let mut spilled = Vec::new();
    if let Some(kf) = picks.keyframes {
        spilled = read_keyframes(
            path,
            &mut messages,
            (kf, picks.graph),
            &graph_updates,
            &mut log,
        )?;
    }
    keep_from(&mut messages, 2);
    if let Some(c) = picks.live {
        log.live = read_live(path, &messages, c)?;
    }
    keep_from(&mut messages, 3);
    // The estimate's and the reference's samples (the same ones when both
    // name the same topic).
    let same = picks.est.is_some() && picks.est.map(|c| c.id) == picks.pose.map(|c| c.id);
    let mut samples_of =
        |c: &ChannelInfo| PoseSamples::of_column(path, poses.remove(&c.id).unwrap_or_default(), c);
    let mut shared = None;
    if let Some(c) = picks.est {
        let samples = samples_of(c)?;
        let rows = samples.rows()?;
        log.frames = Some(read_poses(path, &messages, rows, c, (&None, &None))?);
        if same {
            shared = Some(samples);
        }
    }
    keep_from(&mut messages, 4);
    if let Some(c) = picks.pose {
        let samples = match shared.take() {
            Some(s) => s,
            None => samples_of(c)?,
        };
        match samples {
            // A bounded read's reference stays on disk when its times are in
            // order (it is checked when read back).
            PoseSamples::Disk(rows, true) => {
                log.reference_on_disk = Some(std::sync::Arc::new(TrajectoryFile::new(
                    rows, path, &c.topic,
                )?));
            }
            samples => {
                log.reference = Some(read_poses(
                    path,
                    &messages,
                    samples.rows()?,
                    c,
                    (&options.tf_parent, &options.tf_child),
                )?);
            }
        }
    }
    keep_from(&mut messages, 5);
    if let Some(c) = picks.imu {
        // The column's first bad message is the error, wherever its rows are.
        let rows = imu
            .remove(&c.id)
            .unwrap_or_default()
            .into_rows(path, &c.topic)?;
        match rows.spill {
            Some(spill) => {
                log.imu_on_disk = Some(std::sync::Arc::new(ImuOnDisk::new(spill, path, c)?));
            }
            None => {
                let ImuRows {
                    times, gyro, accel, ..
                } = rows;
                log.imu = Some(imu_by_time(path, &c.topic, (times, gyro, accel))?);
            }
        }
    }
    keep_from(&mut messages, 6);
    if let Some(c) = picks.gnss {
        log.gnss = Some(read_fixes(path, &messages, c)?);
    }
    Ok((log, spilled))
}

/// A keyframe message without its point cloud, and its pixels (for
/// keyframes; live frames have none).
type DecodedKeyframe = (KeyframeMsg<'static>, Option<Pixels>);

/// A keyframe message's pixels.
enum Pixels {
    /// Split into inverse depth, variance and RGB.
    Arrays(Vec<f32>, Vec<f32>, Vec<u8>),
    /// Left in a [`PixelSpill`].
    Spilled(SpilledPixels),
    /// The spill could not be written (the error's text).
    Failed(String),
}

/// What a message becomes inside the chunk task. Errors keep what and where
/// in the message; the file, topic and message index are added when the
/// message is used.
#[derive(Default)]
enum Decoded {
    Keyframe(Box<std::result::Result<DecodedKeyframe, WireError>>),
    Graph(std::result::Result<Vec<(i32, [f64; 7])>, WireError>),
    /// A live frame (a keyframe message with `isKeyframe` false): its time and
    /// `camToWorld`, all that is read of one, unboxed (a log holds one per
    /// camera frame).
    Frame {
        time: f64,
        cam_to_world: [f64; 7],
    },
    /// A checked, normalised pose sample.
    Pose(decode::PoseSample),
    Tf(Vec<StampedPose>),
    Imu(decode::ImuMsg),
    /// Boxed: a fix with its covariance is twice a pose's size, and every
    /// decoded message of a scan is as large as the largest variant.
    Fix(Box<GnssFix>),
    Error(WireError),
    #[default]
    Other,
}

/// The samples of one channel as its messages come (`R`: the rows they
/// make, in message order), and the first message that gave none.
#[derive(Clone, Default)]
struct Column<R> {
    rows: R,
    /// Messages given (the next one's index on its topic).
    n: usize,
    /// The first message that is no sample: its index, log time and why.
    error: Option<(usize, u64, WireError)>,
}

/// The rows of a [`Column`].
trait Rows: Default {
    /// Room for `n` more rows, when the allocator has it (a hint).
    fn reserve(&mut self, n: usize);

    /// The row of a decoded message, or why it gives none.
    fn add(&mut self, value: Decoded) -> std::result::Result<(), WireError>;
}

impl<R: Rows> Column<R> {
    fn push(&mut self, m: Mapped) {
        let i = self.n;
        self.n += 1;
        if self.error.is_some() {
            return;
        }
        if let Err(e) = self.rows.add(m.value) {
            self.error = Some((i, m.log_time, e));
        }
    }

    /// The rows, or the first message's error (`path`, `topic` named).
    fn into_rows(self, path: &Path, topic: &str) -> Result<R> {
        match self.error {
            Some((i, log_time, e)) => Err(at(path, topic, i, log_time, e)),
            None => Ok(self.rows),
        }
    }
}

/// Pose samples: the rows of a [`Trajectory`], in memory or (a bounded
/// read's) on disk.
#[derive(Default)]
struct PoseRows {
    times: Vec<f64>,
    positions: Vec<Vector3<f64>>,
    orientations: Vec<UnitQuaternion<f64>>,
    /// Where the rows go instead, when set: `t x y z qx qy qz qw`.
    spill: Option<RowSpill>,
    /// The latest time given, and whether a time ever went back (or was no
    /// number): the rows on disk are then not a trajectory as they are.
    last: f64,
    unordered: bool,
}

impl Rows for PoseRows {
    fn reserve(&mut self, n: usize) {
        if self.spill.is_some() {
            return;
        }
        let _ = self.times.try_reserve_exact(n);
        let _ = self.positions.try_reserve_exact(n);
        let _ = self.orientations.try_reserve_exact(n);
    }

    fn add(&mut self, value: Decoded) -> std::result::Result<(), WireError> {
        match value {
            Decoded::Pose((t, p, [x, y, z, w])) => {
                match &mut self.spill {
                    Some(spill) => {
                        // Times only go forward (NaN compares false).
                        let forward = spill.is_empty() || t >= self.last;
                        self.unordered |= !forward;
                        self.last = t;
                        spill.push(&[t, p[0], p[1], p[2], x, y, z, w]);
                    }
                    None => {
                        self.times.push(t);
                        self.positions.push(Vector3::from(p));
                        self.orientations
                            .push(UnitQuaternion::new_unchecked(Quaternion::new(w, x, y, z)));
                    }
                }
                Ok(())
            }
            Decoded::Error(e) => Err(e),
            _ => Err(WireError::schema("not a pose message")),
        }
    }
}

/// A pose channel's samples after the scan: in memory, or on disk with
/// whether their times never go back.
enum PoseSamples {
    Memory(PoseRows),
    Disk(std::sync::Arc<RowFile>, bool),
}

impl PoseSamples {
    /// The samples of channel `c`'s column; the column's first bad message
    /// is the error.
    fn of_column(path: &Path, column: PoseColumn, c: &ChannelInfo) -> Result<PoseSamples> {
        let mut rows = column.into_rows(path, &c.topic)?;
        match rows.spill.take() {
            Some(spill) => {
                let what = format!("the poses of {} in {}", c.topic, path.display());
                let file = spill.finish(&what)?;
                Ok(PoseSamples::Disk(
                    std::sync::Arc::new(file),
                    !rows.unordered,
                ))
            }
            None => Ok(PoseSamples::Memory(rows)),
        }
    }

    /// The rows in memory: a copy, or read back from disk.
    fn rows(&self) -> Result<PoseRows> {
        match self {
            PoseSamples::Memory(r) => Ok(PoseRows {
                times: r.times.clone(),
                positions: r.positions.clone(),
                orientations: r.orientations.clone(),
                ..PoseRows::default()
            }),
            PoseSamples::Disk(file, _) => {
                let n = file.len();
                let mut r = PoseRows {
                    times: Vec::with_capacity(n),
                    positions: Vec::with_capacity(n),
                    orientations: Vec::with_capacity(n),
                    ..PoseRows::default()
                };
                file.for_each_piece(ROW_PIECE, |_, values| {
                    for v in values.chunks_exact(8) {
                        let (t, p, q) = crate::io::spill::pose_of_row(v);
                        r.times.push(t);
                        r.positions.push(p);
                        r.orientations.push(q);
                    }
                    Ok(())
                })?;
                Ok(r)
            }
        }
    }
}

/// Finite IMU samples: the rows of [`ImuSamples`], in memory or (a
/// bounded read's) on disk.
#[derive(Default)]
struct ImuRows {
    times: Vec<f64>,
    gyro: Vec<Vector3<f64>>,
    accel: Vec<Vector3<f64>>,
    /// Where the rows go instead, when set: `t gx gy gz ax ay az`.
    spill: Option<RowSpill>,
}

impl Rows for ImuRows {
    fn reserve(&mut self, n: usize) {
        if self.spill.is_some() {
            return;
        }
        let _ = self.times.try_reserve_exact(n);
        let _ = self.gyro.try_reserve_exact(n);
        let _ = self.accel.try_reserve_exact(n);
    }

    fn add(&mut self, value: Decoded) -> std::result::Result<(), WireError> {
        match value {
            Decoded::Imu(s)
                if s.time.is_finite()
                    && s.gyro.iter().chain(s.accel.iter()).all(|v| v.is_finite()) =>
            {
                match &mut self.spill {
                    Some(spill) => {
                        let ([gx, gy, gz], [ax, ay, az]) = (s.gyro, s.accel);
                        spill.push(&[s.time, gx, gy, gz, ax, ay, az]);
                    }
                    None => {
                        self.times.push(s.time);
                        self.gyro.push(Vector3::from(s.gyro));
                        self.accel.push(Vector3::from(s.accel));
                    }
                }
                Ok(())
            }
            Decoded::Imu(s) => Err(WireError::value(format!("non-finite IMU sample {s:?}"))),
            Decoded::Error(e) => Err(e),
            _ => Err(WireError::schema("not an IMU message")),
        }
    }
}

/// The pose samples of one channel.
type PoseColumn = Column<PoseRows>;

/// The IMU samples of one channel.
type ImuColumn = Column<ImuRows>;

/// Every kind, for the per-channel cache of [`read_log_from`].
const KINDS: [MessageKind; 12] = [
    MessageKind::Keyframe,
    MessageKind::KeyframeGraph,
    MessageKind::PoseStamped,
    MessageKind::PoseWithCovarianceStamped,
    MessageKind::Odometry,
    MessageKind::TransformStamped,
    MessageKind::PoseInFrame,
    MessageKind::PosesInFrame,
    MessageKind::Tf,
    MessageKind::Imu,
    MessageKind::NavSatFix,
    MessageKind::LocationFix,
];

fn decode_message(
    kind: Option<MessageKind>,
    c: &ChannelInfo,
    m: &RawMessage<'_>,
    spill: Option<&PixelSpill>,
) -> Decoded {
    use MessageKind as K;
    let enc = c.message_encoding.as_str();
    let err = Decoded::Error;
    match kind {
        // The point cloud goes from the (decompressed) message bytes straight
        // into the keyframe's arrays, or into the spill: no copy of the
        // message is kept.
        Some(K::Keyframe) => match decode::keyframe_ros1(m.data) {
            Ok(k) if !k.is_keyframe => Decoded::Frame {
                time: k.time,
                cam_to_world: k.cam_to_world,
            },
            r => Decoded::Keyframe(Box::new(r.map(|k| {
                let arrays = match spill {
                    None => {
                        let (d, v, c) = decode::split_pointcloud(k.pointcloud);
                        Pixels::Arrays(d, v, c)
                    }
                    Some(s) => match s.put(k.pointcloud) {
                        Ok(at) => Pixels::Spilled(at),
                        Err(e) => Pixels::Failed(e),
                    },
                };
                (
                    KeyframeMsg {
                        pointcloud: &[],
                        ..k
                    },
                    Some(arrays),
                )
            }))),
        },
        Some(K::KeyframeGraph) => Decoded::Graph(decode::graph_ros1(m.data)),
        Some(K::Tf) => match decode::poses(K::Tf, enc, m.data) {
            Ok(v) => Decoded::Tf(v),
            Err(e) => err(e),
        },
        Some(K::Imu) => match decode::imu(enc, m.data) {
            Ok(s) => Decoded::Imu(s),
            Err(e) => err(e),
        },
        Some(k @ (K::NavSatFix | K::LocationFix)) => match gnss::gnss_fix(k, enc, m.data) {
            Ok(f) => Decoded::Fix(Box::new(f)),
            Err(e) => err(e),
        },
        Some(k) if k.is_pose() => {
            match decode::pose_sample(k, enc, m.data).and_then(checked_sample) {
                Ok(s) => Decoded::Pose(s),
                Err(e) => err(e),
            }
        }
        _ => Decoded::Other,
    }
}

type Mapped = MappedMessage<Decoded>;

/// The decode error of message `i` of `topic`.
fn at(path: &Path, topic: &str, i: usize, log_time: u64, e: WireError) -> Error {
    Error::Decode {
        path: path.to_path_buf(),
        topic: topic.to_string(),
        index: i,
        log_time,
        source: e,
    }
}

struct Entry {
    msg: KeyframeMsg<'static>,
    arrays: Pixels,
    topic_index: usize,
    pose: [f64; 7],
    pose_source: String,
}

/// The keyframes of channel `kf` (the latest version of each id), their
/// poses from `graph`'s messages where one came after the version
/// (`updates`, applied as the log was scanned).
fn read_keyframes(
    path: &Path,
    messages: &mut [Mapped],
    (kf, graph): (&ChannelInfo, Option<&ChannelInfo>),
    updates: &GraphUpdates,
    log: &mut Log,
) -> Result<Vec<SpilledPixels>> {
    let graph_id = graph.map(|g| g.id);
    let graph_topic = graph.map(|g| g.topic.as_str()).unwrap_or_default();
    let mut order: Vec<i32> = Vec::new();
    let mut latest: HashMap<i32, Entry> = HashMap::new();
    let mut kf_index = 0usize;
    let mut graph_index = 0usize;
    for m in messages.iter_mut() {
        if m.channel_id == kf.id {
            let i = kf_index;
            kf_index += 1;
            let log_time = m.log_time;
            let fail = |e: WireError| at(path, &kf.topic, i, log_time, e);
            let (msg, arrays) = match &mut m.value {
                Decoded::Keyframe(r) => match r.as_mut() {
                    Ok((msg, arrays)) => (msg, arrays),
                    Err(e) => return Err(fail(e.clone())),
                },
                // A live frame: no pixels, no keyframe.
                Decoded::Frame { .. } => continue,
                _ => return Err(fail(WireError::schema("not a keyframe message"))),
            };
            // Moved out: each version's arrays are used once (the latest wins).
            let Some(arrays) = arrays.take() else {
                continue;
            };
            if !latest.contains_key(&msg.id) {
                order.push(msg.id);
            }
            latest.insert(
                msg.id,
                Entry {
                    msg: msg.clone(),
                    arrays,
                    topic_index: i,
                    pose: msg.cam_to_world,
                    pose_source: format!("topic {}: message {i}", kf.topic),
                },
            );
        } else if Some(m.channel_id) == graph_id {
            // Its poses were applied as the log was scanned.
            let i = graph_index;
            graph_index += 1;
            match &m.value {
                Decoded::Graph(Ok(_)) => {}
                Decoded::Graph(Err(e)) => {
                    return Err(at(path, graph_topic, i, m.log_time, e.clone()))
                }
                _ => {
                    return Err(at(
                        path,
                        graph_topic,
                        i,
                        m.log_time,
                        WireError::schema("not a graph message"),
                    ))
                }
            }
        }
    }
    if let Some(g) = graph {
        if let Some(a) = updates.applied.get(&(kf.id, g.id)) {
            for (id, (i, c2w)) in &a.poses {
                if let Some(e) = latest.get_mut(id) {
                    e.pose = *c2w;
                    e.pose_source = format!("topic {graph_topic}: message {i}");
                }
            }
            log.graph_updates = a.updates;
        }
    }
    log.keyframe_messages = kf_index;
    log.graph_messages = graph_index;
    let mut entries: Vec<Entry> = order.iter().filter_map(|id| latest.remove(id)).collect();
    let keyframes: Result<Vec<(Keyframe, Option<SpilledPixels>)>> = entries
        .par_iter_mut()
        .map(|e| to_keyframe(path, &kf.topic, e))
        .collect();
    let (keyframes, spilled): (Vec<Keyframe>, Vec<Option<SpilledPixels>>) =
        keyframes?.into_iter().unzip();
    log.keyframes = keyframes;
    Ok(spilled.into_iter().flatten().collect())
}

/// The keyframe of `e`, with where its pixels are when they were spilled
/// (the keyframe then holds none).
fn to_keyframe(
    path: &Path,
    topic: &str,
    e: &mut Entry,
) -> Result<(Keyframe, Option<SpilledPixels>)> {
    let m = &e.msg;
    let what = |what: String| {
        Error::log(
            path,
            LogError::Keyframe {
                topic: topic.to_string(),
                index: e.topic_index,
                id: m.id,
                what,
            },
        )
    };
    if e.pose.iter().any(|v| !v.is_finite()) {
        return Err(what(format!(
            "non-finite camToWorld {:?} (from {})",
            e.pose, e.pose_source
        )));
    }
    let pose = Sim3::from_lsd_slam(&e.pose)
        .map_err(|err| what(format!("camToWorld {:?}: {err}", e.pose)))?;
    let camera = PinholeCamera::try_new(m.fx, m.fy, m.cx, m.cy, m.width, m.height)
        .map_err(|err| what(format!("camera: {err}")))?;
    match std::mem::replace(&mut e.arrays, Pixels::Failed(String::new())) {
        Pixels::Arrays(idepth, var, color) => {
            Keyframe::try_new(m.id, m.time, pose, camera, idepth, Some(var), Some(color))
                .map(|k| (k, None))
                .map_err(|err| what(err.to_string()))
        }
        Pixels::Spilled(at) => Keyframe::without_pixels(m.id, m.time, pose, camera, at.pixels)
            .map(|k| (k, Some(at)))
            .map_err(|err| what(err.to_string())),
        Pixels::Failed(reason) => Err(what(format!(
            "its pixels could not be set aside in the temporary folder (TMPDIR): {reason}"
        ))),
    }
}

/// The tracked poses of the live-frame channel `c` (see [`Log::live`]);
/// `None` when it has no message.
fn read_live(path: &Path, messages: &[Mapped], c: &ChannelInfo) -> Result<Option<Trajectory>> {
    // A long log has a live frame per camera frame: the rows are made once,
    // at their exact size, and sorted only when they came out of order.
    let n = messages.iter().filter(|m| m.channel_id == c.id).count();
    if n == 0 {
        return Ok(None);
    }
    let mut times = Vec::with_capacity(n);
    let mut positions = Vec::with_capacity(n);
    let mut orientations = Vec::with_capacity(n);
    for (i, m) in messages.iter().filter(|m| m.channel_id == c.id).enumerate() {
        let fail = |e: WireError| at(path, &c.topic, i, m.log_time, e);
        let (time, cam_to_world) = match &m.value {
            Decoded::Frame { time, cam_to_world } => (*time, cam_to_world),
            Decoded::Keyframe(r) => match r.as_ref() {
                Ok((msg, _)) => (msg.time, &msg.cam_to_world),
                Err(e) => return Err(fail(e.clone())),
            },
            _ => return Err(fail(WireError::schema("not a keyframe message"))),
        };
        let pose = Sim3::from_lsd_slam(cam_to_world).map_err(|e| {
            Error::samples(
                path,
                &c.topic,
                format!("frame {i}: camToWorld {cam_to_world:?}: {e}"),
            )
        })?;
        if !time.is_finite() {
            return Err(Error::samples(
                path,
                &c.topic,
                format!("frame {i}: time {time} is not finite"),
            ));
        }
        times.push(time);
        positions.push(pose.translation);
        orientations.push(pose.rotation);
    }
    // By time, a repeated time keeping its first frame.
    if let Some(order) = time_order(&times, true) {
        reorder(&mut times, &order);
        reorder(&mut positions, &order);
        reorder(&mut orientations, &order);
    }
    Trajectory::try_new(times, positions, Some(orientations))
        .map(Some)
        .map_err(|e| Error::samples(path, &c.topic, e.to_string()))
}

/// The order that sorts `times` (equal times kept in their order; with
/// `dedup`, only the first of them), or `None` when they are in that order
/// already: strictly increasing with `dedup`, else non-decreasing.
fn time_order(times: &[f64], dedup: bool) -> Option<Vec<usize>> {
    let ordered = if dedup {
        times.is_sorted_by(|a, b| a < b)
    } else {
        times.is_sorted_by(|a, b| a <= b)
    };
    if ordered {
        return None;
    }
    let mut order: Vec<usize> = (0..times.len()).collect();
    order.sort_by(|&a, &b| times[a].total_cmp(&times[b]));
    if dedup {
        order.dedup_by(|b, a| times[*a] == times[*b]);
    }
    Some(order)
}

/// `v`'s rows in `order` (from [`time_order`]).
fn reorder<T: Copy>(v: &mut Vec<T>, order: &[usize]) {
    *v = order.iter().map(|&k| v[k]).collect();
}

/// The pose samples of a pose channel: its column (gathered as the log was
/// scanned), or for TF its messages narrowed to one frame pair (`tf`: the
/// parent and child asked for; the most frequent pair that fits).
fn read_poses(
    path: &Path,
    messages: &[Mapped],
    rows: PoseRows,
    c: &ChannelInfo,
    tf: (&Option<String>, &Option<String>),
) -> Result<Trajectory> {
    if kind_of(c) != Some(MessageKind::Tf) {
        let PoseRows {
            mut times,
            mut positions,
            mut orientations,
            ..
        } = rows;
        if let Some(order) = time_order(&times, false) {
            reorder(&mut times, &order);
            reorder(&mut positions, &order);
            reorder(&mut orientations, &order);
        }
        return Trajectory::try_new(times, positions, Some(orientations))
            .map_err(|e| Error::samples(path, &c.topic, e.to_string()));
    }
    let mut decoded: Vec<&Vec<StampedPose>> = Vec::new();
    let mine = messages.iter().filter(|m| m.channel_id == c.id);
    for (i, m) in mine.enumerate() {
        match &m.value {
            Decoded::Tf(v) => decoded.push(v),
            Decoded::Error(e) => return Err(at(path, &c.topic, i, m.log_time, e.clone())),
            _ => {
                return Err(at(
                    path,
                    &c.topic,
                    i,
                    m.log_time,
                    WireError::schema("not a TF message"),
                ))
            }
        }
    }
    let no_transform = || {
        Error::log(
            path,
            LogError::NoTransform {
                topic: c.topic.clone(),
                parent: tf.0.clone(),
                child: tf.1.clone(),
            },
        )
    };
    let pair = match tf {
        (Some(p), Some(ch)) => (p.clone(), ch.clone()),
        (p, ch) => {
            let mut freq: BTreeMap<(String, String), usize> = BTreeMap::new();
            for s in decoded.iter().copied().flatten() {
                let ok_p = p.as_ref().is_none_or(|p| *p == s.frame_id);
                let ok_c = ch.as_ref().is_none_or(|ch| *ch == s.child_frame_id);
                if ok_p && ok_c {
                    *freq
                        .entry((s.frame_id.clone(), s.child_frame_id.clone()))
                        .or_default() += 1;
                }
            }
            match freq
                .into_iter()
                .max_by(|a, b| a.1.cmp(&b.1).then_with(|| b.0.cmp(&a.0)))
            {
                Some((pair, _)) => pair,
                None => return Err(no_transform()),
            }
        }
    };
    let mut samples: Vec<(usize, &StampedPose)> = Vec::new();
    for (i, v) in decoded.iter().enumerate() {
        for s in v.iter() {
            if s.frame_id == pair.0 && s.child_frame_id == pair.1 {
                samples.push((i, s));
            }
        }
    }
    if samples.is_empty() {
        return Err(Error::log(
            path,
            LogError::NoTransform {
                topic: c.topic.clone(),
                parent: Some(pair.0),
                child: Some(pair.1),
            },
        ));
    }
    samples.sort_by(|a, b| a.1.time.total_cmp(&b.1.time));
    trajectory_of(
        path,
        &c.topic,
        samples
            .iter()
            .map(|(i, s)| (*i, s.time, s.position, s.orientation)),
    )
}

/// Checks a pose sample (finite, non-zero quaternion) and normalises its quaternion.
fn checked_sample(s: decode::PoseSample) -> std::result::Result<decode::PoseSample, WireError> {
    let (time, position, orientation) = s;
    let finite = time.is_finite()
        && position
            .iter()
            .chain(orientation.iter())
            .all(|v| v.is_finite());
    let [x, y, z, w] = orientation;
    let norm = (x * x + y * y + z * z + w * w).sqrt();
    if !finite || norm < 1e-9 {
        return Err(WireError::value(format!(
            "{} pose (time {}, position {position:?}, orientation {orientation:?})",
            if finite {
                "zero-quaternion"
            } else {
                "non-finite"
            },
            crate::error::num(time)
        )));
    }
    Ok((time, position, [x / norm, y / norm, z / norm, w / norm]))
}

/// Checks and converts `(message index, time, position, orientation xyzw)` samples.
fn trajectory_of(
    path: &Path,
    topic: &str,
    samples: impl ExactSizeIterator<Item = (usize, f64, [f64; 3], [f64; 4])>,
) -> Result<Trajectory> {
    let n = samples.len();
    let mut times = Vec::with_capacity(n);
    let mut positions = Vec::with_capacity(n);
    let mut orientations = Vec::with_capacity(n);
    for (i, time, position, orientation) in samples {
        let (time, position, [x, y, z, w]) = checked_sample((time, position, orientation))
            .map_err(|e| Error::samples(path, topic, format!("message {i}: {e}")))?;
        times.push(time);
        positions.push(Vector3::from(position));
        orientations.push(UnitQuaternion::new_unchecked(Quaternion::new(w, x, y, z)));
    }
    Trajectory::try_new(times, positions, Some(orientations))
        .map_err(|e| Error::samples(path, topic, e.to_string()))
}

/// The IMU samples of `topic` by time (of samples with the same stamp, the
/// first given), checked.
fn imu_by_time(
    path: &Path,
    topic: &str,
    (mut times, mut gyro, mut accel): (Vec<f64>, Vec<Vector3<f64>>, Vec<Vector3<f64>>),
) -> Result<ImuSamples> {
    if let Some(order) = time_order(&times, true) {
        reorder(&mut times, &order);
        reorder(&mut gyro, &order);
        reorder(&mut accel, &order);
    }
    ImuSamples::try_new(times, gyro, accel).map_err(|e| Error::samples(path, topic, e.to_string()))
}

/// The raw IMU samples of a log read by [`read_log_spilled`], left on disk
/// ([`Log::imu_on_disk`]) until the step that uses them.
#[derive(Debug)]
pub struct ImuOnDisk {
    samples: RowFile,
    path: PathBuf,
    topic: String,
}

impl ImuOnDisk {
    /// The samples `spill` took of channel `c`, on disk.
    fn new(spill: RowSpill, path: &Path, c: &ChannelInfo) -> Result<ImuOnDisk> {
        let what = format!("the IMU samples of {} in {}", c.topic, path.display());
        Ok(ImuOnDisk {
            samples: spill.finish(&what)?,
            path: path.to_path_buf(),
            topic: c.topic.clone(),
        })
    }

    /// Samples held (before those with a repeated time are dropped).
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// True without samples.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// The samples, read back and sorted by time as [`Log::imu`] is.
    pub fn load(&self) -> Result<ImuSamples> {
        let n = self.len();
        let (mut t, mut g, mut a) = (
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
        );
        self.samples.for_each_piece(ROW_PIECE, |_, values| {
            for r in values.chunks_exact(7) {
                t.push(r[0]);
                g.push(Vector3::new(r[1], r[2], r[3]));
                a.push(Vector3::new(r[4], r[5], r[6]));
            }
            Ok(())
        })?;
        imu_by_time(&self.path, &self.topic, (t, g, a))
    }
}

/// What a log's scan is gathered into, as the scan gives it: the pose and
/// IMU samples of each channel straight into columns (a long log's
/// messages are mostly these: a scan entry is 96 bytes, a column row 64 or
/// 56), every other message kept as it came.
struct Gathered<'k> {
    kinds: &'k KindCache,
    messages: Vec<Mapped>,
    poses: HashMap<u16, PoseColumn>,
    imu: HashMap<u16, ImuColumn>,
    stats: ChannelStats,
    /// Messages expected per channel ([`ScanSink::expect`]).
    expected: HashMap<u16, u64>,
    /// Of those, what the channels kept in `messages` so far expect.
    expected_messages: usize,
    /// The graph messages' poses, applied as they come (the messages are
    /// kept without them).
    graph: GraphUpdates,
    /// The pose and IMU columns go to disk (a bounded read: the reference
    /// and the IMU wait there for the steps that use them).
    on_disk: bool,
}

/// Graph messages applied to the keyframes as the scan gives them, for every
/// pair of a keyframe channel and a graph channel: what `read_keyframes`
/// would find going through the messages in order. An LSD-SLAM graph
/// message holds every keyframe's pose so far, so that the messages of a
/// long log grow as the square of its keyframes (37 MB for the 20x log's 467
/// graph messages): they are not kept.
#[derive(Debug, Default)]
struct GraphUpdates {
    /// The keyframe ids each keyframe channel has given so far.
    seen: HashMap<u16, HashSet<i32>>,
    /// Per (keyframe channel, graph channel).
    applied: HashMap<(u16, u16), Applied>,
}

/// The graph messages of one channel applied to the keyframes of one channel.
#[derive(Debug, Default)]
struct Applied {
    /// For each id, the pose of the last graph message after the id's latest
    /// keyframe version, with that message's index on its topic.
    poses: HashMap<i32, (usize, [f64; 7])>,
    /// Poses given to a keyframe, over every graph message.
    updates: usize,
}

impl GraphUpdates {
    /// A version of keyframe `id` on channel `k`: its own pose again.
    fn keyframe(&mut self, k: u16, id: i32) {
        self.seen.entry(k).or_default().insert(id);
        for ((kk, _), a) in self.applied.iter_mut() {
            if *kk == k {
                a.poses.remove(&id);
            }
        }
    }

    /// Graph message `index` of channel `g`: each pose given to the
    /// keyframes seen so far.
    fn graph(&mut self, g: u16, index: usize, frames: &[(i32, [f64; 7])]) {
        for (k, ids) in &self.seen {
            let a = self.applied.entry((*k, g)).or_default();
            for (id, pose) in frames {
                if ids.contains(id) {
                    a.poses.insert(*id, (index, *pose));
                    a.updates += 1;
                }
            }
        }
    }
}

impl<'k> Gathered<'k> {
    fn new(kinds: &'k KindCache, on_disk: bool) -> Gathered<'k> {
        Gathered {
            kinds,
            messages: Vec::new(),
            poses: HashMap::new(),
            imu: HashMap::new(),
            stats: ChannelStats::new(),
            expected: HashMap::new(),
            expected_messages: 0,
            graph: GraphUpdates::default(),
            on_disk,
        }
    }
}

impl ScanSink<Decoded> for Gathered<'_> {
    fn expect(&mut self, counts: &BTreeMap<u16, u64>) {
        self.expected = counts.iter().map(|(id, n)| (*id, *n)).collect();
    }

    fn message(&mut self, mut m: Mapped) {
        // The first message of its channel: room for as many as expected.
        let index = self.stats.0[m.channel_id as usize].0;
        let expected = match index {
            0 => self.expected.get(&m.channel_id).map_or(0, |&n| n as usize),
            _ => 0,
        };
        match &mut m.value {
            Decoded::Keyframe(r) => {
                if let Ok((msg, _)) = r.as_ref() {
                    self.graph.keyframe(m.channel_id, msg.id);
                }
            }
            Decoded::Graph(Ok(frames)) => {
                let frames = std::mem::take(frames);
                let index = usize::try_from(index).unwrap_or(usize::MAX);
                self.graph.graph(m.channel_id, index, &frames);
            }
            _ => {}
        }
        self.stats.add(m.channel_id, m.log_time);
        // A decode error goes where the channel's samples go.
        let kind = match &m.value {
            Decoded::Error(_) => self.kinds.cached(m.channel_id),
            _ => None,
        };
        enum Goes {
            Imu,
            Poses,
            Kept,
        }
        let goes = match (&m.value, kind) {
            (Decoded::Imu(_), _) | (_, Some(MessageKind::Imu)) => Goes::Imu,
            (Decoded::Pose(_), _) => Goes::Poses,
            (_, Some(k)) if k.is_pose() && k != MessageKind::Tf => Goes::Poses,
            _ => Goes::Kept,
        };
        match goes {
            Goes::Imu => {
                let on_disk = self.on_disk;
                let col = self.imu.entry(m.channel_id).or_insert_with(|| ImuColumn {
                    rows: ImuRows {
                        spill: on_disk.then(|| RowSpill::new(7)),
                        ..ImuRows::default()
                    },
                    ..ImuColumn::default()
                });
                col.rows.reserve(expected);
                col.push(m);
            }
            Goes::Poses => {
                let on_disk = self.on_disk;
                let col = self
                    .poses
                    .entry(m.channel_id)
                    .or_insert_with(|| PoseColumn {
                        rows: PoseRows {
                            spill: on_disk.then(|| RowSpill::new(8)),
                            ..PoseRows::default()
                        },
                        ..PoseColumn::default()
                    });
                col.rows.reserve(expected);
                col.push(m);
            }
            Goes::Kept => {
                self.expected_messages += expected;
                let more = self.expected_messages.saturating_sub(self.messages.len());
                let _ = self.messages.try_reserve_exact(more);
                self.messages.push(m);
            }
        }
    }

    fn restart(&mut self) {
        *self = Gathered::new(self.kinds, self.on_disk);
    }
}

/// The fixes of a GNSS channel, in log order, checked by
/// [`GnssFixes::from_fixes`] (its index is the message's on the topic).
fn read_fixes(path: &Path, messages: &[Mapped], c: &ChannelInfo) -> Result<GnssFixes> {
    let mut fixes = Vec::new();
    for (i, m) in messages.iter().filter(|m| m.channel_id == c.id).enumerate() {
        match &m.value {
            Decoded::Fix(f) => fixes.push(**f),
            Decoded::Error(e) => return Err(at(path, &c.topic, i, m.log_time, e.clone())),
            _ => {
                return Err(at(
                    path,
                    &c.topic,
                    i,
                    m.log_time,
                    WireError::schema("not a GNSS message"),
                ))
            }
        }
    }
    GnssFixes::from_fixes(fixes, TimeBase::Source).map_err(|e| match e {
        Error::InvalidFix { .. } => Error::samples(path, &c.topic, e.to_string()),
        e => e,
    })
}

/// What `slam2world inspect` shows of a log of any container.
#[derive(Clone, Debug)]
pub struct Inspection {
    /// The file or folder.
    pub path: PathBuf,
    /// Its container.
    pub container: Container,
    /// The MCAP Header record's profile (`ros1`, `ros2`, …); `ros1` / `ros2` for bags.
    pub profile: String,
    /// Indexed or linear reading.
    pub mode: ReadMode,
    /// True when the counts came from the index without reading a chunk.
    pub from_index: bool,
    /// Every topic, with its count and time range.
    pub topics: Vec<TopicInfo>,
    /// `(role, topic)` for keyframes, graph, reference and imu, where one is found.
    pub picks: Vec<(&'static str, String)>,
}

/// The topics of `source` with their counts (from the index where there is
/// one) and the topics [`read_log`] would use by default.
pub fn inspect_source<S: MessageSource>(
    source: &S,
    container: Container,
    profile: String,
) -> Result<Inspection> {
    let inv = source.inventory()?;
    let (topics, counts) = inventory_topics(&inv);
    let channels: BTreeMap<u16, ChannelInfo> = inv
        .channels
        .into_iter()
        .map(|c| (c.channel.id, c.channel))
        .collect();
    use MessageKind as K;
    let roles: [(&'static str, &[MessageKind]); 5] = [
        ("keyframes", &[K::Keyframe]),
        ("graph", &[K::KeyframeGraph]),
        ("reference", &POSE_KINDS),
        ("imu", &[K::Imu]),
        ("gnss", &GNSS_KINDS),
    ];
    let mut picks = Vec::new();
    for (role, kinds) in roles {
        if let Some(c) = choose(source.path(), role, None, kinds, &channels, &counts, None)? {
            picks.push((role, c.topic.clone()));
        }
    }
    Ok(Inspection {
        path: source.path().to_path_buf(),
        container,
        profile,
        mode: inv.mode,
        from_index: inv.from_index,
        topics,
        picks,
    })
}

/// Lists the topics of the log at `path` (any container), their types,
/// counts and time ranges, and what slam2world would read from it.
pub fn inspect_log(path: impl AsRef<Path>) -> Result<Inspection> {
    let source = AnyContainer::open(path.as_ref())?;
    let profile = match &source {
        AnyContainer::Mcap(f) => f.profile(),
        AnyContainer::Ros1(_) => "ros1".into(),
        AnyContainer::Ros2(_) => "ros2".into(),
    };
    inspect_source(&source, source.kind(), profile)
}

/// An [`Error::Log`] as the [`Error::Mcap`] that `read_mcap` has always given
/// (the same text); other errors unchanged.
fn as_mcap(e: Error) -> Error {
    match e {
        Error::Log { path, reason } => Error::Mcap {
            path,
            reason: reason.to_string(),
        },
        other => other,
    }
}

/// Reads an MCAP log: [`read_log`] for a file that must be MCAP.
/// Keyframes come from `lsd_slam_viewer/keyframeMsg` (+ graph updates), the
/// reference from the first pose schema present in the order PoseStamped,
/// PoseWithCovarianceStamped, Odometry, TransformStamped, PoseInFrame,
/// PosesInFrame, TFMessage (unless a topic is named), the IMU from
/// `sensor_msgs/Imu`. Every message is read and counted.
///
/// Errors ([`Error::Mcap`], naming the file, the topic and the message) on a
/// damaged file, a named topic that is missing or has the wrong schema, or a
/// non-finite pose; [`Error::Decode`] for a message that does not decode.
pub fn read_mcap(path: impl AsRef<Path>, options: &ReadOptions) -> Result<Log> {
    let file = McapFile::open(path.as_ref())?;
    read_log_from(&file, Some(Container::Mcap), None, options).map_err(as_mcap)
}

/// [`inspect_log`] for a file that must be MCAP, with the MCAP reader's
/// errors ([`Error::Mcap`]).
pub fn inspect_mcap(path: impl AsRef<Path>) -> Result<Inspection> {
    let file = McapFile::open(path.as_ref())?;
    inspect_source(&file, Container::Mcap, file.profile()).map_err(as_mcap)
}
