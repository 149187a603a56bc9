//! Two trajectories in, one fit out: the associate-then-fit path every
//! command and binding uses.
//!
//! [`align_trajectories`] associates the SLAM stamps with the reference by
//! time (evo's rule, [`crate::trajectory::associate`], or the TUM benchmark's
//! one-to-one rule, [`crate::trajectory::associate_one_to_one`]), optionally
//! after estimating the time offset, cuts the start-up stages, fits
//! `T_world_slam` with the degrees of freedom and anchor asked for
//! ([`super::dof`]: closed form; robust, with orientations or with a known
//! camera–body extrinsic as asked), refuses fits that say nothing
//! ([`super::checks`]), and reports the absolute position error over every
//! matched pair with the first-order covariance of the fit. The windowed fit
//! and the hand-eye estimate pair their poses through
//! [`crate::trajectory::matched_pairs`] too.

use nalgebra::{UnitQuaternion, Vector3};

use super::checks::{check_fit, check_reference_moves, FitChecks, FitQuality};
use super::covariance::{covariance, Covariance};
use super::dof::{align_dof, align_dof_robust, covariance_dof, Anchor, Dof, DofOptions};
use super::handeye::{align_with_extrinsic_by, align_with_orientations_dof, body_positions};
use super::robust::RobustOptions;
use super::stages::{factors_over, stages_of_pairs, Stages};
use super::time_offset::{estimate_time_offset, TimeOffset, TimeOffsetOptions};
use super::{AlignMethod, Alignment};
use crate::defaults;
use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::trajectory::{matched_pairs_with, Association, Trajectory};

/// Which matched pairs at the start are left out of the fit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SkipInit {
    /// Fit every pair.
    #[default]
    None,
    /// Drop the start-up stages found by [`detect_stages`](super::stages::detect_stages) in the scale factors.
    Auto,
    /// Drop the first `n` matched pairs.
    First(usize),
}

impl std::str::FromStr for SkipInit {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "auto" => Ok(SkipInit::Auto),
            "none" => Ok(SkipInit::None),
            other => other.parse::<usize>().map(SkipInit::First).map_err(|_| {
                Error::invalid(
                    "skip_init",
                    format!(
                        "expected \"auto\", \"none\" or a pair count, got {}",
                        crate::error::cut(s)
                    ),
                )
            }),
        }
    }
}

/// Options of [`align_trajectories`].
#[derive(Clone, Debug, PartialEq)]
pub struct TrajectoryAlignOptions {
    /// Largest time difference of a matched pair, seconds ([`defaults::MAX_DIFF`]).
    pub max_diff: f64,
    /// Seconds added to the SLAM stamps before matching ([`defaults::OFFSET`]).
    pub offset: f64,
    /// Estimate the scale (default true); `false` turns `sim3` into `se3`
    /// and is refused with `scale+4dof`.
    pub scale: bool,
    /// The transforms the fit chooses from ([`defaults::DOF`]).
    pub dof: Dof,
    /// The pair pinned exactly: [`Anchor::First`] maps the first fitted pair
    /// (the first matched pair after the start-up cut) onto its reference.
    pub anchor: Anchor,
    /// Largest tilt of the estimate's gravity (degrees, by the Sim(3) fit) a
    /// yaw-only fit accepts ([`defaults::MAX_TILT_DEG`]); `None`: no check.
    pub max_tilt_deg: Option<f64>,
    /// How SLAM stamps are paired with reference stamps ([`defaults::ASSOCIATION`]).
    pub association: Association,
    /// Fit-quality refusals (static reference, unexplained spread, nothing
    /// fitted) and their thresholds.
    pub checks: FitChecks,
    /// Fit only the first `n` pairs after the start-up cut (evo's
    /// `--n_to_align`; the APE still covers every pair).
    pub n_to_align: Option<usize>,
    /// Rotation solver.
    pub method: AlignMethod,
    /// Pairs left out of the fit at the start.
    pub skip_init: SkipInit,
    /// Fit robustly (RANSAC + IRLS), flagging outlier pairs.
    pub robust: Option<RobustOptions>,
    /// Join the orientations (both trajectories need them) to the positions.
    pub use_orientations: bool,
    /// Estimate the time offset (searched within `max_offset` seconds of
    /// [`TrajectoryAlignOptions::offset`]) and apply it.
    pub estimate_offset: Option<TimeOffsetOptions>,
    /// A known `T_body_cam`: the SLAM camera poses are carried to the body
    /// (reference) origin before the fit (needs SLAM orientations).
    pub body_from_cam: Option<Sim3>,
}

