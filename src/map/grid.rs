//! The octree projected to a 2-D occupancy grid for planners (nav2's
//! `map_server`, `nav_msgs/OccupancyGrid`, `foxglove.Grid`).
//!
//! The grid covers the voxels whose centres lie in a height band
//! `[z_min, z_max]` (world frame, z up, metres; both limits inclusive). Each
//! cell keeps the occupancy probability of the most occupied known voxel of
//! its column in the band — the rule OctoMap's `octomap_server` uses for its
//! projected map, so that a single occupied voxel among free ones makes the
//! cell occupied and a planner cannot miss an obstacle — and the height of the
//! highest occupied voxel. A cell with no known voxel in the band is unknown.
//!
//! The projection works on the tree's leaves, not voxel by voxel: a pruned
//! leaf (`2^k` voxels per axis) fills its footprint in one step, subtrees
//! outside the band are skipped, and large grids are filled in parallel row
//! stripes.

use rayon::prelude::*;

use super::key::{key_to_coord, TREE_DEPTH, TREE_MAX_VAL};
use super::tree::{Node, Tree};
use super::{probability, OccupancyMap, OCCUPIED_LOGODDS};
use crate::error::{Error, Result};

/// Most cells [`OccupancyMap::grid`] allocates (2^24: 128 MiB for the two
/// `f32` layers, e.g. 400 × 400 m at 0.1 m; [`OccupancyMap::grid_bounded`]
/// takes another bound). A larger grid is refused with [`Error::TooLarge`]
/// before anything is allocated: one pruned leaf near the root of a tiny
/// `.bt` file spans 2^15 cells an edge.
pub const MAX_GRID_CELLS: u64 = 1 << 24;

/// Tree nodes at or above which the leaves are collected in parallel.
const PAR_MIN_NODES: usize = 1 << 14;
/// Leaves in the band at or above which the fill runs in parallel stripes.
const PAR_MIN_LEAVES: usize = 1 << 12;

/// A 2-D occupancy grid in the world's x-y plane.
///
/// Cells are stored row-major from cell `(0, 0)`, whose lower-left corner is
/// `origin`: index `col + row · width`, columns along +x, rows along +y (the
/// order of `nav_msgs/OccupancyGrid` and `foxglove.Grid`; an image has row 0
/// at the top, see [`crate::io::nav2`]).
#[derive(Clone, Debug)]
pub struct Grid2d {
    /// Cell edge length (metres): the map's resolution or a whole multiple of it.
    pub resolution: f64,
    /// `(x, y)` of the lower-left corner of cell `(0, 0)`, world frame, metres.
    pub origin: [f64; 2],
    /// Number of columns (cells along x).
    pub width: usize,
    /// Number of rows (cells along y).
    pub height: usize,
    /// The band `[z_min, z_max]` (metres, world z) of voxel centres projected.
    pub z_band: [f64; 2],
    /// Occupancy probability per cell (that of the most occupied known voxel
    /// of the cell's columns in the band), NaN where unknown.
    pub probability: Vec<f32>,
    /// Centre height (metres, world z) of the highest occupied voxel of the
    /// cell in the band, NaN where the cell has none. Its top face lies half a
    /// voxel (the map's resolution, not the cell's) higher.
    pub top_z: Vec<f32>,
}

/// What a 2-D grid is projected from and how its cells are read: the height
/// band, the cell size and the occupancy threshold (`convert --grid`, the
/// online session's `grid`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridParams {
    /// Lowest voxel centre height projected (metres, world z).
    pub z_min: f64,
    /// Highest voxel centre height projected (metres, world z).
    pub z_max: f64,
    /// Cell edge (metres), a whole multiple of the map's resolution; `None`:
    /// the map's resolution.
    pub resolution: Option<f64>,
    /// Cells of probability at or above it are occupied in `map.pgm` and the
    /// trinary messages (the octree's own rule is 0.5).
    pub occupied_threshold: f64,
}

