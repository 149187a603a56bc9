//! Fit-quality refusals: fits that COLMAP's `model_aligner` lets through
//! and that a user should never be handed as an answer.
//!
//! Three checks, each on the fitted pairs (the inliers of a robust fit), each
//! a typed error that names its figure:
//!
//! - **static reference** ([`Error::StaticReference`]): the reference
//!   positions stay within their noise of each other — their rms spread about
//!   their centroid is at most [`FitChecks::min_spread_over_noise`] times the
//!   reference noise, so there is no motion to fit a transform to;
//! - **unexplained spread** ([`Error::UnexplainedSpread`]): the fit rmse is at
//!   least [`FitChecks::max_residual_over_spread`] of that spread — the fit
//!   explains almost none of the reference's motion (mixed frames such as ECEF
//!   beside ENU, a wrong reference, wrong time pairs);
//! - **nothing fitted** ([`Error::NothingFitted`]): a fit that estimates the
//!   scale returns one within [`FitChecks::min_scale_change`] of 1 while its
//!   rmse is more than [`FitChecks::max_unfitted_residual_over_noise`] times
//!   the noise (the estimate handed back as it came).
//!
//! The reference noise (metres, 3-D rms of one position's error) is the
//! stated [`FitChecks::reference_noise`] when given; otherwise it is estimated
//! from the reference's own poses over the fitted time span (every pose of
//! the reference there, at its own rate, not only the matched ones: sparse
//! keyframe pairs would see the path's curvature as noise), in time order, by
//! their second differences: `sqrt(Σ‖b_{k+1} − 2·b_k + b_{k−1}‖² / (6·(n −
//! 2)))`, which for white noise of per-axis deviation `σ` is `√3·σ` (the 3-D
//! rms of one error) and grows only with the path's curvature (`a·Δt²`) for a
//! smooth motion. With fewer than [`MIN_PAIRS_FOR_NOISE`] such poses and no
//! stated noise, the two checks that need the noise are skipped.

use nalgebra::Vector3;

use crate::defaults;
use crate::error::{Error, Result};

/// Fewest reference poses from which the reference noise is estimated.
pub const MIN_PAIRS_FOR_NOISE: usize = 8;

/// Thresholds of the fit-quality refusals (defaults in [`crate::defaults`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitChecks {
    /// Make the checks at all.
    pub enabled: bool,
    /// The reference's position noise, metres (3-D rms of one position's
    /// error, e.g. `√3·σ` for a per-axis deviation `σ`), as stated by the
    /// user; `None`: estimated from the reference's second differences.
    pub reference_noise: Option<f64>,
    /// A reference whose rms spread is at most this many times its noise is
    /// static ([`defaults::MIN_SPREAD_OVER_NOISE`]); 0 turns the check off.
    pub min_spread_over_noise: f64,
    /// A fit whose rmse is at least this fraction of the reference's rms
    /// spread explains none of it ([`defaults::MAX_RESIDUAL_OVER_SPREAD`]);
    /// infinity turns the check off.
    pub max_residual_over_spread: f64,
    /// A fitted scale closer to 1 than this counts as unchanged
    /// ([`defaults::MIN_SCALE_CHANGE`]); 0 turns the check off.
    pub min_scale_change: f64,
    /// ... when the rmse is more than this many times the reference noise
    /// ([`defaults::MAX_UNFITTED_RESIDUAL_OVER_NOISE`]).
    pub max_unfitted_residual_over_noise: f64,
}

impl Default for FitChecks {
    fn default() -> Self {
        FitChecks {
            enabled: true,
            reference_noise: None,
            min_spread_over_noise: defaults::MIN_SPREAD_OVER_NOISE,
            max_residual_over_spread: defaults::MAX_RESIDUAL_OVER_SPREAD,
            min_scale_change: defaults::MIN_SCALE_CHANGE,
            max_unfitted_residual_over_noise: defaults::MAX_UNFITTED_RESIDUAL_OVER_NOISE,
        }
    }
}

impl FitChecks {
    /// No refusal.
    pub fn off() -> Self {
        FitChecks {
            enabled: false,
            ..FitChecks::default()
        }
    }

