//! The start-up cut from live frames: where a log carries the tracked pose of
//! every frame as the SLAM published it (LSD-SLAM's `/lsd_slam/liveframes`),
//! the three start-up stages are found in the scale factors `p_k` of the live
//! frames paired with the reference (interpolated at their stamps) — the
//! tracking is what shows the start-up's scale error; the keyframes' optimised poses have it removed —
//! and the keyframe pairs stamped before the stable stage's first live frame
//! are left out of the fit.
//!
//! The batch conversion (`pipeline::poses`) and the online session
//! (`pipeline::session`) both cut through [`cut_of_pairs`], so that a
//! session fed a whole log ends on the batch cut.

use nalgebra::Vector3;

use crate::align::stages::{stages_of_pairs, Stages};
use crate::align::trajectories::TrajectoryAlignOptions;
use crate::error::Result;
use crate::trajectory::{gap_of, matched_pairs_with, Trajectory};

pub use crate::align::stages::{stage_factors, FACTOR_NOISE};

/// The stages found in the live frames and the time the stable stage starts.
#[derive(Clone, Debug, PartialEq)]
pub struct LiveCut {
    /// The stages, indices into the live frames' scale factors.
    pub stages: Stages,
    /// SLAM stamp of the live frame where the stable stage starts (seconds):
    /// keyframes stamped before it are not fitted.
    pub stable_time: f64,
    /// SLAM stamp of the live frame where the converging stretch starts.
    pub converging_time: f64,
    /// The stamps the stable start may lie between ([`Stages::stable_range`]).
    pub stable_range: (f64, f64),
    /// The stamps the converging start may lie between.
    pub converging_range: (f64, f64),
    /// Live frames paired with the reference.
    pub pairs: usize,
    /// Pairs between the two ends of a factor ([`stage_factors`]).
    pub baseline: usize,
}

impl LiveCut {
    /// One line saying what is cut and why.
    pub fn describe(&self) -> String {
        format!(
            "live frames: converging from {:.3} s ({:.3}..{:.3}), stable from {:.3} s \
             ({:.3}..{:.3}) ({} paired live frames, factors over {} pairs; {})",
            self.converging_time,
            self.converging_range.0,
            self.converging_range.1,
            self.stable_time,
            self.stable_range.0,
            self.stable_range.1,
            self.pairs,
            self.baseline,
            self.stages.describe()
        )
    }
}

/// The stages of the live frames `(time, SLAM position, reference position)`
/// of matched pairs in time order, taken as a whole run; the errors of
/// [`detect_stages`](crate::align::stages::detect_stages) (too few).
pub fn cut_of_pairs(
    times: &[f64],
    slam: &[Vector3<f64>],
    reference: &[Vector3<f64>],
) -> Result<LiveCut> {
    let (stages, baseline) = stages_of_pairs(slam, reference)?;
    cut_of(times, stages, baseline)
}

fn cut_of(times: &[f64], stages: Stages, baseline: usize) -> Result<LiveCut> {
    // Factor k is the step from pair k to k + 1: the stable stage starts at pair
    // `stable_start` (the same index rule as the keyframe cut of `skip_init auto`).
    let at = |k: usize| times[k.min(times.len() - 1)];
    Ok(LiveCut {
        stable_time: at(stages.stable_start),
        converging_time: at(stages.converging_start),
        stable_range: (at(stages.stable_range.0), at(stages.stable_range.1)),
        converging_range: (at(stages.converging_range.0), at(stages.converging_range.1)),
        pairs: times.len(),
        baseline,
        stages,
    })
}

/// Live frames paired with the reference: their stamps, SLAM positions and
/// the reference positions at those stamps.
pub type LivePairs = (Vec<f64>, Vec<Vector3<f64>>, Vec<Vector3<f64>>);

/// The live frames of `live` with the reference interpolated at each one's
/// stamp plus `offset` (between two poses at most [`gap_of`] the reference apart;
/// frames outside are left out, [`Trajectory::interpolate_where_covered`]):
/// `(time, SLAM position, reference position)`. Interpolated, not the
/// nearest pose: a reference slower than the frames, or not in step with
/// them, would otherwise give steps of unequal durations on the two sides,
/// and factors that swing with them.
pub fn live_pairs(live: &Trajectory, reference: &Trajectory, offset: f64) -> Result<LivePairs> {
    let at: Vec<f64> = live.timestamps.iter().map(|t| t + offset).collect();
    let r = reference.interpolate_where_covered(&at, gap_of(&reference.timestamps))?;
    Ok((
        r.kept.iter().map(|&j| live.timestamps[j]).collect(),
        r.kept.iter().map(|&j| live.positions[j]).collect(),
        r.trajectory.positions,
    ))
}

/// The stages in the scale factors of the live frames of `live` paired with
/// `reference` ([`live_pairs`], with `align.offset`); too few pairs: the
/// errors of [`detect_stages`](crate::align::stages::detect_stages) and [`Error::Unmatched`].
pub fn live_cut(
    live: &Trajectory,
    reference: &Trajectory,
    align: &TrajectoryAlignOptions,
) -> Result<LiveCut> {
    let (times, slam, refp) = live_pairs(live, reference, align.offset)?;
    if times.len() < 3 {
        // The association's own error says why (spans, likely cause).
        matched_pairs_with(
            live,
            reference,
            align.max_diff,
            align.offset,
            3,
            align.association,
        )?;
    }
    cut_of_pairs(&times, &slam, &refp)
}

/// How many of the matched pairs of `slam` with `reference` are stamped
/// before `time`: the leading pairs the cut drops.
pub fn pairs_before(
    slam: &Trajectory,
    reference: &Trajectory,
    align: &TrajectoryAlignOptions,
    time: f64,
) -> Result<usize> {
    let pairs = matched_pairs_with(
        slam,
        reference,
        align.max_diff,
        align.offset,
        0,
        align.association,
    )?;
    Ok(pairs
        .iter()
        .filter(|&&(s, _)| slam.timestamps[s] < time)
        .count())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reference of any rate pairs every live frame between its samples: a
    /// 1 Hz one (no frame lay between two poses 0.5 s apart before the gap
    /// followed the rate) as a 200 Hz one; a dropout of more than five
    /// intervals is not bridged.
    #[test]
    fn live_frames_pair_with_a_reference_of_any_rate() {
        let line = |times: Vec<f64>| {
            let p = times.iter().map(|&t| Vector3::new(t, 0.0, 0.0)).collect();
            Trajectory::try_new(times, p, None).unwrap()
        };
        let live = line((0..600).map(|k| k as f64 / 30.0).collect());
        for rate in [1.0, 200.0] {
            let reference = line(
                (0..=(20.0 * rate) as usize)
                    .map(|k| k as f64 / rate)
                    .collect(),
            );
            let (times, slam, refp) = live_pairs(&live, &reference, 0.0).unwrap();
            assert_eq!(times.len(), 600, "{rate} Hz");
            assert!(slam.iter().zip(&refp).all(|(a, b)| (a - b).norm() < 1e-12));
        }
        // 1 Hz with 8 s missing: the frames inside the dropout are left out.
        let sparse = line([0.0, 1.0, 2.0, 3.0, 11.0, 12.0, 13.0].to_vec());
        let (times, _, _) = live_pairs(&live, &sparse, 0.0).unwrap();
        assert!(times.iter().all(|&t| t <= 3.0 || t >= 11.0));
        assert_eq!(times.len(), 91 + 61);
    }
}