impl GridParams {
    /// The band `[z_min, z_max]`, cells of the map's resolution, threshold 0.5.
    pub fn new(z_min: f64, z_max: f64) -> Self {
        GridParams {
            z_min,
            z_max,
            resolution: None,
            occupied_threshold: crate::defaults::OCCUPANCY_THRESHOLD,
        }
    }

    /// Checks what does not depend on the map: finite heights with
    /// `z_min <= z_max`, a positive finite cell size, a threshold in `(0, 1]`.
    pub fn check(&self) -> Result<()> {
        for (what, z) in [("z_min", self.z_min), ("z_max", self.z_max)] {
            if !z.is_finite() {
                return Err(Error::invalid(what, format!("{z} is not a finite height")));
            }
        }
        if self.z_min > self.z_max {
            return Err(Error::invalid(
                "z_min",
                format!("{} is above z_max {}", self.z_min, self.z_max),
            ));
        }
        if let Some(r) = self.resolution {
            if !(r.is_finite() && r > 0.0) {
                return Err(Error::invalid(
                    "grid_resolution",
                    format!("{r} is not a positive length"),
                ));
            }
        }
        let t = self.occupied_threshold;
        if !(t > 0.0 && t <= 1.0) {
            return Err(Error::invalid(
                "occupied_threshold",
                format!("{t} is not a probability in (0, 1]"),
            ));
        }
        Ok(())
    }
}

/// State of a grid cell under an occupancy threshold.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(i8)]
pub enum CellState {
    /// No known voxel in the band.
    Unknown = -1,
    /// Known, probability below the threshold.
    Free = 0,
    /// Probability at or above the threshold.
    Occupied = 1,
}

impl Grid2d {
    /// Whether the grid has no cell (nothing known in the band).
    pub fn is_empty(&self) -> bool {
        self.width == 0 || self.height == 0
    }

    /// Index into the cell vectors of cell `(col, row)`, `None` outside.
    pub fn index(&self, col: usize, row: usize) -> Option<usize> {
        (col < self.width && row < self.height).then(|| col + row * self.width)
    }

    /// The cell `(col, row)` that contains world point `(x, y)` (metres),
    /// `None` outside the grid. Cells are half-open: `[x0, x0 + resolution)`.
    pub fn cell_of(&self, x: f64, y: f64) -> Option<(usize, usize)> {
        let c = ((x - self.origin[0]) / self.resolution).floor();
        let r = ((y - self.origin[1]) / self.resolution).floor();
        if c >= 0.0 && r >= 0.0 && c < self.width as f64 && r < self.height as f64 {
            Some((c as usize, r as usize))
        } else {
            None
        }
    }

    /// World `(x, y)` (metres) of the centre of cell `(col, row)`.
    pub fn cell_center(&self, col: usize, row: usize) -> [f64; 2] {
        [
            self.origin[0] + (col as f64 + 0.5) * self.resolution,
            self.origin[1] + (row as f64 + 0.5) * self.resolution,
        ]
    }

    /// State of every cell: occupied where the probability is at least
    /// `threshold` (compared in `f32`, the cells' type, so that 0.7 takes a
    /// voxel hit once with `prob_hit` 0.7), free where known and below,
    /// unknown where NaN. The map's own rule (and that of its `.bt` files and
    /// `state()`) is 0.5.
    pub fn states(&self, threshold: f64) -> Vec<CellState> {
        let t = threshold as f32;
        self.probability
            .iter()
            .map(|&p| {
                if p.is_nan() {
                    CellState::Unknown
                } else if p >= t {
                    CellState::Occupied
                } else {
                    CellState::Free
                }
            })
            .collect()
    }
}

