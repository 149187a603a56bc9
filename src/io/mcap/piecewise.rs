//! An MCAP writer whose messages may be written a piece at a time: a cloud
//! message of 64 MiB goes from the cloud (in memory or on disk) through the
//! chunk's zstd encoder into the file without ever being whole in memory.
//!
//! The `mcap` crate's writer takes every message as one slice, so
//! `world.mcap`'s cloud message had to be built before it was written: the
//! largest allocation of a conversion. This writer writes the same records
//! (MCAP version 0, zstd chunks, message indexes, a summary with schemas,
//! channels, statistics and chunk indexes, summary offsets, footer) and lays
//! them out deterministically: the same calls give the same bytes.
//!
//! A chunk's header is written with placeholders and patched when the chunk
//! ends (its record length, message times, sizes and CRC are known then), so
//! the destination must seek; one that cannot (a pipe) gets each chunk
//! compressed into memory first.

use std::collections::BTreeMap;
use std::io::{self, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use mcap::records::op;
use mcap::MAGIC;

use crate::error::{Error, Result};

/// A chunk is closed once its uncompressed records pass this size (a larger
/// message still goes whole into one chunk).
const CHUNK_TARGET: u64 = 4 << 20;

/// zstd's default level, as the `mcap` crate writes.
const ZSTD_LEVEL: i32 = 3;

/// Bytes of a chunk record before its (compressed) records: opcode, record
/// length, start and end time, uncompressed size and CRC, the compression
/// string (`zstd`, or empty), the records' length.
fn chunk_head(compression: &[u8]) -> u64 {
    1 + 8 + 8 + 8 + 8 + 4 + (4 + compression.len() as u64) + 8
}

/// Little-endian record fields into a buffer.
#[derive(Default)]
struct Fields(Vec<u8>);

impl Fields {
    fn u8(&mut self, v: u8) -> &mut Self {
        self.0.push(v);
        self
    }
    fn u16(&mut self, v: u16) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn u32(&mut self, v: u32) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn u64(&mut self, v: u64) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    /// A length-prefixed (u32) byte string: MCAP's `String` and `Bytes`.
    fn bytes(&mut self, v: &[u8]) -> &mut Self {
        self.u32(v.len() as u32);
        self.0.extend_from_slice(v);
        self
    }
    /// A map or array, prefixed by its length in bytes (u32).
    fn prefixed(&mut self, body: &[u8]) -> &mut Self {
        self.bytes(body)
    }
    /// The record `opcode` with these fields as its body.
    fn record(&self, opcode: u8) -> Vec<u8> {
        let mut r = Vec::with_capacity(9 + self.0.len());
        r.push(opcode);
        r.extend_from_slice(&(self.0.len() as u64).to_le_bytes());
        r.extend_from_slice(&self.0);
        r
    }
}

/// The chunk being written: its encoder, and what its index will say.
struct OpenChunk {
    /// Offset of the chunk record in the file.
    start: u64,
    /// The compressed records when the file cannot seek.
    memory: Option<Vec<u8>>,
    /// The uncompressed records' length and CRC, the compressed length.
    uncompressed: u64,
    crc: crc32fast::Hasher,
    compressed: u64,
    times: Option<(u64, u64)>,
    /// Per channel: (log time, offset in the uncompressed records).
    index: BTreeMap<u16, Vec<(u64, u64)>>,
    /// The encoder, its output drained after every write (none: the
    /// records stored as they are).
    encoder: Option<zstd::stream::write::Encoder<'static, Vec<u8>>>,
}

impl OpenChunk {
    /// The chunk's compression string.
    fn compression(&self) -> &'static [u8] {
        if self.encoder.is_some() {
            b"zstd"
        } else {
            b""
        }
    }
}

/// The open chunk as a writer of uncompressed records: counted,
/// checksummed, compressed, and the compressed bytes passed on to the file
/// (or kept in the chunk's memory) as the encoder gives them.
struct Compress<'a, W> {
    chunk: &'a mut OpenChunk,
    w: &'a mut W,
    pos: &'a mut u64,
}

