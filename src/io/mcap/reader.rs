//! MCAP container reading over a memory map.
//!
//! [`McapFile::scan`] yields every Message record of a log in file order,
//! together with its channel and schema. Where the summary section has a chunk
//! index and repeats the channels, the chunks are found through the index (and
//! chunks holding no wanted channel are skipped); otherwise the file is scanned
//! record by record from the start. Chunks (zstd, lz4 or uncompressed) are
//! decompressed and CRC-checked in parallel (rayon).

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use mcap::records::{self, op, Record};
use rayon::prelude::*;

use crate::error::{Error, Result};
pub use crate::io::messages::{ChannelInfo, RawMessage, ReadMode};
use crate::io::messages::{Inventory, MappedScan, MessageSource, ScanInfo, ScanSink};

/// The 8 bytes every MCAP file starts and ends with.
pub const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

/// Where a message's bytes are: buffer `MAP` is the file, others a decompressed chunk.
#[derive(Clone, Copy, Debug)]
pub(super) struct Entry {
    pub(super) channel_id: u16,
    pub(super) sequence: u32,
    pub(super) log_time: u64,
    pub(super) publish_time: u64,
    pub(super) buffer: u32,
    pub(super) start: usize,
    pub(super) end: usize,
}

const MAP: u32 = u32::MAX;

/// Every message (or every wanted message) of a log, in file order.
#[derive(Debug)]
pub struct Scan<'a> {
    /// Channels by id (those defined anywhere in the file).
    pub channels: BTreeMap<u16, ChannelInfo>,
    map: &'a [u8],
    buffers: Vec<Vec<u8>>,
    entries: Vec<Entry>,
    /// Indexed or linear.
    pub mode: ReadMode,
    /// The `profile` field of the Header record (`ros1`, `ros2`, …).
    pub profile: String,
}

impl Scan<'_> {
    /// Number of messages.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// True when no message was read.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    fn view(&self, e: &Entry) -> RawMessage<'_> {
        let buf: &[u8] = if e.buffer == MAP {
            self.map
        } else {
            &self.buffers[e.buffer as usize]
        };
        RawMessage {
            channel_id: e.channel_id,
            sequence: e.sequence,
            log_time: e.log_time,
            publish_time: e.publish_time,
            data: &buf[e.start..e.end],
        }
    }

    /// The messages in file order, each borrowing its bytes from the scan.
    pub fn iter(&self) -> impl Iterator<Item = RawMessage<'_>> + '_ {
        self.entries.iter().map(|e| self.view(e))
    }

    /// Message `i` in file order, `None` past the end.
    pub fn get(&self, i: usize) -> Option<RawMessage<'_>> {
        self.entries.get(i).map(|e| self.view(e))
    }

    /// Positions (in file order) of the messages of one channel.
    pub fn indices_of(&self, channel_id: u16) -> Vec<usize> {
        (0..self.entries.len())
            .filter(|&i| self.entries[i].channel_id == channel_id)
            .collect()
    }

    /// The messages in file order, collected.
    pub fn messages(&self) -> Vec<RawMessage<'_>> {
        self.iter().collect()
    }
}

/// An MCAP file opened read-only and memory-mapped (a file that shrinks
/// while it is read is an error, not SIGBUS: [`crate::io::mapped`]).
pub struct McapFile {
    path: PathBuf,
    map: Bytes,
}

/// The bytes an [`McapFile`] reads: a file's map, or a log in memory.
enum Bytes {
    Mapped(crate::io::mapped::Mapped),
    Memory(std::sync::Arc<Vec<u8>>),
}

impl std::ops::Deref for Bytes {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        match self {
            Bytes::Mapped(m) => m,
            Bytes::Memory(b) => b,
        }
    }
}

/// One item of the data section, before chunks are expanded.
pub(super) enum Item<'a> {
    Schema(records::SchemaHeader, Vec<u8>),
    Channel(records::Channel),
    Message(Entry),
    Chunk {
        offset: usize,
        header: records::ChunkHeader,
        data: &'a [u8],
    },
}

/// A schema or channel definition found in the data section or a chunk.
pub(super) enum Def {
    Schema(records::SchemaHeader, Vec<u8>),
    Channel(records::Channel),
}

/// What one item expands to: the decompressed buffer of a chunk, its
/// definitions (applied before its messages) and its messages.
type Expanded = (Option<Vec<u8>>, Vec<Def>, Vec<Entry>);

