//! Timestamped poses: association, interpolation, frame-to-frame scale factors.
//!
//! A trajectory of SLAM keyframes holds `T_slam_cam`; a reference trajectory
//! holds `T_world_body`. Timestamps are seconds.

use nalgebra::{UnitQuaternion, Vector3};

use crate::error::{Error, Result};
use crate::geometry::Sim3;

/// At most `most` (at least 2) indices of `0..n`, evenly spread, the first
/// and the last kept: every index when `n ≤ most`.
pub fn even_indices(n: usize, most: usize) -> Vec<usize> {
    let most = most.max(2);
    if n <= most {
        return (0..n).collect();
    }
    (0..most).map(|i| i * (n - 1) / (most - 1)).collect()
}

/// Timestamped positions with optional orientations.
#[derive(Clone, Debug, Default)]
pub struct Trajectory {
    /// Times, seconds, non-decreasing.
    pub timestamps: Vec<f64>,
    /// Positions (the translation of each pose).
    pub positions: Vec<Vector3<f64>>,
    /// Orientations (the rotation of each pose), when known.
    pub orientations: Option<Vec<UnitQuaternion<f64>>>,
}

impl Trajectory {
    /// Checks lengths, finiteness and non-decreasing times.
    pub fn try_new(
        timestamps: Vec<f64>,
        positions: Vec<Vector3<f64>>,
        orientations: Option<Vec<UnitQuaternion<f64>>>,
    ) -> Result<Self> {
        let n = timestamps.len();
        if positions.len() != n {
            return Err(Error::ShapeMismatch {
                what: "positions".into(),
                expected: format!("({n}, 3), one row per timestamp"),
                got: format!("({}, 3)", positions.len()),
            });
        }
        if let Some(o) = &orientations {
            if o.len() != n {
                return Err(Error::ShapeMismatch {
                    what: "orientations".into(),
                    expected: format!("({n}, 4), one row per timestamp"),
                    got: format!("({}, 4)", o.len()),
                });
            }
        }
        for i in 0..n {
            if !timestamps[i].is_finite() || positions[i].iter().any(|v| !v.is_finite()) {
                return Err(Error::NonFinite {
                    what: "trajectory".into(),
                    index: i,
                });
            }
            if i > 0 && timestamps[i] < timestamps[i - 1] {
                return Err(Error::invalid(
                    "timestamps",
                    format!(
                        "must not decrease (pose {i}: {} after {})",
                        timestamps[i],
                        timestamps[i - 1]
                    ),
                ));
            }
        }
        Ok(Trajectory {
            timestamps,
            positions,
            orientations,
        })
    }

    /// Number of poses.
    pub fn len(&self) -> usize {
        self.timestamps.len()
    }

    /// True when there are no poses.
    pub fn is_empty(&self) -> bool {
        self.timestamps.is_empty()
    }
}

/// The result of [`Trajectory::interpolate_where_covered`].
#[derive(Clone, Debug)]
pub struct Interpolated {
    /// The poses at the covered query times (in query order).
    pub trajectory: Trajectory,
    /// Indices into the query times that were interpolated.
    pub kept: Vec<usize>,
    /// Indices into the query times outside the covered range or inside a gap
    /// longer than `max_gap`.
    pub missing: Vec<usize>,
}

/// Where a query time falls: `(i, k, alpha)` with the pose `lerp(i, k, alpha)`.
type Bracket = (usize, usize, f64);

/// The poses around `t` in sorted stamps `ts`: `(i, k, a)` with `t` at
/// fraction `a` from stamp `i` to stamp `k` (`i == k` at a stamp), or why
/// there are none (before the first, after the last, a gap over `max_gap`).
/// The gap a reference stamped `times` (sorted) is interpolated over by
/// default: [`crate::defaults::GAP_STEPS`] of its median interval (infinite
/// with fewer than two samples, where there is nothing to bridge).
pub fn gap_of(times: &[f64]) -> f64 {
    let mut d: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).collect();
    if d.is_empty() {
        return f64::INFINITY;
    }
    let m = d.len() / 2;
    let (_, median, _) = d.select_nth_unstable_by(m, f64::total_cmp);
    crate::defaults::GAP_STEPS * *median
}

