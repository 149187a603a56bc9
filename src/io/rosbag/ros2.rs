//! rosbag2 bags: a folder (`metadata.yaml` beside `.db3` or `.mcap` files) or
//! a single `.db3` / `.mcap` file.
//!
//! - `metadata.yaml` gives the storage (`sqlite3` or `mcap`), the files
//!   (relative to the folder) and the compression: none, zstd per file
//!   (`FILE`: each file is `*.db3.zstd` / `*.mcap.zstd`, decompressed to a
//!   temporary file while it is read) or zstd per message (`MESSAGE`: each
//!   message's bytes are one zstd frame). Offered QoS profiles are ignored.
//! - A `.db3` is a SQLite database: `topics(id, name, type,
//!   serialization_format, …)` and `messages(id, topic_id, timestamp, data)`.
//!   SQLite opens it, checks the tables and reads `topics`; the rows of
//!   `messages` are read from a map of the file's pages
//!   ([`sqlite_pages`](super::sqlite_pages)), through SQLite where that
//!   reader gives way (WAL mode, a hot journal, another table layout, a page
//!   it does not parse). It has type names but no definitions: channels get
//!   `schema_encoding` `ros2msg` and empty `schema_data`.
//! - An `.mcap` is read with [`McapFile`] (its channels keep their schemas).
//!
//! Channel ids are the `topics.id` of a `.db3` (the MCAP channel ids of an
//! `.mcap`); in a folder of several files, a topic keeps the id it had in the
//! first file that has it. Messages come in time order (`timestamp`, ns), ties
//! in file order, as `ros2 bag play` gives them.

use std::cell::RefCell;
use std::collections::{BTreeMap, HashMap};
use std::io::Read;
use std::path::{Path, PathBuf};

use rusqlite::{Connection, OpenFlags};
use serde::Deserialize;

use super::sqlite_pages::{Pages, Stop};
use super::{sort_by_time, BagError};
use crate::buffer::Region;
use crate::error::{Error, Result};
use crate::io::container::{classify, folder_of, Container};
use crate::io::mcap::reader::McapFile;
use crate::io::messages::{
    ChannelCount, ChannelInfo, Inventory, MappedMessage, MappedScan, MessageSource, RawMessage,
    ReadMode,
};

/// The largest decompressed message accepted in `MESSAGE` mode (1 GiB).
pub const MAX_MESSAGE: u64 = 1 << 30;

/// Where a rosbag2 bag keeps its messages.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ros2Storage {
    /// SQLite databases (`.db3`).
    Sqlite3,
    /// MCAP files.
    Mcap,
}

/// How a rosbag2 bag is compressed (zstd is the only format rosbag2 has).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ros2Compression {
    /// Not compressed.
    None,
    /// Each file compressed whole (`*.db3.zstd`, `*.mcap.zstd`).
    File,
    /// Each message's bytes compressed on their own.
    Message,
}

#[derive(Deserialize)]
struct MetadataFile {
    rosbag2_bagfile_information: Metadata,
}

#[derive(Deserialize)]
struct Metadata {
    storage_identifier: String,
    #[serde(default)]
    relative_file_paths: Vec<String>,
    #[serde(default)]
    files: Vec<FileEntry>,
    #[serde(default)]
    compression_format: Option<String>,
    #[serde(default)]
    compression_mode: Option<String>,
}

#[derive(Deserialize)]
struct FileEntry {
    path: String,
}

/// A rosbag2 bag, opened (`metadata.yaml` read, the files found).
#[derive(Debug)]
pub struct Ros2Bag {
    path: PathBuf,
    folder: bool,
    storage: Ros2Storage,
    compression: Ros2Compression,
    files: Vec<PathBuf>,
}

/// The channels of every file, by id, with one id per (topic, type).
#[derive(Default)]
struct ChannelTable {
    channels: BTreeMap<u16, ChannelInfo>,
    by_topic: HashMap<(String, String), u16>,
}

impl ChannelTable {
    /// The id `info` gets: that of its (topic, type) when known, else its own id
    /// when free, else the smallest free one.
    fn intern(&mut self, mut info: ChannelInfo) -> std::result::Result<u16, BagError> {
        let key = (info.topic.clone(), info.schema_name.clone());
        if let Some(&id) = self.by_topic.get(&key) {
            return Ok(id);
        }
        let id = if self.channels.contains_key(&info.id) {
            (0..=u16::MAX)
                .find(|i| !self.channels.contains_key(i))
                .ok_or(BagError::TooManyConnections { conn: 1 << 16 })?
        } else {
            info.id
        };
        info.id = id;
        self.channels.insert(id, info);
        self.by_topic.insert(key, id);
        Ok(id)
    }
}

impl Ros2Bag {
    /// Opens a rosbag2 folder (or its `metadata.yaml`), or a single `.db3` or
    /// `.mcap` file (told apart by their first bytes). Reads `metadata.yaml` and
    /// checks that every file it names exists.
    pub fn open(path: impl AsRef<Path>) -> Result<Self> {
        let given = path.as_ref();
        let meta = std::fs::metadata(given).map_err(|e| Error::io(given, e))?;
        let is_yaml = given.file_name().is_some_and(|n| n == "metadata.yaml");
        if meta.is_dir() || is_yaml {
            let folder = folder_of(given);
            return Self::open_folder(&folder);
        }
        let mut head = Vec::with_capacity(32);
        std::fs::File::open(given)
            .and_then(|f| f.take(32).read_to_end(&mut head))
            .map_err(|e| Error::io(given, e))?;
        let storage = match classify(&head) {
            Ok(Container::Ros2Sqlite) => Ros2Storage::Sqlite3,
            Ok(Container::Mcap) => Ros2Storage::Mcap,
            Ok(other) => {
                return Err(bag_err(
                    given,
                    BagError::UnsupportedStorage {
                        found: format!("{other:?}"),
                    },
                ))
            }
            Err(reason) => {
                return Err(Error::Container {
                    path: given.to_path_buf(),
                    reason,
                })
            }
        };
        Ok(Ros2Bag {
            path: given.to_path_buf(),
            folder: false,
            storage,
            compression: Ros2Compression::None,
            files: vec![given.to_path_buf()],
        })
    }

