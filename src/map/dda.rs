//! OctoMap's 3-D DDA (`computeRayKeys`): the reference tracer over keys, and
//! a batched tracer that marks the same voxels in a scan's bitset, several
//! rays at a time (AVX2 where the processor has it).
//!
//! Both step exactly as OctoMap does: `f32` direction, `f64` crossing
//! distances advanced by repeated addition, the axis of the smallest distance
//! first (ties to the later axis), and the same stopping rules (the end voxel
//! reached, or the next crossing beyond the ray's length; OctoMap's third,
//! leaving the tree, cannot apply to a batched ray, whose voxels lie inside a
//! layout inside the tree). The batched tracer only changes where the current
//! voxel is kept: as a bit index into the scan's bitset, advanced by per-axis
//! strides, instead of three keys.

use super::key::{key_to_coord, point_to_key, Key};
use crate::simd::Isa;

/// Longest ray, in voxels, that the batched tracer takes. Up to this length
/// the rounding of the `f32` direction moves the ray's end by far less than a
/// voxel, so that the voxels it crosses lie within one voxel of the key box of
/// its origin and end; longer rays go through [`ray_keys`].
pub(crate) const MAX_BATCHED_VOXELS: f64 = 1e5;

/// Margin (voxels) of a [`Layout`] around the keys of the rays it takes in the
/// batched tracer: one for the voxels a ray crosses, one more for the step
/// after its last voxel, which is computed but not marked.
pub(crate) const LAYOUT_MARGIN: i32 = 2;

/// OctoMap's `Vector3::norm`: the squared norm summed in `f32`, its root in `f64`.
#[inline]
pub(crate) fn f32_norm(v: [f32; 3]) -> f64 {
    ((v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) as f64).sqrt()
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
    // OctoMap's f32 direction, widened exactly; in f64 where its f32
    // arithmetic breaks down (see `direction`).
    let (dir, length) = match direction(origin, end) {
        Some((d, l)) => (d.map(f64::from), l),
        None => direction_f64(origin, end),
    };
    let mut step = [0i32; 3];
    let mut t_max = [f64::MAX; 3];
    let mut t_delta = [f64::MAX; 3];
    for i in 0..3 {
        step[i] = step_sign(dir[i]);
        if step[i] != 0 {
            (t_max[i], t_delta[i]) = crossings(ko[i], origin[i], dir[i], step[i], resolution);
        }
    }
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
        if step[dim] == 0 {
            // Every axis the ray moves along is beyond f64::MAX: no crossing
            // left (only reachable through overflow; OctoMap would spin).
            return true;
        }
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

/// OctoMap's normalised `f32` direction of `end − origin` and the segment's
/// length (the `f32` norm, widened to `f64`), or `None` where that `f32`
/// arithmetic breaks down: a squared length that underflows to zero (a
/// segment shorter than about 1e-19 m, e.g. from `(0, 0, 0)` to
/// `(-1e-30, 1e-30, 0)`, which still crosses a voxel face) or overflows, or
/// a squared length below `f32::MIN_POSITIVE`, whose root is too coarse to
/// normalise with. OctoMap divides by the zero or infinite length there and
/// steps a NaN direction forever.
#[inline]
fn direction(origin: [f32; 3], end: [f32; 3]) -> Option<([f32; 3], f64)> {
    let mut dir = [end[0] - origin[0], end[1] - origin[1], end[2] - origin[2]];
    let sq = dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2];
    if !(sq >= f32::MIN_POSITIVE && sq.is_finite()) {
        return None;
    }
    let length = f32_norm(dir) as f32;
    for d in &mut dir {
        *d /= length;
    }
    Some((dir, length as f64))
}

/// The direction and length of `end − origin` in `f64`, where the `f32`
/// arithmetic of [`direction`] breaks down: exact differences of the `f32`
/// points, whose squares neither underflow nor overflow in `f64`. Finite,
/// and non-zero along every axis where the points differ.
fn direction_f64(origin: [f32; 3], end: [f32; 3]) -> ([f64; 3], f64) {
    let d = [0, 1, 2].map(|i| f64::from(end[i]) - f64::from(origin[i]));
    let length = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    (d.map(|v| v / length), length)
}