/// One leaf that meets the band: its lowest x/y key, edge in keys, log-odds
/// and (when occupied) the z key of its highest voxel inside the band.
#[derive(Clone, Copy, Debug)]
struct BandLeaf {
    x: u32,
    y: u32,
    n: u32,
    value: f32,
    top: Option<u32>,
}

/// Inclusive key range `[lo, hi]` of the voxels whose centre lies in
/// `[z_min, z_max]`, or `None` when no voxel of the tree does.
fn band_keys(z_min: f64, z_max: f64, res: f64) -> Option<(u32, u32)> {
    let max_key = (1i64 << TREE_DEPTH) - 1;
    // Estimates from the centre formula, clamped (far values saturate), then
    // corrected against key_to_coord itself so that the rule is exact.
    let est = |z: f64| -> i64 {
        let t = (z / res - 0.5).clamp(-1e6, 1e6);
        (t.round() as i64 + i64::from(TREE_MAX_VAL)).clamp(0, max_key)
    };
    let centre = |k: i64| key_to_coord(k as u16, res);
    let mut lo = est(z_min);
    while lo > 0 && centre(lo - 1) >= z_min {
        lo -= 1;
    }
    while lo <= max_key && centre(lo) < z_min {
        lo += 1;
    }
    let mut hi = est(z_max);
    while hi < max_key && centre(hi + 1) <= z_max {
        hi += 1;
    }
    while hi >= 0 && centre(hi) > z_max {
        hi -= 1;
    }
    (lo <= hi).then_some((lo as u32, hi as u32))
}

/// Collects the leaves of `node` (lowest key `base`, at `depth`) that meet the
/// z key band, skipping subtrees outside it.
fn band_leaves(
    t: &Tree,
    node: Node,
    base: [u32; 3],
    depth: u32,
    band: (u32, u32),
) -> Vec<BandLeaf> {
    let mut out = Vec::new();
    collect(t, node, base, depth, band, &mut out);
    out
}

fn collect(
    t: &Tree,
    node: Node,
    base: [u32; 3],
    depth: u32,
    band: (u32, u32),
    out: &mut Vec<BandLeaf>,
) {
    let n = 1u32 << (TREE_DEPTH - depth);
    if base[2] > band.1 || base[2] + n - 1 < band.0 {
        return;
    }
    if !node.has_children() {
        out.push(BandLeaf {
            x: base[0],
            y: base[1],
            n,
            value: node.value,
            top: (node.value >= OCCUPIED_LOGODDS).then(|| (base[2] + n - 1).min(band.1)),
        });
        return;
    }
    let half = n / 2;
    for (i, c) in t.children(node).iter().enumerate() {
        if c.exists() {
            let k = child_base(base, i, half);
            collect(t, *c, k, depth + 1, band, out);
        }
    }
}

fn child_base(base: [u32; 3], i: usize, half: u32) -> [u32; 3] {
    [
        base[0] + if i & 1 != 0 { half } else { 0 },
        base[1] + if i & 2 != 0 { half } else { 0 },
        base[2] + if i & 4 != 0 { half } else { 0 },
    ]
}

/// Subtrees to traverse in parallel: nodes meeting the band, expanded level
/// by level until there are enough of them (or only leaves remain).
fn frontier(t: &Tree, band: (u32, u32), want: usize) -> Vec<(Node, [u32; 3], u32)> {
    let mut level = vec![(t.root, [0u32; 3], 0u32)];
    while level.len() < want {
        if level.iter().all(|(n, _, _)| !n.has_children()) {
            break;
        }
        let mut next = Vec::with_capacity(level.len() * 8);
        for &(node, base, depth) in &level {
            if !node.has_children() {
                next.push((node, base, depth));
                continue;
            }
            let half = 1u32 << (TREE_DEPTH - depth - 1);
            for (i, c) in t.children(node).iter().enumerate() {
                let k = child_base(base, i, half);
                if c.exists() && k[2] <= band.1 && k[2] + 2 * half > band.0 {
                    next.push((*c, k, depth + 1));
                }
            }
        }
        level = next;
    }
    level
}