impl McapFile {
    /// Opens and maps `path` (read-only). Fails on a missing file or a file that
    /// does not start with the MCAP magic.
    pub fn open(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref().to_path_buf();
        crate::io::mapped::require_file(&path, "an MCAP file")?;
        let file = std::fs::File::open(&path).map_err(|e| Error::io(&path, e))?;
        let map = crate::io::mapped::Mapped::map(file, &path)?;
        Self::with(path, Bytes::Mapped(map))
    }

    /// An MCAP log held in memory, `name` standing for its path in errors.
    /// Fails on bytes that do not start with the MCAP magic.
    pub fn from_bytes(name: impl AsRef<Path>, bytes: std::sync::Arc<Vec<u8>>) -> Result<Self> {
        Self::with(name.as_ref().to_path_buf(), Bytes::Memory(bytes))
    }

    fn with(path: PathBuf, map: Bytes) -> Result<Self> {
        if map.len() < MAGIC.len() || &map[..MAGIC.len()] != MAGIC {
            return Err(Error::Mcap {
                path,
                reason: "not an MCAP file (bad magic at offset 0)".into(),
            });
        }
        Ok(McapFile { path, map })
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The whole file.
    pub fn bytes(&self) -> &[u8] {
        &self.map
    }

    /// Records the schema and channel definitions met inside a chunk (or
    /// between chunks): schemas by id, channels first-seen-wins, and for each
    /// new channel whether `want` keeps it (`keep`: 0 undefined, 1 skipped, 2 kept).
    pub(super) fn apply_defs(
        &self,
        defs: Vec<Def>,
        schemas: &mut BTreeMap<u16, (records::SchemaHeader, Vec<u8>)>,
        channels: &mut BTreeMap<u16, ChannelInfo>,
        keep: &mut [u8],
        want: &impl Fn(&ChannelInfo) -> bool,
    ) -> Result<()> {
        for def in defs {
            match def {
                Def::Schema(h, d) => {
                    schemas.insert(h.id, (h, d));
                }
                Def::Channel(c) => {
                    if let std::collections::btree_map::Entry::Vacant(slot) = channels.entry(c.id) {
                        let info = channel_info(&c, schemas).map_err(|r| self.err(r))?;
                        keep[c.id as usize] = if want(&info) { 2 } else { 1 };
                        slot.insert(info);
                    }
                }
            }
        }
        Ok(())
    }

    pub(super) fn err(&self, reason: impl Into<String>) -> Error {
        Error::Mcap {
            path: self.path.clone(),
            reason: reason.into(),
        }
    }

    /// Channels and schemas only: from the summary when it repeats them, else
    /// by a linear scan (which also reads the messages, then drops them).
    pub fn channels(&self) -> Result<BTreeMap<u16, ChannelInfo>> {
        if let Some((_, channels)) = self.indexed_plan()? {
            return Ok(channels);
        }
        // Mapped to nothing: each chunk's buffer is reused, none is kept.
        Ok(self.scan_map(|_| false, |_, _| ())?.channels)
    }

    /// Gives back the process's pages of `bytes`, a slice of the file's map
    /// that a reader is done with ([`crate::io::mapped::Mapped::release`]).
    pub(crate) fn release(&self, bytes: &[u8]) {
        if let Bytes::Mapped(m) = &self.map {
            m.release(bytes);
        }
    }

    /// Fails when the file shrank while it was read (see [`crate::io::mapped`]).
    pub fn check_unchanged(&self) -> Result<()> {
        match &self.map {
            Bytes::Mapped(m) => m.check(),
            Bytes::Memory(_) => Ok(()),
        }
    }

    /// Reads every message whose channel `want` accepts, in file order.
    pub fn scan(&self, want: impl Fn(&ChannelInfo) -> bool + Sync) -> Result<Scan<'_>> {
        let r = self.scan_unchecked(want);
        self.check_unchanged()?;
        r
    }

