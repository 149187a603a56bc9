//! ROS 1 bags, format version 2.0, over a memory map.
//!
//! A bag is the line `#ROSBAG V2.0\n`, a bag header record (op 0x03) that says
//! where the index starts (`index_pos`), then chunks (op 0x05: `none`, `bz2` or
//! `lz4` as `roslz4` writes it, i.e. LZ4 frames), each followed by one index
//! data record (op 0x04) per connection in it, and at `index_pos` the index:
//! connection records (op 0x07) and chunk info records (op 0x06). Messages
//! (op 0x02) and the first definition of each connection live in the chunks.
//!
//! With a readable index, only the chunks that hold a wanted connection are
//! read. A bag that was not closed (`index_pos` 0, the index cut off or
//! unreadable: what `rosbag reindex` would repair) is read record by record
//! from the start. Either way chunks are decompressed in parallel (rayon), each
//! into a per-thread buffer that the next chunk reuses, and every declared
//! length is checked against the bytes that remain before anything is read or
//! allocated.
//!
//! Record times are `u64` nanoseconds (`sec·1e9 + nsec` of the record's `time`).

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::{sort_by_time, BagError};
use crate::error::{Error, Result};
use crate::io::container::ROS1_MAGIC;
use crate::io::messages::{
    ChannelCount, ChannelInfo, Inventory, MappedMessage, MappedScan, MessageSource, RawMessage,
    ReadMode,
};

/// Record op codes of the bag format 2.0.
mod op {
    pub const MESSAGE_DATA: u8 = 0x02;
    pub const BAG_HEADER: u8 = 0x03;
    pub const INDEX_DATA: u8 = 0x04;
    pub const CHUNK: u8 = 0x05;
    pub const CHUNK_INFO: u8 = 0x06;
    pub const CONNECTION: u8 = 0x07;
}

/// The largest uncompressed chunk accepted (guards allocations against damaged
/// headers; `rosbag record` writes chunks of 768 KiB, or one large message).
pub const MAX_CHUNK: u64 = 1 << 30;

/// A fault at a byte offset of the file.
#[derive(Debug)]
struct Fault {
    offset: u64,
    reason: BagError,
}

type Res<T> = std::result::Result<T, Fault>;

fn fault(offset: usize, reason: BagError) -> Fault {
    Fault {
        offset: offset as u64,
        reason,
    }
}

/// One record: its header fields and its data, both borrowed.
#[derive(Clone, Copy, Debug)]
struct RawRecord<'a> {
    header: &'a [u8],
    data: &'a [u8],
    /// Offset just past the record in the buffer it was read from.
    end: usize,
}

fn le_u32(b: &[u8]) -> u32 {
    u32::from_le_bytes([b[0], b[1], b[2], b[3]])
}

/// Reads the record at `pos` of `buf`, checking both lengths against what remains.
fn read_record(buf: &[u8], pos: usize) -> std::result::Result<RawRecord<'_>, BagError> {
    let rest = buf.get(pos..).unwrap_or(&[]);
    let len_at = |at: usize, what: &'static str| -> std::result::Result<usize, BagError> {
        match rest.get(at..at + 4) {
            Some(b) => Ok(le_u32(b) as usize),
            None => Err(BagError::Truncated {
                what,
                needed: 4,
                available: rest.len().saturating_sub(at) as u64,
            }),
        }
    };
    let header_len = len_at(0, "record header length")?;
    let header = rest
        .get(4..4usize.saturating_add(header_len))
        .ok_or(BagError::Truncated {
            what: "record header",
            needed: header_len as u64,
            available: rest.len().saturating_sub(4) as u64,
        })?;
    let data_at = 4 + header_len;
    let data_len = len_at(data_at, "record data length")?;
    let data = rest
        .get(data_at + 4..(data_at + 4).saturating_add(data_len))
        .ok_or(BagError::Truncated {
            what: "record data",
            needed: data_len as u64,
            available: rest.len().saturating_sub(data_at + 4) as u64,
        })?;
    Ok(RawRecord {
        header,
        data,
        end: pos + data_at + 4 + data_len,
    })
}

/// Calls `f(name, value)` for every `name=value` field of a record header.
fn for_fields<'a>(
    header: &'a [u8],
    record: &'static str,
    mut f: impl FnMut(&'a [u8], &'a [u8]),
) -> std::result::Result<(), BagError> {
    let mut pos = 0;
    while pos < header.len() {
        let Some(len) = header.get(pos..pos + 4).map(le_u32) else {
            return Err(BagError::Truncated {
                what: "header field length",
                needed: 4,
                available: (header.len() - pos) as u64,
            });
        };
        let len = len as usize;
        let Some(field) = header.get(pos + 4..(pos + 4).saturating_add(len)) else {
            return Err(BagError::Truncated {
                what: "header field",
                needed: len as u64,
                available: (header.len() - pos - 4) as u64,
            });
        };
        let Some(eq) = field.iter().position(|&b| b == b'=') else {
            return Err(BagError::BadField {
                record,
                field: String::from_utf8_lossy(&field[..field.len().min(32)]).into_owned(),
                expected: "name=value",
                found: field.len(),
            });
        };
        f(&field[..eq], &field[eq + 1..]);
        pos += 4 + len;
    }
    Ok(())
}