/// [`gap_of`] of stamps that come one at a time (strictly increasing): the
/// median interval kept by two heaps, `O(log n)` a stamp, so that a live
/// session need not go over every interval again at each sample.
#[derive(Clone, Debug, Default)]
pub(crate) struct GapOfStream {
    last: Option<f64>,
    /// The smaller half of the intervals (max-heap), `len / 2` of them.
    lower: std::collections::BinaryHeap<u64>,
    /// The larger half (min-heap); its least is [`gap_of`]'s median.
    upper: std::collections::BinaryHeap<std::cmp::Reverse<u64>>,
}

impl GapOfStream {
    /// Takes the next stamp (after the last one).
    pub(crate) fn push(&mut self, t: f64) {
        if let Some(last) = self.last.replace(t) {
            // Positive finite floats order as their bits.
            let d = (t - last).to_bits();
            self.upper.push(std::cmp::Reverse(d));
            if let Some(std::cmp::Reverse(least)) = self.upper.pop() {
                self.lower.push(least);
            }
            let n = self.lower.len() + self.upper.len();
            while self.lower.len() > n / 2 {
                if let Some(top) = self.lower.pop() {
                    self.upper.push(std::cmp::Reverse(top));
                }
            }
        }
    }

    /// [`gap_of`] of the stamps so far.
    pub(crate) fn gap(&self) -> f64 {
        self.upper.peek().map_or(f64::INFINITY, |r| {
            crate::defaults::GAP_STEPS * f64::from_bits(r.0)
        })
    }
}

pub(crate) fn bracket(ts: &[f64], t: f64, max_gap: f64) -> std::result::Result<Bracket, String> {
    let n = ts.len();
    if n == 0 {
        return Err("the trajectory is empty".into());
    }
    let k = ts.partition_point(|&x| x <= t);
    if k == 0 {
        return Err(format!("before the first pose ({} s)", ts[0]));
    }
    let i = k - 1;
    if ts[i] == t {
        return Ok((i, i, 0.0));
    }
    if k == n {
        return Err(format!("after the last pose ({} s)", ts[n - 1]));
    }
    let gap = ts[k] - ts[i];
    // A gap of max_gap up to the rounding of the stamps is bridged (a 10 Hz
    // stream in Unix seconds has steps of 0.1 ± 2e-7).
    let rounding = 4.0 * f64::EPSILON * ts[k].abs().max(max_gap.abs());
    if max_gap.is_nan() || gap > max_gap + rounding {
        return Err(format!(
            "inside a gap of {gap} s between poses {i} and {k} (max_gap {max_gap} s)"
        ));
    }
    Ok((i, k, (t - ts[i]) / gap))
}

impl Trajectory {
    /// Checks that positions and orientations have one entry per timestamp
    /// (the fields are public, so a literal can break what `try_new` checks).
    pub fn check_lengths(&self) -> Result<()> {
        let n = self.timestamps.len();
        if self.positions.len() != n {
            return Err(Error::ShapeMismatch {
                what: "positions".into(),
                expected: format!("({n}, 3), one row per timestamp"),
                got: format!("({}, 3)", self.positions.len()),
            });
        }
        match &self.orientations {
            Some(o) if o.len() != n => Err(Error::ShapeMismatch {
                what: "orientations".into(),
                expected: format!("({n}, 4), one row per timestamp"),
                got: format!("({}, 4)", o.len()),
            }),
            _ => Ok(()),
        }
    }

