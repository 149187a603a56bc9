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
use crate::io::messages::{ChannelInfo, MappedMessage, MappedScan, RawMessage, ReadMode};

/// What one item gives: its definitions, its messages (mapped, or holding
/// `T::default()` until mapped after the merge) and the bytes of the messages
/// whose channel the task could not see, by position in the item's messages.
type Part<T> = (Vec<Def>, Vec<MappedMessage<T>>, Vec<(usize, Vec<u8>)>);

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
    /// see are mapped after the merge, with the same result.
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
        let r = self.scan_map_checked(want, map);
        // A file that shrank while it was read: that, whatever else went wrong.
        self.check_unchanged()?;
        r
    }

    fn scan_map_checked<T: Send + Default>(
        &self,
        want: impl Fn(&ChannelInfo) -> bool + Sync,
        map: impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync,
    ) -> Result<MappedScan<T>> {
        let scan = self.scan_map_with(&want, &map, true)?;
        if scan.mode == ReadMode::Indexed {
            if let Some(declared) = self.declared_counts() {
                let mut got: BTreeMap<u16, u64> = BTreeMap::new();
                for m in &scan.messages {
                    *got.entry(m.channel_id).or_default() += 1;
                }
                let short = scan.channels.values().filter(|c| want(c)).any(|c| {
                    got.get(&c.id).copied().unwrap_or(0) < declared.get(&c.id).copied().unwrap_or(0)
                });
                if short {
                    drop(scan);
                    return self.scan_map_with(&want, &map, false);
                }
            }
        }
        Ok(scan)
    }

    fn scan_map_with<T: Send + Default>(
        &self,
        want: &(impl Fn(&ChannelInfo) -> bool + Sync),
        map: &(impl Fn(&ChannelInfo, &RawMessage<'_>) -> T + Sync),
        use_index: bool,
    ) -> Result<MappedScan<T>> {
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
        let mut parts: Vec<Result<Part<T>>> = Vec::new();
        if mode == ReadMode::Linear {
            // Writers define a channel in the chunk of its first message: reading up
            // to the first chunk alone lets the parallel tasks know those channels.
            if let Some(first) = items.iter().position(|i| matches!(i, Item::Chunk { .. })) {
                let rest = items.split_off(first + 1);
                let prefix = std::mem::replace(&mut items, rest);
                let mut found = Vec::new();
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
            }
        }
        let table = table_of(&known, want);
        let rest: Vec<Result<Part<T>>> = items
            .into_par_iter()
            .map_init(Vec::new, |buf, item| {
                crate::interrupt::check()?;
                self.map_item(item, &table, buf, want, map)
            })
            .collect();
        parts.extend(rest);
        // Merge in file order (as `scan` does), mapping the deferred messages after.
        let mut channels = if mode == ReadMode::Indexed {
            known.clone()
        } else {
            BTreeMap::new()
        };
        let mut schemas: BTreeMap<u16, (records::SchemaHeader, Vec<u8>)> = BTreeMap::new();
        let mut keep = vec![0u8; 1 << 16];
        for c in channels.values() {
            keep[c.id as usize] = if want(c) { 2 } else { 1 };
        }
        let total: usize = parts
            .iter()
            .map(|p| p.as_ref().map_or(0, |p| p.1.len()))
            .sum();
        // What the chunk tasks freed (their buffers) goes back first.
        crate::buffer::release_free_memory();
        let mut messages: Vec<MappedMessage<T>> = Vec::with_capacity(total);
        let mut deferred: Vec<(usize, Vec<u8>)> = Vec::new();
        let mut releaser = crate::buffer::Releaser::default();
        for part in parts {
            let (defs, msgs, raw) = part?;
            self.apply_defs(defs, &mut schemas, &mut channels, &mut keep, want)?;
            releaser.freed(msgs.capacity() * std::mem::size_of::<MappedMessage<T>>());
            let mut raw = raw.into_iter().peekable();
            for (j, m) in msgs.into_iter().enumerate() {
                let bytes = match raw.peek() {
                    Some((k, _)) if *k == j => raw.next().map(|r| r.1),
                    _ => None,
                };
                match keep[m.channel_id as usize] {
                    2 => {
                        if let Some(b) = bytes {
                            deferred.push((messages.len(), b));
                        }
                        messages.push(m);
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
        }
        // In parallel: a linear scan of a file whose channels are defined in an
        // earlier chunk defers most messages.
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
        Ok(MappedScan {
            channels,
            messages,
            mode,
            profile,
        })
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