#[inline]
fn step_sign(d: f64) -> i32 {
    if d > 0.0 {
        1
    } else if d < 0.0 {
        -1
    } else {
        0
    }
}

/// Distance to the first crossing of axis `i` and between crossings
/// (OctoMap's `tMax` / `tDelta`) for a ray leaving voxel key `k`.
#[inline]
fn crossings(k: u16, origin: f32, dir: f64, step: i32, resolution: f64) -> (f64, f64) {
    let mut border = key_to_coord(k, resolution);
    border += (step as f64 * resolution * 0.5) as f32 as f64;
    ((border - origin as f64) / dir, resolution / dir.abs())
}

/// A box of keys laid out as a bitset: x fastest, each x row padded to whole
/// 64-bit words.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Layout {
    /// Lowest key of the box (inclusive).
    pub lo: [i32; 3],
    /// Number of keys per axis.
    pub dim: [usize; 3],
    /// Bits per x row: `dim[0]` rounded up to whole words.
    pub row: usize,
}

impl Layout {
    /// The box from `lo` to `hi` (inclusive).
    pub fn new(lo: [i32; 3], hi: [i32; 3]) -> Layout {
        let dim = [0, 1, 2].map(|i| (hi[i] - lo[i] + 1).max(0) as usize);
        Layout {
            lo,
            dim,
            row: dim[0].div_ceil(64) * 64,
        }
    }

    /// Number of 64-bit words of the bitset.
    pub fn words(&self) -> usize {
        self.row / 64 * self.dim[1] * self.dim[2]
    }

    /// Bit index of key `k`, `None` outside the box.
    #[inline]
    pub fn index(&self, k: Key) -> Option<usize> {
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

    /// Whether the box holds every key within `margin` of `k`.
    #[inline]
    fn holds_around(&self, k: Key, margin: i32) -> bool {
        (0..3).all(|i| {
            let v = k[i] as i32;
            v - margin >= self.lo[i] && v + margin < self.lo[i] + self.dim[i] as i32
        })
    }
}

/// Sets bit `i` of `bits` (no write when it is already set: most voxels of a
/// scan are crossed by many rays). Indices past the end are ignored.
#[inline(always)]
pub(crate) fn set_bit(bits: &mut [u64], i: usize) {
    if let Some(w) = bits.get_mut(i >> 6) {
        let b = 1u64 << (i & 63);
        if *w & b == 0 {
            *w |= b;
        }
    }
}

/// Sets bit `i` of `bits` unconditionally (no branch on the bit's state).
/// Indices past the end are ignored.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn or_bit(bits: &mut [u64], i: usize) {
    if let Some(w) = bits.get_mut(i >> 6) {
        *w |= 1u64 << (i & 63);
    }
}

/// One ray in the batched tracer: OctoMap's DDA state with the current voxel
/// as a bit index of the scan's [`Layout`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct Lane {
    /// Distance to the next crossing per axis (`f64::MAX` for an axis the ray
    /// does not move along).
    t: [f64; 3],
    /// Distance between crossings per axis.
    dd: [f64; 3],
    /// Bit-index step per axis (signed stride, 0 for an axis not moved along).
    ds: [i64; 3],
    /// Bit index of the current voxel.
    idx: i64,
    /// Bit index of the end voxel.
    end: i64,
    /// Length of the segment (metres).
    len: f64,
}

/// What the batched tracer can do with one ray.
#[derive(Debug)]
pub(crate) enum PreparedRay {
    /// OctoMap's ray holds no voxel (an end outside the tree, or origin and
    /// end in the same voxel).
    Empty,
    /// A ray for [`trace_lanes`].
    Lane(Lane),
    /// A ray that [`ray_keys`] must trace (too long, or too close to the
    /// layout's border).
    Slow,
}

