//! Robust Sim(3) alignment: RANSAC over minimal 3-point Horn fits, refined by
//! iteratively reweighted least squares (Huber or Cauchy), then a plain
//! least-squares fit over the pairs within the inlier threshold.
//!
//! Without an inlier threshold the hypotheses are scored by their median
//! residual (least median of squares) and the threshold is
//! [`AUTO_THRESHOLD_SIGMAS`] robust standard deviations. When every pair lies
//! within the threshold the result is exactly the plain fit of [`align`].

use nalgebra::Vector3;
use rand::seq::index::sample;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::{align, AlignOptions, Alignment};
use crate::error::{Error, Result};

/// Robust standard deviations (per axis) of the automatic inlier threshold.
pub const AUTO_THRESHOLD_SIGMAS: f64 = 4.0;

/// Median of the norm of a 3-D standard normal vector (χ with 3 degrees of
/// freedom): converts a median residual norm into a per-axis sigma.
const CHI3_MEDIAN: f64 = 1.538_172;

/// The loss of the reweighting step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RobustLoss {
    /// Huber: weight `min(1, k/r)`.
    #[default]
    Huber,
    /// Cauchy: weight `1 / (1 + (r/k)²)`.
    Cauchy,
}

impl std::str::FromStr for RobustLoss {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "huber" => Ok(RobustLoss::Huber),
            "cauchy" => Ok(RobustLoss::Cauchy),
            _ => Err(Error::invalid(
                "loss",
                format!("expected \"huber\" or \"cauchy\", got {s:?}"),
            )),
        }
    }
}

/// Options of [`align_robust`].
#[derive(Clone, Debug, PartialEq)]
pub struct RobustOptions {
    /// Largest residual of an inlier, target units (`None`: [`AUTO_THRESHOLD_SIGMAS`]
    /// robust sigmas from the least-median-of-squares hypothesis).
    pub inlier_threshold: Option<f64>,
    /// Number of RANSAC hypotheses (minimal 3-point fits).
    pub iterations: usize,
    /// Loss of the reweighting step.
    pub loss: RobustLoss,
    /// Seed of the sampler (one seed, one answer).
    pub seed: u64,
}

impl Default for RobustOptions {
    fn default() -> Self {
        RobustOptions {
            inlier_threshold: None,
            iterations: crate::defaults::ROBUST_ITERATIONS,
            loss: RobustLoss::Huber,
            seed: 0,
        }
    }
}

/// The result of [`align_robust`].
#[derive(Clone, Debug, PartialEq)]
pub struct RobustAlignment {
    /// The least-squares fit over the inliers; `residuals` are over ALL pairs.
    pub alignment: Alignment,
    /// One flag per pair: residual within `threshold`.
    pub inliers: Vec<bool>,
    /// The inlier threshold used, target units.
    pub threshold: f64,
}

impl RobustAlignment {
    /// Number of inliers.
    pub fn n_inliers(&self) -> usize {
        self.inliers.iter().filter(|&&b| b).count()
    }
}

fn residuals(t: &crate::geometry::Sim3, a: &[Vector3<f64>], b: &[Vector3<f64>]) -> Vec<f64> {
    a.iter()
        .zip(b)
        .map(|(p, q)| (q - t.transform_point(p)).norm())
        .collect()
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let m = s.len() / 2;
    if s.len() % 2 == 1 {
        s[m]
    } else {
        0.5 * (s[m - 1] + s[m])
    }
}

/// Aligns `source` onto `target` while ignoring gross outliers (see the module
/// doc). Errors as [`align`], plus [`Error::InvalidArgument`] for a threshold
/// that is not finite and positive, and [`Error::Degenerate`] when no minimal
/// sample gives a fit or fewer than 3 pairs remain inliers.
pub fn align_robust(
    source: &[Vector3<f64>],
    target: &[Vector3<f64>],
    opts: &AlignOptions,
    robust: &RobustOptions,
) -> Result<RobustAlignment> {
    check_robust(opts.weights.is_some(), robust)?;
    let fitter = Sim3Refit {
        source,
        target,
        opts: AlignOptions {
            weights: None,
            ..opts.clone()
        },
    };
    robust_refit(&fitter, source, target, robust)
}

