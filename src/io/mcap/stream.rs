//! [`McapFile::scan_map`]: every message mapped to a compact value inside the
//! parallel chunk tasks, so that a chunk's decompressed buffer is reused for the
//! next chunk instead of being kept (the memory-lean path of `io::log`).

use std::collections::BTreeMap;

use mcap::records::{self, Record};
use rayon::prelude::*;

use super::reader::{
    channel_info, count_messages, expand_chunk, walk_chunk, ChunkItem, Def, Item, McapFile,
};
use crate::error::Result;
use crate::io::messages::{
    ChannelInfo, MappedMessage, MappedScan, RawMessage, ReadMode, ScanInfo, ScanSink,
};

/// What one item gives: its definitions, its messages (mapped, or holding
/// `T::default()` until mapped after the merge) and the bytes of the messages
/// whose channel the task could not see, by position in the item's messages.
type Part<T> = (Vec<Def>, Vec<MappedMessage<T>>, Vec<(usize, Vec<u8>)>);

/// Decompression buffers kept from one wave of chunk tasks to the next, for
/// as long as one scan runs. Freed at the end of each wave, a chunk's buffer
/// (3.8 MB for the demo's chunks) went back to the system (with the command
/// line's fixed mmap threshold, [`crate::buffer::MMAP_THRESHOLD`], glibc
/// trims the free top of its heap from 128 KiB) and the next wave's tasks
/// faulted its pages in again: 4.7 GB of chunks on the 10x log.
#[derive(Default)]
struct Buffers(std::sync::Mutex<Vec<Vec<u8>>>);

/// A buffer of [`Buffers`] lent to one chunk task (a rayon split), given
/// back when the task ends.
struct Lent<'p> {
    buf: Vec<u8>,
    pool: &'p Buffers,
}

impl Buffers {
    /// Buffers kept at most: one for each thread (a task a waiting thread
    /// stole lends one more, dropped when it ends).
    fn most() -> usize {
        rayon::current_num_threads()
    }

    fn lend(&self) -> Lent<'_> {
        let buf = self.0.lock().ok().and_then(|mut kept| kept.pop());
        Lent {
            buf: buf.unwrap_or_default(),
            pool: self,
        }
    }
}

impl Drop for Lent<'_> {
    fn drop(&mut self) {
        if let Ok(mut kept) = self.pool.0.lock() {
            if kept.len() < Buffers::most() {
                kept.push(std::mem::take(&mut self.buf));
            }
        }
    }
}

/// Channel lookup by id for the chunk tasks: `(info, wanted)`.
fn table_of<'k>(
    known: &'k BTreeMap<u16, ChannelInfo>,
    want: &impl Fn(&ChannelInfo) -> bool,
) -> Vec<Option<(&'k ChannelInfo, bool)>> {
    let mut table = vec![None; 1 << 16];
    for c in known.values() {
        table[c.id as usize] = Some((c, want(c)));
    }
    table
}

impl McapFile {
    /// Like [`McapFile::scan`], but each wanted message is passed to `map`
    /// (with its channel) inside the parallel chunk task, and only the mapped
    /// value is kept. Messages of channels defined later than the chunk task can
    /// see are mapped after their wave's merge, with the same result.
    ///
    /// Read through the index, the messages of each wanted channel are
    /// counted against the summary's Statistics record: when fewer were
    /// found (a chunk index missing from the summary), the file is read
    /// again by a linear scan, whose mode the result reports.
    pub fn scan_map<T: Send + Default>(
        &self,
        want: impl Fn(&ChannelInfo) -> bool + Sync,
        map: impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync,
    ) -> Result<MappedScan<T>> {
        let mut messages = Vec::new();
        let info = self.scan_into(want, map, &mut messages)?;
        Ok(info.with_messages(messages))
    }

    /// [`McapFile::scan_map`] with the messages given to `sink` in file
    /// order, a wave of chunks at a time: the chunk tasks' messages are never
    /// held whole, only what `sink` keeps of them.
    pub fn scan_into<T: Send + Default>(
        &self,
        want: impl Fn(&ChannelInfo) -> bool + Sync,
        map: impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync,
        sink: &mut dyn ScanSink<T>,
    ) -> Result<ScanInfo> {
        let r = self.scan_into_checked(&want, &map, sink);
        // A file that shrank while it was read: that, whatever else went wrong.
        self.check_unchanged()?;
        r
    }