/// The fields of any record header that the reader uses.
#[derive(Clone, Copy, Debug, Default)]
struct Header<'a> {
    op: Option<&'a [u8]>,
    conn: Option<&'a [u8]>,
    time: Option<&'a [u8]>,
    compression: Option<&'a [u8]>,
    size: Option<&'a [u8]>,
    index_pos: Option<&'a [u8]>,
    conn_count: Option<&'a [u8]>,
    chunk_count: Option<&'a [u8]>,
    ver: Option<&'a [u8]>,
    count: Option<&'a [u8]>,
    chunk_pos: Option<&'a [u8]>,
    topic: Option<&'a [u8]>,
}

impl<'a> Header<'a> {
    fn parse(header: &'a [u8], record: &'static str) -> std::result::Result<Self, BagError> {
        let mut h = Header::default();
        for_fields(header, record, |name, value| {
            let slot = match name {
                b"op" => &mut h.op,
                b"conn" => &mut h.conn,
                b"time" => &mut h.time,
                b"compression" => &mut h.compression,
                b"size" => &mut h.size,
                b"index_pos" => &mut h.index_pos,
                b"conn_count" => &mut h.conn_count,
                b"chunk_count" => &mut h.chunk_count,
                b"ver" => &mut h.ver,
                b"count" => &mut h.count,
                b"chunk_pos" => &mut h.chunk_pos,
                b"topic" => &mut h.topic,
                _ => return,
            };
            *slot = Some(value);
        })?;
        Ok(h)
    }

    fn op(&self) -> std::result::Result<u8, BagError> {
        match self.op {
            Some([op]) => Ok(*op),
            Some(v) => Err(BagError::BadField {
                record: "record",
                field: "op".into(),
                expected: "1 byte",
                found: v.len(),
            }),
            None => Err(BagError::MissingField {
                record: "record",
                field: "op",
            }),
        }
    }
}

/// The value of a fixed-size field: present and of `N` bytes.
fn fixed<const N: usize>(
    value: Option<&[u8]>,
    record: &'static str,
    field: &'static str,
) -> std::result::Result<[u8; N], BagError> {
    let v = value.ok_or(BagError::MissingField { record, field })?;
    v.try_into().map_err(|_| BagError::BadField {
        record,
        field: field.into(),
        expected: if N == 4 { "4 bytes" } else { "8 bytes" },
        found: v.len(),
    })
}

fn field_u32(
    v: Option<&[u8]>,
    record: &'static str,
    field: &'static str,
) -> std::result::Result<u32, BagError> {
    fixed::<4>(v, record, field).map(u32::from_le_bytes)
}

fn field_u64(
    v: Option<&[u8]>,
    record: &'static str,
    field: &'static str,
) -> std::result::Result<u64, BagError> {
    fixed::<8>(v, record, field).map(u64::from_le_bytes)
}

/// A ROS time (u32 seconds, u32 nanoseconds) as nanoseconds.
fn time_ns(b: [u8; 8]) -> u64 {
    let sec = u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as u64;
    let nsec = u32::from_le_bytes([b[4], b[5], b[6], b[7]]) as u64;
    sec * 1_000_000_000 + nsec
}

/// What the bag header record says.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BagHeader {
    /// Offset of the index (connection and chunk info records); 0 in a bag
    /// that was not closed.
    pub index_pos: u64,
    /// Connections the index lists.
    pub conn_count: u32,
    /// Chunks the index lists.
    pub chunk_count: u32,
    /// Offset of the first record after the bag header.
    pub data_start: u64,
}

/// A connection record: its id and the channel it becomes.
fn connection(rec: &RawRecord<'_>, h: &Header<'_>) -> std::result::Result<ChannelInfo, BagError> {
    const R: &str = "connection";
    let conn = field_u32(h.conn, R, "conn")?;
    let id = u16::try_from(conn).map_err(|_| BagError::TooManyConnections { conn })?;
    let topic = h.topic.ok_or(BagError::MissingField {
        record: R,
        field: "topic",
    })?;
    let mut info = ChannelInfo {
        id,
        topic: String::from_utf8_lossy(topic).into_owned(),
        message_encoding: "ros1".into(),
        schema_encoding: "ros1msg".into(),
        ..ChannelInfo::default()
    };
    let mut ty = None;
    for_fields(rec.data, R, |name, value| match name {
        b"type" => ty = Some(value),
        b"message_definition" => info.schema_data = value.to_vec(),
        b"md5sum" | b"callerid" | b"latching" => {
            info.metadata.insert(
                String::from_utf8_lossy(name).into_owned(),
                String::from_utf8_lossy(value).into_owned(),
            );
        }
        _ => {}
    })?;
    info.schema_name = String::from_utf8_lossy(ty.ok_or(BagError::MissingField {
        record: R,
        field: "type",
    })?)
    .into_owned();
    Ok(info)
}

