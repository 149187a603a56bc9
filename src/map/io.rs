//! OctoMap files: `.bt` (binary, maximum-likelihood tree: two bits per child)
//! and `.ot` (full tree: `f32` log-odds and a child bitset per node).
//!
//! Layout as in OctoMap's `AbstractOccupancyOcTree::writeBinaryConst` /
//! `readBinaryData` and `AbstractOcTree::write` / `OcTreeBaseImpl::writeData`:
//! a text header (`# Octomap OcTree binary file` or `# Octomap OcTree file`,
//! `id OcTree`, `size N`, `res R`, `data`), then the nodes depth-first in
//! child order `x + 2y + 4z`.

use std::path::Path;

use super::key::TREE_DEPTH;
use super::tree::{max_child, Node, Tree, LEAF};
use super::{MapParams, OccupancyMap, OCCUPIED_LOGODDS};
use crate::error::{Error, Result};
use crate::io::atomic::write_bytes_atomic;

const BT_HEADER: &str = "# Octomap OcTree binary file";
const OT_HEADER: &str = "# Octomap OcTree file";

/// Calls `f(node, child_mask)` for `node` and its descendants, pre-order.
pub(crate) fn visit_preorder(t: &Tree, node: Node, f: &mut impl FnMut(Node, u8)) {
    if !node.has_children() {
        f(node, 0);
        return;
    }
    let blk = t.children(node);
    let mut mask = 0u8;
    for (i, c) in blk.iter().enumerate() {
        if c.exists() {
            mask |= 1 << i;
        }
    }
    f(node, mask);
    for c in blk.iter().filter(|c| c.exists()) {
        visit_preorder(t, *c, f);
    }
}

/// A `f64` as C++'s default `ostream << double` prints it (`%g`, 6 digits).
fn fmt_g(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let exp = x.abs().log10().floor() as i32;
    let s = format!("{:.*e}", 5, x);
    // Re-derive the exponent after rounding to 6 significant digits.
    let (mant, e) = s.split_once('e').unwrap_or((&s, "0"));
    let e: i32 = e.parse().unwrap_or(exp);
    let trim = |m: &str| -> String {
        if m.contains('.') {
            m.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            m.to_string()
        }
    };
    if !(-4..6).contains(&e) {
        let sign = if e < 0 { '-' } else { '+' };
        format!("{}e{}{:02}", trim(mant), sign, e.abs())
    } else {
        let decimals = (5 - e).max(0) as usize;
        trim(&format!("{:.*}", decimals, x))
    }
}

fn header(first: &str, size: usize, res: f64) -> String {
    format!(
        "{first}\n# (feel free to add / change comments, but leave the first line as it is!)\n#\n\
         id OcTree\nsize {size}\nres {}\ndata\n",
        fmt_g(res)
    )
}

impl OccupancyMap {
    /// The tree OctoMap's `writeBinary` would store: every node set to its
    /// maximum-likelihood log-odds (`clamp_max` if occupied else `clamp_min`),
    /// then pruned bottom-up depth by depth, stopping at the first depth where
    /// nothing is pruned (OctoMap's `toMaxLikelihood(); prune()`).
    fn max_likelihood_tree(&self) -> Tree {
        let mut t = self.tree.clone();
        let ml = |v: f32| {
            if v >= OCCUPIED_LOGODDS {
                self.lo.max
            } else {
                self.lo.min
            }
        };
        if !t.root.exists() {
            return t;
        }
        t.root.value = ml(t.root.value);
        for blk in t.blocks.iter_mut() {
            for n in blk.iter_mut() {
                n.value = ml(n.value);
            }
        }
        for depth in (1..TREE_DEPTH).rev() {
            let mut pruned = 0usize;
            let root = t.root;
            t.root = prune_at(&mut t, root, 0, depth, &mut pruned);
            if pruned == 0 {
                break;
            }
        }
        t
    }

    /// The `.bt` file content (OctoMap binary format).
    pub fn to_bt_bytes(&self) -> Vec<u8> {
        let t = self.max_likelihood_tree();
        let mut out = header(BT_HEADER, t.num_nodes, self.params.resolution).into_bytes();
        if t.root.has_children() {
            write_bt_node(&t, t.root, &mut out);
        } else if t.root.exists() {
            out.extend_from_slice(&[0, 0]);
        }
        out
    }

    /// Writes an OctoMap `.bt` file (maximum-likelihood occupancy: free,
    /// occupied or unknown per voxel). The map itself is not changed.
    pub fn write_bt(&self, path: &Path) -> Result<()> {
        write_bytes_atomic(path, &self.to_bt_bytes())
    }

