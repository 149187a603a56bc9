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

/// The 8 bytes every MCAP file starts and ends with.
pub const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

/// A channel of the log with its schema (empty name and encoding when schemaless).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ChannelInfo {
    /// Channel id, unique in the file.
    pub id: u16,
    /// Topic name, e.g. `/lsd_slam/keyframes`.
    pub topic: String,
    /// Message encoding: `ros1`, `cdr`, `protobuf`, `json`, …
    pub message_encoding: String,
    /// Schema id (0 for none).
    pub schema_id: u16,
    /// Schema name, e.g. `geometry_msgs/PoseStamped`; empty without a schema.
    pub schema_name: String,
    /// Schema encoding: `ros1msg`, `ros2msg`, `protobuf`, `jsonschema`, …
    pub schema_encoding: String,
    /// Schema data (message definition text, or a protobuf FileDescriptorSet).
    pub schema_data: Vec<u8>,
    /// Channel metadata.
    pub metadata: BTreeMap<String, String>,
}

/// One Message record. `data` borrows from the memory map for messages outside
/// chunks and owns the bytes of messages decompressed from a chunk.
#[derive(Clone, Debug)]
pub struct RawMessage<'a> {
    /// Channel id (see [`Scan::channels`]).
    pub channel_id: u16,
    /// Publisher sequence number.
    pub sequence: u32,
    /// Log time, nanoseconds.
    pub log_time: u64,
    /// Publish time, nanoseconds.
    pub publish_time: u64,
    /// The serialised message.
    pub data: Cow<'a, [u8]>,
}

/// How the messages were found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReadMode {
    /// Through the summary's chunk index.
    Indexed,
    /// Record by record from the start of the file.
    Linear,
}

/// Every message (or every wanted message) of a log, in file order.
#[derive(Debug)]
pub struct Scan<'a> {
    /// Channels by id (those defined anywhere in the file).
    pub channels: BTreeMap<u16, ChannelInfo>,
    /// Messages in file order.
    pub messages: Vec<RawMessage<'a>>,
    /// Indexed or linear.
    pub mode: ReadMode,
    /// The `profile` field of the Header record (`ros1`, `ros2`, …).
    pub profile: String,
}

/// An MCAP file opened read-only and memory-mapped.
pub struct McapFile {
    path: PathBuf,
    map: memmap2::Mmap,
}

/// One item of the data section, before chunks are expanded.
enum Item<'a> {
    Schema(records::SchemaHeader, Vec<u8>),
    Channel(records::Channel),
    Message(RawMessage<'a>),
    Chunk {
        offset: usize,
        header: records::ChunkHeader,
        data: &'a [u8],
    },
}

/// What a chunk expands to (channels and schemas in it are collected as well).
enum Inner<'a> {
    Schema(records::SchemaHeader, Vec<u8>),
    Channel(records::Channel),
    Message(RawMessage<'a>),
}

impl McapFile {
    /// Opens and maps `path` (read-only). Fails on a missing file or a file that
    /// does not start with the MCAP magic.
    pub fn open(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref().to_path_buf();
        let file = std::fs::File::open(&path).map_err(|e| Error::io(&path, e))?;
        // SAFETY: the map is read-only; the file is opened read-only and a log is not
        // expected to be modified while it is read (as with every mmap-based reader).
        let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| Error::io(&path, e))?;
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

    fn err(&self, reason: impl Into<String>) -> Error {
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
        Ok(self.scan(|_| false)?.channels)
    }

