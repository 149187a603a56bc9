//! rosbag2 bags: a folder (`metadata.yaml` beside `.db3` or `.mcap` files) or
//! a single `.db3` / `.mcap` file.
//!
//! - `metadata.yaml` gives the storage (`sqlite3` or `mcap`), the files
//!   (relative to the folder) and the compression: none, zstd per file
//!   (`FILE`: each file is `*.db3.zstd` / `*.mcap.zstd`, decompressed to a
//!   temporary file while it is read) or zstd per message (`MESSAGE`: each
//!   message's bytes are one zstd frame). Offered QoS profiles are ignored.
//! - A `.db3` is read through SQLite: `topics(id, name, type,
//!   serialization_format, …)` and `messages(id, topic_id, timestamp, data)`.
//!   It has type names but no definitions: channels get `schema_encoding`
//!   `ros2msg` and empty `schema_data`.
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
                    let visit = Rows::Wanted;
                    sqlite_scan(
                        plain,
                        label,
                        &mut table,
                        zstd_messages,
                        visit,
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
        sqlite_range(
            &db,
            sql,
            ranges[k],
            region,
            ids,
            channels,
            zstd_messages,
            map,
        )
        .map_err(at)
    });
    let mut before = 0u64;
    for (part, count) in done {
        let counts = part.map_err(|mut e| {
            // The index among the wanted messages of the whole file.
            if let Error::Bag {
                reason: BagError::MessageData { index, .. },
                ..
            } = &mut e
            {
                *index += before;
            }
            e
        })?;
        before += count as u64;
        for (id, (n, first, last)) in counts {
            let s = stats.entry(id).or_insert((0, u64::MAX, 0));
            s.0 += n;
            s.1 = s.1.min(first);
            s.2 = s.2.max(last);
        }
    }
    out.shrink_to_fit();
    Ok(out)
}

/// The rows of one rowid range `(a, b)` of `sql`, counted and (the wanted
/// topics', whose data is not NULL) mapped into `out`; a message that does
/// not decompress stops the range (its index counted within the range).
#[allow(clippy::too_many_arguments)]
fn sqlite_range<T: Send + Default>(
    db: &Connection,
    sql: &str,
    (a, b): (i64, i64),
    out: &mut Region<'_, MappedMessage<T>>,
    ids: &HashMap<i64, (u16, bool)>,
    channels: &BTreeMap<u16, ChannelInfo>,
    zstd_messages: bool,
    map: &(impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync),
) -> std::result::Result<Stats, BagError> {
    let mut stmt = db.prepare(sql)?;
    let mut rows = stmt.query([a, b])?;
    // Count, first and last stamp per channel, in the order first seen.
    let mut seen: Vec<(u16, (u64, u64, u64))> = Vec::new();
    // The last row's topic and its slot in `seen`: rows of one topic come in
    // runs.
    let mut last: Option<(i64, u16, bool, usize)> = None;
    while let Some(row) = rows.next()? {
        let topic_id: i64 = row.get(1)?;
        let time = row.get::<_, i64>(2)?.max(0) as u64;
        let (id, keep, slot) = match last {
            Some((t, id, keep, slot)) if t == topic_id => (id, keep, slot),
            _ => {
                let Some(&(id, keep)) = ids.get(&topic_id) else {
                    return Err(BagError::UnknownTopic {
                        topic_id,
                        row: row.get(0)?,
                    });
                };
                let slot = match seen.iter().position(|(c, _)| *c == id) {
                    Some(k) => k,
                    None => {
                        seen.push((id, (0, u64::MAX, 0)));
                        seen.len() - 1
                    }
                };
                last = Some((topic_id, id, keep, slot));
                (id, keep, slot)
            }
        };
        let s = &mut seen[slot].1;
        s.0 += 1;
        s.1 = s.1.min(time);
        s.2 = s.2.max(time);
        if !keep {
            continue;
        }
        let data = row.get_ref(3)?.as_blob().map_err(rusqlite::Error::from)?;
        let c = &channels[&id];
        let value = with_bytes(data, zstd_messages, |data| {
            map(
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
    }
    Ok(seen.into_iter().collect())
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
}