/// Refuses a threshold that is not finite and positive, and given weights
/// (the robust fit chooses its own).
pub(crate) fn check_robust(has_weights: bool, robust: &RobustOptions) -> Result<()> {
    if let Some(th) = robust.inlier_threshold {
        if !(th.is_finite() && th > 0.0) {
            return Err(Error::invalid(
                "inlier_threshold",
                format!("must be finite and > 0, got {th}"),
            ));
        }
    }
    if has_weights {
        return Err(Error::invalid(
            "weights",
            "robust alignment chooses its own weights; pass none",
        ));
    }
    Ok(())
}

/// The least-squares fits the robust loop drives: the Sim(3) / SE(3) of
/// [`align`] here, the other degrees of freedom in `align::dof`.
pub(crate) trait Refit {
    /// Pairs drawn for one hypothesis.
    fn minimal(&self) -> usize;
    /// Fewest inliers the final fit accepts.
    fn min_inliers(&self) -> usize {
        self.minimal()
    }
    /// The hypothesis fitted to the pairs `idx` alone.
    fn sample(&self, idx: &[usize]) -> Result<crate::geometry::Sim3>;
    /// The fit over every pair with these weights (`None`: the plain fit,
    /// which also checks the input once for all).
    fn weighted(&self, weights: Option<Vec<f64>>) -> Result<Alignment>;
}

struct Sim3Refit<'a> {
    source: &'a [Vector3<f64>],
    target: &'a [Vector3<f64>],
    /// Without weights.
    opts: AlignOptions,
}

impl Refit for Sim3Refit<'_> {
    fn minimal(&self) -> usize {
        3
    }
    fn sample(&self, idx: &[usize]) -> Result<crate::geometry::Sim3> {
        let a: Vec<_> = idx.iter().map(|&i| self.source[i]).collect();
        let b: Vec<_> = idx.iter().map(|&i| self.target[i]).collect();
        Ok(align(&a, &b, &self.opts)?.transform)
    }
    fn weighted(&self, weights: Option<Vec<f64>>) -> Result<Alignment> {
        align(
            self.source,
            self.target,
            &AlignOptions {
                weights,
                ..self.opts.clone()
            },
        )
    }
}