    /// Reads every message whose channel `want` accepts, in file order.
    pub fn scan(&self, want: impl Fn(&ChannelInfo) -> bool + Sync) -> Result<Scan<'_>> {
        let profile = self.profile();
        if let Some((chunks, channels)) = self.indexed_plan()? {
            let wanted: Vec<u16> = channels
                .values()
                .filter(|c| want(c))
                .map(|c| c.id)
                .collect();
            let mut items = Vec::new();
            for ci in &chunks {
                let has_wanted = ci.message_index_offsets.is_empty()
                    || ci
                        .message_index_offsets
                        .keys()
                        .any(|id| wanted.contains(id));
                if !has_wanted {
                    continue;
                }
                items.push(self.chunk_at(ci)?);
            }
            let (channels, messages) = self.expand(items, &want, channels)?;
            return Ok(Scan {
                channels,
                messages,
                mode: ReadMode::Indexed,
                profile,
            });
        }
        let (items, channels) = self.linear_items()?;
        let (channels, messages) = self.expand(items, &want, channels)?;
        Ok(Scan {
            channels,
            messages,
            mode: ReadMode::Linear,
            profile,
        })
    }

    fn profile(&self) -> String {
        let buf = &self.map[MAGIC.len()..];
        match frame(buf) {
            Some((op::HEADER, body, _)) => match mcap::parse_record(op::HEADER, body) {
                Ok(Record::Header(h)) => h.profile,
                _ => String::new(),
            },
            _ => String::new(),
        }
    }

    /// The chunk indexes (sorted by offset) and channels of the summary, when
    /// the summary has both and every chunk index points at a chunk.
    #[allow(clippy::type_complexity)]
    fn indexed_plan(
        &self,
    ) -> Result<Option<(Vec<records::ChunkIndex>, BTreeMap<u16, ChannelInfo>)>> {
        // A damaged summary is not fatal: the linear scan reports what is wrong.
        let summary = match mcap::Summary::read(&self.map) {
            Ok(Some(s)) => s,
            Ok(None) | Err(_) => return Ok(None),
        };
        if summary.chunk_indexes.is_empty() || summary.channels.is_empty() {
            return Ok(None);
        }
        let mut channels = BTreeMap::new();
        for (id, c) in &summary.channels {
            channels.insert(*id, channel_info_from_summary(c));
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

    fn chunk_at(&self, ci: &records::ChunkIndex) -> Result<Item<'_>> {
        let start = ci.chunk_start_offset as usize;
        let buf = &self.map[start..];
        match frame(buf) {
            Some((op::CHUNK, body, _)) => match mcap::parse_record(op::CHUNK, body) {
                Ok(Record::Chunk {
                    header,
                    data: Cow::Borrowed(data),
                }) => Ok(Item::Chunk {
                    offset: start,
                    header,
                    data,
                }),
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

    /// Walks the top-level records from the start to the footer.
    fn linear_items(&self) -> Result<(Vec<Item<'_>>, BTreeMap<u16, ChannelInfo>)> {
        let map: &[u8] = &self.map;
        let mut pos = MAGIC.len();
        let mut items = Vec::new();
        let channels = BTreeMap::new();
        let mut footer = false;
        while pos < map.len() {
            let Some((opcode, body, next)) = frame(&map[pos..]) else {
                return Err(self.err(format!(
                    "truncated: record at offset {pos} runs past the end of the file ({} bytes)",
                    map.len()
                )));
            };
            let record = mcap::parse_record(opcode, body).map_err(|e| {
                self.err(format!(
                    "record at offset {pos} (opcode {opcode:#04x}): {e}"
                ))
            })?;
            match record {
                Record::Schema { header, data } => {
                    items.push(Item::Schema(header, data.into_owned()));
                }
                Record::Channel(c) => items.push(Item::Channel(c)),
                Record::Message { header, data } => items.push(Item::Message(RawMessage {
                    channel_id: header.channel_id,
                    sequence: header.sequence,
                    log_time: header.log_time,
                    publish_time: header.publish_time,
                    data: match data {
                        Cow::Borrowed(b) => Cow::Borrowed(b),
                        Cow::Owned(v) => Cow::Owned(v),
                    },
                })),
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
        }
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
    fn expand<'a>(
        &'a self,
        items: Vec<Item<'a>>,
        want: &(impl Fn(&ChannelInfo) -> bool + Sync),
        mut channels: BTreeMap<u16, ChannelInfo>,
    ) -> Result<(BTreeMap<u16, ChannelInfo>, Vec<RawMessage<'a>>)> {
        let expanded: Vec<Result<Vec<Inner<'a>>>> = items
            .into_par_iter()
            .map(|item| match item {
                Item::Schema(h, d) => Ok(vec![Inner::Schema(h, d)]),
                Item::Channel(c) => Ok(vec![Inner::Channel(c)]),
                Item::Message(m) => Ok(vec![Inner::Message(m)]),
                Item::Chunk {
                    offset,
                    header,
                    data,
                } => self.read_chunk(offset, header, data),
            })
            .collect();
        let mut schemas: BTreeMap<u16, (records::SchemaHeader, Vec<u8>)> = BTreeMap::new();
        let mut messages = Vec::new();
        let mut keep: BTreeMap<u16, bool> = channels.values().map(|c| (c.id, want(c))).collect();
        for part in expanded {
            for inner in part? {
                match inner {
                    Inner::Schema(h, d) => {
                        schemas.insert(h.id, (h, d));
                    }
                    Inner::Channel(c) => {
                        if let std::collections::btree_map::Entry::Vacant(slot) = channels.entry(c.id) {
                            let info = channel_info(&c, &schemas).map_err(|r| self.err(r))?;
                            keep.insert(c.id, want(&info));
                            slot.insert(info);
                        }
                    }
                    Inner::Message(m) => match keep.get(&m.channel_id) {
                        Some(true) => messages.push(m),
                        Some(false) => {}
                        None => {
                            return Err(self.err(format!(
                                "message (sequence {}, log time {} ns) on channel {} that no Channel record defines",
                                m.sequence, m.log_time, m.channel_id
                            )))
                        }
                    },
                }
            }
        }
        Ok((channels, messages))
    }

    fn read_chunk<'a>(
        &self,
        offset: usize,
        header: records::ChunkHeader,
        data: &'a [u8],
    ) -> Result<Vec<Inner<'a>>> {
        let reader = mcap::read::ChunkReader::new(header, data)
            .map_err(|e| self.err(format!("chunk at offset {offset}: {e}")))?;
        let mut out = Vec::new();
        for rec in reader {
            let rec = rec.map_err(|e| self.err(format!("chunk at offset {offset}: {e}")))?;
            match rec {
                Record::Schema { header, data } => {
                    out.push(Inner::Schema(header, data.into_owned()))
                }
                Record::Channel(c) => out.push(Inner::Channel(c)),
                Record::Message { header, data } => out.push(Inner::Message(RawMessage {
                    channel_id: header.channel_id,
                    sequence: header.sequence,
                    log_time: header.log_time,
                    publish_time: header.publish_time,
                    data: Cow::Owned(data.into_owned()),
                })),
                _ => {}
            }
        }
        Ok(out)
    }
}

/// Splits one record off the front of `buf`: (opcode, body, bytes consumed).
/// `None` when the buffer ends inside the record.
fn frame(buf: &[u8]) -> Option<(u8, &[u8], usize)> {
    let opcode = *buf.first()?;
    let len_bytes: [u8; 8] = buf.get(1..9)?.try_into().ok()?;
    let len = usize::try_from(u64::from_le_bytes(len_bytes)).ok()?;
    let end = 9usize.checked_add(len)?;
    let body = buf.get(9..end)?;
    Some((opcode, body, end))
}

fn channel_info(
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

fn channel_info_from_summary(c: &mcap::Channel<'_>) -> ChannelInfo {
    let (schema_id, name, encoding, data) = match &c.schema {
        Some(s) => (s.id, s.name.clone(), s.encoding.clone(), s.data.to_vec()),
        None => (0, String::new(), String::new(), Vec::new()),
    };
    ChannelInfo {
        id: c.id,
        topic: c.topic.clone(),
        message_encoding: c.message_encoding.clone(),
        schema_id,
        schema_name: name,
        schema_encoding: encoding,
        schema_data: data,
        metadata: c.metadata.clone(),
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
