//! What a conversion reads: one [`Recording`], whatever the input was.
//!
//! Every reader in [`crate::io`] returns its own model (an MCAP [`Log`], a
//! trajectory, a point cloud); a [`Source`] turns one kind of input into a
//! `Recording`, and [`crate::pipeline::convert`] never asks which it was.
//! Adding an input format means writing its reader in `io/` and one `Source`
//! here. Two of the sources are the examples:
//!
//! ```no_run
//! use slam2world::pipeline::source::{LogSource, Source, TrajectoryFiles};
//! use slam2world::io::log::ReadOptions;
//! use slam2world::io::text::TrajectoryFormat;
//!
//! // A log of LSD-SLAM keyframes, graph updates, reference poses, IMU: MCAP,
//! // a ROS 1 bag or a rosbag2 bag (the container is found from the bytes).
//! let log = LogSource { path: "run.bag".into(), read: ReadOptions::default() }.read()?;
//! assert!(!log.keyframes.is_empty());
//!
//! // Text files: SLAM keyframe poses (TUM), a metric reference (EuRoC CSV) and
//! // the SLAM map points (PLY); the frames carry no depth, the cloud no rays.
//! let files = TrajectoryFiles {
//!     slam: "KeyFrameTrajectory.txt".into(),
//!     slam_format: TrajectoryFormat::Tum,
//!     reference: Some(("data.csv".into(), TrajectoryFormat::Euroc)),
//!     cloud: Some("MapPoints.ply".into()),
//! }
//! .read()?;
//! assert!(files.frames.is_some() && files.cloud.is_some());
//! # Ok::<(), slam2world::Error>(())
//! ```
//!
//! A new source (say a ROS bag) implements [`Source::read`] with its reader
//! and fills what it has: keyframes (pose `T_slam_cam`, camera, inverse depth)
//! or frames without depth (poses only) plus a cloud in the SLAM frame; an
//! optional reference trajectory `T_world_body`; optional raw IMU; and in
//! [`SourceInfo`] where each part came from.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use nalgebra::Vector3;

use super::native::{FrameInfo, NativeModel, ReconstructionInfo, ReferenceFileInfo};
use crate::cloud::PointCloud;
use crate::error::{Error, Result};
use crate::geo::GnssFixes;
use crate::imu::ImuSamples;
use crate::io::container::detect;
use crate::io::log::{read_log, Log, ReadOptions, TopicInfo};
use crate::io::text::TrajectoryFormat;
use crate::keyframe::Keyframe;
use crate::trajectory::Trajectory;

/// Where a recording's parts came from.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SourceInfo {
    /// The input (a log, or the SLAM trajectory file).
    pub path: PathBuf,
    /// The input's format, as the report names it (`mcap`, `ros1 bag`,
    /// `rosbag2 folder`, `rosbag2 db3`, `trajectory files`).
    pub format: String,
    /// Topic of the keyframes.
    pub keyframe_topic: Option<String>,
    /// Topic of the graph updates.
    pub graph_topic: Option<String>,
    /// Topic of the SLAM poses without depth (a log's estimate topic).
    pub est_topic: Option<String>,
    /// Topic of the reference poses.
    pub reference_topic: Option<String>,
    /// Topic of the raw IMU.
    pub imu_topic: Option<String>,
    /// Topic of the GNSS fixes.
    pub gnss_topic: Option<String>,
    /// File of the GNSS fixes, when given beside the input.
    pub gnss_path: Option<PathBuf>,
    /// File of the reference, when it is not the input itself.
    pub reference_path: Option<PathBuf>,
    /// File of the cloud, when it is not the input itself.
    pub cloud_path: Option<PathBuf>,
    /// Every topic of a log (empty for files without topics).
    pub topics: Vec<TopicInfo>,
    /// Keyframe messages read (all versions).
    pub keyframe_messages: usize,
    /// Graph messages read.
    pub graph_messages: usize,
    /// Keyframe poses overwritten by graph messages.
    pub graph_updates: usize,
    /// True when a log was read through its index (false: a linear scan).
    pub indexed: bool,
    /// Topic of the live frames, when the log has them.
    pub live_topic: Option<String>,
    /// How a reconstruction input was read (`None` for logs).
    pub reconstruction: Option<ReconstructionInfo>,
    /// The reference file given beside the input, when there is one.
    pub reference_file: Option<ReferenceFileInfo>,
}

