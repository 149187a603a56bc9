//! Scan insertion: OctoMap's `computeUpdate` (free keys along each ray by its
//! 3-D DDA `computeRayKeys`, occupied endpoint keys, occupied winning) run in
//! parallel into per-thread bitsets over the scan's key box, merged, then one
//! ordered batch update of the tree.
//!
//! The key sets are sets: whatever the thread count or the order in which
//! rays are traced, the sorted update list and hence the tree are the same.

use std::collections::BTreeMap;

use rayon::prelude::*;

use super::dda::{
    f32_norm, ray_keys, set_bit, trace_lanes, Lane, Layout, PreparedRay, LAYOUT_MARGIN,
};
use super::key::{morton, point_to_key, Key};
use super::OccupancyMap;
use crate::error::{Error, Result};

/// Points per parallel work item.
const CHUNK: usize = 2048;
/// Largest per-scan bitset (bits) before falling back to sorting keys.
const MAX_GRID_BITS: u64 = 1 << 28;
/// Bytes of the per-thread bitsets of one scan, at most (fewer parallel
/// work items for very large key boxes).
const MARKS_BUDGET: usize = 128 << 20;

/// Counts of one scan's update.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ScanUpdate {
    /// Voxels updated as free.
    pub free: usize,
    /// Voxels updated as occupied.
    pub occupied: usize,
}

/// Where one point's ray ends, its key (`None` outside the tree) and whether
/// it is an occupied voxel.
#[derive(Clone, Copy, Debug)]
struct RayEnd {
    p: [f32; 3],
    key: Option<Key>,
    occupied: bool,
}

/// `f32_norm(d) > m`, without the square root unless the squared norm lies
/// within a relative 1e-9 of `m²` (far wider than the rounding of the root
/// and of `m²`, so the answer is the same).
#[inline]
fn beyond(d: [f32; 3], m: f64) -> bool {
    let s = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) as f64;
    let m2 = m * m;
    if s > m2 * (1.0 + 1e-9) {
        true
    } else if s < m2 * (1.0 - 1e-9) {
        false
    } else {
        f32_norm(d) > m
    }
}

/// Where one point's ray ends and whether its endpoint is an occupied voxel.
#[inline]
fn ray_end(p: [f32; 3], origin: [f32; 3], max_range: Option<f64>) -> ([f32; 3], bool) {
    let d = [p[0] - origin[0], p[1] - origin[1], p[2] - origin[2]];
    match max_range {
        Some(m) if beyond(d, m) => {
            // OctoMap: direction = (p - origin).normalized(); origin + direction * (float) maxrange
            let len = f32_norm(d);
            let l = len as f32;
            let dir = if l > 0.0 && l.is_finite() {
                [d[0] / l, d[1] / l, d[2] / l]
            } else {
                // The f32 squared length overflowed (|d| > 1.8e19): OctoMap's
                // direction would be zero. Normalise in f64 instead (exact
                // differences of the f32 points).
                let d64 = [0, 1, 2].map(|i| f64::from(p[i]) - f64::from(origin[i]));
                let n = (d64[0] * d64[0] + d64[1] * d64[1] + d64[2] * d64[2]).sqrt();
                d64.map(|v| (v / n) as f32)
            };
            let m = m as f32;
            (
                [
                    origin[0] + dir[0] * m,
                    origin[1] + dir[1] * m,
                    origin[2] + dir[2] * m,
                ],
                false,
            )
        }
        _ => (p, true),
    }
}

/// An axis-aligned box of keys, inclusive.
#[derive(Clone, Copy, Debug)]
struct KeyBox {
    lo: [i32; 3],
    hi: [i32; 3],
}

impl KeyBox {
    const EMPTY: KeyBox = KeyBox {
        lo: [i32::MAX; 3],
        hi: [i32::MIN; 3],
    };

    fn add(&mut self, k: Key) {
        for (i, &v) in k.iter().enumerate() {
            self.lo[i] = self.lo[i].min(v as i32);
            self.hi[i] = self.hi[i].max(v as i32);
        }
    }

    fn union(mut self, o: KeyBox) -> KeyBox {
        for i in 0..3 {
            self.lo[i] = self.lo[i].min(o.lo[i]);
            self.hi[i] = self.hi[i].max(o.hi[i]);
        }
        self
    }
}

/// One scan's free and occupied voxels as bitsets over its key [`Layout`],
/// and the (rare) keys outside it as update items (Morton code `<< 1`, bit 0
/// set for occupied).
struct Marks {
    free: Vec<u64>,
    occ: Vec<u64>,
    outside: Vec<u64>,
    /// Scratch: the prepared rays of one chunk.
    lanes: Vec<Lane>,
}