    /// Checks the thresholds: a stated noise finite and `≥ 0`, the ratios
    /// `≥ 0` (and not NaN; `max_residual_over_spread` may be infinite).
    pub fn check(&self) -> Result<()> {
        if let Some(n) = self.reference_noise {
            if !(n.is_finite() && n >= 0.0) {
                return Err(Error::invalid(
                    "reference_noise",
                    format!(
                        "must be a finite number of metres >= 0, got {}",
                        crate::error::num(n)
                    ),
                ));
            }
        }
        for (what, v, infinite_ok) in [
            ("min_spread_over_noise", self.min_spread_over_noise, false),
            (
                "max_residual_over_spread",
                self.max_residual_over_spread,
                true,
            ),
            ("min_scale_change", self.min_scale_change, false),
            (
                "max_unfitted_residual_over_noise",
                self.max_unfitted_residual_over_noise,
                false,
            ),
        ] {
            if !(v >= 0.0 && (infinite_ok || v.is_finite())) {
                return Err(Error::invalid(
                    what,
                    format!("must be a finite number >= 0, got {}", crate::error::num(v)),
                ));
            }
        }
        Ok(())
    }
}

/// Where the reference noise of [`FitQuality`] came from.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
pub enum NoiseSource {
    /// Given by the user ([`FitChecks::reference_noise`]).
    #[serde(rename = "stated")]
    Stated,
    /// Estimated from the reference's second differences.
    #[serde(rename = "second_differences")]
    SecondDifferences,
}

impl NoiseSource {
    fn describe(self) -> &'static str {
        match self {
            NoiseSource::Stated => "as stated",
            NoiseSource::SecondDifferences => {
                "estimated from the second differences of the reference positions"
            }
        }
    }
}

/// The figures the refusals look at, for the report (also when none refused).
#[derive(Clone, Debug, PartialEq, serde::Serialize, schemars::JsonSchema)]
pub struct FitQuality {
    /// rms distance of the fitted reference positions to their centroid, metres.
    pub reference_spread: f64,
    /// The reference noise, metres (3-D rms); `None` when neither stated nor
    /// estimable (too few pairs).
    pub reference_noise: Option<f64>,
    /// Where `reference_noise` came from.
    pub noise_source: Option<NoiseSource>,
    /// `reference_spread / reference_noise` (`None` when the noise is 0 or
    /// unknown).
    pub spread_over_noise: Option<f64>,
    /// Fit rmse over `reference_spread` (0: the fit explains all of it).
    pub residual_over_spread: f64,
    /// `|s − 1|` of the fitted scale.
    pub scale_change: f64,
}

/// The reference noise from second differences of `b` (in time order), 3-D
/// rms; `None` with fewer than [`MIN_PAIRS_FOR_NOISE`] points.
pub fn second_difference_noise(b: &[Vector3<f64>]) -> Option<f64> {
    let n = b.len();
    if n < MIN_PAIRS_FOR_NOISE {
        return None;
    }
    let sum: f64 = b
        .windows(3)
        .map(|w| (w[2] - w[1] * 2.0 + w[0]).norm_squared())
        .sum();
    Some((sum / (6.0 * (n - 2) as f64)).sqrt())
}

/// rms distance of `b` to its centroid.
fn rms_spread(b: &[Vector3<f64>]) -> f64 {
    let n = b.len().max(1) as f64;
    let mean = b.iter().sum::<Vector3<f64>>() / n;
    (b.iter().map(|p| (p - mean).norm_squared()).sum::<f64>() / n).sqrt()
}

fn noise_of(reference: &[Vector3<f64>], checks: &FitChecks) -> (Option<f64>, Option<NoiseSource>) {
    match checks.reference_noise {
        Some(n) => (Some(n), Some(NoiseSource::Stated)),
        None => match second_difference_noise(reference) {
            Some(n) => (Some(n), Some(NoiseSource::SecondDifferences)),
            None => (None, None),
        },
    }
}

