//! The `messages` table of a `.db3`, read straight from a map of the file:
//! its table b-tree walked from the root to the leaves, in rowid order, and
//! the leaves' cells parsed by several threads at once.
//!
//! SQLite's own row loop (its virtual machine stepping a cursor, a column
//! fetch per value) is most of a `.db3` read through SQL. What a rowid
//! table's rows are on disk is fixed by the SQLite file format
//! (<https://www.sqlite.org/fileformat2.html>): the database header, table
//! interior pages (`0x05`) and leaf pages (`0x0D`), cells with their overflow
//! chains, and records. Only these are read here.
//!
//! This reader gives way to SQLite whenever it would not see what SQLite
//! sees. [`Pages::open`] and every walk give `None` for a file in WAL mode
//! (its `-wal` file may hold newer pages), a table that is not rosbag2's
//! `messages(id INTEGER PRIMARY KEY, topic_id, timestamp, data)`, a page or
//! cell that does not parse, a cycle in the tree, or a value of another
//! type. The caller then reads the file through SQLite, which has the last
//! word on what the file holds and names what is wrong with it. A hot
//! journal beside the file is the caller's to check.

/// The header every SQLite database starts with.
const MAGIC: &[u8; 16] = b"SQLite format 3\0";

/// The deepest table b-tree walked (SQLite's own trees stay far below: a
/// depth of 20 holds more rows than a file can).
const MAX_DEPTH: usize = 64;

/// Why a leaf's walk stopped early.
pub(super) enum Stop<E> {
    /// What the reader met is not for it: read the file through SQLite.
    Fallback,
    /// The caller's own error, for this row.
    Error(E),
}

/// A database file, its header read.
pub(super) struct Pages<'a> {
    file: &'a [u8],
    page_size: usize,
    /// Bytes of each page that hold the b-tree (the rest is reserved).
    usable: usize,
    /// Pages in the database.
    count: u32,
}

/// One row of `messages`: its values, and where its `data` is.
pub(super) struct Row<'a> {
    /// The rowid (`id`).
    pub rowid: i64,
    /// `topic_id`.
    pub topic_id: i64,
    /// `timestamp`, ns.
    pub timestamp: i64,
    /// Whether `data` is a blob.
    blob: bool,
    /// The part of `data` in the leaf's cell.
    local: &'a [u8],
    /// Bytes of `data` in the overflow chain, after `local`.
    rest: usize,
    /// Bytes of the overflow chain before `data` starts in it.
    skip: usize,
    /// The first overflow page (0: none).
    overflow: u32,
    pages: &'a Pages<'a>,
}

impl<'a> Pages<'a> {
    /// The header of `file`, or `None` when it is not a database this reader
    /// reads (not SQLite, in WAL mode, or a header out of the format's range).
    pub fn open(file: &'a [u8]) -> Option<Pages<'a>> {
        let head = file.get(..100)?;
        if &head[..16] != MAGIC {
            return None;
        }
        // Write and read versions: 1 is a rollback journal, 2 WAL.
        if head[18] != 1 || head[19] != 1 {
            return None;
        }
        let page_size = match u16::from_be_bytes([head[16], head[17]]) {
            1 => 65536,
            n if n >= 512 && n.is_power_of_two() => usize::from(n),
            _ => return None,
        };
        let usable = page_size.checked_sub(usize::from(head[20]))?;
        if usable < 480 {
            return None;
        }
        // The header's page count holds when its "valid for" counter is the
        // change counter; else the file's length gives it.
        let in_file = u32::try_from(file.len() / page_size).ok()?;
        let declared = be32(head, 28)?;
        let count = if declared != 0 && be32(head, 92)? == be32(head, 24)? {
            declared.min(in_file)
        } else {
            in_file
        };
        Some(Pages {
            file,
            page_size,
            usable,
            count,
        })
    }

    /// Page `n` (1-based) whole, the header of page 1 included.
    fn page(&self, n: u32) -> Option<&'a [u8]> {
        if n == 0 || n > self.count {
            return None;
        }
        let at = (n as usize - 1) * self.page_size;
        self.file.get(at..at + self.page_size)
    }

