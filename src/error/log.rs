//! What can be wrong with a log above the bytes of its records: the reason of
//! [`super::Error::Log`] (topics that cannot give what was asked, in any
//! container); [`crate::io::log`] re-exports it.

/// Why the topics of a log cannot give what was asked: the `reason` of
/// [`crate::Error::Log`] (the file is on the error). Each variant names the
/// topic and what was expected and found.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LogError {
    /// A topic that was asked for by name and is not in the log.
    #[error("{role} topic {topic:?} is not in the log (topics: {})", topics.join(", "))]
    NoTopic {
        /// What the topic was to give (`keyframe`, `pose`, `imu`, …).
        role: &'static str,
        /// The topic asked for.
        topic: String,
        /// The topics the log has.
        topics: Vec<String>,
    },
    /// A topic asked for by name whose type slam2world reads, but not in that role.
    #[error("topic {topic}: schema {type_name:?} cannot be read as {role} (expected {expected})")]
    WrongType {
        /// What the topic was to give.
        role: &'static str,
        /// The topic.
        topic: String,
        /// Its type (schema) name.
        type_name: String,
        /// The types that role reads.
        expected: String,
    },
    /// A topic asked for by name whose type slam2world does not decode (a
    /// `.db3` has type names but no definitions: only known types are read).
    #[error(
        "topic {topic}: type {type_name:?} is not one slam2world decodes (as {role} it reads {expected})"
    )]
    UnknownType {
        /// What the topic was to give.
        role: &'static str,
        /// The topic.
        topic: String,
        /// Its type name.
        type_name: String,
        /// The types that role reads.
        expected: String,
    },
    /// A known type in a message encoding its decoder does not read.
    #[error(
        "topic {topic}: schema {type_name} in message encoding {encoding:?} is not supported (expected {expected})"
    )]
    Encoding {
        /// The topic.
        topic: String,
        /// Its type name.
        type_name: String,
        /// The channel's message encoding.
        encoding: String,
        /// The encodings that decode it.
        expected: String,
    },
    /// A keyframe message that decodes but does not make a keyframe (a
    /// non-finite or degenerate pose, a bad camera, arrays of the wrong size).
    #[error("topic {topic}: message {index} (keyframe {id}): {what}")]
    Keyframe {
        /// The keyframe topic.
        topic: String,
        /// Index of the message on its topic.
        index: usize,
        /// The keyframe id.
        id: i32,
        /// What is wrong.
        what: String,
    },
    /// Pose or IMU samples that do not make a trajectory (a non-finite value,
    /// a zero quaternion, repeated times where the model refuses them).
    #[error("topic {topic}: {what}")]
    Samples {
        /// The topic.
        topic: String,
        /// What is wrong (with the message index where there is one).
        what: String,
    },
    /// A TF topic without a transform of the frame pair asked for.
    #[error("topic {topic}: no transform with parent {parent:?} and child {child:?}")]
    NoTransform {
        /// The TF topic.
        topic: String,
        /// The parent frame asked for (`None`: any).
        parent: Option<String>,
        /// The child frame asked for (`None`: any).
        child: Option<String>,
    },
}