    fn open_folder(folder: &Path) -> Result<Self> {
        let yaml = folder.join("metadata.yaml");
        let text = match std::fs::read_to_string(&yaml) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(bag_err(folder, BagError::NoMetadata))
            }
            Err(e) => return Err(Error::io(&yaml, e)),
        };
        let meta = parse_metadata(&text).map_err(|r| bag_err(&yaml, r))?;
        let storage = match meta.storage_identifier.as_str() {
            "sqlite3" => Ros2Storage::Sqlite3,
            "mcap" => Ros2Storage::Mcap,
            other => {
                return Err(bag_err(
                    &yaml,
                    BagError::UnsupportedStorage {
                        found: other.to_string(),
                    },
                ))
            }
        };
        let format = meta.compression_format.unwrap_or_default();
        let mode = meta.compression_mode.unwrap_or_default();
        let compression = match (format.as_str(), mode.to_ascii_uppercase().as_str()) {
            (_, "" | "NONE") => Ros2Compression::None,
            ("zstd", "FILE") => Ros2Compression::File,
            ("zstd", "MESSAGE") => Ros2Compression::Message,
            _ => {
                return Err(bag_err(
                    &yaml,
                    BagError::UnsupportedCompression { format, mode },
                ))
            }
        };
        let names: Vec<String> = if meta.relative_file_paths.is_empty() {
            meta.files.into_iter().map(|f| f.path).collect()
        } else {
            meta.relative_file_paths
        };
        let mut files = Vec::with_capacity(names.len());
        for name in names {
            let file = folder.join(&name);
            if !file.is_file() {
                return Err(bag_err(&yaml, BagError::MissingFile { file }));
            }
            files.push(file);
        }
        Ok(Ros2Bag {
            path: folder.to_path_buf(),
            folder: true,
            storage,
            compression,
            files,
        })
    }

    /// The folder (or the single file) given.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// True for a folder with `metadata.yaml`, false for a single file.
    pub fn is_folder(&self) -> bool {
        self.folder
    }

    /// SQLite or MCAP.
    pub fn storage(&self) -> Ros2Storage {
        self.storage
    }

    /// None, per file or per message.
    pub fn compression(&self) -> Ros2Compression {
        self.compression
    }

    /// True when [`Ros2Bag::inventory`] counts from the tables without
    /// decompressing a file (`.db3` storage, not compressed per file): one
    /// SQL pass over every row's topic and time, no message data read.
    pub fn counts_from_index(&self) -> bool {
        self.storage == Ros2Storage::Sqlite3 && self.compression != Ros2Compression::File
    }

    /// The data files, in the order `metadata.yaml` lists them.
    pub fn files(&self) -> &[PathBuf] {
        &self.files
    }

    /// Runs `f` on each data file as a plain file: a `FILE`-compressed one is
    /// decompressed to a temporary file first (removed after `f`).
    fn each_file(&self, mut f: impl FnMut(&Path, &Path) -> Result<()>) -> Result<()> {
        for file in &self.files {
            if self.compression == Ros2Compression::File {
                let tmp = decompress_file(file)?;
                f(tmp.path(), file)?;
            } else {
                f(file, file)?;
            }
        }
        Ok(())
    }

    /// The topics as channels, by id.
    pub fn channels(&self) -> Result<BTreeMap<u16, ChannelInfo>> {
        let mut table = ChannelTable::default();
        self.each_file(|plain, label| {
            match self.storage {
                Ros2Storage::Sqlite3 => {
                    let db = open_db(plain, label)?;
                    for (_, info) in topics(&db).map_err(|r| bag_err(label, r))? {
                        table.intern(info).map_err(|r| bag_err(label, r))?;
                    }
                }
                Ros2Storage::Mcap => {
                    for info in McapFile::open(plain)?.channels()?.into_values() {
                        table.intern(info).map_err(|r| bag_err(label, r))?;
                    }
                }
            }
            Ok(())
        })?;
        Ok(table.channels)
    }

    /// Every message of a topic `want` keeps, passed to `map` in parallel
    /// (batches of rows of a `.db3`, chunk tasks of an `.mcap`); only the mapped
    /// values are kept. In `MESSAGE` mode `map` sees the decompressed bytes.
    /// `log_time` and `publish_time` are the stored timestamp (ns), `sequence` 0.
    pub fn scan_map<T: Send + Default>(
        &self,
        want: impl Fn(&ChannelInfo) -> bool + Sync,
        map: impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync,
    ) -> Result<MappedScan<T>> {
        let mut table = ChannelTable::default();
        let mut messages = Vec::new();
        let mut mode = ReadMode::Indexed;
        let zstd_messages = self.compression == Ros2Compression::Message;
        self.each_file(|plain, label| {
            let got = match self.storage {
                Ros2Storage::Sqlite3 => {
                    let mut counts = HashMap::new();
                    sqlite_scan(
                        plain,
                        label,
                        &mut table,
                        zstd_messages,
                        Rows::Wanted,
                        Via::Pages,
                        &want,
                        &map,
                        &mut counts,
                    )?
                }
                Ros2Storage::Mcap => {
                    let (got, m) = mcap_scan(plain, label, &mut table, zstd_messages, &want, &map)?;
                    if m == ReadMode::Linear {
                        mode = ReadMode::Linear;
                    }
                    got
                }
            };
            if messages.is_empty() {
                messages = got;
            } else {
                messages.extend(got);
            }
            Ok(())
        })?;
        sort_by_time(&mut messages);
        Ok(MappedScan {
            channels: table.channels,
            messages,
            mode,
            profile: "ros2".into(),
        })
    }

    /// Counts and time ranges per topic: one SQL pass over each `.db3`'s rows
    /// (topic and time, no message data), a scan of each `.mcap`. A `.db3` row
    /// of a topic that the topics table does not list is an error
    /// ([`BagError::UnknownTopic`]).
    pub fn inventory(&self) -> Result<Inventory> {
        if self.storage == Ros2Storage::Mcap {
            return Ok(Inventory::of_scan(&self.scan_map(|_| true, |_, _| ())?));
        }
        Ok(self.scan_counted(|_| false, |_, _| ())?.1)
    }

    /// [`Ros2Bag::scan_map`] and [`Ros2Bag::inventory`] in one pass: every
    /// message is counted, those of a topic `want` keeps are mapped. A `.db3`
    /// is read once, in rowid order, the data of the other topics' rows left
    /// unread; an `.mcap` is scanned once.
    pub fn scan_counted<T: Send + Default>(
        &self,
        want: impl Fn(&ChannelInfo) -> bool + Sync,
        map: impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync,
    ) -> Result<(MappedScan<T>, Inventory)> {
        if self.storage == Ros2Storage::Mcap {
            let all = self.scan_map(
                |_| true,
                |c, m| if want(c) { map(c, m) } else { T::default() },
            )?;
            let inventory = Inventory::of_scan(&all);
            let keep: Vec<u16> = all
                .channels
                .values()
                .filter(|c| want(c))
                .map(|c| c.id)
                .collect();
            let MappedScan {
                channels,
                mut messages,
                mode,
                profile,
            } = all;
            messages.retain(|m| keep.contains(&m.channel_id));
            let scan = MappedScan {
                channels,
                messages,
                mode,
                profile,
            };
            return Ok((scan, inventory));
        }
        let mut table = ChannelTable::default();
        let mut messages = Vec::new();
        let mut stats: HashMap<u16, (u64, u64, u64)> = HashMap::new();
        let zstd_messages = self.compression == Ros2Compression::Message;
        self.each_file(|plain, label| {
            let got = sqlite_scan(
                plain,
                label,
                &mut table,
                zstd_messages,
                Rows::All,
                Via::Pages,
                &want,
                &map,
                &mut stats,
            )?;
            if messages.is_empty() {
                messages = got;
            } else {
                messages.extend(got);
            }
            Ok(())
        })?;
        sort_by_time(&mut messages);
        let counts = table
            .channels
            .values()
            .map(|c| {
                let (count, lo, hi) = stats.get(&c.id).copied().unwrap_or((0, 0, 0));
                ChannelCount {
                    channel: c.clone(),
                    count,
                    time_range: (count > 0).then_some((lo, hi)),
                }
            })
            .collect();
        let inventory = Inventory {
            channels: counts,
            mode: ReadMode::Indexed,
            from_index: self.counts_from_index(),
        };
        let scan = MappedScan {
            channels: table.channels,
            messages,
            mode: ReadMode::Indexed,
            profile: "ros2".into(),
        };
        Ok((scan, inventory))
    }
}