impl Marks {
    fn new(words: usize) -> Marks {
        Marks {
            free: vec![0; words],
            occ: vec![0; words],
            outside: Vec::new(),
            lanes: Vec::new(),
        }
    }

    /// The union of two scans' marks.
    fn merge(mut self, other: Marks) -> Marks {
        for (a, b) in self.free.iter_mut().zip(&other.free) {
            *a |= b;
        }
        for (a, b) in self.occ.iter_mut().zip(&other.occ) {
            *a |= b;
        }
        self.outside.extend(other.outside);
        self
    }

    /// Marks a free key.
    #[inline]
    fn free(&mut self, layout: &Layout, k: Key) {
        match layout.index(k) {
            Some(j) => set_bit(&mut self.free, j),
            None => self.outside.push(morton(k) << 1),
        }
    }

    /// Marks an occupied key.
    #[inline]
    fn occupied(&mut self, layout: &Layout, k: Key) {
        match layout.index(k) {
            Some(j) => set_bit(&mut self.occ, j),
            None => self.outside.push((morton(k) << 1) | 1),
        }
    }
}

impl OccupancyMap {
    /// Inserts one scan: `points` are `(N, 3)` row-major `f32` metres in the
    /// map frame, `origin` the sensor centre in that frame (OctoMap's
    /// `insertPointCloud(points, origin, max_range, lazy_eval=false,
    /// discretize=false)`). Rays are traced in parallel on the current rayon
    /// pool; the result does not depend on the number of threads.
    pub fn insert_scan(&mut self, points: &[f32], origin: [f32; 3]) -> Result<ScanUpdate> {
        self.insert_scan_impl(points, origin, true)
    }

    /// [`Self::insert_scan`] on the calling thread only.
    pub fn insert_scan_sequential(
        &mut self,
        points: &[f32],
        origin: [f32; 3],
    ) -> Result<ScanUpdate> {
        self.insert_scan_impl(points, origin, false)
    }

    /// Inserts a converted cloud: each point with the camera centre of its
    /// keyframe as the sensor origin. `keyframe_ids[i]` is the keyframe of
    /// point `i`; `origins` maps a keyframe id to its camera centre (metres,
    /// map frame). Keyframes are inserted as scans in ascending id order.
    pub fn insert_keyframes(
        &mut self,
        points: &[f32],
        keyframe_ids: &[i32],
        origins: &BTreeMap<i32, [f32; 3]>,
    ) -> Result<ScanUpdate> {
        check_points("points", points)?;
        if keyframe_ids.len() * 3 != points.len() {
            return Err(Error::ShapeMismatch {
                what: "keyframe_ids".into(),
                expected: format!("({},)", points.len() / 3),
                got: format!("({},)", keyframe_ids.len()),
            });
        }
        let mut groups: BTreeMap<i32, Vec<f32>> = BTreeMap::new();
        for (p, id) in points.chunks_exact(3).zip(keyframe_ids) {
            groups.entry(*id).or_default().extend_from_slice(p);
        }
        let mut total = ScanUpdate::default();
        for (id, pts) in &groups {
            let origin = origins.get(id).ok_or_else(|| {
                Error::invalid(
                    "keyframe_ids",
                    format!("no camera centre for keyframe {id}"),
                )
            })?;
            crate::interrupt::check()?;
            let u = self.insert_scan(pts, *origin).map_err(|e| match e {
                Error::NonFinite { what, index } => Error::NonFinite {
                    what: format!("keyframe {id} {what}"),
                    index,
                },
                other => other,
            })?;
            total.free += u.free;
            total.occupied += u.occupied;
        }
        Ok(total)
    }

    /// Inserts scans `(origin, points)` one after the other.
    pub fn insert_scans(&mut self, scans: &[([f32; 3], &[f32])]) -> Result<ScanUpdate> {
        let mut total = ScanUpdate::default();
        for (origin, pts) in scans {
            let u = self.insert_scan(pts, *origin)?;
            total.free += u.free;
            total.occupied += u.occupied;
        }
        Ok(total)
    }

