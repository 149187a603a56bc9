//! First-order covariance of a fit of [`super::align_dof`] over the dof's own
//! parameters, and its mapping onto the Sim(3) parameterisation of
//! [`crate::align::covariance`] (whose intervals the report shows).
//!
//! The parameters perturb the fit as in `crate::align::covariance`:
//! `R → exp([δθ]ₓ)·R` (rotation vector in the target frame, rad; for a yaw,
//! `δθ = ẑ·δψ`), `t → t + δt` (target units), `s → s·exp(δσ)`. Without
//! anchor they are `(δθ, δt, δσ)` restricted to the dof; with
//! [`Anchor::First`] the translation follows from the rotation and scale
//! (`t = b₀ − s·R·a₀`), so only `(δθ, δσ)` are free. With `vᵢ = s·R·(aᵢ − c)`
//! (`c = 0`, or `a₀` when anchored) the Jacobian `Jᵢ` of prediction `i` has
//! the columns `eⱼ × vᵢ` per rotation axis, `eⱼ` per translation axis and `vᵢ`
//! for the log scale; `H = Σ wᵢ JᵢᵀJᵢ` (the anchor's own pair excluded: its
//! residual is 0 by construction).
//!
//! The target points carry independent isotropic noise of variance `σ²/wᵢ`
//! per axis (the weights are relative precisions). Without anchor the
//! covariance is `σ̂²·H⁻¹` with `σ̂² = Σ wᵢ‖rᵢ‖² / (3·n − p)`. With an anchor
//! the noise `e₀` of `b₀` enters every residual (`rᵢ ≈ eᵢ − e₀ − Jᵢ·δp`): with
//! `G = Σ wᵢ Jᵢ` (3 × p), `δp = H⁻¹·(Σ wᵢ Jᵢᵀ eᵢ − Gᵀ e₀)`, so
//! `Cov(δp) = σ²·(H⁻¹ + H⁻¹GᵀGH⁻¹ / w₀)`, and the translation
//! `t = b₀ − s·R·a₀` moves by `δt = [u₀]ₓ·δθ − u₀·δσ + e₀` (`u₀ = s·R·a₀`),
//! correlated with `δp` through `e₀`; `σ̂² = Σ wᵢ‖rᵢ‖² / (3·n − p + (3·Σwᵢ −
//! tr(H⁻¹GᵀG)) / w₀)` is unbiased under that model (`n`, `Σwᵢ` over the
//! other pairs with positive weight).

use nalgebra::{DMatrix, Matrix3, SMatrix, Vector3};

use super::{Anchor, Dof};
use crate::align::covariance::{Covariance, Matrix7, LOG_SCALE};
use crate::error::{Error, Result};
use crate::geometry::Sim3;

/// One parameter of a dof's covariance.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Param {
    /// Rotation about target axis `0..3` (x, y, z; z alone is the yaw), rad.
    Rotation(usize),
    /// Translation along target axis `0..3`, target units.
    Translation(usize),
    /// `ln s`.
    LogScale,
}

impl Param {
    /// Its index among the Sim(3) parameters `(δθ ×3, δt ×3, ln s)`.
    fn index(self) -> usize {
        match self {
            Param::Rotation(j) => j,
            Param::Translation(j) => 3 + j,
            Param::LogScale => LOG_SCALE,
        }
    }

    fn name(self, dof: Dof) -> &'static str {
        match self {
            Param::Rotation(2) if dof.yaw_only() => "yaw",
            Param::Rotation(0) => "rx",
            Param::Rotation(1) => "ry",
            Param::Rotation(_) => "rz",
            Param::Translation(0) => "tx",
            Param::Translation(1) => "ty",
            Param::Translation(_) => "tz",
            Param::LogScale => "log_scale",
        }
    }
}

fn params(dof: Dof, anchor: Anchor) -> Vec<Param> {
    let mut p: Vec<Param> = if dof.yaw_only() {
        vec![Param::Rotation(2)]
    } else {
        (0..3).map(Param::Rotation).collect()
    };
    if anchor == Anchor::None {
        p.extend((0..3).map(Param::Translation));
    }
    if dof.has_scale() {
        p.push(Param::LogScale);
    }
    p
}

