//! Scan insertion: OctoMap's `computeUpdate` (free keys along each ray by its
//! 3-D DDA `computeRayKeys`, occupied endpoint keys, occupied winning) run in
//! parallel into per-scan bitsets, then one ordered batch update of the tree.
//!
//! The key sets are sets: whatever the thread count or the order in which
//! rays are traced, the sorted update list and hence the tree are the same.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

use super::key::{key_to_coord, morton, point_to_key, Key};
use super::OccupancyMap;
use crate::error::{Error, Result};

/// Points per parallel work item.
const CHUNK: usize = 2048;
/// Largest per-scan bitset (bits) before falling back to sorting keys.
const MAX_GRID_BITS: u64 = 1 << 28;

/// Counts of one scan's update.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ScanUpdate {
    /// Voxels updated as free.
    pub free: usize,
    /// Voxels updated as occupied.
    pub occupied: usize,
}

/// Calls `visit` for every key of OctoMap's `computeRayKeys(origin, end)`:
/// the voxels the segment crosses, origin voxel included, end voxel excluded.
/// Returns `false` (and visits nothing) when either point lies outside the
/// tree. Arithmetic mirrors OctoMap's `f32` points and `f64` steps so that
/// the same keys come out.
#[inline]
pub(crate) fn ray_keys(
    origin: [f32; 3],
    end: [f32; 3],
    resolution: f64,
    resolution_factor: f64,
    mut visit: impl FnMut(Key),
) -> bool {
    let (Some(ko), Some(ke)) = (
        point_to_key(origin, resolution_factor),
        point_to_key(end, resolution_factor),
    ) else {
        return false;
    };
    if ko == ke {
        return true;
    }
    visit(ko);
    let mut dir = [end[0] - origin[0], end[1] - origin[1], end[2] - origin[2]];
    let length = f32_norm(dir) as f32;
    for d in &mut dir {
        *d /= length;
    }
    let mut step = [0i32; 3];
    let mut t_max = [f64::MAX; 3];
    let mut t_delta = [f64::MAX; 3];
    for i in 0..3 {
        step[i] = if dir[i] > 0.0 {
            1
        } else if dir[i] < 0.0 {
            -1
        } else {
            0
        };
        if step[i] != 0 {
            let mut border = key_to_coord(ko[i], resolution);
            border += (step[i] as f64 * resolution * 0.5) as f32 as f64;
            t_max[i] = (border - origin[i] as f64) / dir[i] as f64;
            t_delta[i] = resolution / (dir[i] as f64).abs();
        }
    }
    let length = length as f64;
    let mut cur = [ko[0] as i32, ko[1] as i32, ko[2] as i32];
    let end_k = [ke[0] as i32, ke[1] as i32, ke[2] as i32];
    loop {
        let dim = if t_max[0] < t_max[1] {
            if t_max[0] < t_max[2] {
                0
            } else {
                2
            }
        } else if t_max[1] < t_max[2] {
            1
        } else {
            2
        };
        cur[dim] += step[dim];
        t_max[dim] += t_delta[dim];
        if cur == end_k {
            return true;
        }
        let dist = t_max[0].min(t_max[1]).min(t_max[2]);
        if dist > length || !(0..65536).contains(&cur[dim]) {
            return true;
        }
        visit([cur[0] as u16, cur[1] as u16, cur[2] as u16]);
    }
}