    fn insert_scan_impl(
        &mut self,
        points: &[f32],
        origin: [f32; 3],
        parallel: bool,
    ) -> Result<ScanUpdate> {
        check_points("points", points)?;
        if let Some(i) = origin.iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "origin".into(),
                index: i,
            });
        }
        let items = self.compute_update(points, origin, parallel);
        let occupied = items.iter().filter(|&&i| i & 1 == 1).count();
        self.tree.apply_updates(&items, &self.lo);
        Ok(ScanUpdate {
            free: items.len() - occupied,
            occupied,
        })
    }

    /// The sorted, unique update list of one scan: Morton code `<< 1`, bit 0
    /// set for occupied voxels (occupied wins over free).
    fn compute_update(&self, points: &[f32], origin: [f32; 3], parallel: bool) -> Vec<u64> {
        let res = self.params.resolution;
        let rf = self.resolution_factor;
        let max_range = self.params.max_range;
        let n = points.len() / 3;
        if n == 0 {
            return Vec::new();
        }
        let ranges: Vec<std::ops::Range<usize>> = (0..n)
            .step_by(CHUNK)
            .map(|s| s..(s + CHUNK).min(n))
            .collect();
        let par_min = ranges
            .len()
            .div_ceil(2 * rayon::current_num_threads())
            .max(1);

        // Ray ends (max range applied) and the key box of the scan, in one pass.
        let none = RayEnd {
            p: [0.0; 3],
            key: None,
            occupied: false,
        };
        let mut ends = vec![none; n];
        let ends_of = |(c, out): (usize, &mut [RayEnd])| {
            let mut b = KeyBox::EMPTY;
            for (j, end) in out.iter_mut().enumerate() {
                let i = c * CHUNK + j;
                let (p, occupied) = ray_end(
                    [points[3 * i], points[3 * i + 1], points[3 * i + 2]],
                    origin,
                    max_range,
                );
                let key = point_to_key(p, rf);
                if let Some(k) = key {
                    b.add(k);
                }
                *end = RayEnd { p, key, occupied };
            }
            b
        };
        let mut bx = if parallel {
            ends.par_chunks_mut(CHUNK)
                .enumerate()
                .map(ends_of)
                .reduce(|| KeyBox::EMPTY, KeyBox::union)
        } else {
            ends.chunks_mut(CHUNK)
                .enumerate()
                .map(ends_of)
                .fold(KeyBox::EMPTY, KeyBox::union)
        };
        let ends = ends;
        let ko = point_to_key(origin, rf);
        if let Some(k) = ko {
            bx.add(k);
        }
        if bx.lo[0] > bx.hi[0] {
            return Vec::new();
        }
        // A margin around the box for the voxels rays cross beside their ends.
        // Aligned to whole 4×4×4 bricks for the extraction in Morton order.
        let lo = bx.lo.map(|v| (v - LAYOUT_MARGIN).max(0) & !3);
        let hi = bx.hi.map(|v| (v + LAYOUT_MARGIN).min(65535) | 3);
        let layout = Layout::new(lo, hi);
        let bits = layout.row as u64 * layout.dim[1] as u64 * layout.dim[2] as u64;

        let mut items = if bits <= MAX_GRID_BITS {
            let words = layout.words();
            // Each work item beyond the first holds bitsets of its own: at
            // most MARKS_BUDGET bytes of them in all.
            let most = (MARKS_BUDGET / (words * 16).max(1)).max(1);
            let par_min = par_min.max(ranges.len().div_ceil(most));
            let trace = |mut marks: Marks, r: &std::ops::Range<usize>| -> Marks {
                let ends = &ends[r.clone()];
                let mut slow = Vec::new();
                // OctoMap traces no ray from an origin outside the tree.
                if let Some(ko) = ko {
                    // All lanes first: the divisions of independent rays overlap.
                    marks.lanes.clear();
                    for (j, e) in ends.iter().enumerate() {
                        match Lane::prepare(origin, ko, e.p, e.key, res, &layout) {
                            PreparedRay::Lane(l) => marks.lanes.push(l),
                            PreparedRay::Slow => slow.push(j),
                            PreparedRay::Empty => {}
                        }
                    }
                    let mut lanes = marks.lanes.iter().copied();
                    trace_lanes(|| lanes.next(), &mut marks.free);
                }
                for j in slow {
                    ray_keys(origin, ends[j].p, res, rf, |k| marks.free(&layout, k));
                }
                for e in ends {
                    if let (true, Some(k)) = (e.occupied, e.key) {
                        marks.occupied(&layout, k);
                    }
                }
                marks
            };
            let marks = if parallel {
                ranges
                    .par_iter()
                    .with_min_len(par_min)
                    .fold(|| Marks::new(words), trace)
                    .reduce_with(Marks::merge)
            } else {
                Some(ranges.iter().fold(Marks::new(words), trace))
            };
            let Some(marks) = marks else {
                return Vec::new();
            };
            // Non-empty 4×4×4 bricks as (Morton code of their lowest key,
            // free and occupied voxels in Morton order), sorted: their
            // voxels then come out in Morton order without sorting them.
            let slabs: Vec<usize> = (0..layout.dim[2] / 4).collect();
            let mut bricks: Vec<(u64, u64, u64)> = if parallel {
                slabs
                    .par_iter()
                    .flat_map_iter(|&bz| bricks_of_slab(&marks, &layout, bz))
                    .collect()
            } else {
                slabs
                    .iter()
                    .flat_map(|&bz| bricks_of_slab(&marks, &layout, bz))
                    .collect()
            };
            if parallel {
                bricks.par_sort_unstable_by_key(|b| b.0);
            } else {
                bricks.sort_unstable_by_key(|b| b.0);
            }
            let count: usize = bricks
                .iter()
                .map(|b| (b.1 | b.2).count_ones() as usize)
                .sum();
            let mut items = Vec::with_capacity(count + marks.outside.len());
            for &(code, f, o) in &bricks {
                let mut m = f | o;
                while m != 0 {
                    let c = m.trailing_zeros() as u64;
                    m &= m - 1;
                    items.push(((code | c) << 1) | ((o >> c) & 1));
                }
            }
            if marks.outside.is_empty() {
                // Sorted and unique already (free bits exclude occupied ones).
                return items;
            }
            items.extend(marks.outside);
            items
        } else {
            // Very large scans: every key in a list, sorted and deduplicated below.
            let trace = |r: &std::ops::Range<usize>| -> Vec<u64> {
                let mut out = Vec::new();
                for e in &ends[r.clone()] {
                    ray_keys(origin, e.p, res, rf, |k| out.push(morton(k) << 1));
                    if let (true, Some(k)) = (e.occupied, e.key) {
                        out.push((morton(k) << 1) | 1);
                    }
                }
                out.sort_unstable();
                out.dedup();
                out
            };
            let parts: Vec<Vec<u64>> = if parallel {
                ranges.par_iter().map(trace).collect()
            } else {
                ranges.iter().map(trace).collect()
            };
            parts.concat()
        };
        if parallel {
            items.par_sort_unstable();
        } else {
            items.sort_unstable();
        }
        // Equal codes: the free entry (bit 0 clear) sorts first; keep the last.
        let mut out: Vec<u64> = Vec::with_capacity(items.len());
        for it in items {
            match out.last_mut() {
                Some(last) if *last >> 1 == it >> 1 => *last = it,
                _ => out.push(it),
            }
        }
        out
    }
}