    /// The poses at `times` (seconds, non-decreasing): positions interpolated
    /// linearly, orientations by slerp. Errors ([`Error::OutOfRange`]) for a
    /// time outside `[first, last]` or between two poses more than `max_gap`
    /// seconds apart (a time equal to a pose's stamp is always answered).
    pub fn interpolate(&self, times: &[f64], max_gap: f64) -> Result<Trajectory> {
        self.check_lengths()?;
        check_times(times)?;
        let mut brackets = Vec::with_capacity(times.len());
        for &t in times {
            let b = self
                .bracket(t, max_gap)
                .map_err(|reason| Error::OutOfRange {
                    what: format!("interpolation at t = {t} s"),
                    reason,
                })?;
            brackets.push(b);
        }
        self.build(times.to_vec(), &brackets)
    }

    /// Like [`Trajectory::interpolate`], but times that cannot be answered are
    /// skipped and reported instead of refused.
    pub fn interpolate_where_covered(&self, times: &[f64], max_gap: f64) -> Result<Interpolated> {
        self.check_lengths()?;
        check_times(times)?;
        let (mut kept, mut missing, mut brackets, mut stamps) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (j, &t) in times.iter().enumerate() {
            match self.bracket(t, max_gap) {
                Ok(b) => {
                    kept.push(j);
                    brackets.push(b);
                    stamps.push(t);
                }
                Err(_) => missing.push(j),
            }
        }
        Ok(Interpolated {
            trajectory: self.build(stamps, &brackets)?,
            kept,
            missing,
        })
    }

    fn bracket(&self, t: f64, max_gap: f64) -> std::result::Result<Bracket, String> {
        bracket(&self.timestamps, t, max_gap)
    }

    fn build(&self, stamps: Vec<f64>, brackets: &[Bracket]) -> Result<Trajectory> {
        let positions = brackets
            .iter()
            .map(|&(i, k, a)| self.positions[i].lerp(&self.positions[k], a))
            .collect();
        let orientations = self.orientations.as_ref().map(|o| {
            brackets
                .iter()
                .map(|&(i, k, a)| slerp(&o[i], &o[k], a))
                .collect()
        });
        Trajectory::try_new(stamps, positions, orientations)
    }

    /// The trajectory seen from another frame: with `t = T_world_slam` and poses
    /// `T_slam_cam`, the poses `T_world_cam = T_world_slam · T_slam_cam`
    /// (positions mapped by the full similarity, orientations rotated).
    pub fn transformed(&self, t: &Sim3) -> Trajectory {
        Trajectory {
            timestamps: self.timestamps.clone(),
            positions: self
                .positions
                .iter()
                .map(|p| t.transform_point(p))
                .collect(),
            orientations: self
                .orientations
                .as_ref()
                .map(|o| o.iter().map(|q| t.rotation * q).collect()),
        }
    }
}

fn check_times(times: &[f64]) -> Result<()> {
    if let Some(i) = times.iter().position(|t| !t.is_finite()) {
        return Err(Error::NonFinite {
            what: "times".into(),
            index: i,
        });
    }
    if let Some(i) = (1..times.len()).find(|&i| times[i] < times[i - 1]) {
        return Err(Error::invalid(
            "times",
            format!(
                "must not decrease (time {i}: {} after {})",
                times[i],
                times[i - 1]
            ),
        ));
    }
    Ok(())
}

/// Shortest-path slerp; falls back to normalised lerp where the two rotations
/// are (numerically) equal.
fn slerp(a: &UnitQuaternion<f64>, b: &UnitQuaternion<f64>, t: f64) -> UnitQuaternion<f64> {
    if t == 0.0 {
        return *a;
    }
    a.try_slerp(b, t, 1e-12).unwrap_or_else(|| a.nlerp(b, t))
}

