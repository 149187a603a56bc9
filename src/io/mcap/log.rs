//! [`read_mcap`]: a SLAM log (keyframes, graph updates, reference poses, IMU)
//! read into the crate's types.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU8, Ordering};

use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use rayon::prelude::*;

use super::decode::{self, KeyframeMsg, MessageKind, StampedPose};
use super::reader::{ChannelInfo, McapFile, RawMessage, ReadMode};
use super::stream::MappedMessage;
use crate::error::{Error, Result, WireError};
use crate::geometry::{PinholeCamera, Sim3};
use crate::imu::ImuSamples;
use crate::keyframe::Keyframe;
use crate::trajectory::Trajectory;

/// Which topics to read. `None` finds the topic by its schema name.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// Topic of `lsd_slam_viewer/keyframeMsg`.
    pub keyframe_topic: Option<String>,
    /// Topic of `lsd_slam_viewer/keyframeGraphMsg`.
    pub graph_topic: Option<String>,
    /// Topic of the reference poses (any supported pose schema).
    pub pose_topic: Option<String>,
    /// Topic of `sensor_msgs/Imu`.
    pub imu_topic: Option<String>,
    /// For `tf2_msgs/TFMessage` references: the parent frame (the world side).
    pub tf_parent: Option<String>,
    /// For `tf2_msgs/TFMessage` references: the child frame (the body).
    pub tf_child: Option<String>,
}

/// One topic of the log, as [`read_mcap`] and `slam2world inspect` list it.
#[derive(Clone, Debug, PartialEq)]
pub struct TopicInfo {
    /// Topic name.
    pub topic: String,
    /// Schema name (empty when schemaless).
    pub schema_name: String,
    /// Schema encoding.
    pub schema_encoding: String,
    /// Message encoding.
    pub message_encoding: String,
    /// Messages read on the topic (0 when its chunks were skipped by the index).
    pub count: u64,
    /// First and last log time, nanoseconds, of the messages read.
    pub time_range: Option<(u64, u64)>,
    /// What slam2world makes of the schema, when anything.
    pub kind: Option<MessageKind>,
}

/// A SLAM log: keyframes, reference poses, IMU and the topic inventory.
#[derive(Clone, Debug, Default)]
pub struct Log {
    /// The file read.
    pub path: PathBuf,
    /// Keyframes, the latest version of each id, in order of first arrival; each
    /// pose is the latest of the keyframe message and the graph messages after it.
    /// Timestamps are the messages' own `time`.
    pub keyframes: Vec<Keyframe>,
    /// Reference poses `T_world_body`, sorted by time.
    pub reference: Option<Trajectory>,
    /// Raw IMU samples, sorted by time (samples with a repeated time dropped).
    pub imu: Option<ImuSamples>,
    /// Topic the keyframes came from.
    pub keyframe_topic: Option<String>,
    /// Topic the graph updates came from.
    pub graph_topic: Option<String>,
    /// Topic the reference came from.
    pub reference_topic: Option<String>,
    /// Topic the IMU came from.
    pub imu_topic: Option<String>,
    /// Keyframe messages read (all versions) and graph messages applied.
    pub keyframe_messages: usize,
    /// Graph messages read.
    pub graph_messages: usize,
    /// Keyframe poses overwritten by graph messages.
    pub graph_updates: usize,
    /// Every topic of the log.
    pub topics: Vec<TopicInfo>,
    /// How the file was read.
    pub indexed: bool,
}

fn mcap_err(path: &Path, reason: String) -> Error {
    Error::Mcap {
        path: path.to_path_buf(),
        reason,
    }
}

/// Reference pose kinds in the order they are preferred.
const POSE_KINDS: [MessageKind; 6] = [
    MessageKind::PoseStamped,
    MessageKind::PoseWithCovarianceStamped,
    MessageKind::Odometry,
    MessageKind::PoseInFrame,
    MessageKind::PosesInFrame,
    MessageKind::Tf,
];

fn kind_of(c: &ChannelInfo) -> Option<MessageKind> {
    MessageKind::from_schema(&c.schema_name)
}