    fn scan_unchecked(&self, want: impl Fn(&ChannelInfo) -> bool + Sync) -> Result<Scan<'_>> {
        let profile = self.profile();
        if let Some((chunks, channels)) = self.indexed_plan()? {
            let items = self.wanted_chunks(&chunks, &channels, &want)?;
            let (channels, buffers, entries) = self.expand(items, &want, channels)?;
            return Ok(Scan {
                channels,
                map: &self.map,
                buffers,
                entries,
                mode: ReadMode::Indexed,
                profile,
            });
        }
        let (items, channels) = self.linear_items()?;
        let (channels, buffers, entries) = self.expand(items, &want, channels)?;
        Ok(Scan {
            channels,
            map: &self.map,
            buffers,
            entries,
            mode: ReadMode::Linear,
            profile,
        })
    }

    /// The `profile` field of the Header record (`ros1`, `ros2`, …; empty without one).
    pub fn profile(&self) -> String {
        let buf = &self.map[MAGIC.len()..];
        match frame(buf) {
            Some((op::HEADER, body, _)) => match parse_record(op::HEADER, body) {
                Ok(Record::Header(h)) => h.profile,
                _ => String::new(),
            },
            _ => String::new(),
        }
    }

    /// The chunk indexes (sorted by offset) and channels of the summary, when
    /// the summary has both, every chunk index points at a chunk, and its
    /// Statistics record (when there is one) counts as many chunks as it
    /// indexes: otherwise the file is read by a linear scan.
    #[allow(clippy::type_complexity)]
    pub(super) fn indexed_plan(
        &self,
    ) -> Result<Option<(Vec<records::ChunkIndex>, BTreeMap<u16, ChannelInfo>)>> {
        // A damaged summary is not fatal: the linear scan reports what is wrong.
        let Some(summary) = self.summary() else {
            return Ok(None);
        };
        if summary.chunk_indexes.is_empty() || summary.channels.is_empty() {
            return Ok(None);
        }
        if let Some(stats) = &summary.statistics {
            // A summary that lost a chunk index would silently lose its messages.
            if stats.chunk_count as usize != summary.chunk_indexes.len() {
                return Ok(None);
            }
        }
        let mut channels = BTreeMap::new();
        for c in &summary.channels {
            match channel_info(c, &summary.schemas) {
                Ok(info) => {
                    channels.insert(c.id, info);
                }
                Err(_) => return Ok(None),
            }
        }
        // Every channel that a chunk's message index names must be known.
        for ci in &summary.chunk_indexes {
            if ci
                .message_index_offsets
                .keys()
                .any(|id| !channels.contains_key(id))
            {
                return Ok(None);
            }
            let end = ci.chunk_start_offset.checked_add(ci.chunk_length);
            if end.is_none_or(|e| e > self.map.len() as u64) {
                return Ok(None);
            }
        }
        let mut chunks = summary.chunk_indexes;
        chunks.sort_by_key(|c| c.chunk_start_offset);
        Ok(Some((chunks, channels)))
    }

    /// The summary section: its schemas, channels, chunk indexes and
    /// Statistics record; `None` when the file has none or it is damaged
    /// (every record's lengths checked before it is parsed).
    pub(super) fn summary(&self) -> Option<SummarySection> {
        let map: &[u8] = &self.map;
        // Footer record (opcode, length 20, summary start, summary offset start, crc) + magic.
        const FOOTER: usize = 1 + 8 + 20;
        let end = map.len().checked_sub(MAGIC.len())?;
        if &map[end..] != MAGIC || end < MAGIC.len() + FOOTER {
            return None;
        }
        let foot = end - FOOTER;
        let footer = match frame(&map[foot..end]) {
            Some((op::FOOTER, body, n)) if n == FOOTER => match parse_record(op::FOOTER, body) {
                Ok(Record::Footer(f)) => f,
                _ => return None,
            },
            _ => return None,
        };
        let start = usize::try_from(footer.summary_start).ok()?;
        if start == 0 || start < MAGIC.len() || start > foot {
            return None;
        }
        let mut s = SummarySection::default();
        let mut pos = start;
        while pos < foot {
            let (opcode, body, next) = frame(&map[pos..foot])?;
            match parse_record(opcode, body).ok()? {
                Record::Schema { header, data } => {
                    s.schemas.insert(header.id, (header, data.into_owned()));
                }
                Record::Channel(c) => s.channels.push(c),
                Record::ChunkIndex(ci) => s.chunk_indexes.push(ci),
                Record::Statistics(st) => s.statistics = Some(st),
                _ => {}
            }
            pos += next;
        }
        Some(s)
    }

    /// Messages per channel that the summary's Statistics record counts,
    /// when it has one.
    pub(super) fn declared_counts(&self) -> Option<BTreeMap<u16, u64>> {
        self.summary()?.statistics.map(|s| s.channel_message_counts)
    }

    /// The chunks of an indexed file that hold a message of a channel `want`
    /// keeps (a chunk without a message index is kept: its content is unknown).
    pub(super) fn wanted_chunks(
        &self,
        chunks: &[records::ChunkIndex],
        channels: &BTreeMap<u16, ChannelInfo>,
        want: &impl Fn(&ChannelInfo) -> bool,
    ) -> Result<Vec<Item<'_>>> {
        let wanted: Vec<u16> = channels
            .values()
            .filter(|c| want(c))
            .map(|c| c.id)
            .collect();
        chunks
            .iter()
            .filter(|ci| {
                ci.message_index_offsets.is_empty()
                    || ci
                        .message_index_offsets
                        .keys()
                        .any(|id| wanted.contains(id))
            })
            .map(|ci| self.chunk_at(ci))
            .collect()
    }

    pub(super) fn chunk_at(&self, ci: &records::ChunkIndex) -> Result<Item<'_>> {
        let start = ci.chunk_start_offset as usize;
        let buf = &self.map[start..];
        match frame(buf) {
            Some((op::CHUNK, body, _)) => match parse_record(op::CHUNK, body) {
                Ok(Record::Chunk {
                    header,
                    data: Cow::Borrowed(data),
                }) => {
                    // The summary and the chunk must agree on its sizes.
                    if header.uncompressed_size != ci.uncompressed_size
                        || header.compressed_size != ci.compressed_size
                    {
                        return Err(self.err(format!(
                            "chunk at offset {start}: its header says {} bytes compressed, {} uncompressed; the summary's chunk index {} and {}",
                            header.compressed_size,
                            header.uncompressed_size,
                            ci.compressed_size,
                            ci.uncompressed_size
                        )));
                    }
                    Ok(Item::Chunk {
                        offset: start,
                        header,
                        data,
                    })
                }
                Ok(_) => Err(self.err(format!(
                    "chunk index points at offset {start}, no chunk there"
                ))),
                Err(e) => Err(self.err(format!("chunk at offset {start}: {e}"))),
            },
            _ => Err(self.err(format!(
                "chunk index points at offset {start}, no chunk there"
            ))),
        }
    }

    /// Bytes of the map walked by [`Self::linear_items`] between two releases.
    const WALK_RELEASE: usize = 8 << 20;

    /// Walks the top-level records from the start to the footer.
    pub(super) fn linear_items(&self) -> Result<(Vec<Item<'_>>, BTreeMap<u16, ChannelInfo>)> {
        let map: &[u8] = &self.map;
        let mut pos = MAGIC.len();
        let mut items = Vec::new();
        let channels = BTreeMap::new();
        let mut footer = false;
        let mut released = 0;
        while pos < map.len() {
            let Some((opcode, body, next)) = frame(&map[pos..]) else {
                return Err(self.err(format!(
                    "truncated: record at offset {pos} runs past the end of the file ({} bytes)",
                    map.len()
                )));
            };
            let record = parse_record(opcode, body).map_err(|e| {
                self.err(format!(
                    "record at offset {pos} (opcode {opcode:#04x}): {e}"
                ))
            })?;
            match record {
                Record::Schema { header, data } => {
                    items.push(Item::Schema(header, data.into_owned()));
                }
                Record::Channel(c) => items.push(Item::Channel(c)),
                Record::Message { header, data } => {
                    let start = pos + 9 + (body.len() - data.len());
                    items.push(Item::Message(Entry {
                        channel_id: header.channel_id,
                        sequence: header.sequence,
                        log_time: header.log_time,
                        publish_time: header.publish_time,
                        buffer: MAP,
                        start,
                        end: start + data.len(),
                    }))
                }
                Record::Chunk {
                    header,
                    data: Cow::Borrowed(data),
                } => items.push(Item::Chunk {
                    offset: pos,
                    header,
                    data,
                }),
                Record::Footer(_) => {
                    footer = true;
                    pos += next;
                    break;
                }
                _ => {}
            }
            pos += next;
            // The walk faults in a page of every record it looks at, and the
            // kernel's fault-around pages beside it (most of a long log's
            // map): they go back as it goes, and each chunk task maps its
            // own chunk again.
            if pos - released >= Self::WALK_RELEASE {
                self.release(&map[released..pos.min(map.len())]);
                released = pos;
            }
        }
        self.release(&map[released..pos.min(map.len())]);
        if !footer {
            return Err(self.err(format!("truncated: no footer record ({} bytes)", map.len())));
        }
        if map.len() - pos < MAGIC.len() || &map[pos..pos + MAGIC.len()] != MAGIC {
            return Err(self.err(format!(
                "truncated or damaged: no magic at the end of the file (offset {pos})"
            )));
        }
        Ok((items, channels))
    }

    /// Decompresses the chunks in parallel, then merges everything in file order.
    #[allow(clippy::type_complexity)]
    fn expand(
        &self,
        items: Vec<Item<'_>>,
        want: &(impl Fn(&ChannelInfo) -> bool + Sync),
        mut channels: BTreeMap<u16, ChannelInfo>,
    ) -> Result<(BTreeMap<u16, ChannelInfo>, Vec<Vec<u8>>, Vec<Entry>)> {
        let expanded: Vec<Result<Expanded>> = items
            .into_par_iter()
            .map(|item| match item {
                Item::Schema(h, d) => Ok((None, vec![Def::Schema(h, d)], Vec::new())),
                Item::Channel(c) => Ok((None, vec![Def::Channel(c)], Vec::new())),
                Item::Message(m) => Ok((None, Vec::new(), vec![m])),
                Item::Chunk {
                    offset,
                    header,
                    data,
                } => self.read_chunk(offset, &header, data),
            })
            .collect();
        let mut schemas: BTreeMap<u16, (records::SchemaHeader, Vec<u8>)> = BTreeMap::new();
        let mut entries = Vec::new();
        let mut buffers = Vec::new();
        // Per channel id: 0 undefined, 1 skipped, 2 kept.
        let mut keep = vec![0u8; 1 << 16];
        for c in channels.values() {
            keep[c.id as usize] = if want(c) { 2 } else { 1 };
        }
        for part in expanded {
            let (buffer, defs, msgs) = part?;
            self.apply_defs(defs, &mut schemas, &mut channels, &mut keep, want)?;
            let index = buffers.len() as u32;
            let before = entries.len();
            for mut m in msgs {
                match keep[m.channel_id as usize] {
                    2 => {
                        if buffer.is_some() {
                            m.buffer = index;
                        }
                        entries.push(m);
                    }
                    1 => {}
                    _ => {
                        return Err(self.err(format!(
                            "message (sequence {}, log time {} ns) on channel {} that no Channel record defines",
                            m.sequence, m.log_time, m.channel_id
                        )))
                    }
                }
            }
            if let Some(b) = buffer {
                buffers.push(if entries.len() > before {
                    b
                } else {
                    Vec::new()
                });
            }
        }
        Ok((channels, buffers, entries))
    }

    /// Decompresses one chunk (checking its CRC when set) and lists its records.
    fn read_chunk(
        &self,
        offset: usize,
        header: &records::ChunkHeader,
        data: &[u8],
    ) -> Result<Expanded> {
        let at = |what: String| self.err(format!("chunk at offset {offset}: {what}"));
        let mut buf = Vec::new();
        expand_chunk(header, data, &mut buf).map_err(at)?;
        let mut defs = Vec::new();
        let mut out = Vec::with_capacity(header.uncompressed_size as usize / 64);
        walk_chunk(&buf, |item| {
            match item {
                ChunkItem::Message(start, m) => out.push(Entry {
                    channel_id: m.channel_id,
                    sequence: m.sequence,
                    log_time: m.log_time,
                    publish_time: m.publish_time,
                    buffer: 0,
                    start,
                    end: start + m.data.len(),
                }),
                ChunkItem::Other(Record::Schema { header, data }) => {
                    defs.push(Def::Schema(header, data.into_owned()))
                }
                ChunkItem::Other(Record::Channel(c)) => defs.push(Def::Channel(c)),
                ChunkItem::Other(_) => {}
            }
            Ok(())
        })
        .map_err(at)?;
        Ok((Some(buf), defs, out))
    }
}