impl<W: Write> Write for Compress<'_, W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let Some(encoder) = self.chunk.encoder.as_mut() else {
            self.chunk.crc.update(buf);
            self.chunk.uncompressed += buf.len() as u64;
            match &mut self.chunk.memory {
                Some(m) => m.extend_from_slice(buf),
                None => {
                    self.w.write_all(buf)?;
                    *self.pos += buf.len() as u64;
                }
            }
            self.chunk.compressed += buf.len() as u64;
            return Ok(buf.len());
        };
        let n = encoder.write(buf)?;
        self.chunk.crc.update(&buf[..n]);
        self.chunk.uncompressed += n as u64;
        let out = encoder.get_mut();
        if !out.is_empty() {
            match &mut self.chunk.memory {
                Some(m) => m.extend_from_slice(out),
                None => {
                    self.w.write_all(out)?;
                    *self.pos += out.len() as u64;
                }
            }
            self.chunk.compressed += out.len() as u64;
            out.clear();
        }
        Ok(n)
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// A channel of a [`PiecewiseWriter`], and the sequence number of its next
/// message.
#[derive(Debug)]
pub struct Channel {
    id: u16,
    seq: u32,
}

/// The streaming MCAP writer (see the module's documentation). Nothing but
/// `finish` makes the file a valid MCAP.
pub struct PiecewiseWriter<W: Write + Seek> {
    w: W,
    /// The file, for errors.
    path: PathBuf,
    /// Bytes written to `w` so far (its position, without asking it).
    pos: u64,
    seekable: bool,
    /// Schema records by id, then channel records by id, as written.
    schemas: BTreeMap<u16, Vec<u8>>,
    schema_ids: BTreeMap<(String, String, Vec<u8>), u16>,
    channels: BTreeMap<u16, Vec<u8>>,
    chunk: Option<OpenChunk>,
    chunk_indexes: Vec<Vec<u8>>,
    counts: BTreeMap<u16, u64>,
    times: Option<(u64, u64)>,
    /// Chunks zstd-compressed (the default), or stored as they are.
    compress: bool,
}

impl<W: Write + Seek> PiecewiseWriter<W> {
    /// Chunks stored uncompressed from here on (a file written again and
    /// again for a live viewer: compressing it would cost more than
    /// writing it, and its reader would pay again to decompress).
    pub fn uncompressed(mut self) -> Self {
        self.compress = false;
        self
    }

    /// Starts an MCAP on `w` (at its start; `path` names it in errors):
    /// magic and header.
    pub fn new(mut w: W, path: &Path, profile: &str, library: &str) -> Result<Self> {
        let seekable = w.stream_position().is_ok();
        let mut header = Fields::default();
        header.bytes(profile.as_bytes()).bytes(library.as_bytes());
        let header = header.record(op::HEADER);
        w.write_all(MAGIC)
            .and_then(|_| w.write_all(&header))
            .map_err(|e| Error::io(path, e))?;
        Ok(PiecewiseWriter {
            w,
            path: path.to_path_buf(),
            pos: (MAGIC.len() + header.len()) as u64,
            seekable,
            schemas: BTreeMap::new(),
            schema_ids: BTreeMap::new(),
            channels: BTreeMap::new(),
            chunk: None,
            chunk_indexes: Vec::new(),
            counts: BTreeMap::new(),
            times: None,
            compress: true,
        })
    }

    /// Adds a channel on `topic` with its schema `(name, encoding, data)`
    /// (one record for each distinct schema) and `message_encoding`.
    pub fn add_channel(
        &mut self,
        topic: &str,
        schema: (&str, &str, &[u8]),
        message_encoding: &str,
    ) -> Result<Channel> {
        let key = (
            schema.0.to_string(),
            schema.1.to_string(),
            schema.2.to_vec(),
        );
        let schema_id = match self.schema_ids.get(&key) {
            Some(id) => *id,
            None => {
                let id = self.schema_ids.len() as u16 + 1;
                let mut f = Fields::default();
                f.u16(id)
                    .bytes(schema.0.as_bytes())
                    .bytes(schema.1.as_bytes())
                    .bytes(schema.2);
                let record = f.record(op::SCHEMA);
                self.records(&record)
                    .map_err(|e| Error::io(&self.path, e))?;
                self.schemas.insert(id, record);
                self.schema_ids.insert(key, id);
                id
            }
        };
        let id = self.channels.len() as u16;
        let mut f = Fields::default();
        f.u16(id)
            .u16(schema_id)
            .bytes(topic.as_bytes())
            .bytes(message_encoding.as_bytes())
            .prefixed(&[]); // metadata: an empty map
        let record = f.record(op::CHANNEL);
        self.records(&record)
            .map_err(|e| Error::io(&self.path, e))?;
        self.channels.insert(id, record);
        Ok(Channel { id, seq: 0 })
    }