fn bag_err(path: &Path, reason: BagError) -> Error {
    Error::Bag {
        path: path.to_path_buf(),
        offset: None,
        reason,
    }
}

fn parse_metadata(text: &str) -> std::result::Result<Metadata, BagError> {
    serde_yaml_ng::from_str::<MetadataFile>(text)
        .map(|m| m.rosbag2_bagfile_information)
        .map_err(|e| {
            let (line, column) = e.location().map_or((0, 0), |l| (l.line(), l.column()));
            BagError::Metadata {
                line,
                column,
                message: e.to_string(),
            }
        })
}

/// Decompresses a `FILE`-mode file (a zstd stream) into a temporary file.
fn decompress_file(file: &Path) -> Result<tempfile::NamedTempFile> {
    let input = std::fs::File::open(file).map_err(|e| Error::io(file, e))?;
    let mut tmp = tempfile::NamedTempFile::new().map_err(|e| Error::io(file, e))?;
    zstd::stream::copy_decode(std::io::BufReader::new(input), tmp.as_file_mut()).map_err(|e| {
        bag_err(
            file,
            BagError::Decompress {
                compression: "zstd",
                message: e.to_string(),
            },
        )
    })?;
    Ok(tmp)
}

/// Opens a `.db3` read-only and checks that it has the rosbag2 tables.
fn open_db(path: &Path, label: &Path) -> Result<Connection> {
    let at = |e: rusqlite::Error| bag_err(label, e.into());
    let db = Connection::open_with_flags(
        path,
        OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
    )
    .map_err(at)?;
    // Pages read from a map of the file rather than copied by `pread` into
    // SQLite's page cache (SQLite caps the size at its compile-time limit,
    // 2 GiB; past it, pages are read as before).
    db.pragma_update(None, "mmap_size", 1i64 << 40)
        .map_err(at)?;
    let tables: Vec<String> = {
        let mut stmt = db
            .prepare("SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name")
            .map_err(at)?;
        let names = stmt
            .query_map([], |r| r.get::<_, String>(0))
            .map_err(at)?
            .collect::<std::result::Result<_, _>>()
            .map_err(at)?;
        names
    };
    for missing in ["topics", "messages"] {
        if !tables.iter().any(|t| t == missing) {
            return Err(bag_err(
                label,
                BagError::MissingTable {
                    missing,
                    found: tables,
                },
            ));
        }
    }
    Ok(db)
}

/// The `topics` table: `(topics.id, channel)`, the channel id = `topics.id`.
fn topics(db: &Connection) -> std::result::Result<Vec<(i64, ChannelInfo)>, BagError> {
    let mut stmt =
        db.prepare("SELECT id, name, type, serialization_format FROM topics ORDER BY id")?;
    let mut rows = stmt.query([])?;
    let mut out = Vec::new();
    while let Some(row) = rows.next()? {
        let topic_id: i64 = row.get(0)?;
        let topic: String = row.get(1)?;
        let id = u16::try_from(topic_id).map_err(|_| BagError::TopicId {
            topic_id,
            topic: topic.clone(),
        })?;
        out.push((
            topic_id,
            ChannelInfo {
                id,
                topic,
                message_encoding: row.get(3)?,
                schema_id: 0,
                schema_name: row.get(2)?,
                schema_encoding: "ros2msg".into(),
                schema_data: Vec::new(),
                metadata: BTreeMap::new(),
            },
        ));
    }
    Ok(out)
}

thread_local! {
    /// Per-thread buffer for `MESSAGE`-mode decompression.
    static ZBUF: RefCell<Vec<u8>> = const { RefCell::new(Vec::new()) };
}