    /// The `.ot` file content (OctoMap full format, log-odds per node).
    pub fn to_ot_bytes(&self) -> Vec<u8> {
        let mut out = header(OT_HEADER, self.tree.num_nodes, self.params.resolution).into_bytes();
        if self.tree.root.exists() {
            visit_preorder(&self.tree, self.tree.root, &mut |n, mask| {
                out.extend_from_slice(&n.value.to_le_bytes());
                out.push(mask);
            });
        }
        out
    }

    /// Writes an OctoMap `.ot` file (every node's `f32` log-odds).
    pub fn write_ot(&self, path: &Path) -> Result<()> {
        write_bytes_atomic(path, &self.to_ot_bytes())
    }

    /// Reads an OctoMap `.bt` file. Leaves get the clamping log-odds of
    /// `params` (free: `clamp_min`, occupied: `clamp_max`); the resolution is
    /// the file's. `params.resolution` is ignored.
    pub fn read_bt(path: &Path, params: MapParams) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        let mut pos = 0usize;
        let mut line_no = 0usize;
        let mut lines = bytes.split_inclusive(|&c| c == b'\n');
        let mut next_line = |pos: &mut usize, line_no: &mut usize| -> Option<&[u8]> {
            let l = lines.next()?;
            *pos += l.len();
            *line_no += 1;
            Some(l.strip_suffix(b"\n").unwrap_or(l))
        };
        match next_line(&mut pos, &mut line_no) {
            Some(l) if l.starts_with(BT_HEADER.as_bytes()) => {}
            _ => {
                return Err(Error::parse(
                    path,
                    1,
                    format!("first line is not '{BT_HEADER}'"),
                ))
            }
        }
        let mut res: Option<f64> = None;
        let mut size: Option<usize> = None;
        loop {
            let Some(l) = next_line(&mut pos, &mut line_no) else {
                return Err(Error::parse(path, line_no, "header ends before 'data'"));
            };
            let l = String::from_utf8_lossy(l);
            let l = l.trim();
            if l.is_empty() || l.starts_with('#') {
                continue;
            }
            let (tok, val) = l.split_once(char::is_whitespace).unwrap_or((l, ""));
            let val = val.trim();
            match tok {
                "data" => break,
                "id" => {
                    if val != "OcTree" {
                        return Err(Error::parse(
                            path,
                            line_no,
                            format!("tree type '{val}' is not OcTree"),
                        ));
                    }
                }
                "res" => {
                    res = Some(val.parse().map_err(|_| {
                        Error::parse(path, line_no, format!("bad resolution '{val}'"))
                    })?)
                }
                "size" => {
                    size =
                        Some(val.parse().map_err(|_| {
                            Error::parse(path, line_no, format!("bad size '{val}'"))
                        })?)
                }
                other => {
                    return Err(Error::parse(
                        path,
                        line_no,
                        format!("unknown header field '{other}'"),
                    ))
                }
            }
        }
        let res = res.ok_or_else(|| Error::parse(path, line_no, "no 'res' line in the header"))?;
        let data = &bytes[pos.min(bytes.len())..];
        let mut map = OccupancyMap::try_new(MapParams {
            resolution: res,
            ..params
        })
        .map_err(|e| Error::parse(path, line_no, e.to_string()))?;
        if let Some(size) = size {
            // Each inner node takes 2 bytes and declares at most 8 children:
            // a tree of `size` nodes needs at least (size - 1) / 4 bytes.
            let most = 1 + 4 * data.len() as u64;
            if size as u64 > most {
                return Err(Error::parse(
                    path,
                    line_no,
                    format!(
                        "size {size} declares more nodes than the {} data bytes at byte {pos} \
                         can hold (at most {most})",
                        data.len()
                    ),
                ));
            }
        }
        if size.unwrap_or(0) > 0 && !data.is_empty() {
            // Byte offsets in errors count from the start of the file.
            let mut pos = pos;
            map.tree.num_nodes = 1;
            let mut root = Node {
                value: 0.0,
                child: LEAF,
            };
            let lo = map.lo;
            read_bt_node(
                &mut map.tree,
                &mut root,
                0,
                &bytes,
                &mut pos,
                lo.min,
                lo.max,
            )
            .map_err(|reason| Error::parse(path, 0, reason))?;
            map.tree.root = root;
        }
        // OctoMap's readBinary refuses a tree whose node count differs from
        // the header's `size`.
        if let Some(size) = size {
            if map.tree.num_nodes != size {
                return Err(Error::parse(
                    path,
                    line_no,
                    format!(
                        "size {size} in the header, but the data holds {} nodes",
                        map.tree.num_nodes
                    ),
                ));
            }
        }
        Ok(map)
    }
}