/// A chunk info record: where the chunk is and which connections it holds.
#[derive(Clone, Debug)]
struct ChunkInfo {
    pos: usize,
    /// `(connection, messages)` in the chunk.
    counts: Vec<(u32, u32)>,
}

fn chunk_info(rec: &RawRecord<'_>, h: &Header<'_>) -> std::result::Result<ChunkInfo, BagError> {
    const R: &str = "chunk info";
    let ver = field_u32(h.ver, R, "ver")?;
    if ver != 1 {
        return Err(BagError::BadField {
            record: R,
            field: format!("ver={ver}"),
            expected: "version 1",
            found: 4,
        });
    }
    let pos = field_u64(h.chunk_pos, R, "chunk_pos")?;
    let count = field_u32(h.count, R, "count")? as u64;
    if count * 8 > rec.data.len() as u64 {
        return Err(BagError::Truncated {
            what: "chunk info entries",
            needed: count * 8,
            available: rec.data.len() as u64,
        });
    }
    let counts = rec.data[..count as usize * 8]
        .chunks_exact(8)
        .map(|e| (le_u32(&e[..4]), le_u32(&e[4..])))
        .collect();
    Ok(ChunkInfo {
        pos: usize::try_from(pos).unwrap_or(usize::MAX),
        counts,
    })
}

/// The index at the end of a closed bag.
struct Index {
    channels: BTreeMap<u16, ChannelInfo>,
    chunks: Vec<ChunkInfo>,
}

/// A ROS 1 bag (format 2.0), opened read-only and memory-mapped.
pub struct Ros1Bag {
    path: PathBuf,
    map: crate::io::mapped::Mapped,
    header: BagHeader,
    index: Option<Index>,
}

impl std::fmt::Debug for Ros1Bag {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ros1Bag")
            .field("path", &self.path)
            .field("header", &self.header)
            .field("indexed", &self.index.is_some())
            .finish()
    }
}

/// What a chunk task gives: its connection records, its mapped messages, and
/// the messages whose connection it could not see.
struct Part<T> {
    defs: Vec<ChannelInfo>,
    msgs: Vec<MappedMessage<T>>,
    deferred: Vec<Deferred>,
}

/// A message whose connection its chunk task could not see: its position in
/// the task's messages, connection id, index in the chunk, chunk offset,
/// record time (ns) and bytes.
type Deferred = (usize, u32, u64, usize, u64, Vec<u8>);

/// Connections known to the chunk tasks: `(channel, wanted)` by id.
type Table<'k> = Vec<Option<(&'k ChannelInfo, bool)>>;

fn table_of<'k>(
    known: &'k BTreeMap<u16, ChannelInfo>,
    want: &impl Fn(&ChannelInfo) -> bool,
) -> Table<'k> {
    let mut table = vec![None; 1 << 16];
    for c in known.values() {
        table[c.id as usize] = Some((c, want(c)));
    }
    table
}

impl Ros1Bag {
    /// Opens and maps `path` (read-only), reads the bag header and, when the
    /// bag was closed, its index. Fails on a missing file, a file that is not a
    /// version 2.0 bag, or a bag header that cannot be read; an index that
    /// cannot be read is not an error (the bag is then read linearly).
    pub fn open(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref().to_path_buf();
        let file = std::fs::File::open(&path).map_err(|e| Error::io(&path, e))?;
        let len = file.metadata().map_err(|e| Error::io(&path, e))?.len();
        if len == 0 {
            return Err(bag_err(
                &path,
                fault(
                    0,
                    BagError::NotABag {
                        found: String::new(),
                    },
                ),
            ));
        }
        // A bag truncated while it is read is an error, not SIGBUS (io::mapped).
        let map = crate::io::mapped::Mapped::map(file, &path)?;
        let header = bag_header(&map).map_err(|f| bag_err(&path, f))?;
        let mut bag = Ros1Bag {
            path,
            map,
            header,
            index: None,
        };
        bag.index = bag.read_index();
        Ok(bag)
    }

    /// The bag's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// What the bag header record says.
    pub fn header(&self) -> BagHeader {
        self.header
    }