/// The covariance of a fitted transform over the dof's own parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct DofCovariance {
    /// The degrees of freedom of the fit.
    pub dof: Dof,
    /// Its anchor.
    pub anchor: Anchor,
    /// Names of the parameters, in the order of `matrix`: a subset of `rx`,
    /// `ry`, `rz` (rad) or `yaw` (rad, about z), `tx`, `ty`, `tz` (target
    /// units), `log_scale` (`ln s`). E.g. `yaw, tx, ty, tz` for `4dof`, `yaw`
    /// alone for an anchored `4dof`.
    pub parameters: Vec<&'static str>,
    /// `k × k` over `parameters`.
    pub matrix: DMatrix<f64>,
    /// Estimated per-axis residual variance, target units².
    pub sigma2: f64,
    /// Effective degrees of freedom of the residuals (`3·n − k` without
    /// anchor; see the module doc with one).
    pub redundancy: f64,
    /// Noise variance per axis of the anchor's target point `b₀`
    /// (`σ̂²/w₀`), target units²; `None` without anchor.
    pub anchor_variance: Option<f64>,
    /// `7 × k`: the change of the Sim(3) parameters `(δθ ×3, δt ×3, ln s)`
    /// per unit change of each parameter (with an anchor, the translation
    /// also moves with the anchor's noise, which `to_sim3` adds).
    pub embedding: DMatrix<f64>,
    /// The fitted transform it belongs to.
    pub transform: Sim3,
    /// The same covariance over the Sim(3) parameters ([`Self::to_sim3`]).
    sim3: Matrix7,
}

impl DofCovariance {
    /// Standard deviations of the parameters, in the order of `parameters`.
    pub fn sigmas(&self) -> Vec<f64> {
        self.matrix
            .diagonal()
            .iter()
            .map(|v| v.max(0.0).sqrt())
            .collect()
    }

    /// The standard deviation of a parameter by name (`"yaw"`, `"tz"`, …),
    /// `None` when the dof does not fit it.
    pub fn sigma(&self, name: &str) -> Option<f64> {
        let i = self.parameters.iter().position(|p| *p == name)?;
        Some(self.matrix[(i, i)].max(0.0).sqrt())
    }

    /// The same covariance over the Sim(3) parameters (`E·P·Eᵀ` with the
    /// `embedding` `E`, plus the anchor's noise in the translation): rows and
    /// columns of parameters the dof fixes are zero (a scale interval of
    /// width 0 for `4dof`), and an anchored fit's translation carries the
    /// uncertainty of its rotation, scale and anchor. Its interval methods
    /// give the report's intervals.
    pub fn to_sim3(&self) -> Covariance {
        Covariance {
            matrix: self.sim3,
            sigma2: self.sigma2,
            dof: self.redundancy.round().max(0.0) as usize,
            transform: self.transform,
        }
    }
}