impl OccupancyMap {
    /// The 2-D occupancy grid of the voxels whose centres lie in
    /// `[z_min, z_max]` (metres, world z; both inclusive), with the map's
    /// resolution as cell size or `resolution`, a whole multiple of it (cells
    /// then aligned to multiples of their size in the world frame). The grid
    /// spans the known voxels of the band (empty when there are none); at
    /// most [`MAX_GRID_CELLS`] cells.
    pub fn grid(&self, z_min: f64, z_max: f64, resolution: Option<f64>) -> Result<Grid2d> {
        self.grid_bounded(z_min, z_max, resolution, MAX_GRID_CELLS)
    }

    /// [`Self::grid`] of `params`' band and cell size.
    pub fn grid_of(&self, params: &GridParams) -> Result<Grid2d> {
        params.check()?;
        self.grid(params.z_min, params.z_max, params.resolution)
    }

    /// [`Self::grid`] with another bound on the number of cells.
    pub fn grid_bounded(
        &self,
        z_min: f64,
        z_max: f64,
        resolution: Option<f64>,
        max_cells: u64,
    ) -> Result<Grid2d> {
        for (what, z) in [("z_min", z_min), ("z_max", z_max)] {
            if !z.is_finite() {
                return Err(Error::invalid(what, format!("{z} is not a finite height")));
            }
        }
        if z_min > z_max {
            return Err(Error::invalid(
                "z_min",
                format!("{z_min} is above z_max {z_max}"),
            ));
        }
        let res = self.params.resolution;
        let factor = cell_factor(res, resolution)?;
        let cell = res * factor as f64;
        let empty = Grid2d {
            resolution: cell,
            origin: [0.0, 0.0],
            width: 0,
            height: 0,
            z_band: [z_min, z_max],
            probability: Vec::new(),
            top_z: Vec::new(),
        };
        let Some(band) = band_keys(z_min, z_max, res) else {
            return Ok(empty);
        };
        if !self.tree.root.exists() {
            return Ok(empty);
        }
        let threads = rayon::current_num_threads();
        let parts = frontier(&self.tree, band, 8 * threads);
        let leaves: Vec<BandLeaf> = if self.tree.num_nodes >= PAR_MIN_NODES && threads > 1 {
            parts
                .par_iter()
                .map(|&(n, b, d)| band_leaves(&self.tree, n, b, d, band))
                .collect::<Vec<_>>()
                .concat()
        } else {
            parts
                .iter()
                .flat_map(|&(n, b, d)| band_leaves(&self.tree, n, b, d, band))
                .collect()
        };
        if leaves.is_empty() {
            return Ok(empty);
        }
        let cells_of = CellIndex::new(factor);
        let (mut lo, mut hi) = ([i64::MAX; 2], [i64::MIN; 2]);
        for l in &leaves {
            for (a, k) in [l.x, l.y].into_iter().enumerate() {
                lo[a] = lo[a].min(cells_of.of(k));
                hi[a] = hi[a].max(cells_of.of(k + l.n - 1));
            }
        }
        let width = (hi[0] - lo[0] + 1) as u64;
        let height = (hi[1] - lo[1] + 1) as u64;
        let cells = width * height;
        if cells > max_cells {
            return Err(Error::TooLarge {
                what: format!(
                    "grid of {width} x {height} cells of {cell} m in z [{z_min}, {z_max}]"
                ),
                count: cells,
                limit: max_cells,
            });
        }
        let (width, height) = (width as usize, height as usize);
        // Filled in place: log-odds (−∞ unknown) and the top z key (−1 none),
        // converted to probability and metres at the end.
        let mut prob = vec![f32::NEG_INFINITY; width * height];
        let mut top = vec![-1.0f32; width * height];
        let fill = Fill {
            cells: cells_of,
            lo,
            width,
        };
        if leaves.len() >= PAR_MIN_LEAVES && threads > 1 && height > 1 {
            // Row stripes, each with the leaves that reach into it.
            let stripe = height.div_ceil(4 * threads).max(1);
            let n_stripes = height.div_ceil(stripe);
            let mut buckets: Vec<Vec<u32>> = vec![Vec::new(); n_stripes];
            for (i, l) in leaves.iter().enumerate() {
                let (r0, r1) = fill.span(l.y, l.n, 1);
                for b in &mut buckets[r0 / stripe..=r1 / stripe] {
                    b.push(i as u32);
                }
            }
            prob.par_chunks_mut(stripe * width)
                .zip(top.par_chunks_mut(stripe * width))
                .zip(buckets.par_iter())
                .enumerate()
                .for_each(|(s, ((p, t), b))| {
                    let rows = s * stripe..(s * stripe + p.len() / width);
                    fill.run(rows, p, t, b.iter().map(|&i| &leaves[i as usize]));
                });
        } else {
            fill.run(0..height, &mut prob, &mut top, leaves.iter());
        }
        let to_out = |(p, t): (&mut f32, &mut f32)| {
            *p = if *p == f32::NEG_INFINITY {
                f32::NAN
            } else {
                probability(*p) as f32
            };
            *t = if *t < 0.0 {
                f32::NAN
            } else {
                key_to_coord(*t as u16, res) as f32
            };
        };
        if cells >= 1 << 16 && threads > 1 {
            prob.par_iter_mut().zip(top.par_iter_mut()).for_each(to_out);
        } else {
            prob.iter_mut().zip(top.iter_mut()).for_each(to_out);
        }
        Ok(Grid2d {
            resolution: cell,
            // The corner key's boundary as the key rule has it (x · (1/r)
            // crossing an integer): -2.4, not -24 · 0.1 = -2.4000000000000004.
            origin: lo.map(|c| (c * i64::from(factor)) as f64 / self.resolution_factor),
            width,
            height,
            z_band: [z_min, z_max],
            probability: prob,
            top_z: top,
        })
    }
}