    /// `Indexed` when the index at the end of the bag is readable (then it is
    /// used), `Linear` otherwise.
    pub fn mode(&self) -> ReadMode {
        if self.index.is_some() {
            ReadMode::Indexed
        } else {
            ReadMode::Linear
        }
    }

    fn err(&self, f: Fault) -> Error {
        bag_err(&self.path, f)
    }

    /// The index, when `index_pos` points at `conn_count` connection records and
    /// `chunk_count` chunk info records whose chunks are chunks of this file.
    fn read_index(&self) -> Option<Index> {
        let map: &[u8] = &self.map;
        let start = usize::try_from(self.header.index_pos).ok()?;
        if start == 0 || (start as u64) < self.header.data_start || start >= map.len() {
            return None;
        }
        let mut channels = BTreeMap::new();
        let mut chunks = Vec::new();
        let mut conns = 0u32;
        let mut pos = start;
        while pos < map.len() {
            let rec = read_record(map, pos).ok()?;
            let h = Header::parse(rec.header, "index").ok()?;
            match h.op().ok()? {
                op::CONNECTION => {
                    let info = connection(&rec, &h).ok()?;
                    conns += 1;
                    channels.entry(info.id).or_insert(info);
                }
                op::CHUNK_INFO => chunks.push(chunk_info(&rec, &h).ok()?),
                _ => return None,
            }
            pos = rec.end;
        }
        if conns != self.header.conn_count || chunks.len() != self.header.chunk_count as usize {
            return None;
        }
        for c in &chunks {
            if c.pos < self.header.data_start as usize || c.pos >= start {
                return None;
            }
            let rec = read_record(&map[..start], c.pos).ok()?;
            let h = Header::parse(rec.header, "chunk").ok()?;
            if h.op().ok()? != op::CHUNK {
                return None;
            }
            if c.counts.iter().any(|(conn, _)| {
                u16::try_from(*conn).map_or(true, |id| !channels.contains_key(&id))
            }) {
                return None;
            }
        }
        chunks.sort_by_key(|c| c.pos);
        Some(Index { channels, chunks })
    }

    /// The connections as channels, by id: from the index when there is one,
    /// else by reading every chunk.
    pub fn channels(&self) -> Result<BTreeMap<u16, ChannelInfo>> {
        if let Some(index) = &self.index {
            return Ok(index.channels.clone());
        }
        Ok(self.scan_map(|_| false, |_, _| ())?.channels)
    }

    /// The top-level records of the chunk section: chunk offsets, and the
    /// connection records found outside chunks. Message data records outside a
    /// chunk and a second bag header are refused.
    fn linear_plan(&self) -> Res<(Vec<usize>, Vec<ChannelInfo>)> {
        let map: &[u8] = &self.map;
        let mut pos = self.header.data_start as usize;
        let mut chunks = Vec::new();
        let mut defs = Vec::new();
        while pos < map.len() {
            let rec = read_record(map, pos).map_err(|r| fault(pos, r))?;
            let h = Header::parse(rec.header, "record").map_err(|r| fault(pos, r))?;
            match h.op().map_err(|r| fault(pos, r))? {
                op::CHUNK => chunks.push(pos),
                op::INDEX_DATA | op::CHUNK_INFO => {}
                op::CONNECTION => defs.push(connection(&rec, &h).map_err(|r| fault(pos, r))?),
                other => {
                    return Err(fault(
                        pos,
                        BagError::UnexpectedRecord {
                            op: other,
                            context: "between chunks (expected a chunk, index data, connection or chunk info record)",
                        },
                    ))
                }
            }
            pos = rec.end;
        }
        Ok((chunks, defs))
    }