impl Default for TrajectoryAlignOptions {
    fn default() -> Self {
        TrajectoryAlignOptions {
            max_diff: defaults::MAX_DIFF,
            offset: defaults::OFFSET,
            scale: true,
            dof: Dof::Sim3,
            anchor: Anchor::None,
            max_tilt_deg: Some(defaults::MAX_TILT_DEG),
            association: Association::Evo,
            checks: FitChecks::default(),
            n_to_align: None,
            method: AlignMethod::Horn,
            skip_init: SkipInit::None,
            robust: None,
            use_orientations: false,
            estimate_offset: None,
            body_from_cam: None,
        }
    }
}

impl TrajectoryAlignOptions {
    /// The degrees of freedom fitted: [`Self::dof`] with [`Self::scale`]
    /// applied (`sim3` without scale is `se3`).
    pub fn fitted_dof(&self) -> Result<Dof> {
        self.dof.with_scale_flag(self.scale)
    }

    /// The options of the positions-only fit.
    fn dof_options(&self) -> Result<DofOptions> {
        Ok(DofOptions {
            dof: self.fitted_dof()?,
            anchor: self.anchor,
            weights: None,
            method: self.method,
            max_tilt_deg: self.max_tilt_deg,
        })
    }

    /// Checks what does not depend on the data: `max_diff` finite and `≥ 0`,
    /// `offset` finite, `n_to_align ≥ 3`, `max_tilt_deg` finite and `≥ 0`,
    /// the checks' thresholds, options that cannot be combined (`scale: false`
    /// with `scale+4dof`, a robust fit with orientations).
    pub fn check(&self) -> Result<()> {
        self.fitted_dof()?;
        self.checks.check()?;
        if let Some(t) = self.max_tilt_deg {
            if !(t.is_finite() && t >= 0.0) {
                return Err(Error::invalid(
                    "max_tilt_deg",
                    format!(
                        "must be finite and >= 0 degrees, got {}",
                        crate::error::num(t)
                    ),
                ));
            }
        }
        if !(self.max_diff.is_finite() && self.max_diff >= 0.0) {
            return Err(Error::invalid(
                "max_diff",
                format!(
                    "must be a finite number of seconds >= 0, got {}",
                    crate::error::num(self.max_diff)
                ),
            ));
        }
        if !self.offset.is_finite() {
            return Err(Error::invalid(
                "offset",
                format!("must be finite, got {}", self.offset),
            ));
        }
        if let Some(n) = self.n_to_align {
            if n < 3 {
                return Err(Error::invalid(
                    "n_to_align",
                    format!("a fit needs at least 3 pairs, got {n}"),
                ));
            }
        }
        if self.robust.is_some() && self.use_orientations {
            return Err(Error::invalid(
                "robust",
                "a robust fit uses positions only; it cannot be combined with use_orientations",
            ));
        }
        Ok(())
    }
}

/// Statistics of the absolute position error `‖p_ref − T(p_slam)‖` over all
/// matched pairs, metres (as evo's APE, translation part; `std` is the
/// population standard deviation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ApeStats {
    /// Root mean square.
    pub rmse: f64,
    /// Mean.
    pub mean: f64,
    /// Median (mean of the two middle values for an even count).
    pub median: f64,
    /// Population standard deviation.
    pub std: f64,
    /// Smallest error.
    pub min: f64,
    /// Largest error.
    pub max: f64,
    /// Number of pairs.
    pub n_pairs: usize,
}

