//! What can be wrong with a ROS bag or a container: the `reason` of
//! [`crate::Error::Bag`] and [`crate::Error::Container`].
//!
//! Each variant carries what was expected and what was found; the file and the
//! byte offset of the record at fault are on the enclosing [`crate::Error::Bag`].

use std::path::PathBuf;

/// Why a ROS 1 bag, a rosbag2 folder or a rosbag2 database cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum BagError {
    /// The file does not start with `#ROSBAG V`.
    #[error("not a ROS bag: the file starts with {found:?}, not \"#ROSBAG V2.0\\n\"")]
    NotABag {
        /// The first bytes of the file (lossy UTF-8).
        found: String,
    },
    /// A ROS bag of another version than 2.0.
    #[error("ROS bag version {version:?} is not supported (only 2.0)")]
    UnsupportedVersion {
        /// The version from the `#ROSBAG V…` line.
        version: String,
    },
    /// A record, a header field or a declared length runs past the bytes that remain.
    #[error("{what}: {needed} bytes declared, {available} remain")]
    Truncated {
        /// What was being read (`record header`, `chunk data`, `index entries`, …).
        what: &'static str,
        /// Bytes the length fields ask for.
        needed: u64,
        /// Bytes left in the file (or the decompressed chunk).
        available: u64,
    },
    /// A header field that is malformed: no `=`, or a value of the wrong size.
    #[error("{record} record, field {field:?}: expected {expected}, found {found} bytes")]
    BadField {
        /// The kind of record (`bag header`, `chunk`, `connection`, …).
        record: &'static str,
        /// The field name (lossy UTF-8).
        field: String,
        /// What the value should be (`4 bytes`, `8 bytes`, `name=value`).
        expected: &'static str,
        /// Size of what was found.
        found: usize,
    },
    /// A record without a field it must have.
    #[error("{record} record without its {field:?} field")]
    MissingField {
        /// The kind of record.
        record: &'static str,
        /// The field that is missing.
        field: &'static str,
    },
    /// A record whose op code does not belong where it was found.
    #[error("record with op {op:#04x} {context}")]
    UnexpectedRecord {
        /// The op code found.
        op: u8,
        /// Where it was found and what was expected there.
        context: &'static str,
    },
    /// A chunk compressed with something else than `none`, `bz2` or `lz4`.
    #[error("chunk compression {found:?} is not none, bz2 or lz4")]
    UnknownCompression {
        /// The `compression` field.
        found: String,
    },
    /// A chunk that declares more uncompressed bytes than is sensible.
    #[error("chunk declares {size} uncompressed bytes, beyond the {limit}-byte limit")]
    ChunkTooLarge {
        /// The declared uncompressed size.
        size: u64,
        /// The limit.
        limit: u64,
    },
    /// Compressed data (a bz2 or lz4 chunk, a zstd message or file) that does not decompress.
    #[error("{compression} data does not decompress: {message}")]
    Decompress {
        /// `bz2`, `lz4` or `zstd`.
        compression: &'static str,
        /// The decoder's message.
        message: String,
    },
    /// A chunk that decompressed to another size than its header says.
    #[error("chunk decompressed to {found} bytes, its header says {declared}")]
    ChunkSize {
        /// The size the chunk header declares.
        declared: u64,
        /// The size decompression gave (at most `declared + 1`: decoding stops there).
        found: u64,
    },
    /// A message data record of a connection that no connection record defines.
    #[error("message record {index} names connection {conn}, which no connection record defines")]
    UnknownConnection {
        /// The connection id of the message.
        conn: u32,
        /// Index of the message record in its chunk (0-based; the error's
        /// offset is the chunk's).
        index: u64,
    },
    /// A connection id that does not fit the 16-bit channel ids.
    #[error("connection id {conn} is beyond 65535 (channel ids are 16-bit)")]
    TooManyConnections {
        /// The connection id.
        conn: u32,
    },
    /// An error of the SQLite library (opening or querying a `.db3`).
    #[error("SQLite: {0}")]
    Sqlite(#[from] rusqlite::Error),
    /// An SQLite database that is not a rosbag2 database.
    #[error("not a rosbag2 database: no table {missing:?} (tables: {found:?})")]
    MissingTable {
        /// The table that is missing (`topics` or `messages`).
        missing: &'static str,
        /// The tables the database has.
        found: Vec<String>,
    },
    /// A per-message zstd compressed message (rosbag2 MESSAGE mode) that does not decompress.
    #[error("message {index} (topic {topic:?}) does not decompress: {message}")]
    MessageData {
        /// Index of the message among the wanted messages of its file, in time order.
        index: u64,
        /// Its topic.
        topic: String,
        /// What the zstd decoder said.
        message: String,
    },
    /// A message row naming a topic id the topics table does not list.
    #[error("message row {row} names topic id {topic_id}, which the topics table does not list")]
    UnknownTopic {
        /// The `topic_id` of the row.
        topic_id: i64,
        /// The row's `id`.
        row: i64,
    },
    /// A topic id outside the 16-bit channel ids.
    #[error("topic {topic:?} has id {topic_id}, outside the 16-bit channel ids")]
    TopicId {
        /// The topic's `id` column.
        topic_id: i64,
        /// The topic name.
        topic: String,
    },
    /// A `metadata.yaml` that is not valid YAML or not rosbag2 metadata.
    #[error("metadata.yaml (line {line}, column {column}): {message}")]
    Metadata {
        /// 1-based line (0 when unknown).
        line: usize,
        /// 1-based column (0 when unknown).
        column: usize,
        /// What the YAML parser said.
        message: String,
    },
    /// A rosbag2 folder without `metadata.yaml`.
    #[error("no metadata.yaml in the rosbag2 folder")]
    NoMetadata,
    /// A file that `metadata.yaml` lists and that is not in the folder.
    #[error("metadata.yaml names {}, which does not exist", file.display())]
    MissingFile {
        /// The file, as resolved against the folder.
        file: PathBuf,
    },
    /// A rosbag2 storage other than `sqlite3` or `mcap`.
    #[error("rosbag2 storage {found:?} is not sqlite3 or mcap")]
    UnsupportedStorage {
        /// The `storage_identifier`.
        found: String,
    },
    /// A rosbag2 compression other than zstd per file or per message.
    #[error(
        "rosbag2 compression {format:?} in mode {mode:?} is not supported (zstd, FILE or MESSAGE)"
    )]
    UnsupportedCompression {
        /// `compression_format`.
        format: String,
        /// `compression_mode`.
        mode: String,
    },
}