/// Calls `f` on a message's bytes, zstd-decompressed first when `zstd`;
/// decompression is bounded by [`MAX_MESSAGE`].
fn with_bytes<T>(
    data: &[u8],
    zstd: bool,
    f: impl FnOnce(&[u8]) -> T,
) -> std::result::Result<T, String> {
    if !zstd {
        return Ok(f(data));
    }
    ZBUF.with(|cell| {
        let mut buf = cell.borrow_mut();
        buf.clear();
        match zstd::zstd_safe::get_frame_content_size(data) {
            Ok(Some(n)) if n <= MAX_MESSAGE => {
                buf.try_reserve_exact(n as usize)
                    .map_err(|_| format!("cannot allocate {n} bytes"))?;
                zstd::bulk::Decompressor::new()
                    .and_then(|mut d| d.decompress_to_buffer(data, &mut *buf))
                    .map_err(|e| e.to_string())?;
            }
            Ok(Some(n)) => return Err(format!("declares {n} bytes, beyond {MAX_MESSAGE}")),
            Ok(None) => {
                let d =
                    zstd::stream::read::Decoder::with_buffer(data).map_err(|e| e.to_string())?;
                d.take(MAX_MESSAGE + 1)
                    .read_to_end(&mut buf)
                    .map_err(|e| e.to_string())?;
                if buf.len() as u64 > MAX_MESSAGE {
                    return Err(format!("decompresses beyond {MAX_MESSAGE} bytes"));
                }
            }
            Err(_) => return Err("not a zstd frame".into()),
        }
        Ok(f(&buf))
    })
}

/// Rowids below which a `.db3` is scanned by one connection.
const MIN_RANGE_ROWS: i128 = 1 << 15;

/// Which rows of a `.db3` a scan visits.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Rows {
    /// The wanted topics' rows only (`WHERE topic_id IN (…)`).
    Wanted,
    /// Every row, counted; only the wanted topics' data is read.
    All,
}

/// How a `.db3` scan reads the rows.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Via {
    /// From a map of the file's pages, through SQLite where that reader
    /// gives way.
    Pages,
    /// Through SQLite only: what the tests hold the page reader to.
    #[cfg_attr(not(test), allow(dead_code))]
    Sql,
}

/// Count, first and last stamp (ns) per channel id.
type Stats = HashMap<u16, (u64, u64, u64)>;

/// The wanted messages of one `.db3` in rowid order, each visited row counted
/// into `stats`. The rowid span is cut into one range per thread, each read
/// by its own read-only connection and mapped as it is read (the blob
/// borrowed from SQLite's page, never copied).
#[allow(clippy::too_many_arguments)]
fn sqlite_scan<T: Send + Default>(
    plain: &Path,
    label: &Path,
    table: &mut ChannelTable,
    zstd_messages: bool,
    visit: Rows,
    via: Via,
    want: &(impl Fn(&ChannelInfo) -> bool + Sync),
    map: &(impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync),
    stats: &mut Stats,
) -> Result<Vec<MappedMessage<T>>> {
    let at = |r: BagError| bag_err(label, r);
    let db = open_db(plain, label)?;
    // topics.id -> (channel id, wanted)
    let mut ids: HashMap<i64, (u16, bool)> = HashMap::new();
    for (topic_id, info) in topics(&db).map_err(at)? {
        let id = table.intern(info).map_err(at)?;
        ids.insert(topic_id, (id, table.channels.get(&id).is_some_and(want)));
    }
    let mut wanted: Vec<i64> = ids.iter().filter(|(_, v)| v.1).map(|(t, _)| *t).collect();
    wanted.sort_unstable();
    if wanted.is_empty() && visit == Rows::Wanted {
        return Ok(Vec::new());
    }
    // The pages are read inside a read transaction: SQLite's shared lock,
    // held until the connection closes, keeps any writer from changing the
    // file meanwhile (a writer needs the exclusive lock to write to it). A
    // file SQLite cannot lock now is read through SQL, which says why.
    let locked = via == Via::Pages
        && db
            .execute_batch("BEGIN")
            .and_then(|()| {
                db.query_row(
                    "SELECT count(*) FROM (SELECT 1 FROM messages LIMIT 1)",
                    [],
                    |r| r.get::<_, i64>(0),
                )
            })
            .is_ok();
    if locked {
        if let Some(out) = page_scan(
            plain,
            label,
            &ids,
            &table.channels,
            zstd_messages,
            visit,
            map,
            stats,
        )? {
            return Ok(out);
        }
    }
    // Two queries: SQLite answers a lone `min(id)` or `max(id)` from the
    // rowid b-tree's ends, but `SELECT min(id), max(id)` visits every row.
    let end = |sql: &str| -> Result<Option<i64>> {
        db.query_row(sql, [], |r| r.get(0))
            .map_err(|e| at(e.into()))
    };
    let span = (
        end("SELECT min(id) FROM messages")?,
        end("SELECT max(id) FROM messages")?,
    );
    drop(db);
    let (Some(lo), Some(hi)) = span else {
        return Ok(Vec::new());
    };
    let list = wanted
        .iter()
        .map(i64::to_string)
        .collect::<Vec<_>>()
        .join(",");
    // In id (rowid) order, which is the table's own: `ORDER BY timestamp, id`
    // would sort every row, data and all, in a temporary b-tree (4x slower on
    // 1e6 PoseStamped); the callers' stable sort by time gives that order.
    // Every row counted here rather than with `GROUP BY topic_id` (no index on
    // topic_id: a sort of every row, 4x slower).
    let sql = match visit {
        Rows::Wanted => format!(
            "SELECT id, topic_id, timestamp, data FROM messages \
             WHERE id BETWEEN ?1 AND ?2 AND topic_id IN ({list}) ORDER BY id"
        ),
        // The other rows' data is not read (NULL): no overflow page of theirs
        // is visited.
        Rows::All => format!(
            "SELECT id, topic_id, timestamp, {} FROM messages \
             WHERE id BETWEEN ?1 AND ?2 ORDER BY id",
            if wanted.is_empty() {
                "NULL".to_string()
            } else if wanted.len() == ids.len() {
                // Every topic wanted: no test per row.
                "data".to_string()
            } else {
                format!("CASE WHEN topic_id IN ({list}) THEN data END")
            }
        ),
    };
    // One range per thread, each read by its own connection into its own
    // region of the file's vector: region k has a slot per rowid of range k,
    // so that a table without gaps is read in place, nothing moved after.
    // In i128: rowids may span the whole i64 range.
    let span = i128::from(hi) - i128::from(lo) + 1;
    let parts = (rayon::current_num_threads() as i128).clamp(1, span / MIN_RANGE_ROWS + 1);
    let step = (span + parts - 1) / parts;
    let (lo_w, hi_w) = (i128::from(lo), i128::from(hi));
    let ranges: Vec<(i64, i64)> = (0..parts)
        .map(|k| lo_w + k * step)
        .filter(|&a| a <= hi_w)
        // Within [lo, hi]: the casts are exact.
        .map(|a| (a as i64, (a + step - 1).min(hi_w) as i64))
        .collect();
    // Slots only while the rowids are as many as the file could hold rows
    // (one per 16 bytes): past that (rowids far apart) the regions grow as
    // they are pushed. Pages never written are not resident, and the spare
    // capacity is given back after the merge.
    let file_rows = std::fs::metadata(plain).map_or(0, |m| m.len() / 16);
    let slots = span <= i128::from(file_rows);
    let lens: Vec<usize> = ranges
        .iter()
        // At most `file_rows` when `slots`: fits a usize.
        .map(|&(a, b)| {
            if slots {
                (i128::from(b) - i128::from(a) + 1) as usize
            } else {
                0
            }
        })
        .collect();
    let channels = &table.channels;
    let ids = &ids;
    let sql = sql.as_str();
    let (mut out, done) = crate::buffer::par_fill_regions(&lens, |k, region| {
        let db = open_db(plain, label)?;
        let sink = RowSink::new(visit, ids, channels, zstd_messages, map);
        sqlite_range(&db, sql, ranges[k], region, sink).map_err(at)
    });
    let parts = in_order(done, |e| match e {
        Error::Bag {
            reason: BagError::MessageData { index, .. },
            ..
        } => Some(index),
        _ => None,
    })?;
    for counts in parts {
        merge_stats(stats, counts);
    }
    out.shrink_to_fit();
    Ok(out)
}