impl ApeStats {
    /// Statistics of `errors` (at least one, all finite).
    pub fn from_errors(errors: &[f64]) -> Result<ApeStats> {
        if errors.is_empty() {
            return Err(Error::TooFew {
                what: "errors".into(),
                need: 1,
                got: 0,
            });
        }
        if let Some(i) = errors.iter().position(|e| !e.is_finite()) {
            return Err(Error::NonFinite {
                what: "errors".into(),
                index: i,
            });
        }
        let n = errors.len() as f64;
        let mean = errors.iter().sum::<f64>() / n;
        let rmse = (errors.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
        let std = (errors.iter().map(|e| (e - mean) * (e - mean)).sum::<f64>() / n).sqrt();
        let mut sorted = errors.to_vec();
        sorted.sort_by(f64::total_cmp);
        let m = sorted.len() / 2;
        let median = if sorted.len() % 2 == 1 {
            sorted[m]
        } else {
            (sorted[m - 1] + sorted[m]) / 2.0
        };
        Ok(ApeStats {
            rmse,
            mean,
            median,
            std,
            min: sorted[0],
            max: sorted[sorted.len() - 1],
            n_pairs: errors.len(),
        })
    }
}

/// The result of [`align_trajectories`].
#[derive(Clone, Debug)]
pub struct TrajectoryAlignment {
    /// The fit: `transform` is `T_world_slam` (maps SLAM positions onto the
    /// reference); residuals over the fitted pairs.
    pub alignment: Alignment,
    /// Matched pairs `(slam index, reference index)`, in SLAM time order.
    pub pairs: Vec<(usize, usize)>,
    /// Error statistics over all matched pairs (with the extrinsic applied).
    pub ape: ApeStats,
    /// Per pair `‖p_ref − T(p_slam)‖`, metres, in the order of `pairs`.
    pub errors: Vec<f64>,
    /// Seconds added to the SLAM stamps (given plus estimated).
    pub offset: f64,
    /// The offset search, when asked for.
    pub offset_estimate: Option<TimeOffset>,
    /// The stages, with [`SkipInit::Auto`].
    pub stages: Option<Stages>,
    /// Index of the first fitted pair (pairs before it were dropped).
    pub fit_start: usize,
    /// Number of pairs in the fitted range `fit_start..fit_start + n_fit`.
    pub n_fit: usize,
    /// Why the pairs before `fit_start` were dropped.
    pub skip_reason: String,
    /// Per pair of the fitted range: inlier of the robust fit.
    pub inliers: Option<Vec<bool>>,
    /// First-order covariance of the fit over the Sim(3) parameters
    /// (positions only; zero where the dof fixes a parameter; `None` when the
    /// positions alone do not determine it).
    pub covariance: Option<Covariance>,
    /// The degrees of freedom fitted (`se3` for `sim3` without scale).
    pub dof: Dof,
    /// The anchor of the fit.
    pub anchor: Anchor,
    /// The pairing rule used.
    pub association: Association,
    /// The figures the fit-quality refusals looked at.
    pub quality: FitQuality,
}

impl TrajectoryAlignment {
    /// `T_world_slam`.
    pub fn transform(&self) -> Sim3 {
        self.alignment.transform
    }

    /// True when matched pair `k` (an index into `pairs`) was used in the fit:
    /// inside the fitted range and, with a robust fit, an inlier.
    pub fn fitted(&self, k: usize) -> bool {
        let range = self.fit_start..self.fit_start + self.n_fit;
        range.contains(&k) && self.inliers.as_ref().is_none_or(|m| m[k - self.fit_start])
    }
}

fn shifted(t: &Trajectory, d: f64) -> Trajectory {
    Trajectory {
        timestamps: t.timestamps.iter().map(|x| x + d).collect(),
        positions: t.positions.clone(),
        orientations: t.orientations.clone(),
    }
}

/// The scale factors of consecutive matched pairs as the start-up detection
/// sees them: `p_k = ‖dst_{k+1} − dst_k‖² / ‖src_{k+1} − src_k‖²` (`src` SLAM
/// positions, `dst` reference positions, metres), a zero SLAM step carrying
/// the previous factor so that `k` stays a pair index; `n − 1` factors.
pub fn fit_scale_factors(src: &[Vector3<f64>], dst: &[Vector3<f64>]) -> Vec<f64> {
    factors_over(src, dst, 1)
}

fn orientations<'a>(t: &'a Trajectory, what: &str) -> Result<&'a [UnitQuaternion<f64>]> {
    t.orientations.as_deref().ok_or_else(|| {
        Error::invalid(
            what,
            "orientations are needed (use_orientations / body_from_cam) but the trajectory has none",
        )
    })
}

/// Refuses pairs that hold fewer than 3 distinct stamps on either side (a
/// file whose stamps repeat): the fit would see coincident points and say
/// less about why.
fn distinct_stamps(
    slam: &Trajectory,
    reference: &Trajectory,
    pairs: &[(usize, usize)],
) -> Result<()> {
    let count = |t: &[f64], idx: &mut dyn Iterator<Item = usize>| {
        let mut v: Vec<f64> = idx.map(|i| t[i]).collect();
        v.sort_by(f64::total_cmp);
        v.dedup();
        v.len()
    };
    let s = count(&slam.timestamps, &mut pairs.iter().map(|p| p.0));
    let r = count(&reference.timestamps, &mut pairs.iter().map(|p| p.1));
    if s < 3 || r < 3 {
        return Err(Error::TooFew {
            what: format!(
                "distinct time stamps among the {} matched pairs (SLAM {s}, reference {r}: the stamps repeat)",
                pairs.len()
            ),
            need: 3,
            got: s.min(r),
        });
    }
    Ok(())
}

