//! First-order covariance of a fitted Sim(3) from its residuals.
//!
//! The fit `b ≈ s·R·a + t` is perturbed as `R → exp([δθ]ₓ)·R` (rotation
//! vector in the target frame, rad), `t → t + δt` (target units) and
//! `s → s·exp(δσ)`. With `uᵢ = s·R·aᵢ` the Jacobian of the prediction is
//! `Jᵢ = [−[uᵢ]ₓ, I, uᵢ]`, and the covariance of `(δθ, δt, δσ)` is
//! `σ̂²·(Σ wᵢ JᵢᵀJᵢ)⁻¹` with `σ̂² = Σ wᵢ‖rᵢ‖² / (3·n − p)` (per-axis residual
//! variance; `p` = 7, or 6 without scale). It assumes independent, isotropic
//! residuals of equal variance (given the weights).

use nalgebra::{Matrix3, SMatrix, Vector3};

use crate::error::{Error, Result};
use crate::geometry::Sim3;

/// 7×7 matrix over `(rotation vector (3), translation (3), log scale)`.
pub type Matrix7 = SMatrix<f64, 7, 7>;

/// Index of the log-scale parameter in [`Covariance::matrix`].
pub const LOG_SCALE: usize = 6;

/// The covariance of a fitted transform.
#[derive(Clone, Debug, PartialEq)]
pub struct Covariance {
    /// Over `(δθ rad ×3, δt target units ×3, ln s)`; the last row and column
    /// are zero when the scale was fixed.
    pub matrix: Matrix7,
    /// Estimated per-axis residual variance, target units².
    pub sigma2: f64,
    /// Degrees of freedom `3·n − p`.
    pub dof: usize,
    /// The fitted transform it belongs to.
    pub transform: Sim3,
}

/// Two-sided standard normal quantile for a central `level` (e.g. 0.95 → 1.96).
pub fn normal_quantile(level: f64) -> Result<f64> {
    if !(level > 0.0 && level < 1.0) {
        return Err(Error::invalid(
            "level",
            format!("must be in (0, 1), got {level}"),
        ));
    }
    Ok(inverse_normal_cdf(0.5 + 0.5 * level))
}

/// Acklam's rational approximation of the standard normal quantile (relative
/// error below 1.2e-9), for `p` in (0, 1).
fn inverse_normal_cdf(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    let p_low = 0.02425;
    if p < p_low {
        tail((-2.0 * p.ln()).sqrt())
    } else if p <= 1.0 - p_low {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    } else {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    }
}

impl Covariance {
    /// Standard deviations of the seven parameters.
    pub fn sigmas(&self) -> [f64; 7] {
        std::array::from_fn(|i| self.matrix[(i, i)].max(0.0).sqrt())
    }

    /// Central `level` interval of the scale (from the normal interval of
    /// `ln s`): `(lo, hi)`.
    pub fn scale_interval(&self, level: f64) -> Result<(f64, f64)> {
        let z = normal_quantile(level)?;
        let sd = self.matrix[(LOG_SCALE, LOG_SCALE)].max(0.0).sqrt();
        let s = self.transform.scale;
        Ok((s * (-z * sd).exp(), s * (z * sd).exp()))
    }

    /// Central `level` intervals of the translation components `(lo, hi)` ×3.
    pub fn translation_intervals(&self, level: f64) -> Result<[(f64, f64); 3]> {
        let z = normal_quantile(level)?;
        let t = self.transform.translation;
        Ok(std::array::from_fn(|i| {
            let sd = self.matrix[(3 + i, 3 + i)].max(0.0).sqrt();
            (t[i] - z * sd, t[i] + z * sd)
        }))
    }

    /// Half-width of the central `level` interval of the rotation error about
    /// each target axis, rad.
    pub fn rotation_half_widths(&self, level: f64) -> Result<[f64; 3]> {
        let z = normal_quantile(level)?;
        Ok(std::array::from_fn(|i| {
            z * self.matrix[(i, i)].max(0.0).sqrt()
        }))
    }
}

/// The covariance of `transform` fitted to the pairs `(source, target)`
/// (`weights`: the fit's, or `None`; `scale`: whether the scale was fitted).
/// Errors: [`Error::ShapeMismatch`], [`Error::TooFew`] (no degree of
/// freedom left), [`Error::Degenerate`] (singular normal matrix).
pub fn covariance(
    transform: &Sim3,
    source: &[Vector3<f64>],
    target: &[Vector3<f64>],
    weights: Option<&[f64]>,
    scale: bool,
) -> Result<Covariance> {
    let n = source.len();
    if target.len() != n {
        return Err(Error::ShapeMismatch {
            what: "target".into(),
            expected: format!("({n}, 3), as many points as the source"),
            got: format!("({}, 3)", target.len()),
        });
    }
    if let Some(w) = weights {
        if w.len() != n {
            return Err(Error::ShapeMismatch {
                what: "weights".into(),
                expected: format!("({n},)"),
                got: format!("({},)", w.len()),
            });
        }
    }
    let p = if scale { 7 } else { 6 };
    let used = match weights {
        Some(w) => w.iter().filter(|&&v| v > 0.0).count(),
        None => n,
    };
    if 3 * used <= p {
        return Err(Error::TooFew {
            what: "point pairs for a covariance (3 per pair, more than the parameters)".into(),
            need: 3,
            got: used,
        });
    }
    let m = transform.rotation_matrix() * transform.scale;
    let mut h = Matrix7::zeros();
    let mut sse = 0.0;
    for i in 0..n {
        let w = weights.map_or(1.0, |w| w[i]);
        if w <= 0.0 {
            continue;
        }
        let u = m * source[i];
        let r = target[i] - (u + transform.translation);
        sse += w * r.norm_squared();
        let mut j = SMatrix::<f64, 3, 7>::zeros();
        let ux = -u.cross_matrix();
        j.fixed_view_mut::<3, 3>(0, 0).copy_from(&ux);
        j.fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&Matrix3::identity());
        j.fixed_view_mut::<3, 1>(0, 6).copy_from(&u);
        h += j.transpose() * j * w;
    }
    let dof = 3 * used - p;
    let sigma2 = sse / dof as f64;
    let matrix = if scale {
        h.try_inverse()
    } else {
        h.fixed_view::<6, 6>(0, 0)
            .into_owned()
            .try_inverse()
            .map(|inv| {
                let mut full = Matrix7::zeros();
                full.fixed_view_mut::<6, 6>(0, 0).copy_from(&inv);
                full
            })
    }
    .ok_or_else(|| Error::Degenerate {
        reason: "the normal matrix of the fit is singular: the transform is not determined \
                 (diagnostic: its largest diagonal element)"
            .into(),
        value: h.diagonal().amax(),
    })?;
    Ok(Covariance {
        matrix: matrix * sigma2,
        sigma2,
        dof,
        transform: *transform,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles() {
        assert!((normal_quantile(0.95).unwrap() - 1.959_963_985).abs() < 1e-8);
        assert!((normal_quantile(0.5).unwrap() - 0.674_489_750).abs() < 1e-8);
        assert!((normal_quantile(0.999).unwrap() - 3.290_526_731).abs() < 1e-7);
        assert!(normal_quantile(1.0).is_err());
    }
}