    fn scan_into_checked<T: Send + Default>(
        &self,
        want: &(impl Fn(&ChannelInfo) -> bool + Sync),
        map: &(impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync),
        sink: &mut dyn ScanSink<T>,
    ) -> Result<ScanInfo> {
        let (info, got) = self.scan_into_with(want, map, true, sink)?;
        if info.mode == ReadMode::Indexed {
            if let Some(declared) = self.declared_counts() {
                let short = info
                    .channels
                    .values()
                    .filter(|c| want(c))
                    .any(|c| got[c.id as usize] < declared.get(&c.id).copied().unwrap_or(0));
                if short {
                    sink.restart();
                    return Ok(self.scan_into_with(want, map, false, sink)?.0);
                }
            }
        }
        Ok(info)
    }

    /// The scan, and the messages given per channel id.
    fn scan_into_with<T: Send + Default>(
        &self,
        want: &(impl Fn(&ChannelInfo) -> bool + Sync),
        map: &(impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync),
        use_index: bool,
        sink: &mut dyn ScanSink<T>,
    ) -> Result<(ScanInfo, Vec<u64>)> {
        let profile = self.profile();
        let plan = if use_index {
            self.indexed_plan()?
        } else {
            None
        };
        let (mut items, mut known, mode, mut schemas_seen) = match plan {
            Some((chunks, channels)) => {
                let items = self.wanted_chunks(&chunks, &channels, want)?;
                (items, channels, ReadMode::Indexed, BTreeMap::new())
            }
            None => {
                let (items, _) = self.linear_items()?;
                // Channels defined outside chunks are known to every task.
                let mut schemas = BTreeMap::new();
                let mut known = BTreeMap::new();
                for item in &items {
                    match item {
                        Item::Schema(h, d) => {
                            schemas.insert(h.id, (h.clone(), d.clone()));
                        }
                        Item::Channel(c) => {
                            if let Ok(info) = channel_info(c, &schemas) {
                                known.entry(c.id).or_insert(info);
                            }
                        }
                        _ => {}
                    }
                }
                (items, known, ReadMode::Linear, schemas)
            }
        };
        if let Some(declared) = self.declared_counts() {
            // As many as the file can hold at most (a message record is at
            // least 31 bytes), whatever its summary says.
            let most = (self.bytes().len() / 31) as u64;
            let counts: BTreeMap<u16, u64> = declared
                .into_iter()
                .map(|(id, n)| (id, n.min(most)))
                .collect();
            sink.expect(&counts);
        }
        let mut merge = Merge {
            file: self,
            channels: if mode == ReadMode::Indexed {
                known.clone()
            } else {
                BTreeMap::new()
            },
            schemas: BTreeMap::new(),
            keep: vec![0u8; 1 << 16],
            got: vec![0; 1 << 16],
        };
        for c in merge.channels.values() {
            merge.keep[c.id as usize] = if want(c) { 2 } else { 1 };
        }
        if mode == ReadMode::Linear {
            // Writers define a channel in the chunk of its first message: reading up
            // to the first chunk alone lets the parallel tasks know those channels.
            if let Some(first) = items.iter().position(|i| matches!(i, Item::Chunk { .. })) {
                let rest = items.split_off(first + 1);
                let prefix = std::mem::replace(&mut items, rest);
                let mut found = Vec::new();
                let mut parts = Vec::new();
                {
                    let table = table_of(&known, want);
                    let mut buf = Vec::new();
                    for item in prefix {
                        let part = self.map_item(item, &table, &mut buf, want, map);
                        if let Ok((defs, _, _)) = &part {
                            for d in defs {
                                match d {
                                    Def::Schema(h, data) => {
                                        schemas_seen.insert(h.id, (h.clone(), data.clone()));
                                    }
                                    Def::Channel(c) => {
                                        if let Ok(info) = channel_info(c, &schemas_seen) {
                                            found.push(info);
                                        }
                                    }
                                }
                            }
                        }
                        parts.push(part);
                    }
                }
                for info in found {
                    known.entry(info.id).or_insert(info);
                }
                merge.wave(parts, want, map, sink)?;
            }
        }
        // Waves of items: the messages of one wave are merged and given to the
        // sink before the next wave's tasks run (a long log's messages are never
        // all held), and the channels a wave defined are known to the next.
        let wave = (rayon::current_num_threads() * 4).max(8);
        let buffers = Buffers::default();
        while !items.is_empty() {
            let rest = items.split_off(wave.min(items.len()));
            let batch = std::mem::replace(&mut items, rest);
            let parts: Vec<Result<Part<T>>> = {
                let table = table_of(&known, want);
                batch
                    .into_par_iter()
                    .map_init(
                        || buffers.lend(),
                        |lent, item| {
                            crate::interrupt::check()?;
                            self.map_item(item, &table, &mut lent.buf, want, map)
                        },
                    )
                    .collect()
            };
            // What the chunk tasks freed goes back first.
            crate::buffer::release_free_memory();
            merge.wave(parts, want, map, sink)?;
            for (id, c) in &merge.channels {
                known.entry(*id).or_insert_with(|| c.clone());
            }
        }
        let info = ScanInfo {
            channels: merge.channels,
            mode,
            profile,
        };
        Ok((info, merge.got))
    }