/// Pairs `(i, j)` of poses `a[i]`, `b[j]` whose times match, with evo's
/// semantics (`evo.core.sync.associate_trajectories`, nearest time): the
/// shorter trajectory's poses (`b` on a tie) are each matched at most once to
/// the nearest stamp of the other within `max_diff` seconds; `offset` seconds
/// are added to `b`'s stamps for the comparison. Pairs come in the order of
/// the shorter trajectory.
pub fn associate(
    a: &Trajectory,
    b: &Trajectory,
    max_diff: f64,
    offset: f64,
) -> Vec<(usize, usize)> {
    if a.is_empty() || b.is_empty() {
        return Vec::new();
    }
    if b.len() > a.len() {
        matching_time_indices(&a.timestamps, &b.timestamps, max_diff, offset)
    } else {
        matching_time_indices(&b.timestamps, &a.timestamps, max_diff, -offset)
            .into_iter()
            .map(|(j, i)| (i, j))
            .collect()
    }
}

/// evo's `matching_time_indices` for sorted `long` stamps: for each short
/// stamp, the nearest long stamp (shifted by `offset`) within `max_diff`.
fn matching_time_indices(
    short: &[f64],
    long: &[f64],
    max_diff: f64,
    offset: f64,
) -> Vec<(usize, usize)> {
    let long: Vec<f64> = long.iter().map(|t| t + offset).collect();
    let (first, last) = (long[0], long[long.len() - 1]);
    let mut out = Vec::new();
    for (i, &t) in short.iter().enumerate() {
        if t < first - max_diff || t > last + max_diff {
            continue;
        }
        let k = long.partition_point(|&x| x <= t).min(long.len() - 1);
        let diff_ub = long[k] - t;
        let diff_lb = if k > 0 {
            t - long[k - 1]
        } else {
            f64::INFINITY
        };
        if diff_ub <= max_diff && diff_ub < diff_lb {
            out.push((i, k));
        } else if diff_lb <= max_diff && diff_lb <= diff_ub {
            out.push((i, k - 1));
        }
    }
    out
}

/// Describes `[first, last]` of sorted stamps for an error message.
fn span(t: &[f64]) -> String {
    match (t.first(), t.last()) {
        (Some(a), Some(b)) => format!("{}..{} s", crate::error::num(*a), crate::error::num(*b)),
        _ => "empty".into(),
    }
}

/// Why two sets of stamps may fail to match: a unit mix-up, a constant
/// offset, or too tight a `max_diff`.
fn likely_cause(slam: &[f64], reference: &[f64], max_diff: f64, offset: f64) -> String {
    let (Some(&s0), Some(&s1), Some(&r0), Some(&r1)) = (
        slam.first(),
        slam.last(),
        reference.first(),
        reference.last(),
    ) else {
        return "one trajectory is empty".into();
    };
    let (s0, s1) = (s0 + offset, s1 + offset);
    let mid = |a: f64, b: f64| 0.5 * (a + b);
    let (ms, mr) = (mid(s0, s1).abs(), mid(r0, r1).abs());
    if ms > 0.0 && mr > 0.0 {
        let ratio = ms / mr;
        for (factor, unit) in [
            (1e9, "nanoseconds"),
            (1e6, "microseconds"),
            (1e3, "milliseconds"),
        ] {
            if (ratio / factor).log10().abs() < 0.5 {
                return format!("the SLAM stamps look like {unit} against reference seconds");
            }
            if (ratio * factor).log10().abs() < 0.5 {
                return format!("the reference stamps look like {unit} against SLAM seconds");
            }
        }
    }
    if s1 < r0 || r1 < s0 {
        // The offset that puts the middles of the two ranges together.
        let suggest = offset + mid(r0, r1) - mid(s0, s1);
        return format!(
            "the time ranges do not overlap: an offset of about {} s would line them up (give it as offset, or estimate it)",
            crate::error::num((suggest * 1e3).round() / 1e3)
        );
    }
    format!("the ranges overlap, but no stamps lie within max_diff {max_diff} s of each other (a larger max_diff, or an offset)")
}