/// The largest decompressed chunk accepted (guards allocations against damaged headers).
pub(super) const MAX_CHUNK: usize = 1 << 32;

/// Chunks up to this many decompressed bytes are accepted whatever their
/// compression ratio.
pub const CHUNK_ANY_RATIO: usize = 64 << 20;

/// Above [`CHUNK_ANY_RATIO`], the largest ratio of decompressed to compressed
/// bytes a chunk may declare, so that what a file makes the reader allocate
/// stays within 100 times its size plus a fixed bound. Real logs stay far
/// below (writers cut chunks at a few MB; zstd on keyframes gives 2–20); a
/// chunk of 76 KB that declares 2.5 GB is refused before anything is allocated.
pub const MAX_CHUNK_RATIO: u64 = 100;

/// Decompresses a chunk's records into `out` (cleared first, its allocation reused).
pub(super) fn decompress_into(
    compression: &str,
    data: &[u8],
    size: usize,
    out: &mut Vec<u8>,
) -> std::result::Result<(), String> {
    out.clear();
    out.try_reserve_exact(size)
        .map_err(|_| format!("cannot allocate {size} bytes for the decompressed chunk"))?;
    match compression {
        "" => out.extend_from_slice(data),
        "zstd" => {
            let mut d = zstd::bulk::Decompressor::new().map_err(|e| format!("zstd: {e}"))?;
            d.decompress_to_buffer(data, out)
                .map_err(|e| format!("zstd: {e}"))?;
        }
        // Never past the announced size (a damaged frame could go on).
        "lz4" => crate::io::lz4_frame::decompress_into(data, size, size + 1, out)
            .map_err(|e| format!("lz4: {e}"))?,
        other => return Err(format!("unsupported compression {other:?}")),
    }
    if out.len() != size {
        return Err(format!(
            "decompressed to {} bytes, the chunk header says {size}",
            out.len()
        ));
    }
    Ok(())
}

