//! Trajectory alignment beyond one closed-form fit: the automatic start-up
//! cut, a robust fit, keyframe orientations, a time offset estimated from the
//! data, a known camera–body extrinsic, and the covariance of the result.
//! [`align_trajectories_extended`] with [`ExtendedOptions::default`] is
//! exactly [`crate::trajectory::align_trajectories`].

use nalgebra::{UnitQuaternion, Vector3};

use super::covariance::{covariance, Covariance};
use super::handeye::{align_with_extrinsic, align_with_orientations, body_positions};
use super::robust::{align_robust, RobustOptions};
use super::stages::{detect_stages, Stages};
use super::time_offset::{estimate_time_offset, TimeOffset, TimeOffsetOptions};
use super::{align, AlignOptions};
use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::trajectory::{
    associate, ApeStats, Trajectory, TrajectoryAlignOptions, TrajectoryAlignment,
};

/// Which matched pairs at the start are left out of the fit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SkipInit {
    /// Fit every pair.
    #[default]
    None,
    /// Drop the start-up stages found by [`detect_stages`] in the scale factors.
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
                    format!("expected \"auto\", \"none\" or a pair count, got {s:?}"),
                )
            }),
        }
    }
}

/// The options beyond [`TrajectoryAlignOptions`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ExtendedOptions {
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

/// The result of [`align_trajectories_extended`].
#[derive(Clone, Debug)]
pub struct ExtendedAlignment {
    /// The fit and the APE over all matched pairs (with the extrinsic applied).
    pub trajectory: TrajectoryAlignment,
    /// Seconds added to the SLAM stamps (given plus estimated).
    pub offset: f64,
    /// The offset search, when asked for.
    pub offset_estimate: Option<TimeOffset>,
    /// The stages, with [`SkipInit::Auto`].
    pub stages: Option<Stages>,
    /// Index of the first fitted pair (pairs before it were dropped).
    pub fit_start: usize,
    /// Why the pairs before `fit_start` were dropped.
    pub skip_reason: String,
    /// Per fitted pair: inlier of the robust fit.
    pub inliers: Option<Vec<bool>>,
    /// First-order covariance of the fit (positions only; `None` when the
    /// positions alone do not determine it).
    pub covariance: Option<Covariance>,
}

fn shifted(t: &Trajectory, d: f64) -> Trajectory {
    Trajectory {
        timestamps: t.timestamps.iter().map(|x| x + d).collect(),
        positions: t.positions.clone(),
        orientations: t.orientations.clone(),
    }
}

/// Scale factors of consecutive pairs, a zero SLAM step carrying the previous
/// factor (so that indices stay pair indices).
fn factors(src: &[Vector3<f64>], dst: &[Vector3<f64>]) -> Vec<f64> {
    let mut out = Vec::with_capacity(src.len().saturating_sub(1));
    let mut last = f64::NAN;
    for k in 0..src.len().saturating_sub(1) {
        let ds = (src[k + 1] - src[k]).norm_squared();
        let dr = (dst[k + 1] - dst[k]).norm_squared();
        let p = dr / ds;
        if p.is_finite() && p > 0.0 {
            last = p;
        }
        out.push(last);
    }
    // Leading gaps take the first valid factor.
    if let Some(first) = out.iter().copied().find(|v| v.is_finite()) {
        for v in out.iter_mut() {
            if !v.is_finite() {
                *v = first;
            } else {
                break;
            }
        }
    }
    out
}

fn orientations<'a>(t: &'a Trajectory, what: &str) -> Result<&'a [UnitQuaternion<f64>]> {
    t.orientations.as_deref().ok_or_else(|| {
        Error::invalid(
            what,
            "orientations are needed (use_orientations / body_from_cam) but the trajectory has none",
        )
    })
}

