//! Occupancy octree for path planning, with OctoMap's semantics and file
//! formats (`.bt`, `.ot`), built from scans by parallel ray casting.
//!
//! Keys, log-odds updates, clamping, pruning and the 3-D DDA follow OctoMap's
//! `OcTree` (`floor(coord / resolution) + 32768` per axis, 16 levels, `f32`
//! log-odds, occupied when `log-odds >= 0`): a map built here from the same
//! scans equals the one OctoMap's `insertPointCloud(…, discretize=false)`
//! builds, node for node, and the files read back in OctoMap.
//!
//! All coordinates are metres in the map's frame (the world frame of the
//! converted cloud); sensor origins are camera centres in that frame.

mod dda;
pub mod grid;
mod insert;
mod io;
pub mod key;
mod query;
mod tree;

use crate::error::{Error, Result};
use tree::{LogOdds, Tree};

pub use grid::{CellState, Grid2d, GridParams, MAX_GRID_CELLS};
pub use query::VoxelState;

/// Parameters of the sensor model (probabilities in `(0, 1)`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapParams {
    /// Voxel edge length (metres).
    pub resolution: f64,
    /// Probability that a voxel is occupied given an endpoint in it.
    pub prob_hit: f64,
    /// Probability that a voxel is occupied given a ray through it.
    pub prob_miss: f64,
    /// Lower clamping bound of the occupancy probability.
    pub clamp_min: f64,
    /// Upper clamping bound of the occupancy probability.
    pub clamp_max: f64,
    /// Rays longer than this (metres) only clear space up to it and mark no
    /// endpoint; `None` for no limit.
    pub max_range: Option<f64>,
}

impl MapParams {
    /// OctoMap's defaults (0.7 / 0.4, clamping 0.1192 / 0.971, no max range;
    /// [`crate::defaults`]).
    pub fn new(resolution: f64) -> Self {
        MapParams {
            resolution,
            prob_hit: crate::defaults::PROB_HIT,
            prob_miss: crate::defaults::PROB_MISS,
            clamp_min: crate::defaults::CLAMP_MIN,
            clamp_max: crate::defaults::CLAMP_MAX,
            max_range: None,
        }
    }

    /// Checks the parameters: a positive finite resolution, probabilities in
    /// (0, 1), `clamp_min ≤ clamp_max`, a positive finite max range.
    pub fn check(&self) -> Result<()> {
        let r = self.resolution;
        if !(r.is_finite() && r > 0.0) {
            return Err(Error::invalid(
                "resolution",
                format!("{r} is not a positive length"),
            ));
        }
        // Keys need a finite 1/r, voxel centres a finite extent of the tree.
        if !((1.0 / r).is_finite() && (r * 65536.0).is_finite()) {
            return Err(Error::invalid(
                "resolution",
                format!("{r} m gives no finite octree (keys or extent overflow)"),
            ));
        }
        let open = |what: &str, p: f64| -> Result<()> {
            if p > 0.0 && p < 1.0 {
                Ok(())
            } else {
                Err(Error::invalid(
                    what,
                    format!("{p} is not a probability in (0, 1)"),
                ))
            }
        };
        open("prob_hit", self.prob_hit)?;
        open("prob_miss", self.prob_miss)?;
        open("clamp_min", self.clamp_min)?;
        open("clamp_max", self.clamp_max)?;
        if self.clamp_min > self.clamp_max {
            return Err(Error::invalid(
                "clamp_min",
                format!("{} exceeds clamp_max {}", self.clamp_min, self.clamp_max),
            ));
        }
        if let Some(m) = self.max_range {
            if !(m.is_finite() && m > 0.0) {
                return Err(Error::invalid(
                    "max_range",
                    format!("{m} is not a positive length"),
                ));
            }
        }
        Ok(())
    }
}

/// OctoMap's `logodds`: `ln(p / (1 − p))`, computed in `f64`, stored as `f32`.
pub fn logodds(p: f64) -> f32 {
    (p / (1.0 - p)).ln() as f32
}

/// OctoMap's `probability`: `1 − 1 / (1 + exp(l))`.
pub fn probability(l: f32) -> f64 {
    1.0 - 1.0 / (1.0 + (l as f64).exp())
}

/// Log-odds threshold of the occupied state (probability 0.5).
pub const OCCUPIED_LOGODDS: f32 = 0.0;

/// An occupancy octree (OctoMap `OcTree` semantics).
#[derive(Clone, Debug)]
pub struct OccupancyMap {
    params: MapParams,
    resolution_factor: f64,
    lo: LogOdds,
    tree: Tree,
}