impl Lane {
    /// A lane that never stops and marks nothing.
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    const IDLE: Lane = Lane {
        t: [0.0; 3],
        dd: [0.0; 3],
        ds: [0; 3],
        idx: 0,
        end: -1,
        len: f64::INFINITY,
    };

    /// Prepares the ray from `origin` (voxel `ko`) to `end` (voxel `ke`,
    /// `None` outside the tree) in `layout`.
    #[inline]
    pub fn prepare(
        origin: [f32; 3],
        ko: Key,
        end: [f32; 3],
        ke: Option<Key>,
        resolution: f64,
        layout: &Layout,
    ) -> PreparedRay {
        let Some(ke) = ke else {
            return PreparedRay::Empty;
        };
        if ko == ke {
            return PreparedRay::Empty;
        }
        // Rays whose f32 direction breaks down go through `ray_keys`.
        let Some((dir, len)) = direction(origin, end) else {
            return PreparedRay::Slow;
        };
        if len > MAX_BATCHED_VOXELS * resolution
            || !len.is_finite()
            || !layout.holds_around(ko, LAYOUT_MARGIN)
            || !layout.holds_around(ke, LAYOUT_MARGIN)
        {
            return PreparedRay::Slow;
        }
        let (Some(idx), Some(end)) = (layout.index(ko), layout.index(ke)) else {
            return PreparedRay::Slow;
        };
        let stride = [1i64, layout.row as i64, (layout.row * layout.dim[1]) as i64];
        let mut lane = Lane {
            t: [f64::MAX; 3],
            dd: [f64::MAX; 3],
            ds: [0; 3],
            idx: idx as i64,
            end: end as i64,
            len,
        };
        // `crossings` for the three axes, its six divisions side by side.
        let step = dir.map(|d| step_sign(f64::from(d)));
        let mut num = [resolution; 6];
        let mut den = [1.0f64; 6];
        for i in 0..3 {
            let border =
                key_to_coord(ko[i], resolution) + (step[i] as f64 * resolution * 0.5) as f32 as f64;
            num[i] = border - origin[i] as f64;
            den[i] = dir[i] as f64;
            den[i + 3] = (dir[i] as f64).abs();
        }
        let q: [f64; 6] = std::array::from_fn(|i| num[i] / den[i]);
        for i in 0..3 {
            if step[i] != 0 {
                lane.t[i] = q[i];
                lane.dd[i] = q[i + 3];
                lane.ds[i] = step[i] as i64 * stride[i];
            }
        }
        PreparedRay::Lane(lane)
    }
}

/// Marks in `bits` the voxels of every lane that `next` hands out, as
/// [`ray_keys`] would visit them. Every voxel of a lane lies inside the
/// layout the lanes were prepared for (see [`LAYOUT_MARGIN`]).
pub(crate) fn trace_lanes(next: impl FnMut() -> Option<Lane>, bits: &mut [u64]) {
    match Isa::detect() {
        // SAFETY: `Isa::Avx2Fma` is only detected on a CPU with AVX2 (and FMA).
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2Fma => unsafe { trace_lanes_avx2(next, bits) },
        _ => trace_lanes_scalar(next, bits),
    }
}

/// [`trace_lanes`] one ray after the other.
pub(crate) fn trace_lanes_scalar(mut next: impl FnMut() -> Option<Lane>, bits: &mut [u64]) {
    while let Some(Lane {
        mut t,
        dd,
        ds,
        mut idx,
        end,
        len,
    }) = next()
    {
        set_bit(bits, idx as usize);
        loop {
            let dim = if t[0] < t[1] {
                if t[0] < t[2] {
                    0
                } else {
                    2
                }
            } else if t[1] < t[2] {
                1
            } else {
                2
            };
            t[dim] += dd[dim];
            idx += ds[dim];
            if idx == end || t[0].min(t[1]).min(t[2]) > len {
                break;
            }
            set_bit(bits, idx as usize);
        }
    }
}

