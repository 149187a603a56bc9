//! [`read_mcap`] and [`inspect_mcap`]: the log assembly of [`crate::io::log`]
//! over an MCAP file, with the MCAP reader's errors ([`Error::Mcap`]) as before
//! bags were read. [`crate::io::read_log`] reads every container.

use std::path::Path;

use super::reader::McapFile;
use crate::error::{Error, Result};
use crate::io::container::Container;
use crate::io::log::{inspect_source, read_log_from};
pub use crate::io::log::{Log, ReadOptions, TopicInfo};
use crate::io::messages::ReadMode;

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

/// Reads an MCAP log: [`crate::io::read_log`] for a file that must be MCAP.
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

/// What `inspect_mcap` shows: every topic with its counts, and the topics
/// [`read_mcap`] would use by default.
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

/// Reads every message of `path` (without decoding) and lists its topics
/// ([`crate::io::log::inspect_log`] for every container).
pub fn inspect_mcap(path: impl AsRef<Path>) -> Result<Inventory> {
    let file = McapFile::open(path.as_ref())?;
    let i = inspect_source(&file, Container::Mcap, file.profile()).map_err(as_mcap)?;
    Ok(Inventory {
        profile: i.profile,
        mode: i.mode,
        topics: i.topics,
        picks: i.picks,
    })
}