    /// Writes a message of `data` at `log_time` (also its publish time).
    pub fn message(&mut self, ch: &mut Channel, log_time: u64, data: &[u8]) -> Result<()> {
        let path = self.path.clone();
        self.message_with(ch, log_time, data.len() as u64, |w| {
            w.write_all(data).map_err(|e| Error::io(&path, e))
        })
    }

    /// Writes a message of `len` bytes that `fill` writes, a piece at a time,
    /// into the chunk (its write errors are the file's); an error when `fill`
    /// writes another number of bytes.
    pub fn message_with(
        &mut self,
        ch: &mut Channel,
        log_time: u64,
        len: u64,
        fill: impl FnOnce(&mut dyn Write) -> Result<()>,
    ) -> Result<()> {
        let mut head = Fields::default();
        head.u8(op::MESSAGE)
            .u64(2 + 4 + 8 + 8 + len)
            .u16(ch.id)
            .u32(ch.seq)
            .u64(log_time)
            .u64(log_time);
        let path = self.path.clone();
        let io_err = |e| Error::io(&path, e);
        let mut sink = self.open_chunk().map_err(io_err)?;
        let chunk = &mut *sink.chunk;
        let offset = chunk.uncompressed;
        chunk
            .index
            .entry(ch.id)
            .or_default()
            .push((log_time, offset));
        chunk.times = Some(match chunk.times {
            None => (log_time, log_time),
            Some((a, b)) => (a.min(log_time), b.max(log_time)),
        });
        sink.write_all(&head.0).map_err(io_err)?;
        let before = sink.chunk.uncompressed;
        fill(&mut sink)?;
        let wrote = sink.chunk.uncompressed - before;
        if wrote != len {
            return Err(Error::invalid(
                "message",
                format!("a message declared {len} bytes and was given {wrote}"),
            ));
        }
        ch.seq = ch.seq.wrapping_add(1);
        *self.counts.entry(ch.id).or_insert(0) += 1;
        self.times = Some(match self.times {
            None => (log_time, log_time),
            Some((a, b)) => (a.min(log_time), b.max(log_time)),
        });
        if self
            .chunk
            .as_ref()
            .is_some_and(|c| c.uncompressed >= CHUNK_TARGET)
        {
            self.close_chunk().map_err(io_err)?;
        }
        Ok(())
    }

    /// Writes `bytes` (whole records) into the open chunk, opening one if
    /// none is.
    fn records(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.open_chunk()?.write_all(bytes)
    }