    fn map_item<T: Default>(
        &self,
        item: Item<'_>,
        known: &[Option<(&ChannelInfo, bool)>],
        buf: &mut Vec<u8>,
        want: &(impl Fn(&ChannelInfo) -> bool + Sync),
        map: &(impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync),
    ) -> Result<Part<T>> {
        let mut defs = Vec::new();
        let mut msgs: Vec<MappedMessage<T>> = Vec::new();
        let mut raw_of: Vec<(usize, Vec<u8>)> = Vec::new();
        // Parts wait for the merge: each holds exactly its messages (no
        // guessed spare capacity adding up over a long log, no regrowth
        // leaving freed copies behind).
        let chunk_err =
            |offset: usize, what: String| self.err(format!("chunk at offset {offset}: {what}"));
        let expected = match &item {
            Item::Chunk {
                offset,
                header,
                data,
            } => {
                expand_chunk(header, data, buf).map_err(|what| chunk_err(*offset, what))?;
                count_messages(buf)
            }
            Item::Message(_) => 1,
            _ => 0,
        };
        msgs.reserve_exact(expected);
        let mut local: BTreeMap<u16, ChannelInfo> = BTreeMap::new();
        let mut local_schemas: BTreeMap<u16, (records::SchemaHeader, Vec<u8>)> = BTreeMap::new();
        let mut push = |raw: RawMessage<'_>, local: &BTreeMap<u16, ChannelInfo>| {
            let info = match known[raw.channel_id as usize] {
                Some((c, w)) => Some((c, w)),
                None => local.get(&raw.channel_id).map(|c| (c, want(c))),
            };
            let value = match info {
                Some((c, true)) => map(c, &raw),
                // Unwanted (the merge drops it) or not yet defined (mapped after the merge).
                Some((_, false)) => T::default(),
                None => {
                    raw_of.push((msgs.len(), raw.data.to_vec()));
                    T::default()
                }
            };
            msgs.push(MappedMessage {
                channel_id: raw.channel_id,
                sequence: raw.sequence,
                log_time: raw.log_time,
                publish_time: raw.publish_time,
                value,
            });
        };
        match item {
            Item::Schema(h, d) => defs.push(Def::Schema(h, d)),
            Item::Channel(c) => defs.push(Def::Channel(c)),
            Item::Message(e) => {
                let raw = RawMessage {
                    channel_id: e.channel_id,
                    sequence: e.sequence,
                    log_time: e.log_time,
                    publish_time: e.publish_time,
                    data: &self.bytes()[e.start..e.end],
                };
                push(raw, &local);
            }
            Item::Chunk { offset, data, .. } => {
                let at = |what: String| chunk_err(offset, what);
                walk_chunk(buf, |item| {
                    match item {
                        ChunkItem::Message(_, raw) => push(raw, &local),
                        ChunkItem::Other(Record::Schema { header, data }) => {
                            local_schemas.insert(header.id, (header.clone(), data.to_vec()));
                            defs.push(Def::Schema(header, data.into_owned()));
                        }
                        ChunkItem::Other(Record::Channel(c)) => {
                            if let Ok(info) = channel_info(&c, &local_schemas) {
                                local.entry(c.id).or_insert(info);
                            }
                            defs.push(Def::Channel(c));
                        }
                        ChunkItem::Other(_) => {}
                    }
                    Ok(())
                })
                .map_err(at)?;
                // Done with the chunk's bytes: a long log is not held whole.
                self.release(data);
            }
        }
        Ok((defs, msgs, raw_of))
    }
}