impl PartialEq for OccupancyMap {
    /// Same parameters and the same tree, node for node (values compared bitwise).
    fn eq(&self, other: &Self) -> bool {
        self.params == other.params && self.tree_bits() == other.tree_bits()
    }
}

impl OccupancyMap {
    /// An empty map; checks the parameters.
    pub fn try_new(params: MapParams) -> Result<Self> {
        params.check()?;
        let r = params.resolution;
        Ok(OccupancyMap {
            params,
            resolution_factor: 1.0 / r,
            lo: LogOdds {
                hit: logodds(params.prob_hit),
                miss: logodds(params.prob_miss),
                min: logodds(params.clamp_min),
                max: logodds(params.clamp_max),
            },
            tree: Tree::default(),
        })
    }

    /// The parameters.
    pub fn params(&self) -> &MapParams {
        &self.params
    }

    /// Voxel edge length (metres).
    pub fn resolution(&self) -> f64 {
        self.params.resolution
    }

    /// Number of nodes, inner and leaf (OctoMap's `size()`).
    pub fn num_nodes(&self) -> usize {
        self.tree.num_nodes
    }

    /// Number of leaves (OctoMap's `getNumLeafNodes()`).
    pub fn num_leaf_nodes(&self) -> usize {
        self.tree.num_leaves()
    }

    /// Heap bytes held by the tree (blocks of eight 8-byte slots, allocated
    /// capacity included).
    pub fn memory_bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.tree.blocks.capacity() * std::mem::size_of::<[tree::Node; 8]>()
            + self.tree.free_blocks.capacity() * std::mem::size_of::<u32>()
    }

    /// Bytes of the live blocks only (what OctoMap's `memoryUsage()` counts for
    /// its own nodes: no allocator slack).
    pub fn memory_used_bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + (self.tree.blocks.len() - self.tree.free_blocks.len())
                * std::mem::size_of::<[tree::Node; 8]>()
    }

    /// Log-odds of the root (the maximum over the map), `None` when empty.
    pub fn root_logodds(&self) -> Option<f32> {
        self.tree.root.exists().then_some(self.tree.root.value)
    }

    /// The tree in OctoMap's `.ot` node order: per node its log-odds bits and
    /// child mask. Two maps with equal sequences are the same tree.
    pub fn tree_bits(&self) -> Vec<(u32, u8)> {
        let mut out = Vec::with_capacity(self.tree.num_nodes);
        if self.tree.root.exists() {
            io::visit_preorder(&self.tree, self.tree.root, &mut |n, mask| {
                out.push((n.value.to_bits(), mask))
            });
        }
        out
    }

    /// Checks the tree's invariants: every inner node holds the maximum of its
    /// children, no inner node has eight equal leaf children, `num_nodes`
    /// counts the nodes and no leaf lies below depth 16. Returns the first
    /// violation found.
    pub fn check_invariants(&self) -> std::result::Result<(), String> {
        let t = &self.tree;
        if !t.root.exists() {
            return if t.num_nodes == 0 {
                Ok(())
            } else {
                Err(format!("empty tree with num_nodes {}", t.num_nodes))
            };
        }
        let mut count = 0usize;
        fn rec(
            t: &Tree,
            n: tree::Node,
            depth: u32,
            count: &mut usize,
        ) -> std::result::Result<(), String> {
            *count += 1;
            if !n.has_children() {
                return Ok(());
            }
            if depth >= key::TREE_DEPTH {
                return Err(format!("children below depth {depth}"));
            }
            let blk = t.children(n);
            let m = tree::max_child(blk);
            if m.to_bits() != n.value.to_bits() {
                return Err(format!(
                    "inner node at depth {depth} holds {} but max child is {m}",
                    n.value
                ));
            }
            if blk.iter().all(|c| c.is_leaf() && c.value == blk[0].value) {
                return Err(format!("unpruned node at depth {depth}"));
            }
            if blk.iter().all(|c| !c.exists()) {
                return Err(format!("inner node without children at depth {depth}"));
            }
            for c in blk.iter().filter(|c| c.exists()) {
                rec(t, *c, depth + 1, count)?;
            }
            Ok(())
        }
        rec(t, t.root, 0, &mut count)?;
        if count != t.num_nodes {
            return Err(format!(
                "num_nodes {} but {count} nodes reachable",
                t.num_nodes
            ));
        }
        Ok(())
    }
}