/// How SLAM stamps are paired with reference stamps.
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    Hash,
    serde::Serialize,
    serde::Deserialize,
    schemars::JsonSchema,
)]
pub enum Association {
    /// evo's rule ([`associate`]): each pose of the shorter trajectory takes
    /// the nearest stamp of the other within `max_diff` (`≤`), so a pose of the
    /// longer one can serve twice. evo's published figures use it.
    #[default]
    #[serde(rename = "evo")]
    Evo,
    /// The TUM RGB-D benchmark's `associate.py` (and rpg_trajectory_evaluation's
    /// `associate_timestamps.py`): every pair closer than `max_diff` (`<`) is a
    /// candidate, the closest taken first, and each pose of either trajectory
    /// is used at most once ([`associate_one_to_one`]). Their published figures
    /// (`evaluate_ate.py`, max_difference 0.02 s) use it.
    #[serde(rename = "one_to_one")]
    OneToOne,
}

impl Association {
    /// The name the option takes (`"evo"`, `"one_to_one"`).
    pub fn as_str(self) -> &'static str {
        match self {
            Association::Evo => "evo",
            Association::OneToOne => "one_to_one",
        }
    }
}

impl std::fmt::Display for Association {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for Association {
    type Err = Error;
    /// `"evo"` or `"one_to_one"` (also `"one-to-one"`), any case.
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().replace('-', "_").as_str() {
            "evo" => Ok(Association::Evo),
            "one_to_one" => Ok(Association::OneToOne),
            _ => Err(Error::invalid(
                "association",
                format!(
                    "expected \"evo\" or \"one_to_one\", got {}",
                    crate::error::cut(s)
                ),
            )),
        }
    }
}

/// Stamps of one trajectory that are equal, one node of the merged time line
/// of [`associate_one_to_one`]: its poses are used lowest index first.
struct StampGroup {
    /// The stamp, seconds (SLAM stamps with the offset added).
    time: f64,
    /// True for the reference side.
    reference: bool,
    /// Indices of the poses with this stamp not yet used, in reverse order
    /// (the lowest index is popped first).
    unused: Vec<usize>,
    /// Neighbouring groups with unused poses on the time line.
    prev: Option<usize>,
    next: Option<usize>,
}

/// A candidate pair of neighbouring groups: ordered by time difference, then
/// by reference index, then by SLAM index (the tuple order of `associate.py`'s
/// sort), smallest first.
#[derive(PartialEq)]
struct Candidate {
    diff: f64,
    reference_index: usize,
    slam_index: usize,
    /// The two groups (left one first on the time line).
    groups: (usize, usize),
}

impl Eq for Candidate {}

impl PartialOrd for Candidate {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Candidate {
    /// Reversed, so that `BinaryHeap` pops the smallest.
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        other
            .diff
            .total_cmp(&self.diff)
            .then(other.reference_index.cmp(&self.reference_index))
            .then(other.slam_index.cmp(&self.slam_index))
    }
}