    /// Every message of a connection `want` keeps, passed to `map` inside the
    /// parallel chunk tasks; only the mapped values are kept, and each chunk's
    /// buffer is reused for the next chunk of its thread.
    ///
    /// Order: by record time, as `rosbag` plays a bag; messages of equal time
    /// keep file order (chunk by chunk, record by record). The channel ids are
    /// the connection ids, `log_time` and `publish_time` the record time in
    /// nanoseconds, `sequence` 0.
    pub fn scan_map<T: Send + Default>(
        &self,
        want: impl Fn(&ChannelInfo) -> bool + Sync,
        map: impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync,
    ) -> Result<MappedScan<T>> {
        let (chunks, mut known, mode) = match &self.index {
            Some(index) => {
                // Only the chunks that hold a wanted connection.
                let wanted: Vec<bool> = {
                    let mut w = vec![false; 1 << 16];
                    for c in index.channels.values() {
                        w[c.id as usize] = want(c);
                    }
                    w
                };
                // (offset, wanted messages the chunk info announces)
                let chunks: Vec<(usize, usize)> = index
                    .chunks
                    .iter()
                    .map(|ci| {
                        let n: u64 = ci
                            .counts
                            .iter()
                            .filter(|&&(conn, _)| wanted[conn as usize & 0xffff])
                            .map(|&(_, n)| n as u64)
                            .sum();
                        (ci.pos, n as usize)
                    })
                    .filter(|&(_, n)| n > 0)
                    .collect();
                (chunks, index.channels.clone(), ReadMode::Indexed)
            }
            None => {
                let (chunks, defs) = self.linear_plan().map_err(|f| self.err(f))?;
                let chunks = chunks.into_iter().map(|pos| (pos, 0)).collect();
                let mut known = BTreeMap::new();
                for d in defs {
                    known.entry(d.id).or_insert(d);
                }
                (chunks, known, ReadMode::Linear)
            }
        };
        // Linear: waves of chunks, so that a connection defined in one wave is
        // known to the tasks of the next (writers define it in the chunk of its
        // first message); indexed: every connection is known, one wave.
        let wave = match mode {
            ReadMode::Indexed => chunks.len().max(1),
            ReadMode::Linear => (rayon::current_num_threads() * 4).max(4),
        };
        let mut messages: Vec<MappedMessage<T>> = Vec::new();
        for batch in chunks.chunks(wave) {
            let parts: Vec<Res<Part<T>>> = {
                let table = table_of(&known, &want);
                batch
                    .par_iter()
                    .map_init(Vec::new, |buf, &(pos, hint)| {
                        self.map_chunk(pos, hint, &table, buf, &want, &map)
                    })
                    .collect()
            };
            let mut deferred = Vec::new();
            let mut releaser = crate::buffer::Releaser::default();
            for part in parts {
                let part = part.map_err(|f| self.err(f))?;
                releaser.freed(part.msgs.capacity() * std::mem::size_of::<MappedMessage<T>>());
                for d in part.defs {
                    known.entry(d.id).or_insert(d);
                }
                let base = messages.len();
                for (j, conn, index, pos, time, bytes) in part.deferred {
                    deferred.push((base + j, conn, index, pos, time, bytes));
                }
                messages.extend(part.msgs);
            }
            if deferred.is_empty() {
                continue;
            }
            // Messages of connections defined in the same wave: map them now.
            let values: Vec<std::result::Result<(usize, Option<T>), Fault>> = deferred
                .into_par_iter()
                .map(|(k, conn, index, pos, time, bytes)| {
                    let Some(c) = known.get(&(conn as u16)) else {
                        return Err(fault(pos, BagError::UnknownConnection { conn, index }));
                    };
                    if !want(c) {
                        return Ok((k, None));
                    }
                    let raw = RawMessage {
                        channel_id: c.id,
                        sequence: 0,
                        log_time: time,
                        publish_time: time,
                        data: &bytes,
                    };
                    Ok((k, Some(map(c, &raw))))
                })
                .collect();
            let mut drop_at = Vec::new();
            for v in values {
                match v.map_err(|f| self.err(f))? {
                    (k, Some(value)) => messages[k].value = value,
                    (k, None) => drop_at.push(k),
                }
            }
            if !drop_at.is_empty() {
                let mut i = 0;
                drop_at.sort_unstable();
                let mut d = drop_at.iter().peekable();
                messages.retain(|_| {
                    let keep = d.peek() != Some(&&i);
                    if !keep {
                        d.next();
                    }
                    i += 1;
                    keep
                });
            }
        }
        sort_by_time(&mut messages);
        Ok(MappedScan {
            channels: known,
            messages,
            mode,
            profile: "ros1".into(),
        })
    }