/// [`ray_keys`] specialised to marking a [`Grid`]: the same keys, with the
/// grid index advanced incrementally and the axis choice free of branches.
/// Keys outside the grid go to `outside` (Morton code `<< 1`).
#[inline]
fn ray_into_grid(
    origin: [f32; 3],
    end: [f32; 3],
    resolution: f64,
    resolution_factor: f64,
    grid: &Grid,
    outside: &mut Vec<u64>,
) {
    let (Some(ko), Some(ke)) = (
        point_to_key(origin, resolution_factor),
        point_to_key(end, resolution_factor),
    ) else {
        return;
    };
    if ko == ke {
        return;
    }
    let Some(mut idx) = grid.index(ko) else {
        // The origin lies outside the grid only for degenerate boxes: take the slow path.
        ray_keys(origin, end, resolution, resolution_factor, |k| {
            match grid.index(k) {
                Some(j) => Grid::set(&grid.free, j),
                None => outside.push(morton(k) << 1),
            }
        });
        return;
    };
    Grid::set(&grid.free, idx);
    let mut dir = [end[0] - origin[0], end[1] - origin[1], end[2] - origin[2]];
    let length = f32_norm(dir) as f32;
    for d in &mut dir {
        *d /= length;
    }
    let (step, t_max, t_delta) = dda_init(ko, origin, dir, resolution);
    let length = length as f64;
    // Position relative to the grid's lower corner, kept in registers; the
    // end is reached when the grid index equals the end voxel's.
    let mut rel = [
        ko[0] as i64 - grid.lo[0] as i64,
        ko[1] as i64 - grid.lo[1] as i64,
        ko[2] as i64 - grid.lo[2] as i64,
    ];
    let Some(end_idx) = grid.index(ke) else {
        return;
    };
    let stride = [1i64, grid.row as i64, (grid.row * grid.dim[1]) as i64];
    let dims = [grid.dim[0] as i64, grid.dim[1] as i64, grid.dim[2] as i64];
    let (mut tx, mut ty, mut tz) = (t_max[0], t_max[1], t_max[2]);
    let mut sidx = idx as i64;
    let end_idx = end_idx as i64;
    let (ds, dd) = (
        [
            step[0] * stride[0],
            step[1] * stride[1],
            step[2] * stride[2],
        ],
        t_delta,
    );
    // While the current voxel is at least two voxels (Chebyshev) from the end
    // voxel, the end can be neither reached nor passed: the exit distance is
    // then at least one voxel short of `length`, far beyond rounding. Those
    // checks start once fewer steps remain.
    let cheb = (0..3)
        .map(|i| (ke[i] as i64 - ko[i] as i64).abs())
        .max()
        .unwrap_or(0);
    let mut safe = (cheb - 2).max(0);
    while safe > 0 {
        let dim = if tx < ty {
            if tx < tz {
                0
            } else {
                2
            }
        } else if ty < tz {
            1
        } else {
            2
        };
        let r = rel[dim] + step[dim];
        if (r as u64) >= dims[dim] as u64 {
            break;
        }
        match dim {
            0 => tx += dd[0],
            1 => ty += dd[1],
            _ => tz += dd[2],
        }
        rel[dim] = r;
        sidx += ds[dim];
        Grid::set(&grid.free, sidx as usize);
        safe -= 1;
    }
    loop {
        // OctoMap's axis choice (ties go to the later axis).
        let dim = if tx < ty {
            if tx < tz {
                tx += dd[0];
                0
            } else {
                tz += dd[2];
                2
            }
        } else if ty < tz {
            ty += dd[1];
            1
        } else {
            tz += dd[2];
            2
        };
        rel[dim] += step[dim];
        sidx += ds[dim];
        let inside = (rel[dim] as u64) < dims[dim] as u64;
        if inside && sidx == end_idx {
            return;
        }
        if tx.min(ty).min(tz) > length {
            return;
        }
        if !inside {
            // Left the grid (only by rounding past the end voxel): go on key by key.
            let mut t = [tx, ty, tz];
            let end_rel = [0, 1, 2].map(|i| ke[i] as i64 - grid.lo[i] as i64);
            loop {
                let k = [0, 1, 2].map(|i| rel[i] + grid.lo[i] as i64);
                if !k.iter().all(|&v| (0..65536).contains(&v)) {
                    return;
                }
                let key = [k[0] as u16, k[1] as u16, k[2] as u16];
                match grid.index(key) {
                    Some(j) => Grid::set(&grid.free, j),
                    None => outside.push(morton(key) << 1),
                }
                let m01 = usize::from(t[0] >= t[1]);
                let dim = if t[m01] < t[2] { m01 } else { 2 };
                rel[dim] += step[dim];
                t[dim] += dd[dim];
                if rel == end_rel || t[0].min(t[1]).min(t[2]) > length {
                    return;
                }
            }
        }
        idx = sidx as usize;
        Grid::set(&grid.free, idx);
    }
}

/// Step signs, first crossing distances and per-voxel distances of
/// OctoMap's DDA (`f32` direction, `f64` distances).
#[inline]
fn dda_init(
    ko: Key,
    origin: [f32; 3],
    dir: [f32; 3],
    resolution: f64,
) -> ([i64; 3], [f64; 3], [f64; 3]) {
    let mut step = [0i64; 3];
    let mut t_max = [f64::MAX; 3];
    let mut t_delta = [f64::MAX; 3];
    for i in 0..3 {
        step[i] = if dir[i] > 0.0 {
            1
        } else if dir[i] < 0.0 {
            -1
        } else {
            0
        };
        if step[i] != 0 {
            let mut border = key_to_coord(ko[i], resolution);
            border += (step[i] as f64 * resolution * 0.5) as f32 as f64;
            t_max[i] = (border - origin[i] as f64) / dir[i] as f64;
            t_delta[i] = resolution / (dir[i] as f64).abs();
        }
    }
    (step, t_max, t_delta)
}