/// The merge of a scan's waves, in file order: the definitions applied, the
/// messages of unwanted channels dropped, those mapped late given their value.
struct Merge<'f> {
    file: &'f McapFile,
    channels: BTreeMap<u16, ChannelInfo>,
    schemas: BTreeMap<u16, (records::SchemaHeader, Vec<u8>)>,
    /// Per channel id: 0 undefined, 1 unwanted, 2 wanted.
    keep: Vec<u8>,
    /// Messages given to the sink, per channel id.
    got: Vec<u64>,
}

impl Merge<'_> {
    /// Merges one wave's parts and gives its messages to `sink`.
    fn wave<T: Send + Default>(
        &mut self,
        parts: Vec<Result<Part<T>>>,
        want: &(impl Fn(&ChannelInfo) -> bool + Sync),
        map: &(impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync),
        sink: &mut dyn ScanSink<T>,
    ) -> Result<()> {
        let total: usize = parts
            .iter()
            .map(|p| p.as_ref().map_or(0, |p| p.1.len()))
            .sum();
        let mut messages: Vec<MappedMessage<T>> = Vec::with_capacity(total);
        let mut deferred: Vec<(usize, Vec<u8>)> = Vec::new();
        let mut releaser = crate::buffer::Releaser::default();
        for part in parts {
            let (defs, msgs, raw) = part?;
            self.file.apply_defs(
                defs,
                &mut self.schemas,
                &mut self.channels,
                &mut self.keep,
                want,
            )?;
            releaser.freed(msgs.capacity() * std::mem::size_of::<MappedMessage<T>>());
            let mut raw = raw.into_iter().peekable();
            for (j, m) in msgs.into_iter().enumerate() {
                let bytes = match raw.peek() {
                    Some((k, _)) if *k == j => raw.next().map(|r| r.1),
                    _ => None,
                };
                match self.keep[m.channel_id as usize] {
                    2 => {
                        if let Some(b) = bytes {
                            deferred.push((messages.len(), b));
                        }
                        messages.push(m);
                    }
                    1 => {}
                    _ => {
                        return Err(self.file.err(format!(
                            "message (sequence {}, log time {} ns) on channel {} that no Channel record defines",
                            m.sequence, m.log_time, m.channel_id
                        )))
                    }
                }
            }
        }
        // In parallel: a linear scan of a file whose channels are defined in an
        // earlier chunk of the wave defers their messages.
        let heads: Vec<(usize, u16, u32, u64, u64, Vec<u8>)> = deferred
            .into_iter()
            .map(|(k, bytes)| {
                let m = &messages[k];
                (
                    k,
                    m.channel_id,
                    m.sequence,
                    m.log_time,
                    m.publish_time,
                    bytes,
                )
            })
            .collect();
        let channels = &self.channels;
        let values: Vec<(usize, T)> = heads
            .into_par_iter()
            .filter_map(|(k, channel_id, sequence, log_time, publish_time, bytes)| {
                let raw = RawMessage {
                    channel_id,
                    sequence,
                    log_time,
                    publish_time,
                    data: &bytes,
                };
                channels.get(&channel_id).map(|c| (k, map(c, &raw)))
            })
            .collect();
        for (k, v) in values {
            messages[k].value = v;
        }
        for m in messages {
            self.got[m.channel_id as usize] += 1;
            sink.message(m);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::*;

    type Row = (u16, u32, u64, u64, Vec<u8>);

    /// A log of 3,000 messages in chunks of about 512 bytes (hundreds of
    /// chunks: many waves), its second channel first written 2,000 messages
    /// in; with chunk indexes and the summary's records, or with neither (the
    /// second channel then defined in a late chunk alone).
    fn many_chunks(path: &std::path::Path, indexed: bool) {
        let file = std::fs::File::create(path).unwrap();
        let mut w = mcap::WriteOptions::new()
            .chunk_size(Some(512))
            .emit_chunk_indexes(indexed)
            .emit_summary_records(indexed)
            .create(std::io::BufWriter::new(file))
            .unwrap();
        let schema = w.add_schema("s", "jsonschema", b"{}").unwrap();
        let a = w
            .add_channel(schema, "/a", "json", &BTreeMap::new())
            .unwrap();
        let b = w
            .add_channel(schema, "/b", "json", &BTreeMap::new())
            .unwrap();
        for i in 0..3000u32 {
            let channel_id = if i >= 2000 && i % 3 == 0 { b } else { a };
            let header = mcap::records::MessageHeader {
                channel_id,
                sequence: i,
                log_time: 1_000 + u64::from(i),
                publish_time: 2_000 + u64::from(i),
            };
            let data = format!("{{\"i\": {i}}}");
            w.write_to_known_channel(&header, data.as_bytes()).unwrap();
        }
        w.finish().unwrap();
    }

    #[test]
    fn waves_give_the_messages_the_mcap_crate_reads_in_its_order() {
        let dir = tempfile::tempdir().unwrap();
        for indexed in [true, false] {
            let path = dir.path().join(format!("many-{indexed}.mcap"));
            many_chunks(&path, indexed);
            let bytes = std::fs::read(&path).unwrap();
            let expected: Vec<Row> = mcap::MessageStream::new(&bytes)
                .unwrap()
                .map(|m| {
                    let m = m.unwrap();
                    (
                        m.channel.id,
                        m.sequence,
                        m.log_time,
                        m.publish_time,
                        m.data.to_vec(),
                    )
                })
                .collect();
            assert_eq!(expected.len(), 3000);
            let file = McapFile::open(&path).unwrap();
            let scan = file.scan_map(|_| true, |_, m| m.data.to_vec()).unwrap();
            let mode = if indexed {
                ReadMode::Indexed
            } else {
                ReadMode::Linear
            };
            assert_eq!(scan.mode, mode);
            assert_eq!(scan.channels.len(), 2);
            let got: Vec<Row> = scan
                .messages
                .into_iter()
                .map(|m| {
                    (
                        m.channel_id,
                        m.sequence,
                        m.log_time,
                        m.publish_time,
                        m.value,
                    )
                })
                .collect();
            assert_eq!(got, expected, "indexed {indexed}");
            // One channel alone: the other's messages never reach the sink.
            let only_b = file
                .scan_map(|c| c.topic == "/b", |_, m| m.log_time)
                .unwrap();
            let want: Vec<u64> = expected
                .iter()
                .filter(|r| scan.channels[&r.0].topic == "/b")
                .map(|r| r.2)
                .collect();
            let got: Vec<u64> = only_b.messages.iter().map(|m| m.value).collect();
            assert_eq!(got, want);
        }
    }

    /// Counts what it is given; a restart forgets it.
    #[derive(Default)]
    struct Counted(Vec<u64>);

    impl ScanSink<u64> for Counted {
        fn message(&mut self, m: MappedMessage<u64>) {
            self.0.push(m.value);
        }

        fn restart(&mut self) {
            self.0.clear();
        }
    }

    #[test]
    fn a_scan_given_whole_to_a_sink_keeps_its_order() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("many.mcap");
        many_chunks(&path, true);
        let file = McapFile::open(&path).unwrap();
        let whole = file.scan_map(|_| true, |_, m| m.log_time).unwrap();
        let times: Vec<u64> = whole.messages.iter().map(|m| m.value).collect();
        let mut sink = Counted::default();
        let info = whole.into_sink(&mut sink);
        assert_eq!(sink.0, times);
        assert_eq!(info.channels.len(), 2);
        let mut sink = Counted(vec![7]);
        sink.restart();
        file.scan_into(|_| true, |_, m| m.log_time, &mut sink)
            .unwrap();
        assert_eq!(sink.0, times);
    }
}