/// Everything a conversion needs, from any source.
#[derive(Clone, Debug, Default)]
pub struct Recording {
    /// Where each part came from.
    pub source: SourceInfo,
    /// Keyframes with inverse-depth images (LSD-SLAM, DROID-SLAM), the latest
    /// version of each id in order of first arrival; poses `T_slam_cam`.
    pub keyframes: Vec<Keyframe>,
    /// Frame poses without depth (`T_slam_cam`, sorted by time), for sources
    /// that give poses and a separate cloud.
    pub frames: Option<Trajectory>,
    /// Points in the SLAM frame that come without their camera rays.
    pub cloud: Option<PointCloud>,
    /// Reference poses `T_world_body`, sorted by time; shared, not copied,
    /// with the conversion and the Python objects that show it.
    pub reference: Option<Arc<Trajectory>>,
    /// Raw IMU samples, sorted by time.
    pub imu: Option<ImuSamples>,
    /// The raw IMU samples left on disk by [`Source::read_bounded`] (`imu`
    /// is then `None`): read back after the alignment, for the step that
    /// uses them.
    pub imu_on_disk: Option<Arc<crate::io::log::ImuOnDisk>>,
    /// The reference poses left on disk by [`Source::read_bounded`]
    /// (`reference` is then `None`): read back for the alignment, then read
    /// a piece at a time by the writers.
    pub reference_on_disk: Option<Arc<crate::io::spill::TrajectoryFile>>,
    /// GNSS fixes (WGS84), the reference when present: the world frame is
    /// then ENU at an origin (`pipeline::gnss`).
    pub gnss: Option<GnssFixes>,
    /// Name and camera of each row of `frames` (empty when the input has none).
    pub frame_info: Vec<FrameInfo>,
    /// Ray origins of the cloud's points in the SLAM frame, by the ids in
    /// `cloud.keyframe_ids` (a COLMAP point's observing image), for the octree
    /// of a cloud without keyframes.
    pub cloud_origins: Option<BTreeMap<i32, Vector3<f64>>>,
    /// The input's own model, written back in its format by the conversion.
    pub native: Option<NativeModel>,
    /// The tracked `T_slam_cam` of every frame as the SLAM published it live
    /// (LSD-SLAM's live frames), sorted by time: where the start-up stages are
    /// found when the log has them.
    pub live: Option<Trajectory>,
    /// Where the keyframes' pixels are when the recording was read with them
    /// left on disk ([`Source::read_bounded`]): the keyframes then hold none,
    /// and the conversion reads them back a batch at a time.
    pub pixels: Option<std::sync::Arc<crate::io::spill::SpilledKeyframes>>,
}

impl From<Log> for Recording {
    fn from(log: Log) -> Self {
        Recording {
            source: SourceInfo {
                path: log.path,
                format: log.container.map_or("log", |c| c.name()).to_string(),
                keyframe_topic: log.keyframe_topic,
                graph_topic: log.graph_topic,
                est_topic: log.est_topic,
                reference_topic: log.reference_topic,
                imu_topic: log.imu_topic,
                gnss_topic: log.gnss_topic,
                reference_path: None,
                cloud_path: None,
                topics: log.topics,
                keyframe_messages: log.keyframe_messages,
                graph_messages: log.graph_messages,
                graph_updates: log.graph_updates,
                indexed: log.indexed,
                live_topic: log.live_topic,
                ..SourceInfo::default()
            },
            live: log.live,
            pixels: log.pixels,
            keyframes: log.keyframes,
            frames: log.frames,
            cloud: None,
            reference: log.reference.map(Arc::new),
            imu: log.imu,
            imu_on_disk: log.imu_on_disk,
            reference_on_disk: log.reference_on_disk,
            gnss: log.gnss,
            ..Recording::default()
        }
    }
}

/// One kind of input that a conversion can read.
pub trait Source {
    /// Reads the input into a recording.
    fn read(&self) -> Result<Recording>;

    /// Reads the input with what grows with its length left on disk where
    /// the source can ([`Recording::pixels`]: a log's keyframe pixels), for
    /// a conversion whose memory does not grow with the log. The default
    /// reads it whole.
    fn read_bounded(&self) -> Result<Recording> {
        self.read()
    }
}

/// A log of any container ([`read_log`]: MCAP, ROS 1 bag, rosbag2 folder or
/// `.db3`): `lsd_slam_viewer` keyframes and graph updates or an estimate
/// topic, a pose topic, raw IMU; topics found by type unless named.
#[derive(Clone, Debug, PartialEq)]
pub struct LogSource {
    /// The log (a file, or a rosbag2 folder).
    pub path: PathBuf,
    /// Topics to read.
    pub read: ReadOptions,
}

