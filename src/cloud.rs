//! Keyframes into 3-D points: backprojection with the LSD-SLAM viewer's filters,
//! and point clouds carried between frames by a Sim(3).
//!
//! A keyframe pixel `(x, y)` (column, row) with inverse depth `idepth > 0` is the
//! camera-frame point `p_cam = ((x − cx)/fx · d, (y − cy)/fy · d, d)` with
//! `d = 1/idepth` along z (not a ray length), exactly as the viewer draws it. The
//! point lands in the SLAM frame through the keyframe pose `T_slam_cam`, and in the
//! world frame through `T_world_slam · T_slam_cam`, composed once per keyframe so
//! that every pixel is mapped in one pass.
//!
//! The filters ([`PointFilter`]) are those of `lsd_slam_viewer` (`KeyFrameDisplay`)
//! with the thresholds in effect at run time. Output order is deterministic:
//! keyframes in the order given, pixels row-major within each keyframe.

use std::borrow::Borrow;
use std::mem::MaybeUninit;

use rayon::prelude::*;

use crate::buffer::{copy_advised, filled_advised};
use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::keyframe::Keyframe;
use crate::simd::Isa;

/// Image rows per parallel work item: small enough to balance a few keyframes
/// over many cores, large enough that the two rows a block converts beyond its
/// own (for the 3×3 test) and the per-block bookkeeping stay small.
const ROWS_PER_TASK: usize = 64;

/// Which pixels of a keyframe become points: the LSD-SLAM viewer's rules.
///
/// A pixel is kept when, in this order (as in the viewer):
/// 1. it is not on the image border (`skip_border`);
/// 2. its inverse depth is finite and `> 0`;
/// 3. the sparsify draw keeps it (`sparsify`, seeded by `seed`);
/// 4. `idepth_var · depth⁴ ≤ scaled_depth_var` (`depth = 1/idepth`, `f32` as in the viewer);
/// 5. `idepth_var · depth⁴ · s² ≤ abs_depth_var`, `s` the scale of the keyframe's
///    pose `T_slam_cam` (the viewer's `camToWorld.scale()`);
/// 6. when `min_near_support > 1`: at least that many pixels of its 3×3 block (itself
///    included, only pixels inside the image) have `idepth_n > 0` and
///    `(idepth_n − idepth)² < 2 · idepth_var` (the centre's variance).
///
/// A threshold of `+∞` turns its rule off. Rules 4–6 need a variance: a keyframe
/// without `idepth_var` skips them. Keyframes whose arrival index (position in the
/// input) is `≤ cut_first_keyframes` are dropped whole.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointFilter {
    /// Bound on `idepth_var · depth⁴` (the viewer's `scaledDepthVarTH`), SLAM units².
    pub scaled_depth_var: f32,
    /// Bound on `idepth_var · depth⁴ · s²` (the viewer's `absDepthVarTH`).
    pub abs_depth_var: f32,
    /// Minimum count of agreeing pixels in the 3×3 block; `0` or `1` turns the rule off.
    pub min_near_support: u32,
    /// Keep about one positive pixel in `sparsify` (`1` keeps all; must be `≥ 1`).
    /// The viewer draws with `rand()`; here the draw is a hash of
    /// `(seed, keyframe id, pixel index)`, so the same input gives the same points.
    pub sparsify: u32,
    /// The viewer's `cutFirstNKf`: keyframes with arrival index `i ≤ n` are dropped
    /// (`Some(5)` drops the first six); `None` keeps every keyframe.
    pub cut_first_keyframes: Option<usize>,
    /// Skip the one-pixel image border (the viewer always does).
    pub skip_border: bool,
    /// Seed of the sparsify draw.
    pub seed: u64,
}

impl Default for PointFilter {
    /// The viewer's run-time defaults: `scaledDepthVarTH = 1e-3`,
    /// `absDepthVarTH = 1e-1`, `minNearSupport = 7`, `sparsifyFactor = 1`,
    /// `cutFirstNKf = 5`, border skipped.
    fn default() -> Self {
        use crate::defaults as d;
        PointFilter {
            scaled_depth_var: d::SCALED_DEPTH_VAR as f32,
            abs_depth_var: d::ABS_DEPTH_VAR as f32,
            min_near_support: d::MIN_NEAR_SUPPORT,
            sparsify: d::SPARSIFY,
            cut_first_keyframes: Some(d::CUT_FIRST_KEYFRAMES),
            skip_border: true,
            seed: 0,
        }
    }
}

impl PointFilter {
    /// Every rule off: keeps every pixel with a finite inverse depth `> 0`.
    pub fn none() -> Self {
        PointFilter {
            scaled_depth_var: f32::INFINITY,
            abs_depth_var: f32::INFINITY,
            min_near_support: 0,
            sparsify: 1,
            cut_first_keyframes: None,
            skip_border: false,
            seed: 0,
        }
    }

    /// Checks the parameters: thresholds not NaN and `≥ 0`, `sparsify ≥ 1`.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("scaled_depth_var", self.scaled_depth_var),
            ("abs_depth_var", self.abs_depth_var),
        ] {
            if v.is_nan() || v < 0.0 {
                return Err(Error::invalid(name, format!("must be >= 0, got {v}")));
            }
        }
        if self.sparsify == 0 {
            return Err(Error::invalid("sparsify", "must be >= 1, got 0"));
        }
        Ok(())
    }

    /// True when the keyframe at arrival index `index` is dropped whole.
    pub fn cuts(&self, index: usize) -> bool {
        self.cut_first_keyframes.is_some_and(|n| index <= n)
    }
}

/// A point cloud: `N` points (row-major `(N, 3)` `f32`), optional colours and the
/// id of the keyframe each point came from.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PointCloud {
    /// Coordinates, `N × 3` row-major, in the frame the producer states.
    pub points: Vec<f32>,
    /// Colours, `N × 3` bytes in the order of the source (RGB for PLY).
    pub colors: Option<Vec<u8>>,
    /// Source keyframe id of each point (`N` values; `-1` when unknown).
    pub keyframe_ids: Vec<i32>,
}