/// The fitted range `fit_start..end` of `n` matched pairs, with the stages
/// and the reason for the cut.
fn fit_range(
    opts: &TrajectoryAlignOptions,
    src: &[Vector3<f64>],
    dst: &[Vector3<f64>],
) -> Result<(usize, usize, Option<Stages>, String)> {
    let n = src.len();
    let (fit_start, stages, skip_reason) = match opts.skip_init {
        SkipInit::None => (0, None, "no start-up cut asked for".to_string()),
        SkipInit::First(k) => (
            k.min(n),
            None,
            format!("the first {k} matched pairs dropped as asked"),
        ),
        SkipInit::Auto => {
            let (st, _) = stages_of_pairs(src, dst)?;
            let why = format!(
                "the first {} matched pairs dropped: {}",
                st.stable_start,
                st.describe()
            );
            (st.stable_start, Some(st), why)
        }
    };
    let end = opts.n_to_align.map_or(n, |k| (fit_start + k).min(n));
    if end < fit_start + 3 {
        let what = match (opts.skip_init, opts.n_to_align) {
            (SkipInit::None, None) => "matched pose pairs to fit".to_string(),
            (SkipInit::None, Some(k)) => format!("pairs to fit (n_to_align {k})"),
            (_, _) => format!(
                "pairs left to fit of {n} matched after the start-up cut of {fit_start} ({skip_reason})"
            ),
        };
        return Err(Error::TooFew {
            what,
            need: 3,
            got: end.saturating_sub(fit_start),
        });
    }
    Ok((fit_start, end, stages, skip_reason))
}

/// Associates `slam` with `reference` by time, fits `T_world_slam` as the
/// options ask and reports the APE over all pairs (see the module doc).
///
/// Errors: [`TrajectoryAlignOptions::check`]'s, [`Error::Unmatched`] (fewer
/// than 3 pairs), [`Error::TooFew`] (fewer than 3 pairs left after the cut),
/// [`Error::InvalidArgument`] (missing orientations), the errors of the fit
/// itself (degenerate motion, [`Error::GravityTilted`] for a yaw-only fit of
/// a tilted estimate) and the refusals of [`super::checks`]
/// ([`Error::StaticReference`], [`Error::NothingFitted`],
/// [`Error::UnexplainedSpread`]).
pub fn align_trajectories(
    slam: &Trajectory,
    reference: &Trajectory,
    opts: &TrajectoryAlignOptions,
) -> Result<TrajectoryAlignment> {
    align_trajectories_weighted(slam, reference, None, opts)
}