/// The name of [`LogSource`] from when logs were MCAP only.
pub type McapSource = LogSource;

impl Source for LogSource {
    fn read(&self) -> Result<Recording> {
        read_log(&self.path, &self.read).map(Recording::from)
    }

    fn read_bounded(&self) -> Result<Recording> {
        crate::io::log::read_log_spilled(&self.path, &self.read).map(Recording::from)
    }
}

/// Trajectory text files: the SLAM poses, an optional metric reference and an
/// optional SLAM-frame cloud (PLY, or `x y z` text).
#[derive(Clone, Debug, PartialEq)]
pub struct TrajectoryFiles {
    /// SLAM keyframe or frame poses `T_slam_cam`.
    pub slam: PathBuf,
    /// Their format.
    pub slam_format: TrajectoryFormat,
    /// The reference `T_world_body` and its format.
    pub reference: Option<(PathBuf, TrajectoryFormat)>,
    /// Points in the SLAM frame: PLY (found by its magic line), else `x y z` text.
    pub cloud: Option<PathBuf>,
}

impl Source for TrajectoryFiles {
    fn read(&self) -> Result<Recording> {
        let frames = self.slam_format.read(&self.slam)?;
        let reference = match &self.reference {
            Some((p, f)) => Some(Arc::new(f.read(p)?)),
            None => None,
        };
        let cloud = match &self.cloud {
            Some(p) => Some(crate::io::ply::read_cloud(p)?),
            None => None,
        };
        Ok(Recording {
            source: SourceInfo {
                path: self.slam.clone(),
                format: "trajectory files".into(),
                reference_path: self.reference.as_ref().map(|(p, _)| p.clone()),
                cloud_path: self.cloud.clone(),
                ..SourceInfo::default()
            },
            keyframes: Vec::new(),
            frames: Some(frames),
            cloud,
            reference,
            imu: None,
            ..Recording::default()
        })
    }
}

/// The source of a log, its container found from its first bytes (or a
/// rosbag2 folder's `metadata.yaml`): MCAP, ROS 1 bag, rosbag2 folder, `.db3`.
///
/// Errors: [`Error::Io`] when it cannot be opened, [`Error::Container`] when
/// its content is no log slam2world reads.
pub fn open_log(path: &Path, read: &ReadOptions) -> Result<Box<dyn Source>> {
    detect(path)?;
    Ok(Box::new(LogSource {
        path: path.to_path_buf(),
        read: read.clone(),
    }))
}

impl Recording {
    /// The SLAM poses the fit uses, sorted by time, and for each row the
    /// keyframe it came from (`None` for frames without depth): the keyframe
    /// poses when there are keyframes, else the frames.
    pub fn slam_trajectory(&self) -> Result<(Trajectory, Vec<Option<usize>>)> {
        if self.keyframes.is_empty() {
            let Some(f) = &self.frames else {
                return Err(self.missing_slam());
            };
            return Ok((f.clone(), vec![None; f.len()]));
        }
        let kf = &self.keyframes;
        let mut order: Vec<usize> = (0..kf.len()).collect();
        order.sort_by(|&a, &b| kf[a].timestamp.total_cmp(&kf[b].timestamp));
        let traj = Trajectory::try_new(
            order.iter().map(|&i| kf[i].timestamp).collect(),
            order.iter().map(|&i| kf[i].pose.translation).collect(),
            Some(order.iter().map(|&i| kf[i].pose.rotation).collect()),
        )?;
        Ok((traj, order.into_iter().map(Some).collect()))
    }

    /// The error for an input without SLAM poses.
    pub(crate) fn missing_slam(&self) -> Error {
        let reason = match &self.source.keyframe_topic {
            Some(t) => format!("topic {t}: no keyframe with a point cloud"),
            None if self.is_log() => {
                "no lsd_slam_viewer/keyframeMsg topic in the log (a topic of SLAM poses without depth can be named: est_topic)".into()
            }
            None => "no SLAM poses in the input".into(),
        };
        Error::Mcap {
            path: self.source.path.clone(),
            reason,
        }
    }

    /// True when the recording came from a log (any container), not from files.
    pub(crate) fn is_log(&self) -> bool {
        matches!(
            self.source.format.as_str(),
            "mcap" | "ros1 bag" | "rosbag2 folder" | "rosbag2 db3" | "log"
        )
    }
}