impl PointCloud {
    /// Every `stride`-th point (from the first) as `f64` vectors.
    pub fn points_every(&self, stride: usize) -> impl Iterator<Item = nalgebra::Vector3<f64>> + '_ {
        self.points
            .chunks_exact(3)
            .step_by(stride.max(1))
            .map(|p| nalgebra::Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64))
    }

    /// Builds a cloud, checking the lengths; `keyframe_ids = None` gives `-1` for all.
    pub fn try_new(
        points: Vec<f32>,
        colors: Option<Vec<u8>>,
        keyframe_ids: Option<Vec<i32>>,
    ) -> Result<Self> {
        if points.len() % 3 != 0 {
            return Err(Error::ShapeMismatch {
                what: "points".into(),
                expected: "(N, 3)".into(),
                got: format!("{} values", points.len()),
            });
        }
        let n = points.len() / 3;
        if let Some(c) = &colors {
            if c.len() != 3 * n {
                return Err(Error::ShapeMismatch {
                    what: "colors".into(),
                    expected: format!("({n}, 3)"),
                    got: format!("{} values", c.len()),
                });
            }
        }
        let keyframe_ids = match keyframe_ids {
            Some(ids) if ids.len() != n => {
                return Err(Error::ShapeMismatch {
                    what: "keyframe_ids".into(),
                    expected: format!("({n},)"),
                    got: format!("({},)", ids.len()),
                })
            }
            Some(ids) => ids,
            None => vec![-1; n],
        };
        Ok(PointCloud {
            points,
            colors,
            keyframe_ids,
        })
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len() / 3
    }

    /// True when the cloud has no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The cloud carried by `t` (`T_b_a` for a cloud in frame a gives it in frame b),
    /// in parallel; colours and keyframe ids are copied unchanged.
    pub fn transformed(&self, t: &Sim3) -> Result<PointCloud> {
        Ok(PointCloud {
            points: t.transform_points(&self.points)?,
            colors: self.colors.as_deref().map(copy_advised),
            keyframe_ids: copy_advised(&self.keyframe_ids),
        })
    }

    /// Removes the points with a coordinate that is not finite (colours and
    /// ids kept in step) and says how many there were and whose. One
    /// parallel scan when every point is finite.
    pub fn drop_non_finite(&mut self) -> NonFinite {
        let bad = |p: &[f32]| !(p[0].is_finite() && p[1].is_finite() && p[2].is_finite());
        let any = self
            .points
            .par_chunks(3 * 4096)
            .any(|block| block.chunks_exact(3).any(bad));
        if !any {
            return NonFinite::default();
        }
        let mut out = NonFinite::default();
        let mut keep = 0;
        let n = self.len();
        for i in 0..n {
            if bad(&self.points[3 * i..3 * i + 3]) {
                out.points += 1;
                let id = self.keyframe_ids[i];
                if out.keyframes.last() != Some(&id) && !out.keyframes.contains(&id) {
                    out.keyframes.push(id);
                }
                continue;
            }
            if keep != i {
                self.points.copy_within(3 * i..3 * i + 3, 3 * keep);
                if let Some(c) = &mut self.colors {
                    c.copy_within(3 * i..3 * i + 3, 3 * keep);
                }
                self.keyframe_ids[keep] = self.keyframe_ids[i];
            }
            keep += 1;
        }
        self.points.truncate(3 * keep);
        if let Some(c) = &mut self.colors {
            c.truncate(3 * keep);
        }
        self.keyframe_ids.truncate(keep);
        out
    }

    /// Carries the cloud by `t` in place (see [`PointCloud::transformed`]).
    pub fn transform_in_place(&mut self, t: &Sim3) -> Result<()> {
        t.transform_points_in_place(&mut self.points)
    }
}

/// SplitMix64 finaliser (Steele, Lea & Flood 2014): a well-mixed 64-bit hash.
#[inline(always)]
fn splitmix64(z: u64) -> u64 {
    let mut z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The sparsify draw: keeps pixel `pixel` (index `x + y·W`) of keyframe `id` when
/// `splitmix64(((id as u32) << 32 ^ pixel) ^ seed) mod factor == 0`.
#[inline]
pub fn sparsify_keeps(seed: u64, id: i32, pixel: usize, factor: u32) -> bool {
    let key = ((id as u32 as u64) << 32) ^ pixel as u64;
    splitmix64(key ^ seed) % factor as u64 == 0
}

/// One keyframe prepared for the pixel loop: its image and `T_world_cam`
/// (`T_world_slam · T_slam_cam`) as an affine map.
struct PreparedKeyframe<'a> {
    kf: &'a Keyframe,
    /// `s·R` of `T_world_cam`, row-major.
    m: [[f64; 3]; 3],
    /// Translation of `T_world_cam`.
    t: [f64; 3],
    /// The keyframe pose's scale as `f32` (the viewer's `camToWorld.scale()`).
    pose_scale: f32,
    /// `u · m[k][0]` (`k` = 0, 1, 2) for every column `x`, `u = (x − cx)/fx`.
    um: Vec<[f64; 3]>,
}

impl<'a> PreparedKeyframe<'a> {
    fn new(kf: &'a Keyframe, world_cam: Sim3) -> Self {
        let (m, t) = world_cam.affine();
        let cam = &kf.camera;
        let um = (0..cam.width as usize)
            .map(|x| {
                let u = (x as f64 - cam.cx) / cam.fx;
                [u * m[0][0], u * m[1][0], u * m[2][0]]
            })
            .collect();
        PreparedKeyframe {
            kf,
            m,
            t,
            pose_scale: kf.pose.scale as f32,
            um,
        }
    }
}

/// The kept pixels of one work item: rows `y0..y0 + rows` of one keyframe.
struct Kept {
    /// Index of the keyframe in the prepared list.
    k: usize,
    /// First row.
    y0: usize,
    /// Number of rows.
    rows: usize,
    /// Kept columns, row after row, each row left to right.
    xs: Vec<u32>,
    /// End of each row's columns in `xs`.
    row_ends: [usize; ROWS_PER_TASK],
}

/// Per-thread buffers of the filter pass, reused from row to row and block to block.
#[derive(Default)]
struct Scratch {
    /// Verdict per interior pixel (`0`/`1`), padded with zeros to whole groups of eight.
    mask: Vec<u8>,
    /// Rows of inverse depth not `> 0` made NaN, for the support test.
    ring: PositiveRows,
    /// The kept columns of the block being filtered; its capacity carries over to
    /// the next block, and each block keeps an exact-size copy.
    cols: Vec<u32>,
    /// The kept columns of one row's interior, with room for a whole group of eight past them.
    row_cols: Vec<u32>,
}

