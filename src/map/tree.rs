//! Node storage of the octree: children stored eight at a time in blocks,
//! one `(log-odds f32, child u32)` pair per slot, and the batched update of
//! a scan's voxels in Morton order.
//!
//! Each block slot costs 8 bytes (OctoMap: 8 bytes per child pointer plus a
//! 16-byte node), which keeps memory per leaf below OctoMap's.

use super::key::{Key, TREE_DEPTH};

/// Slot that holds no node.
pub(crate) const ABSENT: u32 = u32::MAX;
/// Node that exists and has no children.
pub(crate) const LEAF: u32 = u32::MAX - 1;

/// One node: its log-odds and either [`ABSENT`], [`LEAF`] or the index of the
/// block that holds its eight children.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Node {
    pub value: f32,
    pub child: u32,
}

impl Node {
    pub const ABSENT: Node = Node {
        value: 0.0,
        child: ABSENT,
    };

    #[inline]
    pub fn exists(self) -> bool {
        self.child != ABSENT
    }

    #[inline]
    pub fn is_leaf(self) -> bool {
        self.child == LEAF
    }

    #[inline]
    pub fn has_children(self) -> bool {
        self.child < LEAF
    }
}

/// Log-odds parameters of an update, all `f32` as in OctoMap.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LogOdds {
    pub hit: f32,
    pub miss: f32,
    pub min: f32,
    pub max: f32,
}

impl LogOdds {
    /// OctoMap's `updateNodeLogOdds`: add, then clamp.
    #[inline]
    fn apply(&self, value: f32, occupied: bool) -> f32 {
        let v = value + if occupied { self.hit } else { self.miss };
        if v < self.min {
            self.min
        } else if v > self.max {
            self.max
        } else {
            v
        }
    }
}

/// The tree: a root node and a pool of eight-child blocks.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Tree {
    pub root: Node,
    pub blocks: Vec<[Node; 8]>,
    pub free_blocks: Vec<u32>,
    /// Number of nodes (OctoMap's `size()`).
    pub num_nodes: usize,
}

impl Default for Tree {
    fn default() -> Self {
        Tree {
            root: Node::ABSENT,
            blocks: Vec::new(),
            free_blocks: Vec::new(),
            num_nodes: 0,
        }
    }
}

impl Tree {
    pub fn alloc_block(&mut self, block: [Node; 8]) -> u32 {
        if let Some(i) = self.free_blocks.pop() {
            self.blocks[i as usize] = block;
            i
        } else {
            self.blocks.push(block);
            (self.blocks.len() - 1) as u32
        }
    }

    pub fn release_block(&mut self, i: u32) {
        self.free_blocks.push(i);
    }

    /// The children of a node that has children.
    #[inline]
    pub fn children(&self, node: Node) -> &[Node; 8] {
        &self.blocks[node.child as usize]
    }

    /// The deepest existing node on the path to `key` and its depth, when the
    /// path ends at a leaf (OctoMap's `search`); `None` where unknown.
    pub fn search(&self, key: Key) -> Option<(Node, u32)> {
        let mut n = self.root;
        if !n.exists() {
            return None;
        }
        for d in 0..TREE_DEPTH {
            if n.is_leaf() {
                return Some((n, d));
            }
            let c = self.blocks[n.child as usize][super::key::child_index(key, d)];
            if !c.exists() {
                return None;
            }
            n = c;
        }
        Some((n, TREE_DEPTH))
    }

    /// Applies one scan's updates: `items` are sorted, unique Morton codes
    /// shifted left by one with bit 0 set for occupied voxels.
    pub fn apply_updates(&mut self, items: &[u64], lo: &LogOdds) {
        if items.is_empty() {
            return;
        }
        let (root, created) = self.root_or_new();
        self.root = self.update_rec(root, created, 0, items, lo);
    }

    /// The root to update, and whether it is new (an empty tree gets a leaf
    /// of log-odds 0, counted).
    pub(crate) fn root_or_new(&mut self) -> (Node, bool) {
        if self.root.exists() {
            return (self.root, false);
        }
        self.num_nodes += 1;
        (
            Node {
                value: 0.0,
                child: LEAF,
            },
            true,
        )
    }