/// Bytes of a message record before its data: channel id, sequence, log
/// time and publish time.
const MESSAGE_HEAD: usize = 22;

/// One record of a decompressed chunk.
pub(super) enum ChunkItem<'a> {
    /// A message and the offset of its data in the chunk.
    Message(usize, RawMessage<'a>),
    /// Any other record (schemas and channels are the ones that matter).
    Other(Record<'a>),
}

/// Decompresses a chunk into `buf` (cleared first): its size bounded by
/// [`MAX_CHUNK`], its CRC checked when set.
pub(super) fn expand_chunk(
    header: &records::ChunkHeader,
    data: &[u8],
    buf: &mut Vec<u8>,
) -> std::result::Result<(), String> {
    let size = usize::try_from(header.uncompressed_size)
        .ok()
        .filter(|&n| n <= MAX_CHUNK)
        .ok_or_else(|| {
            format!(
                "uncompressed size {} is beyond the {MAX_CHUNK}-byte limit",
                header.uncompressed_size
            )
        })?;
    let compressed = data.len() as u64;
    if !header.compression.is_empty()
        && size > CHUNK_ANY_RATIO
        && header.uncompressed_size > compressed.saturating_mul(MAX_CHUNK_RATIO)
    {
        return Err(format!(
            "declares {} bytes uncompressed from {compressed} compressed, a ratio above \
             the {MAX_CHUNK_RATIO}:1 accepted for chunks over {CHUNK_ANY_RATIO} bytes (damaged or hostile)",
            header.uncompressed_size
        ));
    }
    if header.compression.is_empty() && header.uncompressed_size != compressed {
        return Err(format!(
            "uncompressed chunk of {compressed} bytes declares {} bytes",
            header.uncompressed_size
        ));
    }
    decompress_into(&header.compression, data, size, buf)?;
    if header.uncompressed_crc != 0 {
        let crc = crc32fast::hash(buf);
        if crc != header.uncompressed_crc {
            return Err(format!(
                "CRC mismatch: the chunk says {:#010x}, its data hashes to {crc:#010x}",
                header.uncompressed_crc
            ));
        }
    }
    Ok(())
}

/// Calls `f` on every record of a decompressed chunk, in order; errors name
/// the offset in the chunk.
pub(super) fn walk_chunk<'a>(
    buf: &'a [u8],
    mut f: impl FnMut(ChunkItem<'a>) -> std::result::Result<(), String>,
) -> std::result::Result<(), String> {
    let mut pos = 0;
    while pos < buf.len() {
        let Some((opcode, body, next)) = frame(&buf[pos..]) else {
            return Err(format!(
                "record at chunk offset {pos} runs past the chunk's end"
            ));
        };
        if opcode == op::MESSAGE {
            if body.len() < MESSAGE_HEAD {
                return Err(format!(
                    "message record of {} bytes at chunk offset {pos}",
                    body.len()
                ));
            }
            let u64_at = |i: usize| {
                let mut a = [0u8; 8];
                a.copy_from_slice(&body[i..i + 8]);
                u64::from_le_bytes(a)
            };
            let m = RawMessage {
                channel_id: u16::from_le_bytes([body[0], body[1]]),
                sequence: u32::from_le_bytes([body[2], body[3], body[4], body[5]]),
                log_time: u64_at(6),
                publish_time: u64_at(14),
                data: &body[MESSAGE_HEAD..],
            };
            f(ChunkItem::Message(pos + next - m.data.len(), m))?;
        } else {
            let r = parse_record(opcode, body)
                .map_err(|e| format!("record at chunk offset {pos}: {e}"))?;
            f(ChunkItem::Other(r))?;
        }
        pos += next;
    }
    Ok(())
}

/// The message records of a decompressed chunk, counted from the record
/// frames alone (a damaged frame ends the count: [`walk_chunk`] reports it).
pub(super) fn count_messages(buf: &[u8]) -> usize {
    let (mut pos, mut n) = (0, 0);
    while let Some((opcode, _, next)) = buf.get(pos..).and_then(frame) {
        n += usize::from(opcode == op::MESSAGE);
        pos += next;
    }
    n
}

/// Splits one record off the front of `buf`: (opcode, body, bytes consumed).
/// `None` when the buffer ends inside the record.
pub(super) fn frame(buf: &[u8]) -> Option<(u8, &[u8], usize)> {
    let opcode = *buf.first()?;
    let len_bytes: [u8; 8] = buf.get(1..9)?.try_into().ok()?;
    let len = usize::try_from(u64::from_le_bytes(len_bytes)).ok()?;
    let end = 9usize.checked_add(len)?;
    let body = buf.get(9..end)?;
    Some((opcode, body, end))
}

pub(super) fn channel_info(
    c: &records::Channel,
    schemas: &BTreeMap<u16, (records::SchemaHeader, Vec<u8>)>,
) -> std::result::Result<ChannelInfo, String> {
    let (name, encoding, data) = if c.schema_id == 0 {
        (String::new(), String::new(), Vec::new())
    } else {
        match schemas.get(&c.schema_id) {
            Some((h, d)) => (h.name.clone(), h.encoding.clone(), d.clone()),
            None => {
                return Err(format!(
                    "channel {} (topic {:?}) refers to schema {}, which no Schema record defines",
                    c.id, c.topic, c.schema_id
                ))
            }
        }
    };
    Ok(ChannelInfo {
        id: c.id,
        topic: c.topic.clone(),
        message_encoding: c.message_encoding.clone(),
        schema_id: c.schema_id,
        schema_name: name,
        schema_encoding: encoding,
        schema_data: data,
        metadata: c.metadata.clone(),
    })
}

/// What the summary section holds that the reader uses.
#[derive(Default)]
pub(super) struct SummarySection {
    pub(super) schemas: BTreeMap<u16, (records::SchemaHeader, Vec<u8>)>,
    pub(super) channels: Vec<records::Channel>,
    pub(super) chunk_indexes: Vec<records::ChunkIndex>,
    pub(super) statistics: Option<records::Statistics>,
}

/// [`mcap::parse_record`] after every length inside the record (strings,
/// maps, arrays, data) was checked against the bytes of the record: the
/// `mcap` crate reserves a string's declared length before reading it, so a
/// damaged length of 3.5 GB would be allocated.
pub(crate) fn parse_record(opcode: u8, body: &[u8]) -> std::result::Result<Record<'_>, String> {
    check_lengths(opcode, body).map_err(|what| {
        format!(
            "{what} (a record of opcode {opcode:#04x} and {} bytes)",
            body.len()
        )
    })?;
    mcap::parse_record(opcode, body).map_err(|e| e.to_string())
}