/// The static-reference check, before any fit: `reference` are the fitted
/// pairs' reference positions, `run` the reference's poses over their time
/// span in time order (for the noise estimate). Errors:
/// [`Error::StaticReference`].
pub fn check_reference_moves(
    reference: &[Vector3<f64>],
    run: &[Vector3<f64>],
    checks: &FitChecks,
) -> Result<()> {
    if !checks.enabled || checks.min_spread_over_noise == 0.0 {
        return Ok(());
    }
    let spread = rms_spread(reference);
    let (Some(noise), Some(source)) = noise_of(run, checks) else {
        return Ok(());
    };
    if spread <= checks.min_spread_over_noise * noise {
        return Err(Error::StaticReference {
            spread_m: spread,
            noise_m: noise,
            noise_source: source.describe().into(),
            threshold: checks.min_spread_over_noise,
            n: reference.len(),
        });
    }
    Ok(())
}

/// The figures of a fit with rmse `rmse` (metres) and scale `scale` to the
/// pairs' reference positions `reference` (`run`: the reference's poses over
/// their time span, for the noise, as [`check_reference_moves`]), and its
/// refusal: [`Error::NothingFitted`] (only when `fits_scale`), then
/// [`Error::UnexplainedSpread`].
pub fn check_fit(
    reference: &[Vector3<f64>],
    run: &[Vector3<f64>],
    rmse: f64,
    scale: f64,
    fits_scale: bool,
    checks: &FitChecks,
) -> Result<FitQuality> {
    let spread = rms_spread(reference);
    let (noise, source) = noise_of(run, checks);
    let residual_over_spread = if spread > 0.0 {
        rmse / spread
    } else {
        f64::INFINITY
    };
    let quality = FitQuality {
        reference_spread: spread,
        reference_noise: noise,
        noise_source: source,
        spread_over_noise: noise.filter(|&n| n > 0.0).map(|n| spread / n),
        residual_over_spread,
        scale_change: (scale - 1.0).abs(),
    };
    if !checks.enabled {
        return Ok(quality);
    }
    if let (true, Some(noise), Some(source)) = (fits_scale, noise, source) {
        if quality.scale_change < checks.min_scale_change
            && rmse > checks.max_unfitted_residual_over_noise * noise
        {
            return Err(Error::NothingFitted {
                scale,
                scale_change: quality.scale_change,
                threshold: checks.min_scale_change,
                rmse_m: rmse,
                noise_m: noise,
                noise_source: source.describe().into(),
            });
        }
    }
    if residual_over_spread >= checks.max_residual_over_spread {
        return Err(Error::UnexplainedSpread {
            rmse_m: rmse,
            spread_m: spread,
            ratio: residual_over_spread,
            threshold: checks.max_residual_over_spread,
        });
    }
    Ok(quality)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn second_differences_see_white_noise_not_smooth_motion() {
        // A straight line at constant speed: no noise at all.
        let line: Vec<_> = (0..20).map(|i| Vector3::new(i as f64, 0.5, 0.0)).collect();
        assert!(second_difference_noise(&line).unwrap() < 1e-12);
        assert_eq!(second_difference_noise(&line[..7]), None);
        // Alternating ±e per axis: second differences of 4e, so √(3·16e²/6).
        let e = 0.01;
        let zigzag: Vec<_> = (0..40)
            .map(|i| Vector3::repeat(if i % 2 == 0 { e } else { -e }))
            .collect();
        let n = second_difference_noise(&zigzag).unwrap();
        assert!((n - (8.0f64).sqrt() * e).abs() < 1e-15, "{n}");
    }

    #[test]
    fn thresholds_are_checked() {
        let bad = FitChecks {
            reference_noise: Some(-1.0),
            ..FitChecks::default()
        };
        assert!(
            matches!(bad.check(), Err(Error::InvalidArgument { what, .. }) if what == "reference_noise")
        );
        let off = FitChecks {
            max_residual_over_spread: f64::INFINITY,
            ..FitChecks::default()
        };
        assert!(off.check().is_ok());
        let nan = FitChecks {
            min_scale_change: f64::NAN,
            ..FitChecks::default()
        };
        assert!(nan.check().is_err());
    }
}