    /// OctoMap's `updateNodeRecurs` for a batch of keys below `node`, with its
    /// early abort for voxels already clamped, the expansion of pruned nodes,
    /// and pruning / max-of-children on the way up.
    fn update_rec(
        &mut self,
        mut node: Node,
        just_created: bool,
        depth: u32,
        items: &[u64],
        lo: &LogOdds,
    ) -> Node {
        if depth == TREE_DEPTH {
            node.value = lo.apply(node.value, items[0] & 1 == 1);
            return node;
        }
        let mut filtered = Vec::new();
        let mut items = items;
        if node.is_leaf() {
            let block = if just_created {
                [Node::ABSENT; 8]
            } else {
                // A pruned node: voxels whose update cannot change it are skipped.
                let keep_occ = node.value < lo.max;
                let keep_free = node.value > lo.min;
                if !(keep_occ && keep_free) {
                    filtered.extend(items.iter().copied().filter(|&it| {
                        if it & 1 == 1 {
                            keep_occ
                        } else {
                            keep_free
                        }
                    }));
                    if filtered.is_empty() {
                        return node;
                    }
                    items = &filtered;
                }
                self.num_nodes += 8;
                [Node {
                    value: node.value,
                    child: LEAF,
                }; 8]
            };
            node.child = self.alloc_block(block);
        }
        let b = node.child as usize;
        if depth == TREE_DEPTH - 1 {
            // Children are voxels, one item each (items are unique): update in place.
            for &it in items {
                let c = ((it >> 1) & 7) as usize;
                let mut child = self.blocks[b][c];
                if !child.exists() {
                    self.num_nodes += 1;
                    child = Node {
                        value: 0.0,
                        child: LEAF,
                    };
                }
                child.value = lo.apply(child.value, it & 1 == 1);
                self.blocks[b][c] = child;
            }
            return self.finish_inner(node);
        }
        let shift = 3 * (TREE_DEPTH - 1 - depth) + 1;
        let mut i = 0;
        while i < items.len() {
            let c = ((items[i] >> shift) & 7) as usize;
            // Items share every bit above this level, so child indices ascend:
            // the end of child c's run by a galloping search from i (the runs
            // are short next to the slice; this stays near i in memory).
            let le = |it: u64| ((it >> shift) & 7) as usize <= c;
            let mut bound = 1;
            while i + bound < items.len() && le(items[i + bound]) {
                bound *= 2;
            }
            let start = i + bound / 2;
            let end = (i + bound).min(items.len());
            let j = start + items[start..end].partition_point(|&it| le(it));
            let mut child = self.blocks[b][c];
            let created = !child.exists();
            if created {
                self.num_nodes += 1;
                child = Node {
                    value: 0.0,
                    child: LEAF,
                };
            }
            let child = self.update_rec(child, created, depth + 1, &items[i..j], lo);
            self.blocks[b][c] = child;
            i = j;
        }
        self.finish_inner(node)
    }

    /// Prunes `node` when its eight children are equal leaves, else sets its
    /// value to the maximum of its children (OctoMap's `pruneNode` /
    /// `updateOccupancyChildren`).
    pub fn finish_inner(&mut self, mut node: Node) -> Node {
        let blk = self.blocks[node.child as usize];
        let first = blk[0];
        if blk.iter().all(|n| n.is_leaf() && n.value == first.value) {
            self.release_block(node.child);
            self.num_nodes -= 8;
            node.value = first.value;
            node.child = LEAF;
        } else {
            node.value = max_child(&blk);
        }
        node
    }

    /// Calls `f(min_key, depth, value)` for every leaf, in depth-first child order.
    pub fn for_each_leaf(&self, mut f: impl FnMut(Key, u32, f32)) {
        if self.root.exists() {
            self.leaf_rec(self.root, [0; 3], 0, &mut f);
        }
    }

    fn leaf_rec(&self, node: Node, base: Key, depth: u32, f: &mut impl FnMut(Key, u32, f32)) {
        if !node.has_children() {
            f(base, depth, node.value);
            return;
        }
        let half = 1u16 << (TREE_DEPTH - 1 - depth);
        for (i, c) in self.blocks[node.child as usize].iter().enumerate() {
            if c.exists() {
                let k = [
                    base[0] | if i & 1 != 0 { half } else { 0 },
                    base[1] | if i & 2 != 0 { half } else { 0 },
                    base[2] | if i & 4 != 0 { half } else { 0 },
                ];
                self.leaf_rec(*c, k, depth + 1, f);
            }
        }
    }

    /// Number of leaves (OctoMap's `getNumLeafNodes`).
    pub fn num_leaves(&self) -> usize {
        let mut n = 0;
        self.for_each_leaf(|_, _, _| n += 1);
        n
    }
}

/// Largest log-odds among the existing children (OctoMap's `getMaxChildLogOdds`).
#[inline]
pub(crate) fn max_child(blk: &[Node; 8]) -> f32 {
    let mut m = -f32::MAX;
    for n in blk {
        if n.exists() && n.value > m {
            m = n.value;
        }
    }
    m
}