/// Cell index along x or y of a key: `floor((k − 32768) / f)` for cells of
/// `f` voxels aligned to world multiples; a shift where `f` is a power of two.
#[derive(Clone, Copy, Debug)]
struct CellIndex {
    f: i64,
    shift: Option<u32>,
}

impl CellIndex {
    fn new(f: u32) -> Self {
        CellIndex {
            f: i64::from(f),
            shift: f.is_power_of_two().then(|| f.trailing_zeros()),
        }
    }

    #[inline]
    fn of(&self, k: u32) -> i64 {
        let v = i64::from(k) - i64::from(TREE_MAX_VAL);
        match self.shift {
            Some(s) => v >> s,
            None => v.div_euclid(self.f),
        }
    }
}

/// The fill of the cell layers from band leaves.
#[derive(Clone, Copy, Debug)]
struct Fill {
    cells: CellIndex,
    /// Cell index of column 0 and row 0.
    lo: [i64; 2],
    width: usize,
}

impl Fill {
    /// First and last column (`axis` 0) or row (1) of a leaf from key `k`, `n` keys wide.
    #[inline]
    fn span(&self, k: u32, n: u32, axis: usize) -> (usize, usize) {
        (
            (self.cells.of(k) - self.lo[axis]) as usize,
            (self.cells.of(k + n - 1) - self.lo[axis]) as usize,
        )
    }