/// The fields of a record, in order, for [`check_lengths`].
#[derive(Clone, Copy)]
enum Field {
    /// A fixed-size field of this many bytes.
    Fixed(usize),
    /// `u32` length + UTF-8 bytes.
    Str,
    /// `u32` byte length + string pairs.
    StrMap,
    /// `u32` byte length + fixed-size entries (maps of integers, arrays).
    Bytes32,
    /// `u64` length + bytes.
    Bytes64,
    /// Everything that is left.
    Rest,
}

fn layout(opcode: u8) -> &'static [Field] {
    use Field::*;
    match opcode {
        op::HEADER => &[Str, Str],
        op::FOOTER => &[Fixed(20)],
        op::SCHEMA => &[Fixed(2), Str, Str, Bytes32],
        op::CHANNEL => &[Fixed(4), Str, Str, StrMap],
        op::MESSAGE => &[Fixed(22), Rest],
        op::CHUNK => &[Fixed(28), Str, Fixed(8), Rest],
        op::MESSAGE_INDEX => &[Fixed(2), Bytes32],
        op::CHUNK_INDEX => &[Fixed(32), Bytes32, Fixed(8), Str, Fixed(16)],
        op::ATTACHMENT => &[Fixed(16), Str, Str, Bytes64, Fixed(4)],
        op::ATTACHMENT_INDEX => &[Fixed(40), Str, Str],
        op::STATISTICS => &[Fixed(42), Bytes32],
        op::METADATA => &[Str, StrMap],
        op::METADATA_INDEX => &[Fixed(16), Str],
        op::SUMMARY_OFFSET => &[Fixed(17)],
        op::DATA_END => &[Fixed(4)],
        _ => &[Rest],
    }
}