/// Pairs `(slam index, reference index)` one to one, as the TUM benchmark's
/// `associate.py` and rpg_trajectory_evaluation do: of all pairs with
/// `|t_ref − (t_slam + offset)| < max_diff`, the closest is taken first, then
/// the closest of those whose poses are both unused, and so on; ties go to the
/// lower reference index, then the lower SLAM index (`associate.py`'s sort;
/// rpg breaks an exact tie by the estimate's index first). Returned in SLAM
/// index order.
///
/// The closest pair of unused poses is always a pair of neighbours on the
/// merged time line (a pose between them would be closer to one of them), so
/// the candidates are only neighbours, kept in a heap: `O((n + m) log(n + m))`
/// time and `O(n + m)` memory whatever `max_diff` is (the benchmark's script
/// lists every pair within `max_diff`, `O(n·m)` for a wide window). Equal
/// stamps of one trajectory form one node, used lowest index first.
pub fn associate_one_to_one(
    slam: &Trajectory,
    reference: &Trajectory,
    max_diff: f64,
    offset: f64,
) -> Vec<(usize, usize)> {
    let mut items: Vec<(f64, bool, usize)> = Vec::with_capacity(slam.len() + reference.len());
    items.extend(
        slam.timestamps
            .iter()
            .enumerate()
            .map(|(i, &t)| (t + offset, false, i)),
    );
    items.extend(
        reference
            .timestamps
            .iter()
            .enumerate()
            .map(|(j, &t)| (t, true, j)),
    );
    // A stamp that is not a number matches nothing.
    items.retain(|x| !x.0.is_nan());
    items.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(b.2.cmp(&a.2)));
    let mut groups: Vec<StampGroup> = Vec::new();
    for (time, reference, index) in items {
        match groups.last_mut() {
            Some(g) if g.time == time && g.reference == reference => g.unused.push(index),
            _ => {
                let k = groups.len();
                groups.push(StampGroup {
                    time,
                    reference,
                    unused: vec![index],
                    prev: k.checked_sub(1),
                    next: None,
                });
                if k > 0 {
                    groups[k - 1].next = Some(k);
                }
            }
        }
    }
    // The time difference as associate.py computes it: |a − (b + offset)|.
    let candidate = |groups: &[StampGroup], l: usize, r: usize| -> Option<Candidate> {
        let (gl, gr) = (&groups[l], &groups[r]);
        if gl.reference == gr.reference {
            return None;
        }
        let (gs, gref) = if gl.reference { (gr, gl) } else { (gl, gr) };
        let (&s, &j) = (gs.unused.last()?, gref.unused.last()?);
        let diff = (reference.timestamps[j] - (slam.timestamps[s] + offset)).abs();
        (diff < max_diff).then_some(Candidate {
            diff,
            reference_index: j,
            slam_index: s,
            groups: (l, r),
        })
    };
    let mut heap = std::collections::BinaryHeap::new();
    for l in 1..groups.len() {
        heap.extend(candidate(&groups, l - 1, l));
    }
    let mut pairs = Vec::new();
    while let Some(c) = heap.pop() {
        let (l, r) = c.groups;
        // Stale when either group was used up since (neighbours stay
        // neighbours while both have unused poses).
        if groups[l].unused.is_empty() || groups[r].unused.is_empty() {
            continue;
        }
        // Its key is stale when a pose of either group was used since: the
        // next poses have higher indices, so the key only grows; put it back
        // with the key it has now.
        match candidate(&groups, l, r) {
            Some(now)
                if (now.reference_index, now.slam_index) != (c.reference_index, c.slam_index) =>
            {
                heap.push(now);
                continue;
            }
            _ => {}
        }
        let (a, b) = (groups[l].unused.pop(), groups[r].unused.pop());
        if let (Some(a), Some(b)) = (a, b) {
            pairs.push(if groups[l].reference { (b, a) } else { (a, b) });
        }
        for k in [l, r] {
            if groups[k].unused.is_empty() {
                let (p, n) = (groups[k].prev, groups[k].next);
                if let Some(p) = p {
                    groups[p].next = n;
                }
                if let Some(n) = n {
                    groups[n].prev = p;
                }
            }
        }
        // The new neighbours: across a used-up group, or the same two groups
        // again when both still have poses (equal stamps).
        let left = if groups[l].unused.is_empty() {
            groups[l].prev
        } else {
            Some(l)
        };
        let right = if groups[r].unused.is_empty() {
            groups[r].next
        } else {
            Some(r)
        };
        if let (Some(x), Some(y)) = (left, right) {
            heap.extend(candidate(&groups, x, y));
        }
    }
    pairs.sort_unstable();
    pairs
}

/// Pairs `(slam index, reference index)` matched by time as evo does
/// (`offset` seconds added to the SLAM stamps, nearest stamp within
/// `max_diff`), in SLAM time order. Fewer than `need` is an
/// [`Error::Unmatched`] that gives both time ranges and the likely cause.
pub fn matched_pairs(
    slam: &Trajectory,
    reference: &Trajectory,
    max_diff: f64,
    offset: f64,
    need: usize,
) -> Result<Vec<(usize, usize)>> {
    matched_pairs_with(slam, reference, max_diff, offset, need, Association::Evo)
}