/// Ring of three rows of inverse depth with every value that is not `> 0`
/// replaced by NaN (see [`positive_or_nan`]): row `y` lives in slot `y % 3`, so
/// that each row is converted once for the three rows whose blocks read it.
#[derive(Default)]
struct PositiveRows {
    rows: [Vec<f32>; 3],
    /// `(keyframe index, row)` held by each slot.
    held: [Option<(usize, usize)>; 3],
}

impl PositiveRows {
    /// Makes the ring hold rows `y − 1`, `y`, `y + 1` of keyframe `k` and returns them.
    #[inline(always)]
    fn around(&mut self, k: usize, idepth: &[f32], w: usize, y: usize) -> [&[f32]; 3] {
        for r in y - 1..=y + 1 {
            let slot = r % 3;
            if self.held[slot] != Some((k, r)) {
                positive_or_nan(&idepth[r * w..(r + 1) * w], &mut self.rows[slot]);
                self.held[slot] = Some((k, r));
            }
        }
        let [a, b, c] = &self.rows;
        let slot = |r: usize| match r % 3 {
            0 => a.as_slice(),
            1 => b.as_slice(),
            _ => c.as_slice(),
        };
        [slot(y - 1), slot(y), slot(y + 1)]
    }
}

/// `row` with every value that is not `> 0` (zero, negative, NaN) replaced by NaN,
/// into `out`. A neighbour `n` agrees with a centre when `n > 0` and
/// `(n − id)² < 2·var`; with NaN in place of the others, `(q − id)² < 2·var` alone
/// gives the same answer (NaN compares false), one test less per neighbour.
#[inline(always)]
fn positive_or_nan(row: &[f32], out: &mut Vec<f32>) {
    out.clear();
    out.extend(row.iter().map(|&n| if n > 0.0 { n } else { f32::NAN }));
}

/// Backprojects `keyframes` through `filter`. With `transform = Some(T_world_slam)`
/// the points are in the world frame (`T_world_slam · T_slam_cam · p_cam`, composed
/// once per keyframe); without it they are in the SLAM frame.
///
/// Parallel over keyframes and blocks of rows; the output is in keyframe order,
/// then row-major. Colours are returned when every keyframe has colour.
///
/// Points that are not finite (an inverse depth so small, `1e-40`, that its
/// depth overflows `f32`) are dropped; [`backproject_counted`] says how many.
pub fn backproject<K: Borrow<Keyframe> + Sync>(
    keyframes: &[K],
    filter: &PointFilter,
    transform: Option<&Sim3>,
) -> Result<PointCloud> {
    backproject_counted(keyframes, filter, transform).map(|r| r.0)
}

/// [`backproject`], with the non-finite points it dropped.
pub fn backproject_counted<K: Borrow<Keyframe> + Sync>(
    keyframes: &[K],
    filter: &PointFilter,
    transform: Option<&Sim3>,
) -> Result<(PointCloud, NonFinite)> {
    let t = transform.copied().unwrap_or_else(Sim3::identity);
    let mut cloud = backproject_with(keyframes, 0, filter, |_| t, None, Isa::detect())?;
    let dropped = cloud.drop_non_finite();
    Ok((cloud, dropped))
}

/// Like [`backproject`], with its own `T_world_slam` for each keyframe
/// (`transforms[i]` carries `keyframes[i]`), for drift-aware alignments.
pub fn backproject_per_keyframe<K: Borrow<Keyframe> + Sync>(
    keyframes: &[K],
    filter: &PointFilter,
    transforms: &[Sim3],
) -> Result<PointCloud> {
    backproject_per_keyframe_counted(keyframes, filter, transforms).map(|r| r.0)
}

/// [`backproject_per_keyframe`], with the non-finite points it dropped.
pub fn backproject_per_keyframe_counted<K: Borrow<Keyframe> + Sync>(
    keyframes: &[K],
    filter: &PointFilter,
    transforms: &[Sim3],
) -> Result<(PointCloud, NonFinite)> {
    if transforms.len() != keyframes.len() {
        return Err(Error::ShapeMismatch {
            what: "transforms".into(),
            expected: format!("one per keyframe ({})", keyframes.len()),
            got: format!("{}", transforms.len()),
        });
    }
    let mut cloud = backproject_with(keyframes, 0, filter, |i| transforms[i], None, Isa::detect())?;
    let dropped = cloud.drop_non_finite();
    Ok((cloud, dropped))
}

/// One batch of a stream of keyframes, as [`backproject_per_keyframe_counted`]
/// gives its share of the whole: `keyframes` are those at arrival indices
/// `first..` (what [`PointFilter::cuts`] counts), `world_slam(i)` is
/// `T_world_slam` of `keyframes[i]`, and `with_color` says whether every
/// keyframe of the whole stream has colour. The batches' clouds, appended in
/// order, are the cloud of the whole (the filter is per keyframe).
pub(crate) fn backproject_batch_counted<K: Borrow<Keyframe> + Sync>(
    keyframes: &[K],
    first: usize,
    filter: &PointFilter,
    world_slam: impl Fn(usize) -> Sim3,
    with_color: bool,
) -> Result<(PointCloud, NonFinite)> {
    let mut cloud = backproject_with(
        keyframes,
        first,
        filter,
        world_slam,
        Some(with_color),
        Isa::detect(),
    )?;
    let dropped = cloud.drop_non_finite();
    Ok((cloud, dropped))
}

impl NonFinite {
    /// Adds the points another batch dropped (its keyframes follow these).
    pub(crate) fn extend(&mut self, other: NonFinite) {
        self.points += other.points;
        for id in other.keyframes {
            if !self.keyframes.contains(&id) {
                self.keyframes.push(id);
            }
        }
    }
}

/// Points a backprojection dropped because a coordinate was not finite.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct NonFinite {
    /// How many.
    pub points: usize,
    /// The keyframes they came from, each once, in cloud order.
    pub keyframes: Vec<i32>,
}