    /// Decompresses the chunk at `pos` into `buf` (or borrows it from the map
    /// when uncompressed) and maps its wanted messages (`hint`: how many the
    /// index announces, 0 when unknown).
    fn map_chunk<T: Default>(
        &self,
        pos: usize,
        hint: usize,
        table: &Table<'_>,
        buf: &mut Vec<u8>,
        want: &(impl Fn(&ChannelInfo) -> bool + Sync),
        map: &(impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync),
    ) -> Res<Part<T>> {
        let data = self.chunk_data(pos, buf)?;
        let mut part = Part {
            defs: Vec::new(),
            msgs: Vec::new(),
            deferred: Vec::new(),
        };
        // The count the index announces, as far as the chunk's size makes it
        // plausible (a message record takes at least 30 bytes).
        let _ = part.msgs.try_reserve(hint.min(data.len() / 30));
        let mut local: BTreeMap<u16, (ChannelInfo, bool)> = BTreeMap::new();
        let mut at = 0;
        let mut index = 0u64;
        while at < data.len() {
            let here = |r: BagError| fault(pos, r);
            let rec = read_record(data, at).map_err(here)?;
            let h = Header::parse(rec.header, "chunk record").map_err(here)?;
            match h.op().map_err(here)? {
                op::MESSAGE_DATA => {
                    const R: &str = "message data";
                    let conn = field_u32(h.conn, R, "conn").map_err(here)?;
                    let time = time_ns(fixed::<8>(h.time, R, "time").map_err(here)?);
                    let id = u16::try_from(conn)
                        .map_err(|_| here(BagError::TooManyConnections { conn }))?;
                    let info = match table[id as usize] {
                        Some((c, w)) => Some((c, w)),
                        None => local.get(&id).map(|(c, w)| (c, *w)),
                    };
                    let value = match info {
                        Some((c, true)) => Some(map(
                            c,
                            &RawMessage {
                                channel_id: id,
                                sequence: 0,
                                log_time: time,
                                publish_time: time,
                                data: rec.data,
                            },
                        )),
                        Some((_, false)) => None,
                        None => {
                            part.deferred.push((
                                part.msgs.len(),
                                conn,
                                index,
                                pos,
                                time,
                                rec.data.to_vec(),
                            ));
                            Some(T::default())
                        }
                    };
                    if let Some(value) = value {
                        part.msgs.push(MappedMessage {
                            channel_id: id,
                            sequence: 0,
                            log_time: time,
                            publish_time: time,
                            value,
                        });
                    }
                    index += 1;
                }
                op::CONNECTION => {
                    let info = connection(&rec, &h).map_err(here)?;
                    if table[info.id as usize].is_none() && !local.contains_key(&info.id) {
                        let w = want(&info);
                        local.insert(info.id, (info.clone(), w));
                    }
                    part.defs.push(info);
                }
                other => {
                    return Err(here(BagError::UnexpectedRecord {
                        op: other,
                        context: "inside a chunk (expected message data or connection)",
                    }))
                }
            }
            at = rec.end;
        }
        // The reservation was the index's count: spare capacity of parts
        // waiting for the merge would add up over a long bag.
        part.msgs.shrink_to_fit();
        // Done with the chunk's bytes in the map: a long bag is not held whole.
        if let Ok(rec) = read_record(&self.map, pos) {
            self.map.release(rec.data);
        }
        Ok(part)
    }

    /// The records of the chunk at `pos`, decompressed into `buf` (bounded by
    /// the chunk's declared size) or borrowed from the map when uncompressed.
    fn chunk_data<'s>(&'s self, pos: usize, buf: &'s mut Vec<u8>) -> Res<&'s [u8]> {
        let map: &[u8] = &self.map;
        let here = |r: BagError| fault(pos, r);
        let rec = read_record(map, pos).map_err(here)?;
        let h = Header::parse(rec.header, "chunk").map_err(here)?;
        let got = h.op().map_err(here)?;
        if got != op::CHUNK {
            return Err(here(BagError::UnexpectedRecord {
                op: got,
                context: "where a chunk was expected",
            }));
        }
        let size = field_u32(h.size, "chunk", "size").map_err(here)? as u64;
        let compression = h.compression.ok_or(here(BagError::MissingField {
            record: "chunk",
            field: "compression",
        }))?;
        let data_at = pos + rec.header.len() + 8;
        decompress(compression, rec.data, size, buf).map_err(|r| fault(data_at, r))
    }

    /// Counts and time ranges per connection. With an index, from the index
    /// data records that follow each chunk (no chunk is decompressed); without,
    /// by a scan of every message.
    pub fn inventory(&self) -> Result<Inventory> {
        if let Some(index) = &self.index {
            if let Some(inv) = self.index_counts(index) {
                return Ok(inv);
            }
        }
        Ok(Inventory::of_scan(&self.scan_map(|_| true, |_, _| ())?))
    }

    /// Counts from the index data records, when they agree with the chunk infos.
    fn index_counts(&self, index: &Index) -> Option<Inventory> {
        let map: &[u8] = &self.map[..self.header.index_pos as usize];
        let mut stats: BTreeMap<u32, (u64, u64, u64)> = BTreeMap::new();
        let mut pos = self.header.data_start as usize;
        while pos < map.len() {
            let rec = read_record(map, pos).ok()?;
            let h = Header::parse(rec.header, "record").ok()?;
            match h.op().ok()? {
                op::CHUNK => {}
                op::INDEX_DATA => {
                    const R: &str = "index data";
                    if field_u32(h.ver, R, "ver").ok()? != 1 {
                        return None;
                    }
                    let conn = field_u32(h.conn, R, "conn").ok()?;
                    let count = field_u32(h.count, R, "count").ok()? as usize;
                    let entries = rec.data.get(..count.checked_mul(12)?)?;
                    let s = stats.entry(conn).or_insert((0, u64::MAX, 0));
                    for e in entries.chunks_exact(12) {
                        let t = time_ns(e[..8].try_into().ok()?);
                        s.0 += 1;
                        s.1 = s.1.min(t);
                        s.2 = s.2.max(t);
                    }
                }
                _ => return None,
            }
            pos = rec.end;
        }
        let mut from_infos: BTreeMap<u32, u64> = BTreeMap::new();
        for ci in &index.chunks {
            for &(conn, n) in &ci.counts {
                *from_infos.entry(conn).or_default() += n as u64;
            }
        }
        let from_data: BTreeMap<u32, u64> = stats
            .iter()
            .filter(|(_, s)| s.0 > 0)
            .map(|(c, s)| (*c, s.0))
            .collect();
        from_infos.retain(|_, n| *n > 0);
        if from_infos != from_data {
            return None;
        }
        let channels = index
            .channels
            .values()
            .map(|c| {
                let (count, lo, hi) = stats.get(&(c.id as u32)).copied().unwrap_or((0, 0, 0));
                ChannelCount {
                    channel: c.clone(),
                    count,
                    time_range: (count > 0).then_some((lo, hi)),
                }
            })
            .collect();
        Some(Inventory {
            channels,
            mode: ReadMode::Indexed,
            from_index: true,
        })
    }
}