    /// The root page of rosbag2's `messages` table, found in `sqlite_master`
    /// (whose tree is rooted at page 1); `None` when the table is not there
    /// or not declared as rosbag2 declares it.
    pub fn messages_root(&self) -> Option<u32> {
        let mut root = None;
        for leaf in self.leaves(1)? {
            let page = self.page(leaf.0)?;
            let mut bad = false;
            let walked = self.cells(leaf.0, page, |payload| {
                // type, name, tbl_name, rootpage, sql
                let Some(cols) = record::<5>(payload) else {
                    bad = true;
                    return false;
                };
                let text = |k: usize| match cols[k] {
                    Value::Text(a, b) => payload.get(a..b),
                    _ => None,
                };
                if text(0) == Some(b"table") && text(1) == Some(b"messages") {
                    root = match (cols[3], text(4)) {
                        (Value::Int(n), Some(sql)) if is_messages_table(sql) => {
                            u32::try_from(n).ok()
                        }
                        _ => None,
                    };
                    if root.is_none() {
                        bad = true;
                    }
                    return false;
                }
                true
            });
            if !walked || bad {
                return None;
            }
            if root.is_some() {
                break;
            }
        }
        root
    }

    /// The leaf pages of the table b-tree rooted at `root`, in rowid order,
    /// each with its number of cells (rows).
    pub fn leaves(&self, root: u32) -> Option<Vec<(u32, usize)>> {
        let mut seen = vec![0u64; (self.count as usize).div_ceil(64) + 1];
        let mut visit = |n: u32| -> Option<()> {
            let (w, b) = (n as usize / 64, n % 64);
            let word = seen.get_mut(w)?;
            if *word & (1 << b) != 0 {
                return None;
            }
            *word |= 1 << b;
            Some(())
        };
        let mut out = Vec::new();
        // (interior page, the next of its children to go down)
        let mut stack: Vec<(u32, usize)> = Vec::new();
        let mut next = Some(root);
        loop {
            if let Some(n) = next.take() {
                visit(n)?;
                let page = self.page(n)?;
                let h = if n == 1 { 100 } else { 0 };
                match *page.get(h)? {
                    0x0D => {
                        // A cell takes at least 4 bytes and its pointer 2.
                        let cells = usize::from(be16(page, h + 3)?);
                        if h + 8 + 6 * cells > self.usable {
                            return None;
                        }
                        out.push((n, cells));
                    }
                    0x05 => {
                        if stack.len() >= MAX_DEPTH {
                            return None;
                        }
                        stack.push((n, 0));
                    }
                    _ => return None,
                }
            }
            let Some(&mut (n, ref mut k)) = stack.last_mut() else {
                return Some(out);
            };
            let page = self.page(n)?;
            let h = if n == 1 { 100 } else { 0 };
            let cells = usize::from(be16(page, h + 3)?);
            let child = if *k < cells {
                let at = usize::from(be16(page, h + 12 + 2 * *k)?);
                be32(page, at)?
            } else if *k == cells {
                be32(page, h + 8)?
            } else {
                stack.pop();
                continue;
            };
            *k += 1;
            next = Some(child);
        }
    }