fn read_len(body: &[u8], pos: usize, n: usize) -> Option<u64> {
    let b = body.get(pos..pos + n)?;
    Some(if n == 4 {
        u32::from_le_bytes(b.try_into().ok()?) as u64
    } else {
        u64::from_le_bytes(b.try_into().ok()?)
    })
}

/// Checks that every length inside a record fits in the record's `body`.
pub(crate) fn check_lengths(opcode: u8, body: &[u8]) -> std::result::Result<(), &'static str> {
    let mut pos = 0usize;
    let sized = |pos: usize, n: usize| -> std::result::Result<(usize, usize), &'static str> {
        let len = read_len(body, pos, n).ok_or("a length field runs past the record")?;
        let start = pos + n;
        let len = usize::try_from(len).map_err(|_| "a length larger than the record")?;
        if len > body.len() - start {
            return Err("a length larger than the rest of the record");
        }
        Ok((start, start + len))
    };
    for f in layout(opcode) {
        match *f {
            Field::Fixed(n) => {
                if body.len() - pos < n {
                    return Err("the record is shorter than its fixed fields");
                }
                pos += n;
            }
            Field::Str | Field::Bytes32 => pos = sized(pos, 4)?.1,
            Field::Bytes64 => pos = sized(pos, 8)?.1,
            Field::StrMap => {
                let (mut p, end) = sized(pos, 4)?;
                while p < end {
                    for _ in 0..2 {
                        let len =
                            read_len(&body[..end], p, 4).ok_or("a map entry runs past its map")?;
                        let len = usize::try_from(len).map_err(|_| "a map entry too long")?;
                        if len > end - (p + 4) {
                            return Err("a map string longer than the rest of its map");
                        }
                        p += 4 + len;
                    }
                }
                pos = end;
            }
            Field::Rest => pos = body.len(),
        }
    }
    Ok(())
}