/// [`crate::trajectory::align_trajectories`] with the options of
/// [`ExtendedOptions`]: estimate the offset, associate, cut the start, fit
/// (robust / with orientations / with the extrinsic), APE over every pair,
/// covariance. Errors: those of the steps, and [`Error::InvalidArgument`] for
/// options that cannot be combined (robust with orientations) or missing
/// orientations.
pub fn align_trajectories_extended(
    slam: &Trajectory,
    reference: &Trajectory,
    base: &TrajectoryAlignOptions,
    ext: &ExtendedOptions,
) -> Result<ExtendedAlignment> {
    slam.check_lengths()?;
    reference.check_lengths()?;
    if ext.robust.is_some() && ext.use_orientations {
        return Err(Error::invalid(
            "robust",
            "a robust fit uses positions only; it cannot be combined with use_orientations",
        ));
    }
    let mut offset = base.offset;
    let offset_estimate = match &ext.estimate_offset {
        Some(o) => {
            let e = estimate_time_offset(&shifted(slam, base.offset), reference, o)?;
            offset += e.offset;
            Some(e)
        }
        None => None,
    };
    let pairs: Vec<(usize, usize)> = associate(reference, slam, base.max_diff, offset)
        .into_iter()
        .map(|(r, s)| (s, r))
        .collect();
    if pairs.len() < 3 {
        return Err(Error::TooFew {
            what: format!(
                "pose pairs matched within max_diff {} s (offset {offset} s)",
                base.max_diff
            ),
            need: 3,
            got: pairs.len(),
        });
    }
    let src: Vec<Vector3<f64>> = pairs.iter().map(|&(s, _)| slam.positions[s]).collect();
    let dst: Vec<Vector3<f64>> = pairs.iter().map(|&(_, r)| reference.positions[r]).collect();
    let need_rot = ext.use_orientations || ext.body_from_cam.is_some();
    let (src_rot, dst_rot) = if need_rot {
        let a = orientations(slam, "slam")?;
        let b = if ext.use_orientations {
            let b = orientations(reference, "reference")?;
            pairs.iter().map(|&(_, r)| b[r]).collect()
        } else {
            Vec::new()
        };
        (pairs.iter().map(|&(s, _)| a[s]).collect::<Vec<_>>(), b)
    } else {
        (Vec::new(), Vec::new())
    };

    let (fit_start, stages, skip_reason) = match ext.skip_init {
        SkipInit::None => (0, None, "no start-up cut asked for".to_string()),
        SkipInit::First(n) => (
            n.min(pairs.len()),
            None,
            format!("the first {n} matched pairs dropped as asked"),
        ),
        SkipInit::Auto => {
            let st = detect_stages(&factors(&src, &dst))?;
            let why = format!(
                "the first {} matched pairs dropped: {}",
                st.stable_start,
                st.describe()
            );
            (st.stable_start, Some(st), why)
        }
    };
    let end = base
        .first_n
        .map_or(pairs.len(), |n| (fit_start + n).min(pairs.len()));
    if end < fit_start + 3 {
        return Err(Error::TooFew {
            what: format!("pose pairs left to fit after dropping the first {fit_start}"),
            need: 3,
            got: end.saturating_sub(fit_start),
        });
    }
    let range = fit_start..end;
    let aopts = AlignOptions {
        scale: base.scale,
        method: base.method,
        weights: None,
    };
    let (fs, fd) = (&src[range.clone()], &dst[range.clone()]);
    let mut inliers = None;
    let alignment = if ext.use_orientations {
        align_with_orientations(
            fs,
            &src_rot[range.clone()],
            fd,
            &dst_rot[range.clone()],
            ext.body_from_cam.as_ref(),
            base.scale,
        )?
    } else {
        let plain = match &ext.body_from_cam {
            Some(x) => align_with_extrinsic(fs, &src_rot[range.clone()], fd, x, &aopts)?,
            None => align(fs, fd, &aopts)?,
        };
        match &ext.robust {
            Some(r) => {
                let moved = match &ext.body_from_cam {
                    Some(x) => body_positions(
                        fs,
                        &src_rot[range.clone()],
                        &lever(x)?,
                        plain.transform.scale,
                    ),
                    None => fs.to_vec(),
                };
                let rb = align_robust(&moved, fd, &aopts, r)?;
                inliers = Some(rb.inliers);
                rb.alignment
            }
            None => plain,
        }
    };
    let t = alignment.transform;
    // Every pair's SLAM position carried to the body origin with the fitted scale.
    let all_src = match &ext.body_from_cam {
        Some(x) => body_positions(&src, &src_rot, &lever(x)?, t.scale),
        None => src.clone(),
    };
    let errors: Vec<f64> = all_src
        .iter()
        .zip(&dst)
        .map(|(s, d)| (d - t.transform_point(s)).norm())
        .collect();
    let ape = ApeStats::from_errors(&errors)?;
    let weights: Option<Vec<f64>> = inliers
        .as_ref()
        .map(|m| m.iter().map(|&b| f64::from(u8::from(b))).collect());
    let covariance = covariance(
        &t,
        &all_src[range.clone()],
        fd,
        weights.as_deref(),
        base.scale,
    )
    .ok();
    Ok(ExtendedAlignment {
        trajectory: TrajectoryAlignment {
            alignment,
            pairs,
            ape,
            errors,
        },
        offset,
        offset_estimate,
        stages,
        fit_start,
        skip_reason,
        inliers,
        covariance,
    })
}

impl ExtendedAlignment {
    /// The report of what the extras did: start-up cut (and why), offset,
    /// inlier counts, `level` confidence intervals.
    pub fn report_json(&self, level: f64) -> serde_json::Value {
        let r = self;
        let mut v = serde_json::json!({
            "fit_start": r.fit_start,
            "skip_reason": r.skip_reason,
            "offset": r.offset,
        });
        if let Some(st) = &r.stages {
            v["stages"] = serde_json::json!({
                "converging_start": st.converging_start,
                "stable_start": st.stable_start,
                "n_factors": st.n,
                "stable_level": st.stable_level,
                "noise": st.noise,
                "window": st.window,
            });
        }
        if let Some(o) = &r.offset_estimate {
            v["offset_estimate"] = serde_json::json!({
                "estimated": o.offset, "rmse": o.rmse, "rmse_at_zero": o.rmse_at_zero,
                "n_used": o.n_used,
            });
        }
        if let Some(m) = &r.inliers {
            v["n_inliers"] = m.iter().filter(|&&b| b).count().into();
            v["n_outliers"] = m.iter().filter(|&&b| !b).count().into();
        }
        if let Some(c) = &r.covariance {
            if let (Ok(s), Ok(t), Ok(rot)) = (
                c.scale_interval(level),
                c.translation_intervals(level),
                c.rotation_half_widths(level),
            ) {
                v["intervals"] = serde_json::json!({
                    "level": level,
                    "scale": [s.0, s.1],
                    "translation": t.iter().map(|p| [p.0, p.1]).collect::<Vec<_>>(),
                    "rotation_half_width_deg": rot.iter().map(|x| x.to_degrees()).collect::<Vec<_>>(),
                    "sigma": c.sigma2.sqrt(),
                });
            }
        }
        v
    }
}

/// The lever arm `c` (body origin in the camera frame, metres) of `T_body_cam`.
fn lever(body_from_cam: &Sim3) -> Result<Vector3<f64>> {
    let unscaled = Sim3::try_new(body_from_cam.rotation, body_from_cam.translation, 1.0)?;
    Ok(unscaled.inverse().translation)
}