    /// Calls `f(payload)` on each cell of the leaf page `n` (its bytes `page`),
    /// in order, while `f` gives true; false when a cell does not parse or
    /// spills into overflow pages.
    fn cells(&self, n: u32, page: &'a [u8], mut f: impl FnMut(&'a [u8]) -> bool) -> bool {
        let h = if n == 1 { 100 } else { 0 };
        let Some(cells) = be16(page, h + 3) else {
            return false;
        };
        for k in 0..usize::from(cells) {
            let Some(cell) = self.cell(page, h, k) else {
                return false;
            };
            if cell.overflow != 0 {
                return false;
            }
            if !f(cell.local) {
                break;
            }
        }
        true
    }

    /// Cell `k` of a leaf page whose header starts at `h`.
    fn cell(&self, page: &'a [u8], h: usize, k: usize) -> Option<Cell<'a>> {
        let at = usize::from(be16(page, h + 8 + 2 * k)?);
        let body = page.get(at..self.usable)?;
        let (len, a) = varint(body)?;
        let (rowid, b) = varint(&body[a..])?;
        // No payload is longer than the file that holds it.
        let len = usize::try_from(len)
            .ok()
            .filter(|&l| l <= self.file.len())?;
        let start = a + b;
        let local = self.local_len(len);
        let payload = body.get(start..start + local)?;
        let overflow = if local < len {
            be32(body, start + local)?
        } else {
            0
        };
        Some(Cell {
            rowid: rowid as i64,
            len,
            local: payload,
            overflow,
        })
    }

    /// Bytes of a payload of `p` bytes kept in its leaf cell (the file
    /// format's rule for table leaves); the rest goes to overflow pages.
    fn local_len(&self, p: usize) -> usize {
        let u = self.usable;
        let x = u - 35;
        if p <= x {
            return p;
        }
        let m = (u - 12) * 32 / 255 - 23;
        let k = m + (p - m) % (u - 4);
        if k <= x {
            k
        } else {
            m
        }
    }

    /// Calls `f` on each row of the `messages` leaf page `n`, in rowid order;
    /// stops at the first `Err` of `f`, or with [`Stop::Fallback`] at a cell
    /// or record this reader does not read.
    pub fn rows<E>(
        &'a self,
        n: u32,
        mut f: impl FnMut(&Row<'a>) -> Result<(), Stop<E>>,
    ) -> Result<(), Stop<E>> {
        let page = self.page(n).ok_or(Stop::Fallback)?;
        let h = if n == 1 { 100 } else { 0 };
        if page.get(h) != Some(&0x0D) {
            return Err(Stop::Fallback);
        }
        let cells = be16(page, h + 3).ok_or(Stop::Fallback)?;
        for k in 0..usize::from(cells) {
            let cell = self.cell(page, h, k).ok_or(Stop::Fallback)?;
            let row = self.row(&cell).ok_or(Stop::Fallback)?;
            f(&row)?;
        }
        Ok(())
    }

    /// A `messages` row from its cell: `id` NULL (the rowid stands for it),
    /// `topic_id` and `timestamp` integers, the record's header and integers
    /// in the cell's local part.
    fn row(&'a self, cell: &Cell<'a>) -> Option<Row<'a>> {
        let cols = record::<4>(cell.local)?;
        let [Value::Null, Value::Int(topic_id), Value::Int(timestamp), data] = cols else {
            return None;
        };
        // A `data` of another type is found out when it is asked for.
        let (a, b, blob) = match data {
            Value::Blob(a, b) => (a, b, true),
            _ => (0, 0, false),
        };
        if b > cell.len {
            return None;
        }
        let here = cell.local.len();
        let (la, lb) = (a.min(here), b.min(here));
        Some(Row {
            rowid: cell.rowid,
            topic_id,
            timestamp,
            blob,
            local: &cell.local[la..lb],
            rest: (b - a) - (lb - la),
            skip: a.saturating_sub(here),
            overflow: cell.overflow,
            pages: self,
        })
    }
}