impl MessageSource for McapFile {
    fn path(&self) -> &Path {
        McapFile::path(self)
    }

    fn channels(&self) -> Result<BTreeMap<u16, ChannelInfo>> {
        McapFile::channels(self)
    }

    fn scan_map<T: Send + Default>(
        &self,
        want: impl Fn(&ChannelInfo) -> bool + Sync,
        map: impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync,
    ) -> Result<MappedScan<T>> {
        McapFile::scan_map(self, want, map)
    }

    fn scan_into<T: Send + Default>(
        &self,
        want: impl Fn(&ChannelInfo) -> bool + Sync,
        map: impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync,
        sink: &mut dyn ScanSink<T>,
    ) -> Result<ScanInfo> {
        McapFile::scan_into(self, want, map, sink)
    }

    fn inventory(&self) -> Result<Inventory> {
        Ok(Inventory::of_scan(&McapFile::scan_map(
            self,
            |_| true,
            |_, _| (),
        )?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_refuses_short_buffers() {
        assert!(frame(&[]).is_none());
        assert!(frame(&[1, 5, 0, 0, 0, 0, 0, 0, 0, 1, 2]).is_none());
        let buf = [1u8, 2, 0, 0, 0, 0, 0, 0, 0, 7, 8, 9];
        assert_eq!(frame(&buf), Some((1, &buf[9..11], 11)));
        let huge = [1u8, 255, 255, 255, 255, 255, 255, 255, 255];
        assert!(frame(&huge).is_none());
    }
}