/// Two parallel passes: the filter lists the kept columns of each block of rows,
/// then, with every block's offset known, the points, colours and ids are written
/// straight into the output buffers.
///
/// `first` is the arrival index of `keyframes[0]` (a batch of a longer
/// stream); `with_color` (default: every keyframe has colour) whether the
/// points carry colours.
fn backproject_with<K: Borrow<Keyframe> + Sync>(
    keyframes: &[K],
    first: usize,
    filter: &PointFilter,
    world_slam: impl Fn(usize) -> Sim3,
    with_color: Option<bool>,
    kernel: Isa,
) -> Result<PointCloud> {
    filter.validate()?;
    let with_color = with_color.unwrap_or_else(|| {
        !keyframes.is_empty() && keyframes.iter().all(|k| k.borrow().color.is_some())
    });
    let mut prepared = Vec::new();
    for (i, k) in keyframes.iter().enumerate() {
        let kf = k.borrow();
        check_keyframe(kf)?;
        if with_color && kf.color.is_none() {
            return Err(Error::invalid(
                "keyframes",
                format!("keyframe {} has no colour where the others have", kf.id),
            ));
        }
        if filter.cuts(first + i) {
            continue;
        }
        prepared.push(PreparedKeyframe::new(kf, world_slam(i) * kf.pose));
    }
    let tasks: Vec<(usize, usize)> = prepared
        .iter()
        .enumerate()
        .flat_map(|(k, p)| {
            let h = p.kf.camera.height as usize;
            (0..h.div_ceil(ROWS_PER_TASK)).map(move |b| (k, b * ROWS_PER_TASK))
        })
        .collect();
    let kept: Vec<Kept> = tasks
        .par_iter()
        .map_init(Scratch::default, |scratch, &(k, y0)| {
            let p = &prepared[k];
            let y1 = (y0 + ROWS_PER_TASK).min(p.kf.camera.height as usize);
            let ctx = RowCtx {
                p,
                k,
                f: filter,
                scaled_on: filter.scaled_depth_var.is_finite(),
                abs_on: filter.abs_depth_var.is_finite(),
                support_on: filter.min_near_support > 1,
                kernel,
            };
            let mut xs = std::mem::take(&mut scratch.cols);
            xs.clear();
            let mut row_ends = [0; ROWS_PER_TASK];
            for (y, end) in (y0..y1).zip(&mut row_ends) {
                kept_row(&ctx, y, scratch, &mut xs);
                *end = xs.len();
            }
            let kept = Kept {
                k,
                y0,
                rows: y1 - y0,
                xs: xs.clone(),
                row_ends,
            };
            scratch.cols = xs;
            kept
        })
        .collect();
    Ok(write_points(&prepared, &kept, with_color))
}

/// Keyframe arrays must match the camera (a `Keyframe` built by `try_new` does).
fn check_keyframe(kf: &Keyframe) -> Result<()> {
    let n = kf.camera.width as usize * kf.camera.height as usize;
    let var_ok = kf.idepth_var.as_ref().is_none_or(|v| v.len() == n);
    let col_ok = kf.color.as_ref().is_none_or(|c| c.len() == 3 * n);
    if kf.idepth.len() != n || !var_ok || !col_ok {
        return Err(Error::ShapeMismatch {
            what: format!("keyframe {} arrays", kf.id),
            expected: format!("{}x{} pixels", kf.camera.height, kf.camera.width),
            got: format!("{} inverse depths", kf.idepth.len()),
        });
    }
    Ok(())
}

/// `value ≤ threshold`, false for NaN (a NaN variance fails the test).
#[inline(always)]
fn within(value: f32, threshold: f32) -> bool {
    value <= threshold
}

/// Loop-invariant parts of the filter, per keyframe.
struct RowCtx<'a> {
    p: &'a PreparedKeyframe<'a>,
    /// Index of the keyframe in the prepared list.
    k: usize,
    f: &'a PointFilter,
    scaled_on: bool,
    abs_on: bool,
    support_on: bool,
    kernel: Isa,
}

/// The filter for one image row: appends the kept columns to `xs`, left to right.
/// Interior pixels of interior rows of keyframes with a variance take the
/// branch-free mask path ([`interior_mask`]); the others the scalar path.
fn kept_row(c: &RowCtx<'_>, y: usize, scratch: &mut Scratch, xs: &mut Vec<u32>) {
    let (kf, f) = (c.p.kf, c.f);
    let (w, h) = (kf.camera.width as usize, kf.camera.height as usize);
    let (x0, x1) = if f.skip_border {
        if y == 0 || y + 1 >= h || w < 3 {
            return;
        }
        (1, w - 1)
    } else {
        (0, w)
    };
    let Some(var) = kf.idepth_var.as_deref() else {
        scalar_pixels(c, y, x0..x1, xs);
        return;
    };
    if y == 0 || y + 1 >= h || w < 3 {
        scalar_pixels(c, y, x0..x1, xs);
        return;
    }
    if x0 == 0 {
        scalar_pixels(c, y, 0..1, xs);
    }
    let n = w - 2;
    interior_mask(c, var, y, scratch);
    let mask = &mut scratch.mask;
    if f.sparsify > 1 {
        for (j, m) in mask[..n].iter_mut().enumerate() {
            *m &= sparsify_keeps(f.seed, kf.id, j + 1 + y * w, f.sparsify) as u8;
        }
    }
    // Compaction eight pixels at a time without branches: the kept columns of each
    // group come from a table indexed by its verdict bits, written whole; the
    // next group's start moves on by their count.
    let cols = &mut scratch.row_cols;
    cols.resize(mask.len() + 8, 0);
    let mut kept = 0;
    for (g, eight) in mask.chunks_exact(8).enumerate() {
        let bits = pack_bits(eight) as usize;
        // Column of bit `b`: `1 + 8·g + b` (a column of the image: fits a `u32`).
        let base = 1 + 8 * g as u32;
        if let Some(dst) = cols.get_mut(kept..kept + 8) {
            for (d, &b) in dst.iter_mut().zip(&SET_BITS[bits]) {
                *d = base + b as u32;
            }
        }
        kept += SET_BIT_COUNT[bits] as usize;
    }
    xs.extend_from_slice(&cols[..kept]);
    if x1 == w {
        scalar_pixels(c, y, w - 1..w, xs);
    }
}

/// For each byte value, the positions of its set bits in increasing order (the
/// remaining entries `0`).
static SET_BITS: [[u8; 8]; 256] = {
    let mut t = [[0u8; 8]; 256];
    let mut v = 0;
    while v < 256 {
        let (mut b, mut k) = (0, 0);
        while b < 8 {
            if (v >> b) & 1 == 1 {
                t[v][k] = b as u8;
                k += 1;
            }
            b += 1;
        }
        v += 1;
    }
    t
};

/// For each byte value, its number of set bits.
static SET_BIT_COUNT: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut v = 0;
    while v < 256 {
        t[v] = (v as u32).count_ones() as u8;
        v += 1;
    }
    t
};