impl<'a> Row<'a> {
    /// The row's `data`: borrowed from the page when it lies whole in the
    /// cell, else gathered from its overflow chain into `scratch`. `None`
    /// when it is not a blob, or its chain is broken (a page out of the file,
    /// or too short).
    pub fn data<'s>(&self, scratch: &'s mut Vec<u8>) -> Option<&'s [u8]>
    where
        'a: 's,
    {
        if !self.blob {
            return None;
        }
        if self.rest == 0 {
            return Some(self.local);
        }
        scratch.clear();
        scratch
            .try_reserve_exact(self.local.len() + self.rest)
            .ok()?;
        scratch.extend_from_slice(self.local);
        let p = self.pages;
        let (mut skip, mut left, mut next) = (self.skip, self.rest, self.overflow);
        // Each page of the chain holds `usable - 4` bytes: no chain is longer
        // than the payload needs, nor than the file's pages, so a cycle ends
        // here too.
        let mut budget = (skip + left).div_ceil(p.usable - 4).min(p.count as usize);
        while left > 0 {
            if budget == 0 {
                return None;
            }
            budget -= 1;
            let page = p.page(next)?;
            let content = page.get(4..p.usable)?;
            let take = content.len().saturating_sub(skip).min(left);
            if take > 0 {
                scratch.extend_from_slice(&content[skip..skip + take]);
                left -= take;
            }
            skip = skip.saturating_sub(content.len());
            next = be32(page, 0)?;
        }
        Some(scratch.as_slice())
    }
}

/// A leaf cell: rowid, payload length, the part of the payload in the page,
/// and the first overflow page (0: none).
struct Cell<'a> {
    rowid: i64,
    len: usize,
    local: &'a [u8],
    overflow: u32,
}

/// A value of a record: integers read, text and blobs where they lie in the
/// payload.
#[derive(Clone, Copy)]
enum Value {
    Null,
    Int(i64),
    Real,
    /// `start..end` in the payload.
    Text(usize, usize),
    /// `start..end` in the payload.
    Blob(usize, usize),
}

/// The first `N` values of the record `payload` (whose later bytes may be
/// missing: only the header and the integers must be there); `None` when the
/// record has fewer values or its header does not parse.
fn record<const N: usize>(payload: &[u8]) -> Option<[Value; N]> {
    let (header_len, mut h) = varint(payload)?;
    let header_len = usize::try_from(header_len).ok()?;
    let header = payload.get(..header_len)?;
    let mut at = header_len;
    let mut out = [Value::Null; N];
    for v in out.iter_mut() {
        let (t, n) = varint(header.get(h..)?)?;
        h += n;
        let int = |len: usize| -> Option<i64> {
            let b = payload.get(at..at + len)?;
            // Big-endian two's complement, sign-extended.
            let first = i64::from(b[0] as i8);
            Some(b[1..].iter().fold(first, |a, &x| (a << 8) | i64::from(x)))
        };
        let (value, len) = match t {
            0 => (Value::Null, 0),
            1..=4 => (Value::Int(int(t as usize)?), t as usize),
            5 => (Value::Int(int(6)?), 6),
            6 => (Value::Int(int(8)?), 8),
            7 => (Value::Real, 8),
            8 => (Value::Int(0), 0),
            9 => (Value::Int(1), 0),
            10 | 11 => return None,
            t => {
                let len = usize::try_from((t - 12) / 2).ok()?;
                let end = at.checked_add(len)?;
                if t % 2 == 0 {
                    (Value::Blob(at, end), len)
                } else {
                    (Value::Text(at, end), len)
                }
            }
        };
        *v = value;
        at = at.checked_add(len)?;
    }
    Some(out)
}

/// True when `sql` declares rosbag2's `messages` table: exactly the columns
/// `id INTEGER PRIMARY KEY` (the rowid), `topic_id`, `timestamp`, `data`, in
/// this order, and a rowid table.
fn is_messages_table(sql: &[u8]) -> bool {
    let Ok(sql) = std::str::from_utf8(sql) else {
        return false;
    };
    let upper = sql.to_ascii_uppercase();
    if upper.contains("WITHOUT") {
        return false;
    }
    let (Some(a), Some(b)) = (sql.find('('), sql.rfind(')')) else {
        return false;
    };
    let Some(body) = sql.get(a + 1..b) else {
        return false;
    };
    let defs: Vec<&str> = body.split(',').map(str::trim).collect();
    let names = ["id", "topic_id", "timestamp", "data"];
    if defs.len() != names.len() {
        return false;
    }
    for (def, want) in defs.iter().zip(names) {
        let name = def
            .split_whitespace()
            .next()
            .unwrap_or("")
            .trim_matches(|c| matches!(c, '"' | '`' | '[' | ']'));
        if !name.eq_ignore_ascii_case(want) {
            return false;
        }
    }
    // `INTEGER PRIMARY KEY` makes `id` the rowid, stored as NULL in the
    // record; `… DESC` would not.
    let id: Vec<String> = defs[0]
        .split_whitespace()
        .skip(1)
        .map(str::to_ascii_uppercase)
        .collect();
    id.len() >= 3 && id[..3] == ["INTEGER", "PRIMARY", "KEY"] && !id.iter().any(|w| w == "DESC")
}