    /// Fills rows `rows` (`prob` and `top` hold exactly those rows) with the
    /// leaves' log-odds (maximum) and top z keys (maximum).
    fn run<'a>(
        &self,
        rows: std::ops::Range<usize>,
        prob: &mut [f32],
        top: &mut [f32],
        leaves: impl Iterator<Item = &'a BandLeaf>,
    ) {
        let w = self.width;
        for l in leaves {
            let t = l.top.map_or(-1.0, |t| t as f32);
            if l.n == 1 {
                // A voxel: one cell (the common case).
                let (c, _) = self.span(l.x, 1, 0);
                let (r, _) = self.span(l.y, 1, 1);
                if rows.contains(&r) {
                    let i = (r - rows.start) * w + c;
                    prob[i] = prob[i].max(l.value);
                    top[i] = top[i].max(t);
                }
                continue;
            }
            let (c0, c1) = self.span(l.x, l.n, 0);
            let (r0, r1) = self.span(l.y, l.n, 1);
            for r in r0.max(rows.start)..=r1.min(rows.end - 1) {
                let row = (r - rows.start) * w;
                for i in row + c0..=row + c1 {
                    prob[i] = prob[i].max(l.value);
                    top[i] = top[i].max(t);
                }
            }
        }
    }
}

/// Cell size as a whole number of voxels: 1 by default; `resolution` must be
/// a positive whole multiple of the map's (to a relative 1e-9).
fn cell_factor(map_res: f64, resolution: Option<f64>) -> Result<u32> {
    let Some(r) = resolution else {
        return Ok(1);
    };
    if !(r.is_finite() && r > 0.0) {
        return Err(Error::invalid(
            "resolution",
            format!("{r} is not a positive length"),
        ));
    }
    let k = (r / map_res).round();
    if k < 1.0 {
        return Err(Error::invalid(
            "resolution",
            format!("{r} m is finer than the map's resolution {map_res} m"),
        ));
    }
    if (k * map_res - r).abs() > 1e-9 * r || k > f64::from(1u32 << TREE_DEPTH) {
        return Err(Error::invalid(
            "resolution",
            format!("{r} m is not a whole multiple of the map's resolution {map_res} m"),
        ));
    }
    Ok(k as u32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn band_keys_follow_voxel_centres_inclusively() {
        let r = 0.1;
        // Voxel centres ..., -0.05, 0.05, 0.15, ... : key 32768 has centre 0.05.
        let c = |k: u16| key_to_coord(k, r);
        assert_eq!(band_keys(c(32768), c(32769), r), Some((32768, 32769)));
        assert_eq!(
            band_keys(c(32768) + 1e-9, c(32769), r),
            Some((32769, 32769))
        );
        assert_eq!(
            band_keys(c(32768), c(32769) - 1e-9, r),
            Some((32768, 32768))
        );
        assert_eq!(band_keys(0.06, 0.14, r), None);
        assert_eq!(band_keys(0.0, 0.1, r), Some((32768, 32768)));
        assert_eq!(band_keys(c(32767), c(32767), r), Some((32767, 32767)));
        assert_eq!(band_keys(-1e300, 1e300, r), Some((0, 65535)));
        assert_eq!(band_keys(1e300, 1e300, r), None);
        assert_eq!(band_keys(-1e300, -1e299, r), None);
        for k in [0u16, 1, 32767, 32768, 65534, 65535] {
            let c = key_to_coord(k, r);
            assert_eq!(band_keys(c, c, r), Some((k as u32, k as u32)), "key {k}");
        }
    }

    #[test]
    fn cell_sizes_are_whole_multiples() {
        assert_eq!(cell_factor(0.1, None).unwrap(), 1);
        assert_eq!(cell_factor(0.1, Some(0.1)).unwrap(), 1);
        assert_eq!(cell_factor(0.1, Some(0.3)).unwrap(), 3);
        assert_eq!(cell_factor(0.05, Some(0.2)).unwrap(), 4);
        for bad in [0.05, 0.15, 0.0, -0.2, f64::NAN, f64::INFINITY, 1e9] {
            assert!(
                matches!(
                    cell_factor(0.1, Some(bad)),
                    Err(Error::InvalidArgument { ref what, .. }) if what == "resolution"
                ),
                "{bad}"
            );
        }
    }
}