/// [`matched_pairs`] with the pairing rule `association`.
pub fn matched_pairs_with(
    slam: &Trajectory,
    reference: &Trajectory,
    max_diff: f64,
    offset: f64,
    need: usize,
    association: Association,
) -> Result<Vec<(usize, usize)>> {
    let mut pairs: Vec<(usize, usize)> = match association {
        Association::Evo => associate(reference, slam, max_diff, offset)
            .into_iter()
            .map(|(r, s)| (s, r))
            .collect(),
        Association::OneToOne => associate_one_to_one(slam, reference, max_diff, offset),
    };
    pairs.sort_unstable();
    if pairs.len() < need {
        return Err(Error::Unmatched {
            matched: pairs.len(),
            need,
            slam_span: span(&slam.timestamps),
            reference_span: span(&reference.timestamps),
            max_diff,
            offset,
            cause: likely_cause(&slam.timestamps, &reference.timestamps, max_diff, offset),
        });
    }
    Ok(pairs)
}

/// The paper's frame-to-frame scale factors
/// `p_k = ‖t'_{k+1} − t'_k‖² / ‖t_{k+1} − t_k‖²` (`t'` reference, metres;
/// `t` SLAM), `k = 0 … N−2`; about `s²` once the SLAM scale has settled.
/// Errors on unequal lengths, fewer than 2 positions, non-finite values, or a
/// SLAM step of zero length (the factor would be infinite).
pub fn scale_factors(slam: &[Vector3<f64>], reference: &[Vector3<f64>]) -> Result<Vec<f64>> {
    if slam.len() != reference.len() {
        return Err(Error::ShapeMismatch {
            what: "reference positions".into(),
            expected: format!("({}, 3), one per SLAM position", slam.len()),
            got: format!("({}, 3)", reference.len()),
        });
    }
    if slam.len() < 2 {
        return Err(Error::TooFew {
            what: "positions".into(),
            need: 2,
            got: slam.len(),
        });
    }
    for (what, pts) in [("slam positions", slam), ("reference positions", reference)] {
        if let Some(i) = pts.iter().position(|p| p.iter().any(|v| !v.is_finite())) {
            return Err(Error::NonFinite {
                what: what.into(),
                index: i,
            });
        }
    }
    let mut out = Vec::with_capacity(slam.len() - 1);
    for k in 0..slam.len() - 1 {
        let ds = (slam[k + 1] - slam[k]).norm_squared();
        if ds == 0.0 {
            return Err(Error::Degenerate {
                reason: format!("the SLAM position does not move from {k} to {}", k + 1),
                value: 0.0,
            });
        }
        out.push((reference[k + 1] - reference[k]).norm_squared() / ds);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_streamed_gap_is_the_gap_of_the_stamps_so_far() {
        let mut t = 0.0;
        let mut times = Vec::new();
        let mut stream = GapOfStream::default();
        assert_eq!(stream.gap(), f64::INFINITY);
        for k in 0..200u32 {
            // Uneven steps: 0.1 s with dropouts and jitter.
            t += 0.1 * (1 + (k * 7919) % 5 / 4) as f64 + 1e-3 * ((k * 31) % 7) as f64;
            times.push(t);
            stream.push(t);
            assert_eq!(stream.gap(), gap_of(&times), "after {} stamps", times.len());
        }
    }

    fn line(times: &[f64]) -> Trajectory {
        let p = times
            .iter()
            .map(|&t| Vector3::new(t, 2.0 * t, 0.0))
            .collect();
        let q = times
            .iter()
            .map(|&t| UnitQuaternion::from_euler_angles(0.0, 0.0, t))
            .collect();
        Trajectory::try_new(times.to_vec(), p, Some(q)).unwrap()
    }

    #[test]
    fn associate_nearest_within_max_diff() {
        let a = line(&[0.0, 1.0, 2.0, 3.0, 4.0]);
        let b = line(&[0.004, 1.5, 2.995, 3.008]);
        // b is shorter: each b stamp finds its nearest a stamp.
        assert_eq!(associate(&a, &b, 0.01, 0.0), vec![(0, 0), (3, 2), (3, 3)]);
        assert_eq!(associate(&a, &b, 0.001, 0.0), vec![]);
        // The offset is added to b's stamps.
        assert_eq!(associate(&a, &b, 0.01, 0.5), vec![(2, 1)]);
    }

    #[test]
    fn interpolate_lerp_slerp_and_gaps() {
        let t = line(&[0.0, 1.0, 2.0, 5.0]);
        let r = t.interpolate(&[0.25, 1.0, 2.0], 1.5).unwrap();
        assert!((r.positions[0] - Vector3::new(0.25, 0.5, 0.0)).norm() < 1e-15);
        let q = r.orientations.as_ref().unwrap()[0];
        assert!((q.angle() - 0.25).abs() < 1e-12);
        assert!(matches!(
            t.interpolate(&[3.0], 1.5),
            Err(Error::OutOfRange { .. })
        ));
        assert!(t.interpolate(&[-0.1], 1.5).is_err());
        assert!(t.interpolate(&[5.1], 10.0).is_err());
        let w = t
            .interpolate_where_covered(&[-1.0, 0.5, 3.0, 5.0], 1.5)
            .unwrap();
        assert_eq!(w.kept, vec![1, 3]);
        assert_eq!(w.missing, vec![0, 2]);
        assert_eq!(w.trajectory.len(), 2);
    }

    #[test]
    fn a_gap_of_max_gap_is_bridged_whatever_the_rounding_of_the_stamps() {
        // 10 Hz in Unix seconds: the steps are 0.1 only up to the stamps' rounding.
        let times: Vec<f64> = (0..20).map(|i| 1.4e9 + i as f64 * 0.1).collect();
        let t = line(&times);
        let mid: Vec<f64> = times.windows(2).map(|w| 0.5 * (w[0] + w[1])).collect();
        assert_eq!(t.interpolate(&mid, 0.1).unwrap().len(), mid.len());
        // A gap clearly longer than max_gap is not.
        let sparse = line(&[0.0, 0.1, 0.3]);
        assert!(sparse.interpolate(&[0.2], 0.1).is_err());
        assert!(sparse.interpolate(&[0.05], 0.1).is_ok());
    }

    #[test]
    fn inconsistent_literals_are_refused_not_panicking() {
        let mut t = line(&[0.0, 1.0, 2.0]);
        t.positions.pop();
        assert!(matches!(
            t.interpolate(&[0.5], 1.0),
            Err(Error::ShapeMismatch { .. })
        ));
    }

    #[test]
    fn scale_factors_are_squared_scale() {
        let slam: Vec<_> = (0..5).map(|i| Vector3::new(i as f64, 0.0, 1.0)).collect();
        let reference: Vec<_> = slam.iter().map(|p| p * 3.0).collect();
        let p = scale_factors(&slam, &reference).unwrap();
        assert_eq!(p.len(), 4);
        assert!(p.iter().all(|v| (v - 9.0).abs() < 1e-12));
        assert!(scale_factors(&slam, &reference[..4]).is_err());
        let still = vec![Vector3::zeros(); 3];
        assert!(matches!(
            scale_factors(&still, &reference[..3]),
            Err(Error::Degenerate { .. })
        ));
    }

    #[test]
    fn transformed_maps_positions_and_rotates() {
        let t = line(&[0.0, 1.0]);
        let s = Sim3::from_quaternion_xyzw([0.0, 0.0, 1.0, 1.0], Vector3::new(1.0, 0.0, 0.0), 2.0)
            .unwrap();
        let u = t.transformed(&s);
        assert!((u.positions[1] - s.transform_point(&t.positions[1])).norm() < 1e-15);
        let q = u.orientations.unwrap()[1];
        assert!((q.angle() - (1.0 + std::f64::consts::FRAC_PI_2)).abs() < 1e-12);
    }
}