    /// The open chunk as a writer (opened now if none is: its header
    /// written with placeholders where the file can seek back to patch it).
    fn open_chunk(&mut self) -> io::Result<Compress<'_, W>> {
        let PiecewiseWriter {
            w,
            pos,
            seekable,
            chunk,
            compress,
            ..
        } = self;
        let chunk = match chunk {
            Some(c) => c,
            None => {
                let start = *pos;
                let encoder = match compress {
                    true => Some(zstd::stream::write::Encoder::new(Vec::new(), ZSTD_LEVEL)?),
                    false => None,
                };
                let head = chunk_head(if encoder.is_some() { b"zstd" } else { b"" });
                let memory = if *seekable {
                    w.write_all(&vec![0; head as usize])?;
                    *pos += head;
                    None
                } else {
                    Some(Vec::new())
                };
                chunk.insert(OpenChunk {
                    start,
                    memory,
                    uncompressed: 0,
                    crc: crc32fast::Hasher::new(),
                    compressed: 0,
                    times: None,
                    index: BTreeMap::new(),
                    encoder,
                })
            }
        };
        Ok(Compress { chunk, w, pos })
    }

    /// Ends the open chunk, if any: the encoder flushed, the header patched
    /// (or the chunk written from memory), its message indexes written after
    /// it and its chunk index kept for the summary.
    fn close_chunk(&mut self) -> io::Result<()> {
        let Some(chunk) = self.chunk.take() else {
            return Ok(());
        };
        let compression = chunk.compression();
        // The encoder's last bytes.
        let tail = match chunk.encoder {
            Some(e) => e.finish()?,
            None => Vec::new(),
        };
        let (start_time, end_time) = chunk.times.unwrap_or((0, 0));
        let mut head = Fields::default();
        let compressed = chunk.compressed + tail.len() as u64;
        head.u8(op::CHUNK)
            .u64(chunk_head(compression) - 9 + compressed)
            .u64(start_time)
            .u64(end_time)
            .u64(chunk.uncompressed)
            .u32(chunk.crc.clone().finalize())
            .bytes(compression)
            .u64(compressed);
        match chunk.memory {
            None => {
                self.w.write_all(&tail)?;
                let end = self.pos + tail.len() as u64;
                self.w.seek(SeekFrom::Start(chunk.start))?;
                self.w.write_all(&head.0)?;
                self.w.seek(SeekFrom::Start(end))?;
                self.pos = end;
            }
            Some(body) => {
                self.w.write_all(&head.0)?;
                self.w.write_all(&body)?;
                self.w.write_all(&tail)?;
                self.pos += head.0.len() as u64 + body.len() as u64 + tail.len() as u64;
            }
        }
        let chunk_length = self.pos - chunk.start;
        let index_start = self.pos;
        let mut offsets = Fields::default();
        for (channel, entries) in &chunk.index {
            let mut list = Fields::default();
            for (t, o) in entries {
                list.u64(*t).u64(*o);
            }
            let mut f = Fields::default();
            f.u16(*channel).prefixed(&list.0);
            let record = f.record(op::MESSAGE_INDEX);
            offsets.u16(*channel).u64(self.pos);
            self.w.write_all(&record)?;
            self.pos += record.len() as u64;
        }
        let mut index = Fields::default();
        index
            .u64(start_time)
            .u64(end_time)
            .u64(chunk.start)
            .u64(chunk_length)
            .prefixed(&offsets.0)
            .u64(self.pos - index_start)
            .bytes(compression)
            .u64(compressed)
            .u64(chunk.uncompressed);
        self.chunk_indexes.push(index.record(op::CHUNK_INDEX));
        Ok(())
    }

    /// Ends the file: the last chunk, the data end, the summary (schemas,
    /// channels, statistics, chunk indexes), the summary offsets, the footer
    /// and the magic; returns the destination.
    pub fn finish(self) -> Result<W> {
        let path = self.path.clone();
        self.finish_io().map_err(|e| Error::io(path, e))
    }

    fn finish_io(mut self) -> io::Result<W> {
        self.close_chunk()?;
        // The data section's CRC is not computed (0: not available), as the
        // chunks' headers are patched after their bytes went by.
        let mut end = Fields::default();
        end.u32(0);
        let end = end.record(op::DATA_END);
        self.w.write_all(&end)?;
        self.pos += end.len() as u64;
        let summary_start = self.pos;
        let mut summary: Vec<u8> = Vec::new();
        let mut groups: Vec<(u8, u64, u64)> = Vec::new();
        let mut group = |opcode: u8, records: &mut dyn Iterator<Item = &Vec<u8>>| {
            let start = summary.len() as u64;
            for r in records {
                summary.extend_from_slice(r);
            }
            let len = summary.len() as u64 - start;
            if len > 0 {
                groups.push((opcode, summary_start + start, len));
            }
        };
        group(op::SCHEMA, &mut self.schemas.values());
        group(op::CHANNEL, &mut self.channels.values());
        let (start_time, end_time) = self.times.unwrap_or((0, 0));
        let mut counts = Fields::default();
        for (c, n) in &self.counts {
            counts.u16(*c).u64(*n);
        }
        let mut stats = Fields::default();
        stats
            .u64(self.counts.values().sum())
            .u16(self.schemas.len() as u16)
            .u32(self.channels.len() as u32)
            .u32(0) // attachments
            .u32(0) // metadata
            .u32(self.chunk_indexes.len() as u32)
            .u64(start_time)
            .u64(end_time)
            .prefixed(&counts.0);
        let stats = stats.record(op::STATISTICS);
        group(op::STATISTICS, &mut std::iter::once(&stats));
        group(op::CHUNK_INDEX, &mut self.chunk_indexes.iter());
        let offsets_start = summary_start + summary.len() as u64;
        for (opcode, start, len) in &groups {
            let mut f = Fields::default();
            f.u8(*opcode).u64(*start).u64(*len);
            summary.extend_from_slice(&f.record(op::SUMMARY_OFFSET));
        }
        // The footer's CRC covers the summary from its start through the
        // footer's fields before the CRC.
        let mut footer = Fields::default();
        footer.u64(summary_start).u64(offsets_start);
        let mut footer = footer.record(op::FOOTER);
        // The record's length counts the CRC that follows.
        footer[1..9].copy_from_slice(&(8u64 + 8 + 4).to_le_bytes());
        let mut crc = crc32fast::Hasher::new();
        crc.update(&summary);
        crc.update(&footer);
        footer.extend_from_slice(&crc.finalize().to_le_bytes());
        self.w.write_all(&summary)?;
        self.w.write_all(&footer)?;
        self.w.write_all(MAGIC)?;
        self.w.flush()?;
        Ok(self.w)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    /// A destination that cannot seek (a pipe).
    struct Pipe(Vec<u8>);

    impl Write for Pipe {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            self.0.write(buf)
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    impl Seek for Pipe {
        fn seek(&mut self, _: SeekFrom) -> io::Result<u64> {
            Err(io::Error::new(io::ErrorKind::Unsupported, "a pipe"))
        }
    }

    /// Three channels (two sharing a schema), small messages and one of
    /// 10 MiB written in 1000-byte pieces: more than one chunk.
    fn write<W: Write + Seek>(w: W) -> W {
        write_with(w, true)
    }

    /// [`write`], the chunks compressed or stored.
    fn write_with<W: Write + Seek>(w: W, compress: bool) -> W {
        let path = Path::new("test.mcap");
        let m = PiecewiseWriter::new(w, path, "ros2", "slam2world test").unwrap();
        let mut m = if compress { m } else { m.uncompressed() };
        let mut a = m
            .add_channel("/a", ("A", "protobuf", b"schema a"), "protobuf")
            .unwrap();
        let mut b = m
            .add_channel("/b", ("B", "ros2msg", b"schema b"), "cdr")
            .unwrap();
        let mut c = m
            .add_channel("/c", ("A", "protobuf", b"schema a"), "protobuf")
            .unwrap();
        m.message(&mut a, 5, b"first").unwrap();
        m.message(&mut b, 3, &[7; 100]).unwrap();
        let big = 10 << 20;
        m.message_with(&mut c, 9, big, |out| {
            for i in 0..big / 1000 {
                out.write_all(&[(i % 251) as u8; 1000]).unwrap();
            }
            out.write_all(&vec![1; (big % 1000) as usize]).unwrap();
            Ok(())
        })
        .unwrap();
        m.message(&mut a, 7, b"second").unwrap();
        m.finish().unwrap()
    }

    fn big_message() -> Vec<u8> {
        let big = 10 << 20;
        let mut v: Vec<u8> = (0..big / 1000)
            .flat_map(|i| [(i % 251) as u8; 1000])
            .collect();
        v.resize(big, 1);
        v
    }

    #[test]
    fn the_mcap_crate_reads_every_message_index_and_summary_record() {
        for compress in [true, false] {
            crate_reads(compress);
        }
    }

    fn crate_reads(compress: bool) {
        let file = write_with(Cursor::new(Vec::new()), compress).into_inner();
        // Linear read, chunk CRCs checked.
        let messages: Vec<_> = mcap::MessageStream::new(&file)
            .unwrap()
            .map(|m| m.unwrap())
            .map(|m| {
                let schema = m.channel.schema.as_ref().unwrap();
                (
                    m.channel.topic.clone(),
                    schema.name.clone(),
                    schema.data.to_vec(),
                    m.channel.message_encoding.clone(),
                    m.sequence,
                    m.log_time,
                    m.publish_time,
                    m.data.to_vec(),
                )
            })
            .collect();
        let text = |s: &str| s.to_string();
        let expect = vec![
            (
                text("/a"),
                text("A"),
                b"schema a".to_vec(),
                text("protobuf"),
                0,
                5,
                5,
                b"first".to_vec(),
            ),
            (
                text("/b"),
                text("B"),
                b"schema b".to_vec(),
                text("cdr"),
                0,
                3,
                3,
                vec![7; 100],
            ),
            (
                text("/c"),
                text("A"),
                b"schema a".to_vec(),
                text("protobuf"),
                0,
                9,
                9,
                big_message(),
            ),
            (
                text("/a"),
                text("A"),
                b"schema a".to_vec(),
                text("protobuf"),
                1,
                7,
                7,
                b"second".to_vec(),
            ),
        ];
        assert!(messages == expect, "messages differ");

        // The summary: two schemas, three channels, the statistics, and
        // chunk indexes whose message indexes find every message.
        let summary = mcap::Summary::read(&file).unwrap().unwrap();
        assert_eq!(summary.schemas.len(), 2);
        assert_eq!(summary.channels.len(), 3);
        let stats = summary.stats.as_ref().unwrap();
        assert_eq!(stats.message_count, 4);
        assert_eq!((stats.message_start_time, stats.message_end_time), (3, 9));
        assert_eq!(stats.channel_message_counts.values().sum::<u64>(), 4);
        assert_eq!(stats.chunk_count as usize, summary.chunk_indexes.len());
        assert!(summary.chunk_indexes.len() >= 2);
        let mut found = Vec::new();
        for index in &summary.chunk_indexes {
            for (channel, entries) in summary.read_message_indexes(&file, index).unwrap() {
                for e in entries {
                    let m = summary.seek_message(&file, index, &e).unwrap();
                    assert_eq!(m.channel.id, channel.id);
                    assert_eq!(m.log_time, e.log_time);
                    found.push((m.channel.topic.clone(), m.log_time, m.data.len()));
                }
            }
        }
        found.sort();
        assert_eq!(
            found,
            vec![
                (text("/a"), 5, 5),
                (text("/a"), 7, 6),
                (text("/b"), 3, 100),
                (text("/c"), 9, 10 << 20)
            ]
        );
        // The footer's summary CRC is checked by the crate.
        let footer = mcap::read::footer(&file).unwrap();
        assert_ne!(footer.summary_crc, 0);
        let want = if compress { "zstd" } else { "" };
        assert!(summary.chunk_indexes.iter().all(|c| c.compression == want));
        // Stored: the 10 MiB message is in the file as it is.
        assert_eq!(file.len() > 10 << 20, !compress);
    }

    #[test]
    fn a_pipe_gets_the_same_bytes_and_the_same_calls_give_the_same_file() {
        for compress in [true, false] {
            let seeking = write_with(Cursor::new(Vec::new()), compress).into_inner();
            assert_eq!(write_with(Pipe(Vec::new()), compress).0, seeking);
            assert_eq!(
                write_with(Cursor::new(Vec::new()), compress).into_inner(),
                seeking
            );
        }
    }

    #[test]
    fn a_message_given_other_bytes_than_it_declared_is_refused() {
        let path = Path::new("test.mcap");
        let mut m = PiecewiseWriter::new(Cursor::new(Vec::new()), path, "", "t").unwrap();
        let mut a = m
            .add_channel("/a", ("A", "protobuf", b""), "protobuf")
            .unwrap();
        let e = m
            .message_with(&mut a, 1, 10, |out| {
                out.write_all(b"short").map_err(|e| Error::io(path, e))
            })
            .unwrap_err();
        assert!(
            e.to_string().contains("declared 10 bytes and was given 5"),
            "{e}"
        );
    }

    #[test]
    fn the_project_reader_reads_the_file_indexed() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.mcap");
        std::fs::write(&path, write(Cursor::new(Vec::new())).into_inner()).unwrap();
        let f = crate::io::mcap::McapFile::open(&path).unwrap();
        let scan = f.scan(|_| true).unwrap();
        assert_eq!(scan.mode, crate::io::mcap::ReadMode::Indexed);
        assert_eq!(scan.len(), 4);
    }
}