/// The parts' counts in file order, or the first failed part's error, with
/// the index of a message that did not decompress (`index_of`, counted within
/// its part) made the index among the wanted messages of the whole file.
fn in_order<E>(
    done: Vec<(std::result::Result<Stats, E>, usize)>,
    index_of: impl Fn(&mut E) -> Option<&mut u64>,
) -> std::result::Result<Vec<Stats>, E> {
    let mut before = 0u64;
    let mut parts = Vec::with_capacity(done.len());
    for (part, count) in done {
        match part {
            Ok(counts) => parts.push(counts),
            Err(mut e) => {
                if let Some(index) = index_of(&mut e) {
                    *index += before;
                }
                return Err(e);
            }
        }
        before += count as u64;
    }
    Ok(parts)
}

/// What a `.db3` scan does with each row it visits, whether read through
/// SQLite or from the file's pages: counts it (per channel, in the order
/// first seen) and maps the wanted topics' messages into a region.
struct RowSink<'s, M> {
    visit: Rows,
    ids: &'s HashMap<i64, (u16, bool)>,
    channels: &'s BTreeMap<u16, ChannelInfo>,
    zstd_messages: bool,
    map: &'s M,
    /// Count, first and last stamp per channel, in the order first seen.
    seen: Vec<(u16, (u64, u64, u64))>,
    /// The last row's topic, its channel, whether kept, and its slot in
    /// `seen`: rows of one topic come in runs.
    last: Option<(i64, u16, bool, usize)>,
}

impl<'s, M> RowSink<'s, M> {
    fn new(
        visit: Rows,
        ids: &'s HashMap<i64, (u16, bool)>,
        channels: &'s BTreeMap<u16, ChannelInfo>,
        zstd_messages: bool,
        map: &'s M,
    ) -> Self {
        RowSink {
            visit,
            ids,
            channels,
            zstd_messages,
            map,
            seen: Vec::new(),
            last: None,
        }
    }

    /// Counts a row of `topic_id` at `time` (ns): the channel id when its
    /// data is wanted. With [`Rows::Wanted`], rows of the other topics (known
    /// or not) are passed over, uncounted, as `WHERE topic_id IN (…)` does;
    /// with [`Rows::All`] a topic the topics table does not list is an error
    /// naming the row (`rowid`, asked for only then).
    fn count(
        &mut self,
        topic_id: i64,
        time: u64,
        rowid: impl FnOnce() -> std::result::Result<i64, BagError>,
    ) -> std::result::Result<Option<u16>, BagError> {
        let (id, keep, slot) = match self.last {
            Some((t, id, keep, slot)) if t == topic_id => (id, keep, slot),
            _ => {
                let known = self.ids.get(&topic_id).copied();
                let Some((id, keep)) = known.filter(|k| k.1 || self.visit == Rows::All) else {
                    if self.visit == Rows::Wanted {
                        return Ok(None);
                    }
                    return Err(BagError::UnknownTopic {
                        topic_id,
                        row: rowid()?,
                    });
                };
                let slot = match self.seen.iter().position(|(c, _)| *c == id) {
                    Some(k) => k,
                    None => {
                        self.seen.push((id, (0, u64::MAX, 0)));
                        self.seen.len() - 1
                    }
                };
                self.last = Some((topic_id, id, keep, slot));
                (id, keep, slot)
            }
        };
        let s = &mut self.seen[slot].1;
        s.0 += 1;
        s.1 = s.1.min(time);
        s.2 = s.2.max(time);
        Ok(keep.then_some(id))
    }