/// OctoMap's `Vector3::norm`: the squared norm summed in `f32`, its root in `f64`.
#[inline]
fn f32_norm(v: [f32; 3]) -> f64 {
    ((v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) as f64).sqrt()
}

/// Where one point's ray ends and whether its endpoint is an occupied voxel.
#[inline]
fn ray_end(p: [f32; 3], origin: [f32; 3], max_range: Option<f64>) -> ([f32; 3], bool) {
    let d = [p[0] - origin[0], p[1] - origin[1], p[2] - origin[2]];
    match max_range {
        Some(m) if f32_norm(d) > m => {
            // OctoMap: direction = (p - origin).normalized(); origin + direction * (float) maxrange
            let len = f32_norm(d);
            let l = len as f32;
            let dir = if len > 0.0 {
                [d[0] / l, d[1] / l, d[2] / l]
            } else {
                d
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

/// One scan's free and occupied voxels as a dense bitset over its key box.
struct Grid {
    lo: [i32; 3],
    dim: [usize; 3],
    /// Bits per x row: `dim[0]` rounded up to whole words, so that no word
    /// spans two rows.
    row: usize,
    free: Vec<AtomicU64>,
    occ: Vec<AtomicU64>,
}

impl Grid {
    #[inline]
    fn index(&self, k: Key) -> Option<usize> {
        let x = k[0] as i32 - self.lo[0];
        let y = k[1] as i32 - self.lo[1];
        let z = k[2] as i32 - self.lo[2];
        if x < 0 || y < 0 || z < 0 {
            return None;
        }
        let (x, y, z) = (x as usize, y as usize, z as usize);
        if x >= self.dim[0] || y >= self.dim[1] || z >= self.dim[2] {
            return None;
        }
        Some(x + self.row * (y + self.dim[1] * z))
    }

    #[inline]
    fn set(words: &[AtomicU64], i: usize) {
        let w = &words[i >> 6];
        let bit = 1u64 << (i & 63);
        if w.load(Ordering::Relaxed) & bit == 0 {
            w.fetch_or(bit, Ordering::Relaxed);
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
            let u = self.insert_scan(pts, *origin)?;
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
        let pt = |i: usize| [points[3 * i], points[3 * i + 1], points[3 * i + 2]];

        // Key box of the scan: origin and ray ends.
        let box_of = |r: std::ops::Range<usize>| {
            let mut b = KeyBox::EMPTY;
            for i in r {
                let (e, _) = ray_end(pt(i), origin, max_range);
                if let Some(k) = point_to_key(e, rf) {
                    b.add(k);
                }
            }
            b
        };
        let ranges: Vec<std::ops::Range<usize>> = (0..n)
            .step_by(CHUNK)
            .map(|s| s..(s + CHUNK).min(n))
            .collect();
        let mut bx = if parallel {
            ranges
                .par_iter()
                .map(|r| box_of(r.clone()))
                .reduce(|| KeyBox::EMPTY, KeyBox::union)
        } else {
            ranges
                .iter()
                .map(|r| box_of(r.clone()))
                .fold(KeyBox::EMPTY, KeyBox::union)
        };
        if let Some(k) = point_to_key(origin, rf) {
            bx.add(k);
        }
        if bx.lo[0] > bx.hi[0] {
            return Vec::new();
        }
        // One voxel of margin for rays that round past their end voxel.
        let lo = bx.lo.map(|v| (v - 1).max(0));
        let hi = bx.hi.map(|v| (v + 1).min(65535));
        let dim = [
            (hi[0] - lo[0] + 1) as usize,
            (hi[1] - lo[1] + 1) as usize,
            (hi[2] - lo[2] + 1) as usize,
        ];
        let row = dim[0].div_ceil(64) * 64;
        let bits = row as u64 * dim[1] as u64 * dim[2] as u64;

        let mut items = if bits <= MAX_GRID_BITS {
            let words = (bits / 64) as usize;
            let grid = Grid {
                lo,
                dim,
                row,
                free: (0..words).map(|_| AtomicU64::new(0)).collect(),
                occ: (0..words).map(|_| AtomicU64::new(0)).collect(),
            };
            let trace = |r: std::ops::Range<usize>| -> Vec<u64> {
                let mut outside = Vec::new();
                for i in r {
                    let (e, occupied) = ray_end(pt(i), origin, max_range);
                    ray_into_grid(origin, e, res, rf, &grid, &mut outside);
                    if occupied {
                        if let Some(k) = point_to_key(e, rf) {
                            match grid.index(k) {
                                Some(j) => Grid::set(&grid.occ, j),
                                None => outside.push((morton(k) << 1) | 1),
                            }
                        }
                    }
                }
                outside
            };
            let outside: Vec<Vec<u64>> = if parallel {
                ranges.par_iter().map(|r| trace(r.clone())).collect()
            } else {
                ranges.iter().map(|r| trace(r.clone())).collect()
            };
            let words_per_row = row / 64;
            let extract = |w0: usize, w1: usize| -> Vec<u64> {
                let mut out = Vec::new();
                for w in w0..w1 {
                    let o = grid.occ[w].load(Ordering::Relaxed);
                    let f = grid.free[w].load(Ordering::Relaxed) & !o;
                    if f | o == 0 {
                        continue;
                    }
                    // One row per word: y, z and their Morton bits once per word.
                    let r = w / words_per_row;
                    let y = (lo[1] + (r % dim[1]) as i32) as u16;
                    let z = (lo[2] + (r / dim[1]) as i32) as u16;
                    let yz = morton([0, y, z]);
                    let x0 = lo[0] + ((w % words_per_row) * 64) as i32;
                    for (mut m, flag) in [(f, 0u64), (o, 1u64)] {
                        while m != 0 {
                            let b = m.trailing_zeros() as i32;
                            m &= m - 1;
                            let x = (x0 + b) as u16;
                            out.push(((morton([x, 0, 0]) | yz) << 1) | flag);
                        }
                    }
                }
                out
            };
            let step = 4096;
            let spans: Vec<(usize, usize)> = (0..words)
                .step_by(step)
                .map(|s| (s, (s + step).min(words)))
                .collect();
            let parts: Vec<Vec<u64>> = if parallel {
                spans.par_iter().map(|&(a, b)| extract(a, b)).collect()
            } else {
                spans.iter().map(|&(a, b)| extract(a, b)).collect()
            };
            let mut items: Vec<u64> = parts.concat();
            for o in outside {
                items.extend(o);
            }
            items
        } else {
            // Very large scans: every key in a list, sorted and deduplicated below.
            let trace = |r: std::ops::Range<usize>| -> Vec<u64> {
                let mut out = Vec::new();
                for i in r {
                    let (e, occupied) = ray_end(pt(i), origin, max_range);
                    ray_keys(origin, e, res, rf, |k| out.push(morton(k) << 1));
                    if occupied {
                        if let Some(k) = point_to_key(e, rf) {
                            out.push((morton(k) << 1) | 1);
                        }
                    }
                }
                out.sort_unstable();
                out.dedup();
                out
            };
            let parts: Vec<Vec<u64>> = if parallel {
                ranges.par_iter().map(|r| trace(r.clone())).collect()
            } else {
                ranges.iter().map(|r| trace(r.clone())).collect()
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
    use rand::{Rng, SeedableRng};

    /// The grid-specialised tracer visits exactly OctoMap's ray keys.
    #[test]
    fn grid_tracer_matches_reference_ray_keys() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let (res, rf) = (0.1, 1.0 / 0.1);
        for _ in 0..2000 {
            let o = [0, 1, 2].map(|_| rng.random_range(-2.0f32..2.0));
            let mut e = [0, 1, 2].map(|_| rng.random_range(-6.0f32..6.0));
            if rng.random_bool(0.2) {
                e[1] = o[1]; // axis-parallel components
            }
            let mut reference = Vec::new();
            ray_keys(o, e, res, rf, |k| reference.push(morton(k) << 1));
            reference.sort_unstable();
            reference.dedup();

            let mut bx = KeyBox::EMPTY;
            bx.add(point_to_key(o, rf).unwrap());
            bx.add(point_to_key(e, rf).unwrap());
            let lo = bx.lo.map(|v| v - 1);
            let dim = [0, 1, 2].map(|i| (bx.hi[i] + 1 - lo[i] + 1) as usize);
            let row = dim[0].div_ceil(64) * 64;
            let words = row * dim[1] * dim[2] / 64;
            let grid = Grid {
                lo,
                dim,
                row,
                free: (0..words).map(|_| AtomicU64::new(0)).collect(),
                occ: Vec::new(),
            };
            let mut outside = Vec::new();
            ray_into_grid(o, e, res, rf, &grid, &mut outside);
            let mut got = outside;
            for (w, word) in grid.free.iter().enumerate() {
                let mut m = word.load(Ordering::Relaxed);
                while m != 0 {
                    let j = (w << 6) | m.trailing_zeros() as usize;
                    m &= m - 1;
                    let k = [
                        (lo[0] + (j % row) as i32) as u16,
                        (lo[1] + (j / row % dim[1]) as i32) as u16,
                        (lo[2] + (j / row / dim[1]) as i32) as u16,
                    ];
                    got.push(morton(k) << 1);
                }
            }
            got.sort_unstable();
            got.dedup();
            assert_eq!(got, reference, "ray {o:?} -> {e:?}");
        }
    }
}