/// Why a path is no log that [`crate::io::container::detect`] knows.
#[derive(Debug, thiserror::Error)]
pub enum ContainerError {
    /// A file of zero bytes.
    #[error("the file is empty")]
    Empty,
    /// A FIFO, a socket or a device: not read, so that nothing blocks.
    #[error("not a regular file or folder (a {kind})")]
    NotAFile {
        /// `FIFO`, `socket`, `character device`, `block device` or `special file`.
        kind: &'static str,
    },
    /// A folder where a log file was expected.
    #[error("a folder, not a log file (expected {expected})")]
    Folder {
        /// What was expected, e.g. `an MCAP file`.
        expected: &'static str,
    },
    /// A folder without `metadata.yaml` (the file every rosbag2 folder has).
    #[error("a folder without metadata.yaml is not a rosbag2 bag")]
    NoMetadata,
    /// A ROS bag of a version other than 2.0.
    #[error("ROS bag version {version:?}: only 2.0 is read")]
    BagVersion {
        /// What follows `#ROSBAG V` on the first line.
        version: String,
    },
    /// Bytes that are none of the known magics.
    #[error("unknown container: the file starts with {head:?} (not MCAP, a ROS bag or SQLite)")]
    Unknown {
        /// The first bytes (up to 16), lossy UTF-8 with escapes.
        head: String,
    },
}

/// ` (byte N)` for an error message, or nothing.
pub(crate) fn at_offset(offset: Option<u64>) -> String {
    offset.map_or_else(String::new, |o| format!(" (byte {o})"))
}
