//! The robust fit ([`crate::align::robust`]: RANSAC, IRLS, inlier refit)
//! with the degrees of freedom and anchor of [`DofOptions`].

use nalgebra::Vector3;

use super::{check_gravity, check_max_tilt, fit_alignment, Anchor, Dof, DofOptions};
use crate::align::robust::{
    align_robust, check_robust, robust_refit, Refit, RobustAlignment, RobustOptions,
};
use crate::align::{AlignMethod, Alignment};
use crate::error::Result;
use crate::geometry::Sim3;

/// [`super::align_dof`] that ignores gross outliers, as
/// [`crate::align::robust::align_robust`] does for Sim(3) (and exactly it
/// for `sim3` / `se3` without anchor). Hypotheses are minimal fits of the
/// dof: 2 pairs for a yaw, 3 for a full rotation, one fewer beside the anchor
/// when anchored (the anchor is always in the sample, and always an inlier).
/// The gravity check of a yaw-only fit is made once, on the final inlier fit.
///
/// Errors: those of [`super::align_dof`] and of `align_robust` (given weights,
/// a threshold that is not finite and positive, too few inliers).
pub fn align_dof_robust(
    source: &[Vector3<f64>],
    target: &[Vector3<f64>],
    opts: &DofOptions,
    robust: &RobustOptions,
) -> Result<RobustAlignment> {
    check_robust(opts.weights.is_some(), robust)?;
    check_max_tilt(opts.max_tilt_deg)?;
    if opts.anchor == Anchor::None && !opts.dof.yaw_only() {
        return align_robust(source, target, &opts.align_options(), robust);
    }
    let fitter = DofRefit {
        source,
        target,
        dof: opts.dof,
        anchor: opts.anchor,
        method: opts.method,
    };
    let r = robust_refit(&fitter, source, target, robust)?;
    check_gravity(&r.alignment, opts)?;
    Ok(r)
}

struct DofRefit<'a> {
    source: &'a [Vector3<f64>],
    target: &'a [Vector3<f64>],
    dof: Dof,
    anchor: Anchor,
    method: AlignMethod,
}

impl Refit for DofRefit<'_> {
    fn minimal(&self) -> usize {
        match self.anchor {
            Anchor::None => self.dof.min_pairs(),
            Anchor::First => self.dof.min_pairs() - 1,
        }
    }

    fn min_inliers(&self) -> usize {
        self.dof.min_pairs()
    }

    fn sample(&self, idx: &[usize]) -> Result<Sim3> {
        let first = match self.anchor {
            Anchor::None => None,
            Anchor::First => Some(0),
        };
        let pick: Vec<usize> = first.into_iter().chain(idx.iter().copied()).collect();
        let a: Vec<_> = pick.iter().map(|&i| self.source[i]).collect();
        let b: Vec<_> = pick.iter().map(|&i| self.target[i]).collect();
        Ok(fit_alignment(&a, &b, None, self.dof, self.anchor, self.method)?.transform)
    }

    fn weighted(&self, weights: Option<Vec<f64>>) -> Result<Alignment> {
        fit_alignment(
            self.source,
            self.target,
            weights.as_deref(),
            self.dof,
            self.anchor,
            self.method,
        )
    }
}