/// Counts and time ranges per channel, as topics and as a count map;
/// `messages` yields `(channel id, log time)`.
fn topic_inventory(
    channels: &BTreeMap<u16, ChannelInfo>,
    messages: impl Iterator<Item = (u16, u64)>,
) -> (Vec<TopicInfo>, HashMap<u16, u64>) {
    // (count, first, last) per channel id
    let mut stats = vec![(0u64, u64::MAX, 0u64); 1 << 16];
    for (id, t) in messages {
        let s = &mut stats[id as usize];
        s.0 += 1;
        s.1 = s.1.min(t);
        s.2 = s.2.max(t);
    }
    let topics = channels
        .values()
        .map(|c| {
            let (count, first, last) = stats[c.id as usize];
            TopicInfo {
                topic: c.topic.clone(),
                schema_name: c.schema_name.clone(),
                schema_encoding: c.schema_encoding.clone(),
                message_encoding: c.message_encoding.clone(),
                count,
                time_range: (count > 0).then_some((first, last)),
                kind: kind_of(c),
            }
        })
        .collect();
    let counts = channels
        .keys()
        .map(|id| (*id, stats[*id as usize].0))
        .collect();
    (topics, counts)
}

/// Picks the channel for a role: the named topic (which must exist and carry
/// one of `kinds`), else the channel of the first kind in `kinds` present (most
/// messages first, then topic name).
fn choose<'c>(
    path: &Path,
    role: &str,
    named: Option<&str>,
    kinds: &[MessageKind],
    channels: &'c BTreeMap<u16, ChannelInfo>,
    counts: &HashMap<u16, u64>,
) -> Result<Option<&'c ChannelInfo>> {
    if let Some(topic) = named {
        let Some(c) = channels.values().find(|c| c.topic == topic) else {
            let all: Vec<&str> = channels.values().map(|c| c.topic.as_str()).collect();
            return Err(mcap_err(
                path,
                format!(
                    "{role} topic {topic:?} is not in the log (topics: {})",
                    all.join(", ")
                ),
            ));
        };
        return match kind_of(c) {
            Some(k) if kinds.contains(&k) => Ok(Some(c)),
            _ => Err(mcap_err(
                path,
                format!(
                    "topic {topic}: schema {:?} cannot be read as {role} (expected {})",
                    c.schema_name,
                    kinds
                        .iter()
                        .map(|k| format!("{k:?}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            )),
        };
    }
    for k in kinds {
        let mut cands: Vec<&ChannelInfo> = channels
            .values()
            .filter(|c| kind_of(c) == Some(*k))
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
        Err(mcap_err(
            path,
            format!(
                "topic {}: schema {} in message encoding {:?} is not supported (expected {})",
                c.topic,
                c.schema_name,
                c.message_encoding,
                kind.encodings().join(" or ")
            ),
        ))
    }
}

/// Reads a log. Keyframes come from `lsd_slam_viewer/keyframeMsg` (+ graph
/// updates), the reference from the first pose schema present in the order
/// PoseStamped, PoseWithCovarianceStamped, Odometry, PoseInFrame, PosesInFrame,
/// TFMessage (unless a topic is named), the IMU from `sensor_msgs/Imu`.
///
/// Errors ([`Error::Mcap`], naming the file, the topic and the message) on a
/// damaged file, a named topic that is missing or has the wrong schema, a
/// message that does not decode, or a non-finite pose.
pub fn read_mcap(path: impl AsRef<Path>, options: &ReadOptions) -> Result<Log> {
    let path = path.as_ref();
    let file = McapFile::open(path)?;
    // Every message is counted; those of a known schema are decoded inside the
    // parallel chunk tasks (decompressed buffers are reused, not kept).
    // The kind of each channel, found once (0 not yet, 1 none, 2 + index in KINDS).
    let kinds: Vec<AtomicU8> = (0..1 << 16).map(|_| AtomicU8::new(0)).collect();
    let kind_cached = |c: &ChannelInfo| {
        let slot = &kinds[c.id as usize];
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
    };
    let scan = file.scan_map(|_| true, |c, m| decode_message(kind_cached(c), c, m))?;
    let (topics, counts) = topic_inventory(
        &scan.channels,
        scan.messages.iter().map(|m| (m.channel_id, m.log_time)),
    );

    use MessageKind as K;
    let ch = &scan.channels;
    let kf = choose(
        path,
        "keyframe",
        options.keyframe_topic.as_deref(),
        &[K::Keyframe],
        ch,
        &counts,
    )?;
    let graph = choose(
        path,
        "graph",
        options.graph_topic.as_deref(),
        &[K::KeyframeGraph],
        ch,
        &counts,
    )?;
    let pose = choose(
        path,
        "pose",
        options.pose_topic.as_deref(),
        &POSE_KINDS,
        ch,
        &counts,
    )?;
    let imu_ch = choose(
        path,
        "imu",
        options.imu_topic.as_deref(),
        &[K::Imu],
        ch,
        &counts,
    )?;
    for c in [kf, graph, pose, imu_ch].into_iter().flatten() {
        if let Some(k) = kind_of(c) {
            check_encoding(path, c, k)?;
        }
    }

    let mut log = Log {
        path: path.to_path_buf(),
        keyframe_topic: kf.map(|c| c.topic.clone()),
        graph_topic: graph.map(|c| c.topic.clone()),
        reference_topic: pose.map(|c| c.topic.clone()),
        imu_topic: imu_ch.map(|c| c.topic.clone()),
        topics,
        indexed: scan.mode == ReadMode::Indexed,
        ..Log::default()
    };
    let mut messages = scan.messages;
    if let Some(kf) = kf {
        read_keyframes(path, &mut messages, kf, graph, &mut log)?;
    }
    if let Some(pc) = pose {
        log.reference = Some(read_reference(path, &messages, pc, options)?);
    }
    if let Some(ic) = imu_ch {
        log.imu = Some(read_imu(path, &messages, ic)?);
    }
    Ok(log)
}

/// A keyframe message without its point cloud, and the cloud split into
/// inverse depth, variance and RGB (for keyframes; live frames have none).
type DecodedKeyframe = (KeyframeMsg<'static>, Option<(Vec<f32>, Vec<f32>, Vec<u8>)>);

/// What a message becomes inside the chunk task. Errors keep what and where
/// in the message; the file, topic and message index are added when the
/// message is used.
#[derive(Default)]
enum Decoded {
    Keyframe(Box<std::result::Result<DecodedKeyframe, WireError>>),
    Graph(std::result::Result<Vec<(i32, [f64; 7])>, WireError>),
    /// A checked, normalised pose sample.
    Pose(decode::PoseSample),
    Tf(Vec<StampedPose>),
    Imu(decode::ImuMsg),
    Error(WireError),
    #[default]
    Other,
}

/// Every kind, for the per-channel cache of `read_mcap`.
const KINDS: [MessageKind; 9] = [
    MessageKind::Keyframe,
    MessageKind::KeyframeGraph,
    MessageKind::PoseStamped,
    MessageKind::PoseWithCovarianceStamped,
    MessageKind::Odometry,
    MessageKind::PoseInFrame,
    MessageKind::PosesInFrame,
    MessageKind::Tf,
    MessageKind::Imu,
];

fn decode_message(kind: Option<MessageKind>, c: &ChannelInfo, m: &RawMessage<'_>) -> Decoded {
    use MessageKind as K;
    let enc = c.message_encoding.as_str();
    let err = Decoded::Error;
    match kind {
        Some(K::Keyframe) => Decoded::Keyframe(Box::new(decode::keyframe_ros1(m.data).map(|k| {
            let arrays = k
                .is_keyframe
                .then(|| decode::split_pointcloud(k.pointcloud));
            (
                KeyframeMsg {
                    pointcloud: &[],
                    ..k
                },
                arrays,
            )
        }))),
        Some(K::KeyframeGraph) => Decoded::Graph(decode::graph_ros1(m.data)),
        Some(K::Tf) => match decode::poses(K::Tf, enc, m.data) {
            Ok(v) => Decoded::Tf(v),
            Err(e) => err(e),
        },
        Some(K::Imu) => match decode::imu(enc, m.data) {
            Ok(s) => Decoded::Imu(s),
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
    arrays: (Vec<f32>, Vec<f32>, Vec<u8>),
    topic_index: usize,
    pose: [f64; 7],
    pose_source: String,
}

fn read_keyframes(
    path: &Path,
    messages: &mut [Mapped],
    kf: &ChannelInfo,
    graph: Option<&ChannelInfo>,
    log: &mut Log,
) -> Result<()> {
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
            let i = graph_index;
            graph_index += 1;
            let frames = match &m.value {
                Decoded::Graph(Ok(f)) => f,
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
            };
            for (id, c2w) in frames {
                if let Some(e) = latest.get_mut(id) {
                    e.pose = *c2w;
                    e.pose_source = format!("topic {graph_topic}: message {i}");
                    log.graph_updates += 1;
                }
            }
        }
    }
    log.keyframe_messages = kf_index;
    log.graph_messages = graph_index;
    let mut entries: Vec<Entry> = order.iter().filter_map(|id| latest.remove(id)).collect();
    let keyframes: Result<Vec<Keyframe>> = entries
        .par_iter_mut()
        .map(|e| to_keyframe(path, &kf.topic, e))
        .collect();
    log.keyframes = keyframes?;
    Ok(())
}

fn to_keyframe(path: &Path, topic: &str, e: &mut Entry) -> Result<Keyframe> {
    let m = &e.msg;
    let what = |reason: String| {
        mcap_err(
            path,
            format!(
                "topic {topic}: message {} (keyframe {}): {reason}",
                e.topic_index, m.id
            ),
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
    let (idepth, var, color) = std::mem::take(&mut e.arrays);
    Keyframe::try_new(m.id, m.time, pose, camera, idepth, Some(var), Some(color))
        .map_err(|err| what(err.to_string()))
}

/// The pose samples of a reference channel, with TF narrowed to one frame pair.
fn read_reference(
    path: &Path,
    messages: &[Mapped],
    c: &ChannelInfo,
    options: &ReadOptions,
) -> Result<Trajectory> {
    let mine = messages.iter().filter(|m| m.channel_id == c.id);
    if kind_of(c) != Some(MessageKind::Tf) {
        let mut times: Vec<f64> = Vec::new();
        let mut positions: Vec<Vector3<f64>> = Vec::new();
        let mut orientations: Vec<UnitQuaternion<f64>> = Vec::new();
        for (i, m) in mine.enumerate() {
            match &m.value {
                Decoded::Pose((t, p, [x, y, z, w])) => {
                    times.push(*t);
                    positions.push(Vector3::from(*p));
                    orientations.push(UnitQuaternion::new_unchecked(Quaternion::new(
                        *w, *x, *y, *z,
                    )));
                }
                Decoded::Error(e) => return Err(at(path, &c.topic, i, m.log_time, e.clone())),
                _ => {
                    return Err(at(
                        path,
                        &c.topic,
                        i,
                        m.log_time,
                        WireError::schema("not a pose message"),
                    ))
                }
            }
        }
        if !times.is_sorted_by(|a, b| a <= b) {
            let mut order: Vec<usize> = (0..times.len()).collect();
            order.sort_by(|&a, &b| times[a].total_cmp(&times[b]));
            times = order.iter().map(|&k| times[k]).collect();
            positions = order.iter().map(|&k| positions[k]).collect();
            orientations = order.iter().map(|&k| orientations[k]).collect();
        }
        return Trajectory::try_new(times, positions, Some(orientations))
            .map_err(|e| mcap_err(path, format!("topic {}: {e}", c.topic)));
    }
    let mut decoded: Vec<&Vec<StampedPose>> = Vec::new();
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
    let pair = match (&options.tf_parent, &options.tf_child) {
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
                None => {
                    return Err(mcap_err(
                        path,
                        format!(
                            "topic {}: no transform with parent {:?} and child {:?}",
                            c.topic, p, ch
                        ),
                    ))
                }
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
        return Err(mcap_err(
            path,
            format!(
                "topic {}: no transform from {:?} to {:?}",
                c.topic, pair.0, pair.1
            ),
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
            .map_err(|e| mcap_err(path, format!("topic {topic}: message {i}: {e}")))?;
        times.push(time);
        positions.push(Vector3::from(position));
        orientations.push(UnitQuaternion::new_unchecked(Quaternion::new(w, x, y, z)));
    }
    Trajectory::try_new(times, positions, Some(orientations))
        .map_err(|e| mcap_err(path, format!("topic {topic}: {e}")))
}

fn read_imu(path: &Path, messages: &[Mapped], c: &ChannelInfo) -> Result<ImuSamples> {
    let mut samples: Vec<&decode::ImuMsg> = Vec::new();
    for (i, m) in messages.iter().filter(|m| m.channel_id == c.id).enumerate() {
        match &m.value {
            Decoded::Imu(s) => {
                if !s.time.is_finite()
                    || s.gyro.iter().chain(s.accel.iter()).any(|v| !v.is_finite())
                {
                    return Err(at(
                        path,
                        &c.topic,
                        i,
                        m.log_time,
                        WireError::value(format!("non-finite IMU sample {s:?}")),
                    ));
                }
                samples.push(s);
            }
            Decoded::Error(e) => return Err(at(path, &c.topic, i, m.log_time, e.clone())),
            _ => {
                return Err(at(
                    path,
                    &c.topic,
                    i,
                    m.log_time,
                    WireError::schema("not an IMU message"),
                ))
            }
        }
    }
    samples.sort_by(|a, b| a.time.total_cmp(&b.time));
    samples.dedup_by(|b, a| a.time == b.time);
    ImuSamples::try_new(
        samples.iter().map(|s| s.time).collect(),
        samples.iter().map(|s| Vector3::from(s.gyro)).collect(),
        samples.iter().map(|s| Vector3::from(s.accel)).collect(),
    )
    .map_err(|e| mcap_err(path, format!("topic {}: {e}", c.topic)))
}

/// What `slam2world inspect` shows: every topic with its counts, and the
/// topics [`read_mcap`] would use by default.
#[derive(Clone, Debug)]
pub struct Inventory {
    /// The Header record's profile (`ros1`, `ros2`, …).
    pub profile: String,
    /// Indexed or linear reading.
    pub mode: ReadMode,
    /// Every topic, with all its messages counted.
    pub topics: Vec<TopicInfo>,
    /// `(role, topic)` for keyframe, graph, pose and imu, where one is found.
    pub picks: Vec<(&'static str, String)>,
}

/// Reads every message of `path` (without decoding) and lists its topics.
pub fn inspect_mcap(path: impl AsRef<Path>) -> Result<Inventory> {
    let path = path.as_ref();
    let file = McapFile::open(path)?;
    // Counted without keeping any chunk: each task reuses its buffer.
    let scan = file.scan_map(|_| true, |_, _| ())?;
    let (topics, counts) = topic_inventory(
        &scan.channels,
        scan.messages.iter().map(|m| (m.channel_id, m.log_time)),
    );
    use MessageKind as K;
    let roles: [(&'static str, &[MessageKind]); 4] = [
        ("keyframes", &[K::Keyframe]),
        ("graph", &[K::KeyframeGraph]),
        ("reference", &POSE_KINDS),
        ("imu", &[K::Imu]),
    ];
    let mut picks = Vec::new();
    for (role, kinds) in roles {
        if let Some(c) = choose(path, role, None, kinds, &scan.channels, &counts)? {
            picks.push((role, c.topic.clone()));
        }
    }
    Ok(Inventory {
        profile: scan.profile,
        mode: scan.mode,
        topics,
        picks,
    })
}