/// A 4-bit x row of a brick spread to its Morton positions (bit `dx` of the
/// nibble to bit `dx & 1 | (dx & 2) << 2`).
const SPREAD4: [u64; 16] = {
    let mut t = [0u64; 16];
    let mut v = 0;
    while v < 16 {
        let mut dx = 0;
        while dx < 4 {
            if v >> dx & 1 == 1 {
                t[v] |= 1 << ((dx & 1) | (dx & 2) << 2);
            }
            dx += 1;
        }
        v += 1;
    }
    t
};

/// The non-empty 4×4×4 bricks of brick slab `bz` (z keys `4·bz .. 4·bz + 4`
/// of the layout): Morton code of the brick's lowest key, and its free
/// (not occupied) and occupied voxels as 64-bit masks in Morton order.
fn bricks_of_slab(marks: &Marks, layout: &Layout, bz: usize) -> Vec<(u64, u64, u64)> {
    let wpr = layout.row / 64;
    let mut out = Vec::new();
    // Shift of a brick row (dy, dz) in the brick's Morton mask.
    let row_shift =
        |dy: usize, dz: usize| 2 * ((dy & 1) | (dy & 2) << 2) + 4 * ((dz & 1) | (dz & 2) << 2);
    for by in 0..layout.dim[1] / 4 {
        let row_word = |dy: usize, dz: usize, w: usize| {
            ((4 * bz + dz) * layout.dim[1] + 4 * by + dy) * wpr + w
        };
        for w in 0..wpr {
            let mut any = 0u64;
            for dz in 0..4 {
                for dy in 0..4 {
                    let i = row_word(dy, dz, w);
                    any |= marks.free[i] | marks.occ[i];
                }
            }
            while any != 0 {
                let nib = any.trailing_zeros() / 4;
                any &= !(0xF << (4 * nib));
                let (mut f, mut o) = (0u64, 0u64);
                for dz in 0..4 {
                    for dy in 0..4 {
                        let i = row_word(dy, dz, w);
                        let occ = (marks.occ[i] >> (4 * nib)) & 0xF;
                        let free = (marks.free[i] >> (4 * nib)) & 0xF & !occ;
                        let sh = row_shift(dy, dz);
                        f |= SPREAD4[free as usize] << sh;
                        o |= SPREAD4[occ as usize] << sh;
                    }
                }
                if f | o != 0 {
                    let key = [
                        (layout.lo[0] + (64 * w) as i32 + 4 * nib as i32) as u16,
                        (layout.lo[1] + 4 * by as i32) as u16,
                        (layout.lo[2] + 4 * bz as i32) as u16,
                    ];
                    out.push((morton(key), f, o));
                }
            }
        }
    }
    out
}