/// Prunes collapsible nodes at `target` depth below `node` (OctoMap's `pruneRecurs`).
fn prune_at(t: &mut Tree, node: Node, depth: u32, target: u32, pruned: &mut usize) -> Node {
    if !node.has_children() {
        return node;
    }
    let b = node.child as usize;
    if depth < target {
        for i in 0..8 {
            let c = t.blocks[b][i];
            if c.exists() {
                let c = prune_at(t, c, depth + 1, target, pruned);
                t.blocks[b][i] = c;
            }
        }
        return node;
    }
    let blk = t.blocks[b];
    if blk.iter().all(|c| c.is_leaf() && c.value == blk[0].value) {
        t.release_block(node.child);
        t.num_nodes -= 8;
        *pruned += 1;
        Node {
            value: blk[0].value,
            child: LEAF,
        }
    } else {
        node
    }
}

/// OctoMap's `writeBinaryNode`: per child two bits (`01` occupied leaf,
/// `10` free leaf, `11` inner, `00` unknown), children 0–3 in the first byte,
/// 4–7 in the second, then the inner children recursively.
fn write_bt_node(t: &Tree, node: Node, out: &mut Vec<u8>) {
    let blk = t.children(node);
    let mut bits = [0u8; 2];
    for (i, c) in blk.iter().enumerate() {
        let code: u8 = if !c.exists() {
            0b00
        } else if c.has_children() {
            0b11
        } else if c.value >= OCCUPIED_LOGODDS {
            0b10 // bit 2i clear, bit 2i+1 set
        } else {
            0b01 // bit 2i set
        };
        bits[i / 4] |= code << (2 * (i % 4));
    }
    out.extend_from_slice(&bits);
    for c in blk.iter() {
        if c.has_children() {
            write_bt_node(t, *c, out);
        }
    }
}

/// OctoMap's `readBinaryNode`; `node` must be a fresh leaf.
fn read_bt_node(
    t: &mut Tree,
    node: &mut Node,
    depth: u32,
    data: &[u8],
    pos: &mut usize,
    free_value: f32,
    occ_value: f32,
) -> std::result::Result<(), String> {
    if depth >= TREE_DEPTH {
        return Err(format!("inner node below depth {TREE_DEPTH} at byte {pos}"));
    }
    let Some(b) = data.get(*pos..*pos + 2) else {
        return Err(format!("data ends at byte {pos} inside a node"));
    };
    let bits = u16::from(b[0]) | (u16::from(b[1]) << 8);
    *pos += 2;
    let mut blk = [Node::ABSENT; 8];
    for (i, c) in blk.iter_mut().enumerate() {
        match (bits >> (2 * i)) & 0b11 {
            0b01 => {
                *c = Node {
                    value: free_value,
                    child: LEAF,
                }
            }
            0b10 => {
                *c = Node {
                    value: occ_value,
                    child: LEAF,
                }
            }
            0b11 => {
                *c = Node {
                    value: f32::NAN,
                    child: LEAF,
                }
            }
            _ => continue,
        }
        t.num_nodes += 1;
    }
    let idx = t.alloc_block(blk);
    node.child = idx;
    for i in 0..8 {
        let mut c = t.blocks[idx as usize][i];
        if c.exists() && c.value.is_nan() {
            read_bt_node(t, &mut c, depth + 1, data, pos, free_value, occ_value)?;
            t.blocks[idx as usize][i] = c;
        }
    }
    let blk = t.blocks[idx as usize];
    if blk.iter().all(|c| !c.exists()) {
        // OctoMap keeps such a node as a leaf holding the maximum over no
        // children (`-FLT_MAX`), hence free.
        t.release_block(idx);
        node.child = LEAF;
        node.value = -f32::MAX;
        return Ok(());
    }
    node.value = max_child(&blk);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::fmt_g;

    #[test]
    fn resolution_prints_like_cpp() {
        assert_eq!(fmt_g(0.1), "0.1");
        assert_eq!(fmt_g(0.05), "0.05");
        assert_eq!(fmt_g(0.025), "0.025");
        assert_eq!(fmt_g(1.0), "1");
        assert_eq!(fmt_g(0.123456789), "0.123457");
        assert_eq!(fmt_g(2.0 / 3.0), "0.666667");
        assert_eq!(fmt_g(1e-5), "1e-05");
        assert_eq!(fmt_g(1234567.0), "1.23457e+06");
    }
}