    /// Maps a wanted row's `data` (zstd-decompressed first in `MESSAGE` mode)
    /// into `out`; a message that does not decompress is an error naming its
    /// index within the region.
    fn push<T>(
        &self,
        id: u16,
        time: u64,
        data: &[u8],
        out: &mut Region<'_, MappedMessage<T>>,
    ) -> std::result::Result<(), BagError>
    where
        M: Fn(&ChannelInfo, &RawMessage<'_>) -> T,
    {
        let c = &self.channels[&id];
        let value = with_bytes(data, self.zstd_messages, |data| {
            (self.map)(
                c,
                &RawMessage {
                    channel_id: id,
                    sequence: 0,
                    log_time: time,
                    publish_time: time,
                    data,
                },
            )
        })
        .map_err(|message| BagError::MessageData {
            index: out.len() as u64,
            topic: c.topic.clone(),
            message,
        })?;
        out.push(MappedMessage {
            channel_id: id,
            sequence: 0,
            log_time: time,
            publish_time: time,
            value,
        });
        Ok(())
    }

    fn stats(self) -> Stats {
        self.seen.into_iter().collect()
    }
}

/// The rows of one rowid range `(a, b)` of `sql`, counted and (the wanted
/// topics', whose data is not NULL) mapped into `out`; a message that does
/// not decompress stops the range (its index counted within the range).
fn sqlite_range<T: Send + Default>(
    db: &Connection,
    sql: &str,
    (a, b): (i64, i64),
    out: &mut Region<'_, MappedMessage<T>>,
    mut sink: RowSink<'_, impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync>,
) -> std::result::Result<Stats, BagError> {
    let mut stmt = db.prepare(sql)?;
    let mut rows = stmt.query([a, b])?;
    while let Some(row) = rows.next()? {
        let topic_id: i64 = row.get(1)?;
        let time = row.get::<_, i64>(2)?.max(0) as u64;
        let Some(id) = sink.count(topic_id, time, || Ok(row.get(0)?))? else {
            continue;
        };
        let data = row.get_ref(3)?.as_blob().map_err(rusqlite::Error::from)?;
        sink.push(id, time, data, out)?;
    }
    Ok(sink.stats())
}

/// The leaf pages of one part of a page scan, counted and mapped into `out`
/// like [`sqlite_range`]'s rows; [`Stop::Fallback`] when a page or row is
/// not one this reader reads.
fn page_range<T: Send + Default>(
    pages: &Pages<'_>,
    leaves: &[(u32, usize)],
    out: &mut Region<'_, MappedMessage<T>>,
    mut sink: RowSink<'_, impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync>,
) -> std::result::Result<Stats, Stop<BagError>> {
    let mut scratch = Vec::new();
    for &(leaf, _) in leaves {
        pages.rows(leaf, |row| {
            let time = row.timestamp.max(0) as u64;
            let Some(id) = sink
                .count(row.topic_id, time, || Ok(row.rowid))
                .map_err(Stop::Error)?
            else {
                return Ok(());
            };
            let data = row.data(&mut scratch).ok_or(Stop::Fallback)?;
            sink.push(id, time, data, out).map_err(Stop::Error)
        })?;
    }
    Ok(sink.stats())
}

/// The wanted messages of one `.db3` read from a map of its pages
/// ([`sqlite_pages`](super::sqlite_pages)), the leaves cut into one part per
/// thread; `Ok(None)` when that reader gives way to SQLite (the file in WAL
/// mode or with a hot journal, a table or page it does not read).
#[allow(clippy::too_many_arguments)]
fn page_scan<T: Send + Default>(
    plain: &Path,
    label: &Path,
    ids: &HashMap<i64, (u16, bool)>,
    channels: &BTreeMap<u16, ChannelInfo>,
    zstd_messages: bool,
    visit: Rows,
    map: &(impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync),
    stats: &mut Stats,
) -> Result<Option<Vec<MappedMessage<T>>>> {
    // A journal beside the file (a writer's uncommitted or interrupted
    // transaction) is SQLite's to roll back or read.
    for side in ["-journal", "-wal"] {
        let mut p = plain.as_os_str().to_owned();
        p.push(side);
        if std::fs::metadata(&p).is_ok_and(|m| m.len() > 0) {
            return Ok(None);
        }
    }
    let file = std::fs::File::open(plain).map_err(|e| Error::io(plain, e))?;
    let map_ = crate::io::mapped::Mapped::map(file, plain)?;
    let Some(pages) = Pages::open(&map_) else {
        return Ok(None);
    };
    let Some(leaves) = pages.messages_root().and_then(|root| pages.leaves(root)) else {
        return Ok(None);
    };
    // One part per thread, of about equal rows; region k has a slot per row of
    // part k, so that the rows are read in place.
    let rows: usize = leaves.iter().map(|l| l.1).sum();
    let parts = rayon::current_num_threads().clamp(1, rows / MIN_RANGE_ROWS as usize + 1);
    let mut cuts = vec![0usize];
    let mut acc = 0usize;
    for (k, leaf) in leaves.iter().enumerate() {
        acc += leaf.1;
        if acc * parts >= rows * cuts.len() && cuts.len() < parts && k + 1 < leaves.len() {
            cuts.push(k + 1);
        }
    }
    cuts.push(leaves.len());
    let parts: Vec<&[(u32, usize)]> = cuts.windows(2).map(|w| &leaves[w[0]..w[1]]).collect();
    let lens: Vec<usize> = parts.iter().map(|p| p.iter().map(|l| l.1).sum()).collect();
    let pages = &pages;
    let (mut out, done) = crate::buffer::par_fill_regions(&lens, |k, region| {
        let sink = RowSink::new(visit, ids, channels, zstd_messages, map);
        page_range(pages, parts[k], region, sink)
    });
    let found = match in_order(done, |e| match e {
        Stop::Error(BagError::MessageData { index, .. }) => Some(index),
        _ => None,
    }) {
        Ok(found) => found,
        Err(Stop::Fallback) => return Ok(None),
        Err(Stop::Error(reason)) => return Err(bag_err(label, reason)),
    };
    // A file cut short while it was read gave zero pages: an error, not rows.
    map_.check()?;
    for counts in found {
        merge_stats(stats, counts);
    }
    out.shrink_to_fit();
    Ok(Some(out))
}

/// Adds one part's counts and time ranges to a file's.
fn merge_stats(stats: &mut Stats, part: Stats) {
    for (id, (n, first, last)) in part {
        let s = stats.entry(id).or_insert((0, u64::MAX, 0));
        s.0 += n;
        s.1 = s.1.min(first);
        s.2 = s.2.max(last);
    }
}

/// What the map of an `.mcap` in `MESSAGE` mode gives: the value, or why the
/// message did not decompress.
enum Slot<T> {
    Value(T),
    Failed(String),
}

impl<T: Default> Default for Slot<T> {
    fn default() -> Self {
        Slot::Value(T::default())
    }
}

/// The wanted messages of one `.mcap`, with channel ids made those of `table`.
fn mcap_scan<T: Send + Default>(
    plain: &Path,
    label: &Path,
    table: &mut ChannelTable,
    zstd_messages: bool,
    want: &(impl Fn(&ChannelInfo) -> bool + Sync),
    map: &(impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync),
) -> Result<(Vec<MappedMessage<T>>, ReadMode)> {
    let file = McapFile::open(plain)?;
    // The file's channel id -> the table's channel.
    let mut remap: Vec<Option<u16>> = vec![None; 1 << 16];
    for info in file.channels()?.into_values() {
        let own = info.id;
        remap[own as usize] = Some(table.intern(info).map_err(|r| bag_err(label, r))?);
    }
    let channels = &table.channels;
    let of = |c: &ChannelInfo| remap[c.id as usize].and_then(|id| channels.get(&id));
    let scan = file.scan_map(
        |c| of(c).is_some_and(want),
        |c, m| {
            let Some(info) = of(c) else {
                return Slot::Value(T::default());
            };
            match with_bytes(m.data, zstd_messages, |data| {
                map(
                    info,
                    &RawMessage {
                        channel_id: info.id,
                        data,
                        ..*m
                    },
                )
            }) {
                Ok(v) => Slot::Value(v),
                Err(e) => Slot::Failed(e),
            }
        },
    )?;
    let mut out = Vec::with_capacity(scan.messages.len());
    for (index, m) in scan.messages.into_iter().enumerate() {
        let Some(id) = remap[m.channel_id as usize] else {
            continue;
        };
        let value = match m.value {
            Slot::Value(v) => v,
            Slot::Failed(message) => {
                return Err(bag_err(
                    label,
                    BagError::MessageData {
                        index: index as u64,
                        topic: channels[&id].topic.clone(),
                        message,
                    },
                ))
            }
        };
        out.push(MappedMessage {
            channel_id: id,
            sequence: m.sequence,
            log_time: m.log_time,
            publish_time: m.publish_time,
            value,
        });
    }
    Ok((out, scan.mode))
}

impl MessageSource for Ros2Bag {
    fn path(&self) -> &Path {
        &self.path
    }