/// [`trace_lanes`] four rays at a time in AVX2 registers: the axis choice as
/// masks (no branches), a finished lane refilled with the next ray.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub(crate) unsafe fn trace_lanes_avx2(mut next: impl FnMut() -> Option<Lane>, bits: &mut [u64]) {
    use std::arch::x86_64::*;

    let mut lanes = [Lane::IDLE; 4];
    let mut live = 0u32;
    for (l, lane) in lanes.iter_mut().enumerate() {
        if let Some(x) = next() {
            *lane = x;
            live |= 1 << l;
            set_bit(bits, x.idx as usize);
        }
    }
    let pd = |v: [f64; 4]| _mm256_set_pd(v[3], v[2], v[1], v[0]);
    let pi = |v: [i64; 4]| _mm256_set_epi64x(v[3], v[2], v[1], v[0]);
    let mut tx = pd(lanes.map(|l| l.t[0]));
    let mut ty = pd(lanes.map(|l| l.t[1]));
    let mut tz = pd(lanes.map(|l| l.t[2]));
    let mut dx = pd(lanes.map(|l| l.dd[0]));
    let mut dy = pd(lanes.map(|l| l.dd[1]));
    let mut dz = pd(lanes.map(|l| l.dd[2]));
    let mut len = pd(lanes.map(|l| l.len));
    let mut sx = pi(lanes.map(|l| l.ds[0]));
    let mut sy = pi(lanes.map(|l| l.ds[1]));
    let mut sz = pi(lanes.map(|l| l.ds[2]));
    let mut end = pi(lanes.map(|l| l.end));
    let mut idx = pi(lanes.map(|l| l.idx));
    // Lane l's mask, for replacing one lane of every vector.
    let lane_mask = [0, 1, 2, 3].map(|l| {
        let mut m = [0i64; 4];
        m[l] = -1;
        pi(m)
    });
    while live != 0 {
        let stopped = loop {
            // OctoMap's choice: x if tx < ty and tx < tz, else y if ty < tz, else z.
            let cxy = _mm256_cmp_pd::<_CMP_LT_OQ>(tx, ty);
            let cxz = _mm256_cmp_pd::<_CMP_LT_OQ>(tx, tz);
            let cyz = _mm256_cmp_pd::<_CMP_LT_OQ>(ty, tz);
            let mx = _mm256_and_pd(cxy, cxz);
            let my = _mm256_andnot_pd(cxy, cyz);
            let mxy = _mm256_or_pd(mx, my);
            tx = _mm256_blendv_pd(tx, _mm256_add_pd(tx, dx), mx);
            ty = _mm256_blendv_pd(ty, _mm256_add_pd(ty, dy), my);
            tz = _mm256_blendv_pd(_mm256_add_pd(tz, dz), tz, mxy);
            let step = _mm256_castpd_si256(_mm256_blendv_pd(
                _mm256_blendv_pd(_mm256_castsi256_pd(sz), _mm256_castsi256_pd(sy), my),
                _mm256_castsi256_pd(sx),
                mx,
            ));
            idx = _mm256_add_epi64(idx, step);
            let dist = _mm256_min_pd(_mm256_min_pd(tx, ty), tz);
            let stop = _mm256_or_pd(
                _mm256_cmp_pd::<_CMP_GT_OQ>(dist, len),
                _mm256_castsi256_pd(_mm256_cmpeq_epi64(idx, end)),
            );
            let stop = _mm256_movemask_pd(stop) as u32;
            let mark = live & !stop;
            if mark & 1 != 0 {
                or_bit(bits, _mm256_extract_epi64::<0>(idx) as usize);
            }
            if mark & 2 != 0 {
                or_bit(bits, _mm256_extract_epi64::<1>(idx) as usize);
            }
            if mark & 4 != 0 {
                or_bit(bits, _mm256_extract_epi64::<2>(idx) as usize);
            }
            if mark & 8 != 0 {
                or_bit(bits, _mm256_extract_epi64::<3>(idx) as usize);
            }
            if stop != 0 {
                break stop;
            }
        };
        for (l, m) in lane_mask.iter().enumerate() {
            if stopped & (1 << l) == 0 {
                continue;
            }
            let x = match next() {
                Some(x) => {
                    set_bit(bits, x.idx as usize);
                    x
                }
                None => {
                    live &= !(1 << l);
                    Lane::IDLE
                }
            };
            let m = _mm256_castsi256_pd(*m);
            let f = |v: __m256d, x: f64| _mm256_blendv_pd(v, _mm256_set1_pd(x), m);
            let i = |v: __m256i, x: i64| {
                _mm256_castpd_si256(_mm256_blendv_pd(
                    _mm256_castsi256_pd(v),
                    _mm256_castsi256_pd(_mm256_set1_epi64x(x)),
                    m,
                ))
            };
            tx = f(tx, x.t[0]);
            ty = f(ty, x.t[1]);
            tz = f(tz, x.t[2]);
            dx = f(dx, x.dd[0]);
            dy = f(dy, x.dd[1]);
            dz = f(dz, x.dd[2]);
            len = f(len, x.len);
            sx = i(sx, x.ds[0]);
            sy = i(sy, x.ds[1]);
            sz = i(sz, x.ds[2]);
            end = i(end, x.end);
            idx = i(idx, x.idx);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::key::morton;
    use rand::{Rng, SeedableRng};

    /// Keys of the set bits of `bits` in `layout`, as sorted Morton codes.
    fn keys_of(bits: &[u64], layout: &Layout) -> Vec<u64> {
        let mut out = Vec::new();
        for (w, word) in bits.iter().enumerate() {
            let mut m = *word;
            while m != 0 {
                let j = (w << 6) | m.trailing_zeros() as usize;
                m &= m - 1;
                let k = [
                    (layout.lo[0] + (j % layout.row) as i32) as u16,
                    (layout.lo[1] + (j / layout.row % layout.dim[1]) as i32) as u16,
                    (layout.lo[2] + (j / layout.row / layout.dim[1]) as i32) as u16,
                ];
                out.push(morton(k));
            }
        }
        out.sort_unstable();
        out
    }

    /// Rays of every kind: random, axis-parallel components, through voxel
    /// corners and along faces (coordinates on the grid), very short.
    fn random_ray(rng: &mut rand_chacha::ChaCha8Rng, res: f32) -> ([f32; 3], [f32; 3]) {
        let grid =
            |rng: &mut rand_chacha::ChaCha8Rng, r: i32| rng.random_range(-r..=r) as f32 * res;
        let mut o = [0, 1, 2].map(|_| rng.random_range(-2.0f32..2.0));
        let mut e = [0, 1, 2].map(|_| rng.random_range(-8.0f32..8.0));
        match rng.random_range(0..6) {
            0 => {}
            1 => {
                let i = rng.random_range(0..3);
                e[i] = o[i]; // one axis-parallel component
            }
            2 => {
                let i = rng.random_range(0..3);
                e[i] = o[i];
                e[(i + 1) % 3] = o[(i + 1) % 3]; // along an axis
            }
            3 => {
                // corners: on the grid, diagonal steps
                o = [0, 1, 2].map(|_| grid(rng, 20));
                let n = rng.random_range(1..40) as f32 * res;
                let s = [0, 1, 2].map(|_| [-1.0f32, 0.0, 1.0][rng.random_range(0..3)]);
                e = [0, 1, 2].map(|i| o[i] + s[i] * n);
            }
            4 => {
                o = [0, 1, 2].map(|_| grid(rng, 20));
                e = [0, 1, 2].map(|_| grid(rng, 60));
            }
            _ => e = [0, 1, 2].map(|i| o[i] + rng.random_range(-0.15f32..0.15)),
        }
        (o, e)
    }

    /// The batched tracers (AVX2 and scalar) mark exactly the keys of
    /// OctoMap's `computeRayKeys`, ray by ray and for bundles from one origin.
    #[test]
    #[ignore = "slow: make test runs it"]
    fn batched_tracers_match_reference_ray_keys() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for &res in &[0.1f64, 0.05, 0.25] {
            let rf = 1.0 / res;
            for round in 0..300 {
                let n = if round % 3 == 0 { 1 } else { 40 };
                let (o, _) = random_ray(&mut rng, res as f32);
                let ends: Vec<[f32; 3]> = (0..n)
                    .map(|_| {
                        let (o2, e) = random_ray(&mut rng, res as f32);
                        // Same origin for the bundle: shift the end with it.
                        [0, 1, 2].map(|i| e[i] - o2[i] + o[i])
                    })
                    .collect();
                let ko = point_to_key(o, rf).unwrap();
                let mut reference = Vec::new();
                let (mut lo, mut hi) = (ko.map(i32::from), ko.map(i32::from));
                for e in &ends {
                    ray_keys(o, *e, res, rf, |k| reference.push(morton(k)));
                    let ke = point_to_key(*e, rf).unwrap();
                    for i in 0..3 {
                        lo[i] = lo[i].min(ke[i] as i32);
                        hi[i] = hi[i].max(ke[i] as i32);
                    }
                }
                reference.sort_unstable();
                reference.dedup();
                let layout =
                    Layout::new(lo.map(|v| v - LAYOUT_MARGIN), hi.map(|v| v + LAYOUT_MARGIN));
                let lanes: Vec<Lane> = ends
                    .iter()
                    .filter_map(|e| {
                        match Lane::prepare(o, ko, *e, point_to_key(*e, rf), res, &layout) {
                            PreparedRay::Lane(l) => Some(l),
                            PreparedRay::Empty => None,
                            PreparedRay::Slow => panic!("short ray {o:?} -> {e:?} taken as slow"),
                        }
                    })
                    .collect();
                let mut bits = vec![0u64; layout.words()];
                let mut it = lanes.iter().copied();
                trace_lanes_scalar(|| it.next(), &mut bits);
                assert_eq!(keys_of(&bits, &layout), reference, "scalar, origin {o:?}");
                #[cfg(target_arch = "x86_64")]
                if Isa::available().contains(&Isa::Avx2Fma) {
                    let mut bits = vec![0u64; layout.words()];
                    let mut it = lanes.iter().copied();
                    // SAFETY: AVX2 is available (`Isa::available` detected it).
                    unsafe { trace_lanes_avx2(|| it.next(), &mut bits) };
                    assert_eq!(keys_of(&bits, &layout), reference, "avx2, origin {o:?}");
                }
            }
        }
    }

    #[test]
    fn long_rays_and_rays_near_the_border_are_slow() {
        let (res, rf) = (0.1, 10.0);
        let o = [0.0f32; 3];
        let layout = Layout::new([32760; 3], [32800; 3]);
        // Across the tree's diagonal: more than 1e5 voxels long.
        let (o_far, far) = ([-3000.0f32; 3], [3000.0f32; 3]);
        let edge = [3.75f32, 0.0, 0.0]; // key 32805: beyond the margin
        let prep = |o: [f32; 3], e: [f32; 3], layout: &Layout| {
            let ko = point_to_key(o, rf).unwrap();
            Lane::prepare(o, ko, e, point_to_key(e, rf), res, layout)
        };
        let whole = Layout::new([0; 3], [65535; 3]);
        assert!(matches!(prep(o_far, far, &whole), PreparedRay::Slow));
        assert!(matches!(prep(o, edge, &layout), PreparedRay::Slow));
        assert!(matches!(
            prep(o, [0.01, 0.0, 0.0], &layout),
            PreparedRay::Empty
        ));
        assert!(matches!(
            prep(o, [1.0, 0.5, 0.2], &layout),
            PreparedRay::Lane(_)
        ));
    }
}