/// Checks an `(N, 3)` row-major point slice: length and finiteness.
pub(crate) fn check_points(what: &str, points: &[f32]) -> Result<()> {
    if points.len() % 3 != 0 {
        return Err(Error::ShapeMismatch {
            what: what.into(),
            expected: "(N, 3)".into(),
            got: format!("{} values", points.len()),
        });
    }
    if let Some(i) = points.iter().position(|v| !v.is_finite()) {
        return Err(Error::NonFinite {
            what: what.into(),
            index: i / 3,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::key::{child_index, TREE_DEPTH};
    use crate::map::tree::{Node, Tree, LEAF};
    use crate::map::MapParams;
    use rand::{Rng, SeedableRng};

    /// OctoMap's `updateNode(key, occupied)` for one key: the early abort on
    /// a clamped leaf, `updateNodeRecurs` with the expansion of pruned nodes,
    /// pruning or max-of-children on the way up.
    fn reference_update(map: &mut OccupancyMap, key: Key, occupied: bool) {
        let lo = map.lo;
        if let Some((leaf, _)) = map.tree.search(key) {
            if (occupied && leaf.value >= lo.max) || (!occupied && leaf.value <= lo.min) {
                return;
            }
        }
        let t = &mut map.tree;
        let (root, created) = t.root_or_new();
        t.root = reference_rec(t, root, created, key, 0, occupied, &lo);
    }

    fn reference_rec(
        t: &mut Tree,
        mut node: Node,
        just_created: bool,
        key: Key,
        depth: u32,
        occupied: bool,
        lo: &super::super::tree::LogOdds,
    ) -> Node {
        if depth == TREE_DEPTH {
            let v = node.value + if occupied { lo.hit } else { lo.miss };
            node.value = v.clamp(lo.min, lo.max);
            return node;
        }
        let pos = child_index(key, depth);
        if !node.has_children() {
            node.child = if just_created {
                t.alloc_block([Node::ABSENT; 8])
            } else {
                t.num_nodes += 8;
                t.alloc_block(
                    [Node {
                        value: node.value,
                        child: LEAF,
                    }; 8],
                )
            };
        }
        let mut child = t.blocks[node.child as usize][pos];
        let created = !child.exists();
        if created {
            t.num_nodes += 1;
            child = Node {
                value: 0.0,
                child: LEAF,
            };
        }
        let child = reference_rec(t, child, created, key, depth + 1, occupied, lo);
        t.blocks[node.child as usize][pos] = child;
        t.finish_inner(node)
    }

    /// One scan the reference way: the key sets of `computeUpdate` from
    /// [`ray_keys`] (occupied winning), then one `updateNode` per key.
    fn reference_scan(map: &mut OccupancyMap, points: &[f32], origin: [f32; 3]) {
        let (res, rf) = (map.params.resolution, map.resolution_factor);
        let mut free = std::collections::BTreeSet::new();
        let mut occ = std::collections::BTreeSet::new();
        for p in points.chunks_exact(3) {
            let (e, occupied) = ray_end([p[0], p[1], p[2]], origin, map.params.max_range);
            ray_keys(origin, e, res, rf, |k| {
                free.insert(morton(k));
            });
            if occupied {
                if let Some(k) = point_to_key(e, rf) {
                    occ.insert(morton(k));
                }
            }
        }
        let mut items: Vec<(u64, bool)> = free
            .difference(&occ)
            .map(|&c| (c, false))
            .chain(occ.iter().map(|&c| (c, true)))
            .collect();
        items.sort_unstable();
        for (c, occupied) in items {
            reference_update(map, crate::map::key::from_morton(c), occupied);
        }
    }

    /// Random scans with rays of every kind: beyond the max range, along the
    /// axes, through voxel corners (points on the grid), repeated so that
    /// voxels clamp and nodes prune.
    fn random_scans(seed: u64, res: f32) -> Vec<([f32; 3], Vec<f32>)> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut scans = Vec::new();
        for s in 0..6 {
            let origin = if s % 2 == 0 {
                [0, 1, 2].map(|_| rng.random_range(-8..8) as f32 * res)
            } else {
                [0, 1, 2].map(|_| rng.random_range(-1.0f32..1.0))
            };
            let mut pts = Vec::new();
            for i in 0..3000 {
                let p: [f32; 3] = match i % 4 {
                    0 => [0, 1, 2].map(|_| rng.random_range(-40..40) as f32 * res),
                    1 => {
                        let mut p = origin;
                        p[rng.random_range(0..3)] += rng.random_range(-6.0f32..6.0);
                        p
                    }
                    _ => [0, 1, 2].map(|_| rng.random_range(-7.0f32..7.0)),
                };
                pts.extend_from_slice(&p);
            }
            scans.push((origin, pts));
        }
        // Near two faces of the tree: rays leaving it, a key box cut by it
        // (rays traced key by key, voxels outside the bitset).
        let edge = 32768.0 * res;
        let origin = [edge - 2.0, 0.5, 3.0 - edge];
        let pts: Vec<f32> = (0..6000)
            .flat_map(|_| [0, 1, 2].map(|i| origin[i] + rng.random_range(-6.0f32..6.0)))
            .collect();
        scans.push((origin, pts));
        // The same scans again: clamped voxels, pruned nodes, early aborts.
        let again = scans.clone();
        scans.extend(again);
        scans
    }

    /// The max-range test without the root decides as the one with it, also
    /// for points at the range to the last bit.
    #[test]
    fn max_range_test_without_root_equals_norm_test() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        for _ in 0..200_000 {
            let m = [10.0, 0.3, 7.77, 1e3][rng.random_range(0..4)];
            let dir = [0, 1, 2].map(|_| rng.random_range(-1.0f32..1.0));
            let n = f32_norm(dir) as f32;
            if n < 1e-3 {
                continue;
            }
            let scale = m as f32 * (1.0 + rng.random_range(-4i32..=4) as f32 * f32::EPSILON);
            let d = dir.map(|v| v / n * scale);
            assert_eq!(beyond(d, m), f32_norm(d) > m, "{d:?} at {m}");
        }
        assert!(
            !beyond([0.0; 3], 1.0)
                && beyond([f32::MAX; 3], 1e300) == (f32_norm([f32::MAX; 3]) > 1e300)
        );
    }

    /// The batched insertion (lanes, bricks, ordered batch update) builds
    /// exactly the tree of OctoMap's per-key updates, sequential and parallel.
    #[test]
    #[ignore = "slow: make test runs it"]
    fn batched_insertion_equals_per_key_reference() {
        for (seed, res) in [(1u64, 0.1f32), (2, 0.25), (3, 0.05)] {
            let params = MapParams {
                max_range: Some(5.0),
                ..MapParams::new(res as f64)
            };
            let mut reference = OccupancyMap::try_new(params).unwrap();
            let mut seq = OccupancyMap::try_new(params).unwrap();
            let mut par = OccupancyMap::try_new(params).unwrap();
            for (origin, pts) in random_scans(seed, res) {
                reference_scan(&mut reference, &pts, origin);
                seq.insert_scan_sequential(&pts, origin).unwrap();
                par.insert_scan(&pts, origin).unwrap();
                assert_eq!(seq.num_nodes(), reference.num_nodes(), "seed {seed}");
                assert!(seq.tree_bits() == reference.tree_bits(), "seed {seed}");
                assert!(par.tree_bits() == reference.tree_bits(), "seed {seed}");
            }
            assert!(reference.num_nodes() > 1000);
            // The scans reach the clamping bounds and prune (inner leaves).
            let (mut clamped, mut pruned) = (0, 0);
            reference.tree.for_each_leaf(|_, depth, v| {
                clamped += usize::from(v == reference.lo.min);
                pruned += usize::from(depth < TREE_DEPTH);
            });
            assert!(
                clamped > 0 && pruned > 0,
                "{clamped} clamped, {pruned} pruned"
            );
            seq.check_invariants().unwrap();
        }
    }
}
