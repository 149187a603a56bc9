//! The start-up cut from live frames: where a log carries the tracked pose of
//! every frame as the SLAM published it (LSD-SLAM's `/lsd_slam/liveframes`),
//! the three start-up stages are found in the scale factors `p_k` of the live
//! frames matched with the reference — the tracking is what shows the
//! start-up's scale error; the keyframes' optimised poses have it removed —
//! and the keyframe pairs stamped before the stable stage's first live frame
//! are left out of the fit.
//!
//! The batch conversion (`pipeline::poses`) and the online session
//! (`pipeline::session`) both cut through [`cut_of_pairs`], so that a
//! session fed a whole log ends on the batch cut.

use crate::align::stages::{detect_stages, Stages};
use crate::align::trajectories::{fit_scale_factors, TrajectoryAlignOptions};
use crate::error::Result;
use crate::trajectory::{matched_pairs_with, Trajectory};

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
    /// Live frames matched with a reference pose.
    pub pairs: usize,
}

impl LiveCut {
    /// One line saying what is cut and why.
    pub fn describe(&self) -> String {
        format!(
            "live frames: converging from {:.3} s, stable from {:.3} s ({} matched live frames; {})",
            self.converging_time,
            self.stable_time,
            self.pairs,
            self.stages.describe()
        )
    }
}

/// The stages of the live frames `(time, SLAM position, reference position)`
/// of matched pairs in time order; the errors of [`detect_stages`] (too few).
pub fn cut_of_pairs(
    times: &[f64],
    slam: &[nalgebra::Vector3<f64>],
    reference: &[nalgebra::Vector3<f64>],
) -> Result<LiveCut> {
    let stages = detect_stages(&fit_scale_factors(slam, reference))?;
    // Factor k is the step from pair k to k + 1: the stable stage starts at pair
    // `stable_start` (the same index rule as the keyframe cut of `skip_init auto`).
    let at = |k: usize| times[k.min(times.len() - 1)];
    Ok(LiveCut {
        stable_time: at(stages.stable_start),
        converging_time: at(stages.converging_start),
        pairs: times.len(),
        stages,
    })
}

/// The live frames of `live` matched with `reference` (the fit's association
/// rule, `max_diff` and `offset`) and the stages in their scale factors.
pub fn live_cut(
    live: &Trajectory,
    reference: &Trajectory,
    align: &TrajectoryAlignOptions,
) -> Result<LiveCut> {
    let pairs = matched_pairs_with(
        live,
        reference,
        align.max_diff,
        align.offset,
        3,
        align.association,
    )?;
    let times: Vec<f64> = pairs.iter().map(|&(s, _)| live.timestamps[s]).collect();
    let slam: Vec<_> = pairs.iter().map(|&(s, _)| live.positions[s]).collect();
    let refp: Vec<_> = pairs.iter().map(|&(_, r)| reference.positions[r]).collect();
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