/// The covariance of `transform`, a fit of `dof` and `anchor` to the pairs
/// `(source, target)` with `weights` (the fit's, or `None`).
///
/// Errors: [`Error::ShapeMismatch`], [`Error::TooFew`] (no degree of freedom
/// left for the residuals), [`Error::Degenerate`] (singular normal matrix:
/// the pairs do not determine the parameters).
pub fn covariance_dof(
    transform: &Sim3,
    source: &[Vector3<f64>],
    target: &[Vector3<f64>],
    weights: Option<&[f64]>,
    dof: Dof,
    anchor: Anchor,
) -> Result<DofCovariance> {
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
    if anchor == Anchor::First && n == 0 {
        return Err(Error::TooFew {
            what: "point pairs (the anchor is the first)".into(),
            need: 1,
            got: 0,
        });
    }
    let ps = params(dof, anchor);
    let k = ps.len();
    let first = usize::from(anchor == Anchor::First);
    let w = |i: usize| weights.map_or(1.0, |w| w[i]);
    let used = (first..n).filter(|&i| w(i) > 0.0).count();
    if 3 * used <= k {
        return Err(Error::TooFew {
            what: format!(
                "point pairs for a {dof} covariance (3 per pair, more than the {k} parameters)"
            ),
            need: k / 3 + 1,
            got: used,
        });
    }
    let sr = transform.rotation_matrix() * transform.scale;
    let centre = match anchor {
        Anchor::None => Vector3::zeros(),
        Anchor::First => source[0],
    };
    // The dof's Jacobian columns are a selection of the Sim(3) Jacobian
    // J = [−[v]ₓ, I, v] (without anchor v = s·R·a: the Jacobian of
    // crate::align::covariance), whose sums need only Σw, Σw·v and Σw·v·vᵀ:
    // JᵀJ = [[|v|²I − vvᵀ, [v]ₓ, 0], [−[v]ₓ, I, v], [0, vᵀ, |v|²]].
    let (mut sse, mut wsum) = (0.0, 0.0);
    let mut m = Vector3::zeros();
    let mut outer = Matrix3::zeros();
    for i in first..n {
        let wi = w(i);
        if wi <= 0.0 {
            continue;
        }
        let r = target[i] - transform.transform_point(&source[i]);
        sse += wi * r.norm_squared();
        wsum += wi;
        let v = sr * (source[i] - centre);
        m += v * wi;
        outer += v * v.transpose() * wi;
    }
    let q = outer.trace();
    let mut h7 = Matrix7::zeros();
    h7.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(Matrix3::identity() * q - outer));
    h7.fixed_view_mut::<3, 3>(0, 3).copy_from(&m.cross_matrix());
    h7.fixed_view_mut::<3, 3>(3, 0)
        .copy_from(&(-m.cross_matrix()));
    h7.fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&(Matrix3::identity() * wsum));
    h7.fixed_view_mut::<3, 1>(3, LOG_SCALE).copy_from(&m);
    h7.fixed_view_mut::<1, 3>(LOG_SCALE, 3)
        .copy_from(&m.transpose());
    h7[(LOG_SCALE, LOG_SCALE)] = q;
    let mut g7 = SMatrix::<f64, 3, 7>::zeros();
    g7.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(-m.cross_matrix()));
    g7.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&(Matrix3::identity() * wsum));
    g7.fixed_view_mut::<3, 1>(0, LOG_SCALE).copy_from(&m);
    let index: Vec<usize> = ps.iter().map(|p| p.index()).collect();
    let h = DMatrix::from_fn(k, k, |a, b| h7[(index[a], index[b])]);
    let g = DMatrix::from_fn(3, k, |ax, b| g7[(ax, index[b])]);
    let largest = h.diagonal().amax();
    let hinv = h
        .cholesky()
        .map(|c| c.inverse())
        .ok_or_else(|| Error::Degenerate {
            reason: format!(
                "the normal matrix of the {dof} fit is singular: its parameters are not \
             determined (diagnostic: its largest diagonal element)"
            ),
            value: largest,
        })?;
    // ∂(δθ, δt, δσ)/∂p; anchored: δt = [u₀]ₓ·δθ − u₀·δσ (+ e₀).
    let u0 = sr * centre;
    let mut embedding = DMatrix::<f64>::zeros(7, k);
    for (col, p) in ps.iter().enumerate() {
        match *p {
            Param::Rotation(j) => {
                embedding[(j, col)] = 1.0;
                if anchor == Anchor::First {
                    let dt = u0.cross(&Vector3::ith(j, 1.0));
                    for a in 0..3 {
                        embedding[(3 + a, col)] = dt[a];
                    }
                }
            }
            Param::Translation(j) => embedding[(3 + j, col)] = 1.0,
            Param::LogScale => {
                embedding[(LOG_SCALE, col)] = 1.0;
                if anchor == Anchor::First {
                    for a in 0..3 {
                        embedding[(3 + a, col)] = -u0[a];
                    }
                }
            }
        }
    }
    let base = (3 * used - k) as f64;
    let (matrix, sigma2, redundancy, anchor_variance, sim3) = match anchor {
        Anchor::None => {
            let sigma2 = sse / base;
            let p = &hinv * sigma2;
            let full = &embedding * &p * embedding.transpose();
            (p, sigma2, base, None, full)
        }
        Anchor::First => {
            let w0 = w(0);
            if w0 <= 0.0 {
                return Err(Error::Degenerate {
                    reason: "the anchor (the first pair) has weight 0: the noise of the point \
                             every other pair is measured from is unbounded (diagnostic: its \
                             weight)"
                        .into(),
                    value: w0,
                });
            }
            let q = &hinv * g.transpose(); // H⁻¹Gᵀ, k × 3
            let redundancy = base + (3.0 * wsum - (&g * &q).trace()) / w0;
            let sigma2 = sse / redundancy;
            let a = sigma2 / w0;
            let p = &hinv * sigma2 + &q * q.transpose() * a;
            // Joint over (δp, e₀): Cov(δp, e₀) = −a·H⁻¹Gᵀ, Cov(e₀) = a·I.
            let mut joint = DMatrix::<f64>::zeros(k + 3, k + 3);
            joint.view_mut((0, 0), (k, k)).copy_from(&p);
            joint.view_mut((0, k), (k, 3)).copy_from(&(&q * -a));
            joint
                .view_mut((k, 0), (3, k))
                .copy_from(&(q.transpose() * -a));
            joint
                .view_mut((k, k), (3, 3))
                .copy_from(&(DMatrix::<f64>::identity(3, 3) * a));
            let mut e = DMatrix::<f64>::zeros(7, k + 3);
            e.view_mut((0, 0), (7, k)).copy_from(&embedding);
            for ax in 0..3 {
                e[(3 + ax, k + ax)] = 1.0;
            }
            let full = &e * joint * e.transpose();
            (p, sigma2, redundancy, Some(a), full)
        }
    };
    Ok(DofCovariance {
        dof,
        anchor,
        parameters: ps.iter().map(|p| p.name(dof)).collect(),
        matrix,
        sigma2,
        redundancy,
        anchor_variance,
        embedding,
        transform: *transform,
        sim3: Matrix7::from_fn(|i, j| sim3[(i, j)]),
    })
}