/// [`align_trajectories`] with one weight per reference pose
/// (`reference_weights`, non-negative, e.g. `1/σ²` of a GNSS fix): each
/// matched pair weighs what its reference pose does, in the closed-form fit
/// and its covariance. Refused with a robust fit (which chooses its own
/// weights) and with `use_orientations` (the joint fit takes none).
pub fn align_trajectories_weighted(
    slam: &Trajectory,
    reference: &Trajectory,
    reference_weights: Option<&[f64]>,
    opts: &TrajectoryAlignOptions,
) -> Result<TrajectoryAlignment> {
    opts.check()?;
    if let Some(w) = reference_weights {
        if w.len() != reference.len() {
            return Err(Error::ShapeMismatch {
                what: "reference weights".into(),
                expected: format!("({},), one per reference pose", reference.len()),
                got: format!("({},)", w.len()),
            });
        }
        if opts.robust.is_some() || opts.use_orientations {
            return Err(Error::invalid(
                "weights",
                "per-pose weights cannot be combined with a robust fit or use_orientations",
            ));
        }
    }
    slam.check_lengths()?;
    reference.check_lengths()?;
    let mut offset = opts.offset;
    let offset_estimate = match &opts.estimate_offset {
        Some(o) => {
            let e = estimate_time_offset(&shifted(slam, opts.offset), reference, o)?;
            offset += e.offset;
            Some(e)
        }
        None => None,
    };
    let pairs = matched_pairs_with(slam, reference, opts.max_diff, offset, 3, opts.association)?;
    distinct_stamps(slam, reference, &pairs)?;
    let src: Vec<Vector3<f64>> = pairs.iter().map(|&(s, _)| slam.positions[s]).collect();
    let dst: Vec<Vector3<f64>> = pairs.iter().map(|&(_, r)| reference.positions[r]).collect();
    let need_rot = opts.use_orientations || opts.body_from_cam.is_some();
    let (src_rot, dst_rot) = if need_rot {
        let a = orientations(slam, "slam")?;
        let b = if opts.use_orientations {
            let b = orientations(reference, "reference")?;
            pairs.iter().map(|&(_, r)| b[r]).collect()
        } else {
            Vec::new()
        };
        (pairs.iter().map(|&(s, _)| a[s]).collect::<Vec<_>>(), b)
    } else {
        (Vec::new(), Vec::new())
    };

    let (fit_start, end, stages, skip_reason) = fit_range(opts, &src, &dst)?;
    let range = fit_start..end;
    let mut dopts = opts.dof_options()?;
    let pair_weights: Option<Vec<f64>> =
        reference_weights.map(|w| pairs[range.clone()].iter().map(|&(_, r)| w[r]).collect());
    dopts.weights = pair_weights.clone();
    let dof = dopts.dof;
    let (fs, fd) = (&src[range.clone()], &dst[range.clone()]);
    // The reference's own poses over the fitted span, for its noise.
    let run = {
        let fitted = &pairs[range.clone()];
        let lo = fitted.iter().map(|p| p.1).min().unwrap_or(0);
        let hi = fitted.iter().map(|p| p.1).max().unwrap_or(0);
        &reference.positions[lo..=hi.max(lo)]
    };
    check_reference_moves(fd, run, &opts.checks)?;
    let mut inliers = None;
    let alignment = if opts.use_orientations {
        align_with_orientations_dof(
            fs,
            &src_rot[range.clone()],
            fd,
            &dst_rot[range.clone()],
            opts.body_from_cam.as_ref(),
            &dopts,
        )?
    } else {
        let fit = |a: &[Vector3<f64>], b: &[Vector3<f64>]| align_dof(a, b, &dopts);
        let plain = match &opts.body_from_cam {
            Some(x) => align_with_extrinsic_by(fs, &src_rot[range.clone()], fd, x, fit)?,
            None => fit(fs, fd)?,
        };
        match &opts.robust {
            Some(r) => {
                let moved = match &opts.body_from_cam {
                    Some(x) => body_positions(
                        fs,
                        &src_rot[range.clone()],
                        &lever(x)?,
                        plain.transform.scale,
                    ),
                    None => fs.to_vec(),
                };
                let rb = align_dof_robust(&moved, fd, &dopts, r)?;
                inliers = Some(rb.inliers);
                rb.alignment
            }
            None => plain,
        }
    };
    let t = alignment.transform;
    // Every pair's SLAM position carried to the body origin with the fitted scale.
    let all_src = match &opts.body_from_cam {
        Some(x) => body_positions(&src, &src_rot, &lever(x)?, t.scale),
        None => src,
    };
    let errors: Vec<f64> = all_src
        .iter()
        .zip(&dst)
        .map(|(s, d)| (d - t.transform_point(s)).norm())
        .collect();
    let ape = ApeStats::from_errors(&errors)?;
    let weights: Option<Vec<f64>> = inliers
        .as_ref()
        .map(|m| m.iter().map(|&b| f64::from(u8::from(b))).collect())
        .or(pair_weights);
    let fitted_reference: Vec<Vector3<f64>> = match &inliers {
        Some(m) => fd
            .iter()
            .zip(m)
            .filter(|(_, &k)| k)
            .map(|(p, _)| *p)
            .collect(),
        None => fd.to_vec(),
    };
    let quality = check_fit(
        &fitted_reference,
        run,
        alignment.rmse,
        t.scale,
        dof.has_scale(),
        &opts.checks,
    )?;
    let fitted_src = &all_src[range.clone()];
    let covariance = match (dof, opts.anchor) {
        (Dof::Sim3 | Dof::Se3, Anchor::None) => {
            covariance(&t, fitted_src, fd, weights.as_deref(), dof.has_scale()).ok()
        }
        _ => covariance_dof(&t, fitted_src, fd, weights.as_deref(), dof, opts.anchor)
            .ok()
            .map(|c| c.to_sim3()),
    };
    Ok(TrajectoryAlignment {
        alignment,
        pairs,
        ape,
        errors,
        offset,
        offset_estimate,
        stages,
        fit_start,
        n_fit: end - fit_start,
        skip_reason,
        inliers,
        covariance,
        dof,
        anchor: opts.anchor,
        association: opts.association,
        quality,
    })
}