/// RANSAC / LMedS over the fitter's minimal samples, IRLS, and the
/// least-squares fit over the inliers (the module doc), for any [`Refit`].
pub(crate) fn robust_refit<F: Refit>(
    fitter: &F,
    source: &[Vector3<f64>],
    target: &[Vector3<f64>],
    robust: &RobustOptions,
) -> Result<RobustAlignment> {
    // The plain fit checks shapes, finiteness and degeneracy once for all.
    let plain = fitter.weighted(None)?;
    let n = source.len();

    // RANSAC / LMedS over minimal samples; the plain fit is hypothesis zero.
    let mut rng = ChaCha8Rng::seed_from_u64(robust.seed);
    let score = |r: &[f64]| -> f64 {
        match robust.inlier_threshold {
            // MSAC: truncated squared residuals.
            Some(th) => r.iter().map(|e| (e * e).min(th * th)).sum(),
            None => median(r),
        }
    };
    let mut best_t = plain.transform;
    let mut best_r = plain.residuals.clone();
    let mut best_score = score(&best_r);
    let m = fitter.minimal();
    if n > m {
        for _ in 0..robust.iterations {
            let idx = sample(&mut rng, n, m).into_vec();
            let Ok(h) = fitter.sample(&idx) else {
                continue;
            };
            let r = residuals(&h, source, target);
            let s = score(&r);
            if s < best_score {
                best_score = s;
                best_t = h;
                best_r = r;
            }
        }
    }
    let threshold = match robust.inlier_threshold {
        Some(th) => th,
        None => {
            let sigma = median(&best_r) / CHI3_MEDIAN;
            // Floor: exact data (sigma 0) still admits rounding.
            let floor = 1e-12 * (1.0 + plain.diagnostics.target_spread);
            (AUTO_THRESHOLD_SIGMAS * sigma).max(floor)
        }
    };

    // IRLS from the best hypothesis.
    let k = threshold / 2.0;
    let mut t = best_t;
    let mut r = best_r;
    for _ in 0..30 {
        let w: Vec<f64> = r
            .iter()
            .map(|&e| {
                if e > 2.0 * threshold {
                    0.0
                } else {
                    match robust.loss {
                        RobustLoss::Huber => {
                            if e <= k {
                                1.0
                            } else {
                                k / e
                            }
                        }
                        RobustLoss::Cauchy => 1.0 / (1.0 + (e / k) * (e / k)),
                    }
                }
            })
            .collect();
        let Ok(fit) = fitter.weighted(Some(w)) else {
            break;
        };
        let moved = (fit.transform.matrix() - t.matrix()).amax();
        t = fit.transform;
        r = residuals(&t, source, target);
        if moved <= 1e-12 * (1.0 + t.matrix().amax()) {
            break;
        }
    }

    // Least squares over the inliers, re-classified until stable.
    let mut inliers: Vec<bool> = r.iter().map(|&e| e <= threshold).collect();
    let mut result = None;
    for _ in 0..10 {
        let count = inliers.iter().filter(|&&b| b).count();
        if count < fitter.min_inliers() {
            return Err(Error::Degenerate {
                reason: format!(
                    "only {count} of {n} pairs lie within the inlier threshold {threshold:.3e} \
                     (diagnostic: the threshold)"
                ),
                value: threshold,
            });
        }
        let fit = if count == n {
            plain.clone()
        } else {
            let w = inliers.iter().map(|&b| f64::from(u8::from(b))).collect();
            fitter.weighted(Some(w))?
        };
        let next: Vec<bool> = fit.residuals.iter().map(|&e| e <= threshold).collect();
        let stable = next == inliers;
        result = Some(fit);
        if stable {
            break;
        }
        inliers = next;
    }
    let Some(mut alignment) = result else {
        return Err(Error::Degenerate {
            reason: "the robust fit did not run".into(),
            value: 0.0,
        });
    };
    // The rmse over the inliers (the weights were 0/1): report it unweighted
    // over them, residuals over all pairs.
    let (sse, cnt) = alignment
        .residuals
        .iter()
        .zip(&inliers)
        .filter(|(_, &b)| b)
        .fold((0.0, 0usize), |(s, c), (e, _)| (s + e * e, c + 1));
    alignment.rmse = (sse / cnt.max(1) as f64).sqrt();
    Ok(RobustAlignment {
        alignment,
        inliers,
        threshold,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Sim3;

    fn data(n: usize) -> (Vec<Vector3<f64>>, Vec<Vector3<f64>>, Sim3) {
        let t =
            Sim3::from_quaternion_xyzw([0.1, 0.3, -0.2, 0.9], Vector3::new(1.0, 2.0, -3.0), 4.2)
                .unwrap();
        let a: Vec<_> = (0..n)
            .map(|i| {
                let f = i as f64;
                Vector3::new((f * 0.7).sin(), (f * 0.31).cos(), f * 0.05)
            })
            .collect();
        let b = a.iter().map(|p| t.transform_point(p)).collect();
        (a, b, t)
    }

    #[test]
    fn no_outliers_gives_the_plain_fit() {
        let (a, b, _) = data(40);
        let r = align_robust(&a, &b, &AlignOptions::default(), &RobustOptions::default()).unwrap();
        let p = align(&a, &b, &AlignOptions::default()).unwrap();
        assert_eq!(r.alignment, p);
        assert!(r.inliers.iter().all(|&x| x));
    }

    #[test]
    fn outliers_are_found_and_ignored() {
        let (a, mut b, t) = data(60);
        for i in (0..60).step_by(4) {
            b[i] += Vector3::new(5.0, -3.0, 2.0 + i as f64 * 0.1);
        }
        for loss in [RobustLoss::Huber, RobustLoss::Cauchy] {
            let opts = RobustOptions {
                loss,
                ..Default::default()
            };
            let r = align_robust(&a, &b, &AlignOptions::default(), &opts).unwrap();
            assert!((r.alignment.transform.scale - t.scale).abs() < 1e-9);
            for (i, &inl) in r.inliers.iter().enumerate() {
                assert_eq!(inl, i % 4 != 0, "pair {i}");
            }
        }
        let bad = RobustOptions {
            inlier_threshold: Some(-1.0),
            ..Default::default()
        };
        assert!(align_robust(&a, &b, &AlignOptions::default(), &bad).is_err());
    }
}