/// Eight `0`/`1` bytes as the low eight bits of a word (byte `i` to bit `i`): the
/// product places each byte's bit at `56 + i` with no two partial products
/// overlapping, so no carries.
#[inline(always)]
fn pack_bits(eight: &[u8]) -> u64 {
    let mut b = [0u8; 8];
    b.copy_from_slice(eight);
    u64::from_le_bytes(b).wrapping_mul(0x0102_0408_1020_4080) >> 56
}

/// [`interior_mask_portable`] with the kernel `c.kernel`.
fn interior_mask(c: &RowCtx<'_>, var: &[f32], y: usize, scratch: &mut Scratch) {
    match c.kernel {
        // SAFETY: `Isa::Avx2Fma` is only detected on a CPU with AVX2 (and FMA).
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2Fma => unsafe { interior_mask_avx2(c, var, y, scratch) },
        _ => interior_mask_portable(c, var, y, scratch),
    }
}

/// [`interior_mask_portable`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn interior_mask_avx2(c: &RowCtx<'_>, var: &[f32], y: usize, scratch: &mut Scratch) {
    interior_mask_portable(c, var, y, scratch)
}

/// The rules for pixels `1..w-1` of row `y` (which has a row above and below),
/// without branches on the data so that the loop vectorises: `scratch.mask[j]`
/// is `1` when pixel `x = j + 1` is kept, before the sparsify draw (`0` from
/// `w − 2` to the next multiple of 8). The arithmetic is that of [`scalar_pixels`].
#[inline(always)]
fn interior_mask_portable(c: &RowCtx<'_>, var: &[f32], y: usize, scratch: &mut Scratch) {
    let kf = c.p.kf;
    let w = kf.camera.width as usize;
    let n = w - 2;
    let [above, centre, below] = scratch.ring.around(c.k, &kf.idepth, w, y);
    let (a0, a1, a2) = (&above[..n], &above[1..n + 1], &above[2..n + 2]);
    let (b0, b1, b2) = (&centre[..n], &centre[1..n + 1], &centre[2..n + 2]);
    let (c0, c1, c2) = (&below[..n], &below[1..n + 1], &below[2..n + 2]);
    let vv = &var[y * w + 1..y * w + 1 + n];
    let mask = &mut scratch.mask;
    mask.clear();
    mask.resize(n.next_multiple_of(8), 0);
    let mask = &mut mask[..n];
    let (th_s, th_a, s) = (c.f.scaled_depth_var, c.f.abs_depth_var, c.p.pose_scale);
    let (scaled_off, abs_off) = (!c.scaled_on, !c.abs_on);
    let min_support = if c.support_on {
        c.f.min_near_support
    } else {
        0
    };
    for j in 0..n {
        // The centre's inverse depth, NaN unless `> 0`: `≤ f32::MAX` is "finite and > 0".
        let id = b1[j];
        let v = vv[j];
        let depth = 1.0f32 / id;
        let d2 = depth * depth;
        let e = v * (d2 * d2);
        let mut ok = id <= f32::MAX;
        ok &= within(e, th_s) | scaled_off;
        ok &= within(e * s * s, th_a) | abs_off;
        let two_var = 2.0 * v;
        // Neighbours not `> 0` are NaN here and never agree.
        let agree = |n: f32| {
            let diff = n - id;
            (diff * diff < two_var) as u32
        };
        // The centre agrees with itself when `0 < 2·var` (its own `> 0` is in `ok`).
        let support = agree(a0[j])
            + agree(a1[j])
            + agree(a2[j])
            + agree(b0[j])
            + (0.0 < two_var) as u32
            + agree(b2[j])
            + agree(c0[j])
            + agree(c1[j])
            + agree(c2[j]);
        mask[j] = (ok & (support >= min_support)) as u8;
    }
}

/// The viewer's rules, pixel by pixel, for pixels `xs` of row `y` (any position,
/// with or without a variance): appends the kept columns to `out`.
fn scalar_pixels(c: &RowCtx<'_>, y: usize, xs: std::ops::Range<usize>, out: &mut Vec<u32>) {
    let (kf, f) = (c.p.kf, c.f);
    let (w, h) = (kf.camera.width as usize, kf.camera.height as usize);
    let idepth = &kf.idepth;
    let var = kf.idepth_var.as_deref();
    let s = c.p.pose_scale;
    // The rows of the 3×3 block that lie inside the image.
    let rows: [Option<&[f32]>; 3] = [
        y.checked_sub(1).map(|r| &idepth[r * w..(r + 1) * w]),
        Some(&idepth[y * w..(y + 1) * w]),
        (y + 1 < h).then(|| &idepth[(y + 1) * w..(y + 2) * w]),
    ];
    for x in xs {
        let i = x + y * w;
        let id = idepth[i];
        if !(id > 0.0 && id.is_finite()) {
            continue;
        }
        if f.sparsify > 1 && !sparsify_keeps(f.seed, kf.id, i, f.sparsify) {
            continue;
        }
        if let Some(var) = var {
            let vi = var[i];
            let depth = 1.0f32 / id;
            let d2 = depth * depth;
            let d4 = d2 * d2;
            if c.scaled_on && !within(vi * d4, f.scaled_depth_var) {
                continue;
            }
            if c.abs_on && !within(vi * d4 * s * s, f.abs_depth_var) {
                continue;
            }
            if c.support_on {
                let (xlo, xhi) = (x.saturating_sub(1), (x + 1).min(w - 1));
                let support: u32 = rows
                    .iter()
                    .flatten()
                    .map(|r| near_support(&r[xlo..=xhi], id, 2.0 * vi))
                    .sum();
                if support < f.min_near_support {
                    continue;
                }
            }
        }
        // The column index of an image whose pixel count fits memory fits a `u32`
        // (`Keyframe` widths are `u32`).
        out.push(x as u32);
    }
}

/// Pixels of `block` (one row of the 3×3 neighbourhood) with a positive inverse
/// depth within `sqrt(two_var)` of `id`; branch-free.
#[inline(always)]
fn near_support(block: &[f32], id: f32, two_var: f32) -> u32 {
    block
        .iter()
        .map(|&n| {
            let diff = n - id;
            ((n > 0.0) & (diff * diff < two_var)) as u32
        })
        .sum()
}

