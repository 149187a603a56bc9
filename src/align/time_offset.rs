//! Time offset between a SLAM trajectory and a reference, by maximising the
//! alignment quality: for a candidate offset `δ` the reference is interpolated
//! (lerp) at the SLAM stamps `+ δ`, a Sim(3) is fitted, and the rms residual
//! scored; a coarse grid over `[−max_offset, max_offset]` is refined around the
//! best value until the step is below [`TimeOffsetOptions::tolerance`].

use nalgebra::Vector3;

use super::{align, AlignOptions};
use crate::error::{Error, Result};
use crate::trajectory::Trajectory;

/// Options of [`estimate_time_offset`].
#[derive(Clone, Debug, PartialEq)]
pub struct TimeOffsetOptions {
    /// Largest offset searched, seconds (both signs).
    pub max_offset: f64,
    /// Largest reference gap bridged by interpolation, seconds.
    pub max_gap: f64,
    /// Fit Sim(3) (`false`: SE(3)).
    pub scale: bool,
    /// Stop refining when the grid step falls below this, seconds.
    pub tolerance: f64,
}

impl Default for TimeOffsetOptions {
    fn default() -> Self {
        TimeOffsetOptions {
            max_offset: crate::defaults::MAX_OFFSET,
            max_gap: crate::defaults::MAX_GAP,
            scale: true,
            tolerance: 1e-5,
        }
    }
}

/// The result of [`estimate_time_offset`].
#[derive(Clone, Debug, PartialEq)]
pub struct TimeOffset {
    /// Seconds to add to the SLAM stamps to match the reference.
    pub offset: f64,
    /// rms residual of the fit at that offset, reference units.
    pub rmse: f64,
    /// rms residual at offset 0 (same pairs), reference units.
    pub rmse_at_zero: f64,
    /// SLAM poses used (covered by the reference at every candidate offset).
    pub n_used: usize,
}

/// Estimates the seconds to add to `slam`'s stamps so that its motion matches
/// `reference` best (see the module doc). Errors: [`Error::InvalidArgument`]
/// (bad option), [`Error::TooFew`] (fewer than 3 SLAM poses covered at every
/// offset), and the errors of [`align`].
pub fn estimate_time_offset(
    slam: &Trajectory,
    reference: &Trajectory,
    opts: &TimeOffsetOptions,
) -> Result<TimeOffset> {
    slam.check_lengths()?;
    reference.check_lengths()?;
    for (what, v) in [
        ("max_offset", opts.max_offset),
        ("max_gap", opts.max_gap),
        ("tolerance", opts.tolerance),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(Error::invalid(
                what,
                format!("must be finite and > 0, got {}", crate::error::num(v)),
            ));
        }
    }
    let (Some(&r0), Some(&r1)) = (reference.timestamps.first(), reference.timestamps.last()) else {
        return Err(Error::TooFew {
            what: "reference poses".into(),
            need: 2,
            got: 0,
        });
    };
    // SLAM poses covered at every candidate offset.
    let m = opts.max_offset;
    if 2.0 * m >= r1 - r0 {
        return Err(Error::invalid(
            "max_offset",
            format!(
                "{} s is not below half the reference's span ({} s): no SLAM pose is covered at every offset searched",
                crate::error::num(m),
                crate::error::num(r1 - r0)
            ),
        ));
    }
    let used: Vec<usize> = (0..slam.len())
        .filter(|&i| {
            let t = slam.timestamps[i];
            t - m >= r0 && t + m <= r1
        })
        .collect();
    let times: Vec<f64> = used.iter().map(|&i| slam.timestamps[i]).collect();
    let src: Vec<Vector3<f64>> = used.iter().map(|&i| slam.positions[i]).collect();
    // Poses inside a reference gap at some offset are dropped up front: a set
    // that changes with the offset would make the score jump.
    let mut keep = vec![true; times.len()];
    let probes = 21;
    for j in 0..probes {
        let d = -m + 2.0 * m * j as f64 / (probes - 1) as f64;
        let shifted: Vec<f64> = times.iter().map(|t| t + d).collect();
        let w = reference.interpolate_where_covered(&shifted, opts.max_gap)?;
        for &k in &w.missing {
            keep[k] = false;
        }
    }
    let times: Vec<f64> = times
        .iter()
        .zip(&keep)
        .filter(|(_, &k)| k)
        .map(|(t, _)| *t)
        .collect();
    let src: Vec<Vector3<f64>> = src
        .iter()
        .zip(&keep)
        .filter(|(_, &k)| k)
        .map(|(p, _)| *p)
        .collect();
    if times.len() < 3 {
        return Err(Error::TooFew {
            what: format!(
                "SLAM poses covered by the reference at every offset within ±{} s",
                crate::error::num(m)
            ),
            need: 3,
            got: times.len(),
        });
    }
    let align_opts = AlignOptions {
        scale: opts.scale,
        ..Default::default()
    };
    let cost = |d: f64| -> Result<f64> {
        let shifted: Vec<f64> = times.iter().map(|t| t + d).collect();
        let w = reference.interpolate_where_covered(&shifted, opts.max_gap)?;
        if !w.missing.is_empty() {
            // A gap wider than max_gap met between probes: score it as poor.
            return Ok(f64::INFINITY);
        }
        let fit = align(&src, &w.trajectory.positions, &align_opts)?;
        Ok(fit.rmse)
    };
    let coarse = 50usize;
    let mut step = 2.0 * m / coarse as f64;
    let mut best = (0.0, cost(0.0)?);
    let rmse_at_zero = best.1;
    for j in 0..=coarse {
        let d = -m + step * j as f64;
        let c = cost(d)?;
        if c < best.1 {
            best = (d, c);
        }
    }
    while step > opts.tolerance {
        let centre = best.0;
        step /= 4.0;
        for j in -4i32..=4 {
            let d = (centre + step * f64::from(j)).clamp(-m, m);
            let c = cost(d)?;
            if c < best.1 {
                best = (d, c);
            }
        }
    }
    Ok(TimeOffset {
        offset: best.0,
        rmse: best.1,
        rmse_at_zero,
        n_used: times.len(),
    })
}