    fn channels(&self) -> Result<BTreeMap<u16, ChannelInfo>> {
        Ros2Bag::channels(self)
    }

    fn scan_map<T: Send + Default>(
        &self,
        want: impl Fn(&ChannelInfo) -> bool + Sync,
        map: impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync,
    ) -> Result<MappedScan<T>> {
        Ros2Bag::scan_map(self, want, map)
    }

    fn inventory(&self) -> Result<Inventory> {
        Ros2Bag::inventory(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metadata_errors_name_the_place() {
        assert!(matches!(
            parse_metadata("rosbag2_bagfile_information: [1, 2"),
            Err(BagError::Metadata { line, .. }) if line >= 1
        ));
        assert!(matches!(
            parse_metadata("something_else: 1"),
            Err(BagError::Metadata { .. })
        ));
        let m = parse_metadata(
            "rosbag2_bagfile_information:\n  storage_identifier: mcap\n  relative_file_paths: [a.mcap]\n  custom_data: ~\n",
        )
        .unwrap();
        assert_eq!(m.storage_identifier, "mcap");
        assert_eq!(m.relative_file_paths, ["a.mcap"]);
    }

    #[test]
    fn channel_ids_are_kept_per_topic() {
        let mut t = ChannelTable::default();
        let info = |id: u16, topic: &str| ChannelInfo {
            id,
            topic: topic.into(),
            schema_name: "x/msg/Y".into(),
            ..ChannelInfo::default()
        };
        assert_eq!(t.intern(info(1, "/a")).unwrap(), 1);
        assert_eq!(t.intern(info(1, "/b")).unwrap(), 0);
        assert_eq!(t.intern(info(7, "/a")).unwrap(), 1);
        assert_eq!(t.intern(info(7, "/c")).unwrap(), 7);
    }

    #[test]
    fn message_decompression_is_checked() {
        let frame = zstd::bulk::compress(b"hello", 3).unwrap();
        assert_eq!(with_bytes(&frame, true, |d| d.to_vec()).unwrap(), b"hello");
        assert!(with_bytes(b"garbage!", true, |d| d.len()).is_err());
        assert_eq!(with_bytes(b"raw", false, |d| d.len()).unwrap(), 3);
    }

    /// A `.db3` written through SQL with `page_size` and `journal` mode: the
    /// rows `(id, topic, stamp, data)`, rosbag2's tables (topics 1 to
    /// `topics`), then `sql` run on it.
    fn db3(path: &Path, page_size: u32, journal: &str, topics: i64, rows: &[Db3Row], sql: &str) {
        let c = rusqlite::Connection::open(path).unwrap();
        c.execute_batch(&format!(
            "PRAGMA page_size = {page_size}; PRAGMA journal_mode = {journal};
             CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, \
             serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
             CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, \
             timestamp INTEGER NOT NULL, data BLOB NOT NULL);
             CREATE INDEX timestamp_idx ON messages (timestamp ASC);"
        ))
        .unwrap();
        for t in 1..=topics {
            c.execute(
                "INSERT INTO topics VALUES (?1, ?2, 'std_msgs/msg/String', 'cdr', '')",
                rusqlite::params![t, format!("/t{t}")],
            )
            .unwrap();
        }
        c.execute_batch("BEGIN").unwrap();
        {
            let mut ins = c
                .prepare("INSERT INTO messages VALUES (?1, ?2, ?3, ?4)")
                .unwrap();
            for (id, topic, stamp, data) in rows {
                ins.execute(rusqlite::params![id, topic, stamp, data])
                    .unwrap();
            }
        }
        c.execute_batch("COMMIT").unwrap();
        c.execute_batch(sql).unwrap();
    }

    type Db3Row = (i64, i64, i64, Vec<u8>);

    /// `n` rows on topics 1 to 3 with rowid gaps and stamps out of order;
    /// every 50th row's data spills over several pages of `page_size`, every
    /// 50th after it lies about the size where a cell starts to spill.
    fn db3_rows(n: i64, page_size: usize) -> Vec<Db3Row> {
        (0..n)
            .map(|k| {
                let len = match k % 50 {
                    0 => (3 * page_size).min(20_000) + (k % 97) as usize,
                    1 => page_size - 37 + (k % 5) as usize,
                    _ => 8 + (k % 33) as usize,
                };
                let data = (0..len).map(|j| (k as usize * 31 + j) as u8).collect();
                let stamp = if k % 1000 == 999 { k - 500 } else { k } * 1000;
                (k + k / 7 + 1, 1 + (k / 3) % 3, stamp, data)
            })
            .collect()
    }

    type Scanned = (Vec<(u16, u64, Vec<u8>)>, Stats);

    /// The messages (channel, stamp, data) of the topics `want` names, and
    /// the counts, read `via` pages or SQL.
    fn scan(path: &Path, visit: Rows, via: Via, want: &[&str]) -> Result<Scanned> {
        let mut table = ChannelTable::default();
        let mut stats = Stats::new();
        let got = sqlite_scan(
            path,
            path,
            &mut table,
            false,
            visit,
            via,
            &|c: &ChannelInfo| want.contains(&c.topic.as_str()),
            &|_: &ChannelInfo, m: &RawMessage<'_>| m.data.to_vec(),
            &mut stats,
        )?;
        let got = got
            .into_iter()
            .map(|m| (m.channel_id, m.log_time, m.value))
            .collect();
        Ok((got, stats))
    }

    /// True when the file's pages are read without giving way to SQLite.
    fn read_from_pages(path: &Path, visit: Rows) -> bool {
        let db = open_db(path, path).unwrap();
        let listed = topics(&db).unwrap();
        let ids: HashMap<i64, (u16, bool)> =
            listed.iter().map(|(t, c)| (*t, (c.id, true))).collect();
        let channels = listed.into_iter().map(|(_, c)| (c.id, c)).collect();
        let map = |_: &ChannelInfo, m: &RawMessage<'_>| m.data.len();
        let mut stats = Stats::new();
        page_scan(path, path, &ids, &channels, false, visit, &map, &mut stats)
            .unwrap()
            .is_some()
    }

    #[test]
    fn db3_pages_read_what_sqlite_reads() {
        let dir = tempfile::tempdir().unwrap();
        for page_size in [512u32, 4096, 65536] {
            let path = dir.path().join(format!("p{page_size}.db3"));
            let rows = db3_rows(20_000, page_size as usize);
            // Rows deleted and grown after the insert: freed pages, cells
            // moved, new overflow chains.
            let after = "DELETE FROM messages WHERE id % 11 = 0; \
                         UPDATE messages SET data = CAST(zeroblob(1500) || data AS BLOB) WHERE id % 13 = 0;";
            db3(&path, page_size, "DELETE", 3, &rows, after);
            for visit in [Rows::Wanted, Rows::All] {
                assert!(read_from_pages(&path, visit), "page size {page_size}");
                for want in [&["/t1", "/t3"][..], &["/t2"], &[]] {
                    let pages = scan(&path, visit, Via::Pages, want).unwrap();
                    let sql = scan(&path, visit, Via::Sql, want).unwrap();
                    assert_eq!(pages.1, sql.1, "counts, page size {page_size}");
                    assert!(
                        pages.0 == sql.0,
                        "messages, page size {page_size}, {want:?}"
                    );
                    if visit == Rows::All {
                        assert_eq!(pages.1.values().map(|s| s.0).sum::<u64>(), 18_182);
                    }
                }
            }
        }
    }

    #[test]
    fn db3_pages_give_way_to_sqlite_where_it_knows_better() {
        let dir = tempfile::tempdir().unwrap();
        let rows = db3_rows(3000, 4096);
        let same = |path: &Path| {
            for visit in [Rows::Wanted, Rows::All] {
                let pages = scan(path, visit, Via::Pages, &["/t1", "/t2"]);
                let sql = scan(path, visit, Via::Sql, &["/t1", "/t2"]);
                match (pages, sql) {
                    (Ok(p), Ok(s)) => assert!(p == s),
                    (Err(p), Err(s)) => assert_eq!(p.to_string(), s.to_string()),
                    (p, s) => panic!("pages {:?}, sql {:?}", p.is_ok(), s.is_ok()),
                }
            }
        };
        // WAL mode: the header says so, whether or not a -wal file is left.
        let wal = dir.path().join("wal.db3");
        db3(&wal, 4096, "WAL", 3, &rows, "");
        assert!(!read_from_pages(&wal, Rows::All));
        same(&wal);
        // Columns in another order than rosbag2's.
        let other = dir.path().join("other.db3");
        db3(
            &other,
            4096,
            "DELETE",
            3,
            &rows,
            "ALTER TABLE messages RENAME TO old; \
             CREATE TABLE messages(id INTEGER PRIMARY KEY, timestamp INTEGER, topic_id INTEGER, data BLOB); \
             INSERT INTO messages SELECT id, timestamp, topic_id, data FROM old; DROP TABLE old;",
        );
        assert!(!read_from_pages(&other, Rows::All));
        same(&other);
        // A row whose data is text: SQLite names the error.
        let text = dir.path().join("text.db3");
        db3(
            &text,
            4096,
            "DELETE",
            3,
            &rows,
            "UPDATE messages SET data = 'x' WHERE id = 2;",
        );
        assert!(!read_from_pages(&text, Rows::All));
        same(&text);
        assert!(scan(&text, Rows::All, Via::Pages, &["/t1"]).is_err());
        // Not an error where the row's data is not read (another topic's).
        assert_eq!(
            scan(&text, Rows::All, Via::Pages, &["/t2"]).unwrap(),
            scan(&text, Rows::All, Via::Sql, &["/t2"]).unwrap()
        );
        // A topic the topics table does not list: the same error, the same row.
        let unknown = dir.path().join("unknown.db3");
        db3(&unknown, 4096, "DELETE", 2, &rows, "");
        same(&unknown);
        let e = scan(&unknown, Rows::All, Via::Pages, &["/t1"]).unwrap_err();
        assert!(
            matches!(
                e,
                Error::Bag {
                    reason: BagError::UnknownTopic {
                        topic_id: 3,
                        row: 7
                    },
                    ..
                }
            ),
            "{e}"
        );
        // Without the unlisted topic's rows, only the wanted are read.
        assert_eq!(
            scan(&unknown, Rows::Wanted, Via::Pages, &["/t1"])
                .unwrap()
                .0
                .len(),
            scan(&unknown, Rows::Wanted, Via::Sql, &["/t1"])
                .unwrap()
                .0
                .len()
        );
    }
}