/// A SQLite varint (1 to 9 bytes, big-endian) and its length.
fn varint(b: &[u8]) -> Option<(u64, usize)> {
    let mut v = 0u64;
    for k in 0..8 {
        let x = *b.get(k)?;
        v = (v << 7) | u64::from(x & 0x7F);
        if x & 0x80 == 0 {
            return Some((v, k + 1));
        }
    }
    Some(((v << 8) | u64::from(*b.get(8)?), 9))
}

fn be16(b: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_be_bytes(b.get(at..at + 2)?.try_into().ok()?))
}

fn be32(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_be_bytes(b.get(at..at + 4)?.try_into().ok()?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn varints_are_read_as_the_format_writes_them() {
        assert_eq!(varint(&[0x05]), Some((5, 1)));
        assert_eq!(varint(&[0x81, 0x00]), Some((128, 2)));
        assert_eq!(varint(&[0xFF; 9]), Some((u64::MAX, 9)));
        assert_eq!(varint(&[0x81]), None);
    }

    #[test]
    fn only_rosbag2_messages_tables_are_read_here() {
        let ok =
            b"CREATE TABLE messages(\n  id INTEGER PRIMARY KEY,\n  topic_id INTEGER NOT NULL,\n  \
                   timestamp INTEGER NOT NULL,\n  data BLOB NOT NULL\n)";
        assert!(is_messages_table(ok));
        assert!(is_messages_table(
            b"CREATE TABLE \"messages\" (\"id\" INTEGER PRIMARY KEY, topic_id INTEGER, timestamp INTEGER, data BLOB)"
        ));
        for bad in [
            &b"CREATE TABLE messages(id INTEGER PRIMARY KEY DESC, topic_id INTEGER, timestamp INTEGER, data BLOB)"[..],
            b"CREATE TABLE messages(id INTEGER, topic_id INTEGER, timestamp INTEGER, data BLOB)",
            b"CREATE TABLE messages(id INTEGER PRIMARY KEY, timestamp INTEGER, topic_id INTEGER, data BLOB)",
            b"CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER, timestamp INTEGER, data BLOB, extra)",
            b"CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER, timestamp INTEGER, data BLOB) WITHOUT ROWID",
        ] {
            assert!(!is_messages_table(bad), "{}", String::from_utf8_lossy(bad));
        }
    }

    #[test]
    fn records_give_their_first_values_or_nothing() {
        // header: len 5; NULL, int8 (1), int16 (2), blob of 3 (18)
        let rec = [5u8, 0, 1, 2, 18, 0xFF, 0x01, 0x00, b'a', b'b', b'c'];
        let v = record::<4>(&rec).unwrap();
        assert!(matches!(v[0], Value::Null));
        assert!(matches!(v[1], Value::Int(-1)));
        assert!(matches!(v[2], Value::Int(256)));
        assert!(matches!(v[3], Value::Blob(8, 11)));
        // The blob's bytes need not be there, only the header and integers.
        assert!(record::<4>(&rec[..8]).is_some());
        // A header cut short, an integer cut short, fewer values than asked
        // for, a reserved type.
        assert!(record::<4>(&rec[..4]).is_none());
        assert!(record::<4>(&rec[..6]).is_none());
        assert!(record::<4>(&[4u8, 0, 1, 2, 0xFF, 0, 1]).is_none());
        assert!(record::<2>(&[3u8, 0, 10]).is_none());
    }
}