/// Allocates the outputs at their final size and fills them in parallel, each
/// block of rows at its offset: point `T_world_cam · ((x − cx)/fx · d, (y − cy)/fy · d, d)`,
/// `d = 1/idepth`, computed in `f64` as `d · (u·m₀ + v·m₁ + m₂) + t`.
fn write_points(prepared: &[PreparedKeyframe<'_>], kept: &[Kept], with_color: bool) -> PointCloud {
    let total: usize = kept.iter().map(|b| b.xs.len()).sum();
    // Every element is written once by `fill_all` (fresh buffers, no zero-fill pass).
    let (mut colors, mut ids) = (Vec::new(), Vec::new());
    // SAFETY: `fill_all` writes every element of the three buffers (`3·N`
    // points, `3·N` colours or none, `N` ids), see its doc.
    let points = unsafe {
        filled_advised(3 * total, |pts| {
            colors = filled_advised(if with_color { 3 * total } else { 0 }, |cols| {
                ids = filled_advised(total, |ids| fill_all(prepared, kept, pts, cols, ids));
            });
        })
    };
    PointCloud {
        points,
        colors: with_color.then_some(colors),
        keyframe_ids: ids,
    }
}

/// Splits the outputs at each block's offset and fills the blocks in parallel:
/// every element of `pts` (`3·N`), `cols` (`3·N`, or empty without colour) and
/// `ids` (`N`) is written.
fn fill_all(
    prepared: &[PreparedKeyframe<'_>],
    kept: &[Kept],
    pts: &mut [MaybeUninit<f32>],
    cols: &mut [MaybeUninit<u8>],
    ids: &mut [MaybeUninit<i32>],
) {
    let with_color = !cols.is_empty();
    let mut jobs = Vec::with_capacity(kept.len());
    let (mut pr, mut cr, mut ir) = (pts, cols, ids);
    for b in kept {
        let n = b.xs.len();
        let (p, p_rest) = pr.split_at_mut(3 * n);
        let (c, c_rest) = cr.split_at_mut(if with_color { 3 * n } else { 0 });
        let (i, i_rest) = ir.split_at_mut(n);
        jobs.push((b, p, c, i));
        (pr, cr, ir) = (p_rest, c_rest, i_rest);
    }
    jobs.into_par_iter().for_each(|(b, pts, cols, ids)| {
        let p = &prepared[b.k];
        fill_block(p, b, pts, cols);
        for i in ids {
            i.write(p.kf.id);
        }
    });
}

/// The points (and, when `cols` is not empty, colours) of one block's kept pixels.
fn fill_block(
    p: &PreparedKeyframe<'_>,
    b: &Kept,
    pts: &mut [MaybeUninit<f32>],
    cols: &mut [MaybeUninit<u8>],
) {
    let kf = p.kf;
    let cam = &kf.camera;
    let w = cam.width as usize;
    let (m, t) = (&p.m, &p.t);
    // The point of column `x` of a row with `vm = v·m[k][1]`, `v = (y − cy)/fy`.
    let point = |row: &[f32], vm: &[f64; 3], x: usize| {
        let d = 1.0 / row[x] as f64;
        let um = &p.um[x];
        [0, 1, 2].map(|k| MaybeUninit::new((d * (um[k] + vm[k] + m[k][2]) + t[k]) as f32))
    };
    let mut start = 0;
    for (r, &end) in b.row_ends[..b.rows].iter().enumerate() {
        let y = b.y0 + r;
        let xs = &b.xs[start..end];
        let row = &kf.idepth[y * w..(y + 1) * w];
        let v = (y as f64 - cam.cy) / cam.fy;
        let vm = [v * m[0][1], v * m[1][1], v * m[2][1]];
        let out = pts[3 * start..3 * end].chunks_exact_mut(3);
        match (&kf.color, cols.is_empty()) {
            (Some(col), false) => {
                let src = &col[3 * y * w..3 * (y + 1) * w];
                let out_c = cols[3 * start..3 * end].chunks_exact_mut(3);
                for ((&x, q), c) in xs.iter().zip(out).zip(out_c) {
                    let x = x as usize;
                    q.copy_from_slice(&point(row, &vm, x));
                    let rgb = &src[3 * x..3 * x + 3];
                    c.copy_from_slice(&[rgb[0], rgb[1], rgb[2]].map(MaybeUninit::new));
                }
            }
            _ => {
                for (&x, q) in xs.iter().zip(out) {
                    q.copy_from_slice(&point(row, &vm, x as usize));
                }
            }
        }
        start = end;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::PinholeCamera;
    use nalgebra::Vector3;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn keyframe(id: i32, w: u32, h: u32, idepth: Vec<f32>, var: Option<Vec<f32>>) -> Keyframe {
        let cam =
            PinholeCamera::try_new(100.0, 120.0, w as f64 / 2.0, h as f64 / 2.0, w, h).unwrap();
        Keyframe::try_new(id, id as f64, Sim3::identity(), cam, idepth, var, None).unwrap()
    }

    #[test]
    fn none_keeps_every_positive_pixel_at_its_pinhole_point() {
        let (w, h) = (5u32, 4u32);
        let idepth: Vec<f32> = (0..20)
            .map(|i| if i % 3 == 0 { 0.0 } else { 0.5 })
            .collect();
        let kf = keyframe(3, w, h, idepth.clone(), None);
        let cloud = backproject(std::slice::from_ref(&kf), &PointFilter::none(), None).unwrap();
        let expected = idepth.iter().filter(|&&v| v > 0.0).count();
        assert_eq!(cloud.len(), expected);
        assert!(cloud.keyframe_ids.iter().all(|&i| i == 3));
        // Pixel (1, 0) is the first kept: depth 2 along z.
        let p = kf.camera.backproject(1.0, 0.0, 2.0);
        for (got, want) in cloud.points.iter().zip(p) {
            assert!((*got as f64 - want).abs() < 1e-6);
        }
    }

    /// The viewer's rules pixel by pixel, written from the documentation of
    /// [`PointFilter`] with no shared code: the 3×3 block read cell by cell, the
    /// point as `T_world_cam · ((x − cx)/fx · d, (y − cy)/fy · d, d)` in `f64`.
    fn reference(kfs: &[Keyframe], f: &PointFilter, world_slam: &Sim3) -> PointCloud {
        let with_color = !kfs.is_empty() && kfs.iter().all(|k| k.color.is_some());
        let (mut points, mut colors, mut ids) = (Vec::new(), Vec::new(), Vec::new());
        for (index, kf) in kfs.iter().enumerate() {
            if f.cut_first_keyframes.is_some_and(|n| index <= n) {
                continue;
            }
            let (m, t) = (*world_slam * kf.pose).affine();
            let cam = &kf.camera;
            let (w, h) = (cam.width as i64, cam.height as i64);
            let b = f.skip_border as i64;
            let s = kf.pose.scale as f32;
            let at = |x: i64, y: i64| (x + y * w) as usize;
            for y in b..h - b {
                for x in b..w - b {
                    let id = kf.idepth[at(x, y)];
                    if !(id > 0.0 && id.is_finite()) {
                        continue;
                    }
                    if f.sparsify > 1 && !sparsify_keeps(f.seed, kf.id, at(x, y), f.sparsify) {
                        continue;
                    }
                    if let Some(var) = &kf.idepth_var {
                        let v = var[at(x, y)];
                        let depth = 1.0f32 / id;
                        let d4 = (depth * depth) * (depth * depth);
                        // A threshold of +inf is off; a NaN value fails a finite one.
                        let passes = |e: f32, th: f32| th == f32::INFINITY || e <= th;
                        if !passes(v * d4, f.scaled_depth_var)
                            || !passes(v * d4 * s * s, f.abs_depth_var)
                        {
                            continue;
                        }
                        if f.min_near_support > 1 {
                            let mut support = 0;
                            for ny in y - 1..=y + 1 {
                                for nx in x - 1..=x + 1 {
                                    if nx < 0 || ny < 0 || nx >= w || ny >= h {
                                        continue;
                                    }
                                    let n = kf.idepth[at(nx, ny)];
                                    let diff = n - id;
                                    if n > 0.0 && diff * diff < 2.0 * v {
                                        support += 1;
                                    }
                                }
                            }
                            if support < f.min_near_support {
                                continue;
                            }
                        }
                    }
                    let d = 1.0 / id as f64;
                    let u = (x as f64 - cam.cx) / cam.fx;
                    let v = (y as f64 - cam.cy) / cam.fy;
                    for k in 0..3 {
                        points.push((d * (u * m[k][0] + v * m[k][1] + m[k][2]) + t[k]) as f32);
                    }
                    if let (true, Some(c)) = (with_color, &kf.color) {
                        colors.extend_from_slice(&c[3 * at(x, y)..3 * at(x, y) + 3]);
                    }
                    ids.push(kf.id);
                }
            }
        }
        PointCloud {
            points,
            colors: with_color.then_some(colors),
            keyframe_ids: ids,
        }
    }

    /// A keyframe of inverse depths near `1` (so that neighbours often agree),
    /// sprinkled with the values the rules must reject or survive: NaN, ±∞,
    /// negative, zero, tiny and huge inverse depths, and NaN, zero, infinite and
    /// negative variances.
    fn random_keyframe(
        rng: &mut ChaCha8Rng,
        id: i32,
        w: u32,
        h: u32,
        var: bool,
        color: bool,
    ) -> Keyframe {
        let n = (w * h) as usize;
        let base = rng.random_range(0.3..3.0f32);
        let idepth = (0..n)
            .map(|_| match rng.random_range(0..100) {
                0..4 => f32::NAN,
                4..7 => f32::INFINITY,
                7..9 => f32::NEG_INFINITY,
                9..14 => -base,
                14..22 => 0.0,
                22 => 1e-30,
                23 => 3e38,
                24 => f32::MIN_POSITIVE,
                _ => base * (1.0 + rng.random_range(-0.02..0.02f32)),
            })
            .collect();
        let var = var.then(|| {
            (0..n)
                .map(|_| match rng.random_range(0..100) {
                    0..3 => f32::NAN,
                    3..5 => 0.0,
                    5 => f32::INFINITY,
                    6 => -1e-3,
                    _ => 10f32.powf(rng.random_range(-5.0..-2.0)),
                })
                .collect()
        });
        let color = color.then(|| (0..3 * n).map(|_| rng.random()).collect());
        let cam = PinholeCamera::try_new(
            rng.random_range(50.0..500.0),
            rng.random_range(50.0..500.0),
            w as f64 * rng.random_range(0.3..0.7),
            h as f64 * rng.random_range(0.3..0.7),
            w,
            h,
        )
        .unwrap();
        let pose = Sim3::from_quaternion_xyzw(
            [rng.random(), rng.random(), rng.random(), 1.0],
            Vector3::new(rng.random(), rng.random(), rng.random()),
            rng.random_range(0.2..5.0),
        )
        .unwrap();
        Keyframe::try_new(id, id as f64, pose, cam, idepth, var, color).unwrap()
    }

    fn assert_same_cloud(got: &PointCloud, want: &PointCloud, what: &str) {
        assert_eq!(got.len(), want.len(), "{what}: count");
        let bits = |c: &PointCloud| c.points.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert!(bits(got) == bits(want), "{what}: points differ");
        assert_eq!(got.colors, want.colors, "{what}: colours");
        assert_eq!(got.keyframe_ids, want.keyframe_ids, "{what}: ids");
    }

    #[test]
    fn every_kernel_equals_the_pixel_by_pixel_reference() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        // Sizes below, at and above the vector widths, one-pixel and two-pixel
        // images, and images of several blocks of rows (`ROWS_PER_TASK`).
        let sizes = [
            (1, 1),
            (2, 2),
            (3, 3),
            (1, 7),
            (7, 1),
            (2, 9),
            (4, 3),
            (17, 5),
        ];
        let sizes = sizes
            .into_iter()
            .chain([(37, 33), (64, 40), (71, 9), (13, 150)]);
        let mut keyframes = Vec::new();
        for (i, (w, h)) in sizes.enumerate() {
            keyframes.push(random_keyframe(&mut rng, i as i32, w, h, true, true));
        }
        let sets = [
            keyframes.clone(),
            // Without variance, and a keyframe without colour (no colours at all).
            vec![
                random_keyframe(&mut rng, 20, 23, 140, false, true),
                random_keyframe(&mut rng, 21, 33, 35, true, true),
                random_keyframe(&mut rng, 22, 9, 40, true, false),
            ],
            // Keyframes of one size one after the other (per-thread buffers reused).
            (30..38)
                .map(|id| random_keyframe(&mut rng, id, 19, 70, true, true))
                .collect(),
        ];
        let filters = [
            PointFilter::default(),
            PointFilter::none(),
            PointFilter {
                cut_first_keyframes: None,
                ..PointFilter::default()
            },
            PointFilter {
                cut_first_keyframes: Some(0),
                min_near_support: 3,
                sparsify: 3,
                seed: 5,
                ..PointFilter::default()
            },
            PointFilter {
                cut_first_keyframes: None,
                skip_border: false,
                min_near_support: 9,
                scaled_depth_var: 1e-2,
                abs_depth_var: 3e-3,
                ..PointFilter::default()
            },
            PointFilter {
                cut_first_keyframes: None,
                skip_border: false,
                min_near_support: 1,
                scaled_depth_var: 0.0,
                sparsify: 2,
                ..PointFilter::default()
            },
        ];
        let world =
            Sim3::from_quaternion_xyzw([0.3, 0.1, -0.2, 1.0], Vector3::new(1.0, -2.0, 3.0), 2.5)
                .unwrap();
        let kernels = Isa::available();
        for (si, set) in sets.iter().enumerate() {
            for (fi, f) in filters.iter().enumerate() {
                let want = reference(set, f, &world);
                // The default cuts every keyframe of the three-keyframe set.
                assert!(
                    !want.is_empty() || (si, fi) == (1, 0),
                    "set {si} filter {fi}"
                );
                for &kernel in &kernels {
                    let got = backproject_with(set, 0, f, |_| world, None, kernel).unwrap();
                    assert_same_cloud(&got, &want, &format!("set {si} filter {fi} {kernel:?}"));
                }
            }
        }
    }

    #[test]
    fn positive_rows_follow_the_keyframe_and_the_row() {
        let w = 4;
        let a: Vec<f32> = (0..20).map(|i| i as f32 - 5.0).collect();
        let b: Vec<f32> = a.iter().map(|v| 2.0 * v + 1.0).collect();
        let mut ring = PositiveRows::default();
        // The same rows of another keyframe, rows out of order, and back.
        for (k, img) in [(0, &a), (1, &b), (0, &a)] {
            for y in [1, 3, 2, 1] {
                let got = ring.around(k, img, w, y);
                for (r, got) in (y - 1..=y + 1).zip(got) {
                    let want =
                        img[r * w..(r + 1) * w]
                            .iter()
                            .map(|&n| if n > 0.0 { n } else { f32::NAN });
                    assert!(got
                        .iter()
                        .zip(want)
                        .all(|(g, w)| g.to_bits() == w.to_bits()));
                }
            }
        }
    }

    #[test]
    fn default_cuts_the_first_six_keyframes_and_the_border() {
        let kfs: Vec<Keyframe> = (0..8)
            .map(|i| keyframe(i, 4, 4, vec![1.0; 16], Some(vec![1e-6; 16])))
            .collect();
        let cloud = backproject(&kfs, &PointFilter::default(), None).unwrap();
        // Two keyframes survive, each with its 2x2 interior (full 3x3 support).
        assert_eq!(cloud.len(), 8);
        assert_eq!(&cloud.keyframe_ids[..], &[6, 6, 6, 6, 7, 7, 7, 7]);
    }

    #[test]
    fn fused_transform_equals_transform_after() {
        let mut kf = keyframe(1, 6, 5, vec![0.25; 30], None);
        kf.pose =
            Sim3::from_quaternion_xyzw([0.1, 0.2, -0.3, 0.9], Vector3::new(1.0, 2.0, 3.0), 0.7)
                .unwrap();
        let t = Sim3::from_quaternion_xyzw([0.0, 0.3, 0.0, 1.0], Vector3::new(-4.0, 0.5, 2.0), 3.0)
            .unwrap();
        let f = PointFilter::none();
        let fused = backproject(&[&kf], &f, Some(&t)).unwrap();
        let after = backproject(&[&kf], &f, None)
            .unwrap()
            .transformed(&t)
            .unwrap();
        assert_eq!(fused.len(), 30);
        for (a, b) in fused.points.iter().zip(&after.points) {
            assert!((a - b).abs() <= 1e-5 * a.abs().max(1.0));
        }
        let per = backproject_per_keyframe(&[&kf], &f, &[t]).unwrap();
        assert_eq!(per.points, fused.points);
        assert!(backproject_per_keyframe(&[&kf], &f, &[]).is_err());
    }

    #[test]
    fn sparsify_is_deterministic_and_near_its_rate() {
        let kf = keyframe(2, 100, 100, vec![1.0; 10_000], None);
        let f = PointFilter {
            sparsify: 4,
            ..PointFilter::none()
        };
        let a = backproject(&[&kf], &f, None).unwrap();
        let b = backproject(&[&kf], &f, None).unwrap();
        assert_eq!(a, b);
        assert!((2200..2800).contains(&a.len()), "kept {}", a.len());
        let c = backproject(&[&kf], &PointFilter { seed: 9, ..f }, None).unwrap();
        assert_ne!(a.points, c.points);
    }

    #[test]
    fn rejects_bad_filters_and_inconsistent_keyframes() {
        let kf = keyframe(0, 3, 3, vec![1.0; 9], None);
        let bad = PointFilter {
            sparsify: 0,
            ..PointFilter::none()
        };
        assert!(backproject(&[&kf], &bad, None).is_err());
        let nan = PointFilter {
            scaled_depth_var: f32::NAN,
            ..PointFilter::none()
        };
        assert!(backproject(&[&kf], &nan, None).is_err());
        let mut broken = kf.clone();
        broken.idepth.pop();
        assert!(backproject(&[broken], &PointFilter::none(), None).is_err());
    }

    #[test]
    fn transformed_matches_sim3_point_map() {
        let t =
            Sim3::from_quaternion_xyzw([0.4, -0.1, 0.2, 0.8], Vector3::new(1.0, -1.0, 0.5), 2.5)
                .unwrap();
        let n = 3 * (1 << 15) + 5; // more than one parallel block
        let pts: Vec<f32> = (0..3 * n)
            .map(|i| ((i * 37) % 101) as f32 * 0.1 - 5.0)
            .collect();
        let cloud = PointCloud::try_new(pts.clone(), None, None).unwrap();
        let out = cloud.transformed(&t).unwrap();
        for i in (0..n).step_by(331) {
            let p = Vector3::new(
                pts[3 * i] as f64,
                pts[3 * i + 1] as f64,
                pts[3 * i + 2] as f64,
            );
            let q = t.transform_point(&p);
            for k in 0..3 {
                assert!((out.points[3 * i + k] as f64 - q[k]).abs() < 1e-5 * q[k].abs().max(1.0));
            }
        }
        assert!(t.transform_points(&pts[..4]).is_err());
        assert!(PointCloud::try_new(vec![0.0; 6], Some(vec![0; 3]), None).is_err());
    }
}