/// The lever arm `c` (body origin in the camera frame, metres) of `T_body_cam`.
fn lever(body_from_cam: &Sim3) -> Result<Vector3<f64>> {
    let unscaled = Sim3::try_new(body_from_cam.rotation, body_from_cam.translation, 1.0)?;
    Ok(unscaled.inverse().translation)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(times: &[f64]) -> Trajectory {
        let p = times
            .iter()
            .map(|&t| Vector3::new(t, 2.0 * t * t, t.sin()))
            .collect();
        Trajectory::try_new(times.to_vec(), p, None).unwrap()
    }

    #[test]
    fn ape_stats_match_definitions() {
        let s = ApeStats::from_errors(&[1.0, 2.0, 3.0, 4.0]).unwrap();
        assert_eq!(s.median, 2.5);
        assert!((s.rmse - 7.5f64.sqrt()).abs() < 1e-15);
        assert!((s.std - 1.25f64.sqrt()).abs() < 1e-15);
        assert_eq!((s.min, s.max, s.n_pairs), (1.0, 4.0, 4));
        assert!(ApeStats::from_errors(&[]).is_err());
    }

    #[test]
    fn inconsistent_literals_are_refused_not_panicking() {
        let mut t = line(&[0.0, 1.0, 2.0]);
        t.positions.pop();
        let r = line(&[0.0, 1.0, 2.0]);
        let opts = TrajectoryAlignOptions::default();
        assert!(matches!(
            align_trajectories(&t, &r, &opts),
            Err(Error::ShapeMismatch { .. })
        ));
        assert!(align_trajectories(&r, &t, &opts).is_err());
    }

    #[test]
    fn unmatched_names_the_ranges_and_the_cause() {
        let secs: Vec<f64> = (0..20).map(|i| 100.0 + i as f64 * 0.1).collect();
        let nanos: Vec<f64> = secs.iter().map(|t| t * 1e9).collect();
        let opts = TrajectoryAlignOptions::default();
        let e = align_trajectories(&line(&nanos), &line(&secs), &opts).unwrap_err();
        let Error::Unmatched {
            matched,
            need,
            cause,
            ..
        } = &e
        else {
            panic!("{e}")
        };
        assert_eq!((*matched, *need), (0, 3));
        assert!(cause.contains("nanoseconds"), "{cause}");
        let later: Vec<f64> = secs.iter().map(|t| t + 50.0).collect();
        let Err(Error::Unmatched { cause, .. }) =
            align_trajectories(&line(&later), &line(&secs), &opts)
        else {
            panic!("expected Unmatched")
        };
        assert!(cause.contains("offset of about -50 s"), "{cause}");
        // A shifted SLAM clock matched once the offset is given.
        let shifted = TrajectoryAlignOptions {
            offset: -50.0,
            ..TrajectoryAlignOptions::default()
        };
        assert_eq!(
            align_trajectories(&line(&later), &line(&secs), &shifted)
                .unwrap()
                .pairs
                .len(),
            20
        );
    }

    #[test]
    fn options_are_checked_before_the_data() {
        let t = line(&[0.0, 1.0, 2.0, 3.0]);
        for (opts, what) in [
            (
                TrajectoryAlignOptions {
                    n_to_align: Some(0),
                    ..Default::default()
                },
                "n_to_align",
            ),
            (
                TrajectoryAlignOptions {
                    max_diff: f64::NAN,
                    ..Default::default()
                },
                "max_diff",
            ),
            (
                TrajectoryAlignOptions {
                    robust: Some(RobustOptions::default()),
                    use_orientations: true,
                    ..Default::default()
                },
                "robust",
            ),
        ] {
            match align_trajectories(&t, &t, &opts) {
                Err(Error::InvalidArgument { what: w, .. }) => assert_eq!(w, what),
                other => panic!("{what}: {other:?}"),
            }
        }
    }

    #[test]
    fn a_cut_that_leaves_too_few_says_so() {
        let times: Vec<f64> = (0..10).map(|i| i as f64).collect();
        let t = line(&times);
        let opts = TrajectoryAlignOptions {
            skip_init: SkipInit::First(99),
            ..Default::default()
        };
        let Err(Error::TooFew { what, got, .. }) = align_trajectories(&t, &t, &opts) else {
            panic!("expected TooFew")
        };
        assert_eq!(got, 0);
        assert!(
            what.contains("of 10 matched after the start-up cut of 10"),
            "{what}"
        );
    }
}