fn bag_err(path: &Path, f: Fault) -> Error {
    Error::Bag {
        path: path.to_path_buf(),
        offset: Some(f.offset),
        reason: f.reason,
    }
}

/// The version line and the bag header record.
fn bag_header(map: &[u8]) -> Res<BagHeader> {
    if !map.starts_with(b"#ROSBAG V") {
        let head = &map[..map.len().min(16)];
        return Err(fault(
            0,
            BagError::NotABag {
                found: head.escape_ascii().to_string(),
            },
        ));
    }
    if !map.starts_with(ROS1_MAGIC) {
        let line = &map[9..map.len().min(40)];
        let line = line.split(|&b| b == b'\n').next().unwrap_or(line);
        return Err(fault(
            0,
            BagError::UnsupportedVersion {
                version: String::from_utf8_lossy(line).into_owned(),
            },
        ));
    }
    let pos = ROS1_MAGIC.len();
    let here = |r: BagError| fault(pos, r);
    let rec = read_record(map, pos).map_err(here)?;
    let h = Header::parse(rec.header, "bag header").map_err(here)?;
    let got = h.op().map_err(here)?;
    if got != op::BAG_HEADER {
        return Err(here(BagError::UnexpectedRecord {
            op: got,
            context: "after the version line (expected the bag header, op 0x03)",
        }));
    }
    const R: &str = "bag header";
    Ok(BagHeader {
        index_pos: field_u64(h.index_pos, R, "index_pos").map_err(here)?,
        conn_count: field_u32(h.conn_count, R, "conn_count").map_err(here)?,
        chunk_count: field_u32(h.chunk_count, R, "chunk_count").map_err(here)?,
        data_start: rec.end as u64,
    })
}

/// Decompresses a chunk's records into `buf` (cleared first) and returns them;
/// an uncompressed chunk is returned as it is. Decoding stops one byte past the
/// declared size, and memory is reserved ahead only as far as the compressed
/// size makes plausible (lz4 expands at most about 255 times).
pub(crate) fn decompress<'a>(
    compression: &[u8],
    data: &'a [u8],
    size: u64,
    buf: &'a mut Vec<u8>,
) -> std::result::Result<&'a [u8], BagError> {
    if size > MAX_CHUNK {
        return Err(BagError::ChunkTooLarge {
            size,
            limit: MAX_CHUNK,
        });
    }
    let (name, ratio): (&'static str, u64) = match compression {
        b"none" => {
            if data.len() as u64 != size {
                return Err(BagError::ChunkSize {
                    declared: size,
                    found: data.len() as u64,
                });
            }
            return Ok(data);
        }
        b"bz2" => ("bz2", 64),
        b"lz4" => ("lz4", 256),
        other => {
            return Err(BagError::UnknownCompression {
                found: String::from_utf8_lossy(other).into_owned(),
            })
        }
    };
    let ahead = size.min((data.len() as u64).saturating_mul(ratio).saturating_add(64));
    let failed = |e: std::io::Error| BagError::Decompress {
        compression: name,
        message: e.to_string(),
    };
    match name {
        "bz2" => {
            buf.clear();
            buf.try_reserve_exact(ahead as usize + 1)
                .map_err(|_| BagError::ChunkTooLarge {
                    size,
                    limit: MAX_CHUNK,
                })?;
            bzip2::bufread::BzDecoder::new(data)
                .take(size + 1)
                .read_to_end(buf)
                .map_err(failed)?;
        }
        _ => {
            // One call of liblz4's frame decoder, in place (no zero fill, no
            // copy of the input or of the history).
            crate::io::lz4_frame::decompress_into(data, ahead as usize + 1, size as usize + 1, buf)
                .map_err(|message| BagError::Decompress {
                    compression: name,
                    message,
                })?;
        }
    }
    if buf.len() as u64 != size {
        return Err(BagError::ChunkSize {
            declared: size,
            found: buf.len() as u64,
        });
    }
    Ok(buf)
}

impl MessageSource for Ros1Bag {
    fn path(&self) -> &Path {
        &self.path
    }

    fn channels(&self) -> Result<BTreeMap<u16, ChannelInfo>> {
        Ros1Bag::channels(self)
    }

    fn scan_map<T: Send + Default>(
        &self,
        want: impl Fn(&ChannelInfo) -> bool + Sync,
        map: impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync,
    ) -> Result<MappedScan<T>> {
        let r = Ros1Bag::scan_map(self, want, map);
        self.map.check()?;
        r
    }

    fn inventory(&self) -> Result<Inventory> {
        let r = Ros1Bag::inventory(self);
        self.map.check()?;
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn field(name: &str, value: &[u8]) -> Vec<u8> {
        let mut f = ((name.len() + 1 + value.len()) as u32)
            .to_le_bytes()
            .to_vec();
        f.extend_from_slice(name.as_bytes());
        f.push(b'=');
        f.extend_from_slice(value);
        f
    }

    #[test]
    fn record_lengths_are_checked() {
        let mut rec = Vec::new();
        let h = field("op", &[op::CHUNK]);
        rec.extend_from_slice(&(h.len() as u32).to_le_bytes());
        rec.extend_from_slice(&h);
        rec.extend_from_slice(&100u32.to_le_bytes());
        rec.extend_from_slice(&[0; 10]);
        assert!(matches!(
            read_record(&rec, 0),
            Err(BagError::Truncated {
                what: "record data",
                needed: 100,
                available: 10
            })
        ));
        assert!(matches!(
            read_record(&rec[..3], 0),
            Err(BagError::Truncated {
                what: "record header length",
                ..
            })
        ));
        rec.truncate(rec.len() - 10 - 4);
        rec.extend_from_slice(&10u32.to_le_bytes());
        rec.extend_from_slice(&[0; 10]);
        let r = read_record(&rec, 0).unwrap();
        assert_eq!(r.data.len(), 10);
        assert_eq!(r.end, rec.len());
    }

    #[test]
    fn fields_need_an_equals_sign() {
        let mut h = field("op", &[2]);
        h.extend_from_slice(&3u32.to_le_bytes());
        h.extend_from_slice(b"abc");
        assert!(matches!(
            Header::parse(&h, "x"),
            Err(BagError::BadField {
                expected: "name=value",
                ..
            })
        ));
        let h = field("op", &[2, 3]);
        assert!(matches!(
            Header::parse(&h, "x").unwrap().op(),
            Err(BagError::BadField {
                expected: "1 byte",
                found: 2,
                ..
            })
        ));
    }

    #[test]
    fn decompress_bounds_the_output() {
        let mut buf = Vec::new();
        assert!(matches!(
            decompress(b"lz4", &[1, 2, 3], MAX_CHUNK + 1, &mut buf),
            Err(BagError::ChunkTooLarge { .. })
        ));
        assert!(matches!(
            decompress(b"zstd", &[], 0, &mut buf),
            Err(BagError::UnknownCompression { found }) if found == "zstd"
        ));
        assert!(matches!(
            decompress(b"none", &[1, 2], 3, &mut buf),
            Err(BagError::ChunkSize {
                declared: 3,
                found: 2
            })
        ));
        // 1000 zeros as an lz4 frame, declared as 10 bytes: decoding stops at 11.
        let mut enc = lz4::EncoderBuilder::new().build(Vec::new()).unwrap();
        std::io::Write::write_all(&mut enc, &[0u8; 1000]).unwrap();
        let (frame, r) = enc.finish();
        r.unwrap();
        assert!(matches!(
            decompress(b"lz4", &frame, 10, &mut buf),
            Err(BagError::ChunkSize {
                declared: 10,
                found: 11
            })
        ));
        assert_eq!(
            decompress(b"lz4", &frame, 1000, &mut buf).unwrap(),
            &[0u8; 1000][..]
        );
        assert!(matches!(
            decompress(b"bz2", b"BZh9garbage", 100, &mut buf),
            Err(BagError::Decompress {
                compression: "bz2",
                ..
            })
        ));
    }

    #[test]
    fn times_are_nanoseconds() {
        let mut b = [0u8; 8];
        b[..4].copy_from_slice(&2u32.to_le_bytes());
        b[4..].copy_from_slice(&5u32.to_le_bytes());
        assert_eq!(time_ns(b), 2_000_000_005);
        assert_eq!(
            time_ns([255; 8]),
            u32::MAX as u64 * 1_000_000_000 + u32::MAX as u64
        );
    }
}
