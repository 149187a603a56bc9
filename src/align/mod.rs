//! Closed-form Sim(3) / SE(3) alignment of corresponding point sets.
//!
//! Given pairs `(a_i, b_i)` (source `a`, e.g. SLAM positions; target `b`, e.g.
//! metric world positions) find `T_b_a = (s, R, t)` minimising
//! `Σ w_i ‖b_i − (s·R·a_i + t)‖²`.
//!
//! One pass accumulates the weighted first and second moments (shifted by a
//! sample of the data for precision, in parallel for large inputs); the
//! rotation then comes from a 4×4 (Horn 1987, the default) or 3×3 (Umeyama
//! 1991, the cross-check) problem, and the scale from Horn's asymmetric form
//! `s = Σ b̂ᵢ·R(âᵢ) / Σ‖âᵢ‖²` — the denominator over the **source** points,
//! equal to Umeyama's `tr(DS)/σ²_a`. (The paper prints the denominator over
//! the target points, which yields `1/s`.)

pub mod checks;
pub mod covariance;
pub mod dof;
pub mod ground;
pub mod handeye;
mod horn;
mod moments;
pub mod priors;
pub mod robust;
pub mod stages;
pub mod time_offset;
pub mod trajectories;
mod umeyama;
pub mod windowed;

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::geometry::Sim3;

pub(crate) use moments::Moments;
pub use moments::Rows;
use moments::{FlatRows, Prior};

/// Relative eigen-gap of Horn's `N` below which the rotation is refused as
/// undetermined (collinear points, or an exact reflection ambiguity).
pub const MIN_RELATIVE_EIGEN_GAP: f64 = 1e-10;

/// Relative spread (rms distance to the centroid over rms distance to the
/// origin) below which a point set counts as all coincident.
pub const MIN_RELATIVE_SPREAD: f64 = 1e-12;

/// Points per parallel work item of the residual pass.
const RESIDUALS_PER_TASK: usize = 1 << 15;

/// Pairs (at most) fitted first, in [`PRIOR_BLOCKS`] evenly spaced runs, for
/// the prior guess that the full moments are taken relative to.
const PRIOR_SAMPLES: usize = 2048;
const PRIOR_BLOCKS: usize = 16;

/// The residual sum of squares is taken from the moments when it is at least
/// this fraction of the magnitude of the terms it is summed from (rounding
/// error then below about 1e-12 relative); below, one more pass sums the
/// squared residuals directly.
const CLOSED_FORM_MIN_FRACTION: f64 = 1e-4;

/// How the rotation is solved for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum AlignMethod {
    /// Horn's unit-quaternion method: eigenvector of the largest eigenvalue of a
    /// symmetric 4×4 matrix.
    #[default]
    Horn,
    /// Umeyama's SVD method with the reflection correction (as in evo).
    Umeyama,
}

impl std::str::FromStr for AlignMethod {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "horn" => Ok(AlignMethod::Horn),
            "umeyama" => Ok(AlignMethod::Umeyama),
            _ => Err(Error::invalid(
                "method",
                format!("expected \"horn\" or \"umeyama\", got {s:?}"),
            )),
        }
    }
}

/// Options of [`align`].
#[derive(Clone, Debug, PartialEq)]
pub struct AlignOptions {
    /// Estimate the scale (Sim(3)); `false` fixes `s = 1` (SE(3)).
    pub scale: bool,
    /// Rotation solver.
    pub method: AlignMethod,
    /// One non-negative weight per pair (`None`: all 1). At least three pairs
    /// must have a positive weight.
    pub weights: Option<Vec<f64>>,
}

impl Default for AlignOptions {
    fn default() -> Self {
        AlignOptions {
            scale: true,
            method: AlignMethod::Horn,
            weights: None,
        }
    }
}

/// What the data said about how well it determines the transform.
#[derive(Clone, Debug, PartialEq)]
pub struct AlignDiagnostics {
    /// Number of pairs.
    pub n: usize,
    /// Sum of the weights (`n` without weights).
    pub weight_sum: f64,
    /// Eigenvalues of Horn's 4×4 `N`, largest first.
    pub eigenvalues: [f64; 4],
    /// `(λ₁ − λ₂) / max|λ|`: near 0 the rotation is not determined.
    pub relative_eigen_gap: f64,
    /// Singular values of the 3×3 cross-covariance `Σ w·âᵢ b̂ᵢᵀ / Σ w`, largest
    /// first; the second near 0 means collinear points.
    pub singular_values: [f64; 3],
    /// Weighted rms distance of the source points to their centroid (source units).
    pub source_spread: f64,
    /// Weighted rms distance of the target points to their centroid (target units).
    pub target_spread: f64,
    /// What a fit with other degrees of freedom or an anchor ([`dof::align_dof`])
    /// adds (the spreads above are then about the anchor when there is one);
    /// `None` for the plain Sim(3) / SE(3) fit.
    pub dof: Option<dof::DofDiagnostics>,
}

/// The result of [`align`].
#[derive(Clone, Debug, PartialEq)]
pub struct Alignment {
    /// `T_target_source`: maps source points into the target frame (`T_world_slam`
    /// when the source is SLAM and the target the world).
    pub transform: Sim3,
    /// Per pair `‖b_i − T(a_i)‖`, target units.
    pub residuals: Vec<f64>,
    /// `sqrt(Σ w·r² / Σ w)`, target units (the plain rms without weights).
    pub rmse: f64,
    /// Conditioning of the problem.
    pub diagnostics: AlignDiagnostics,
}

/// Aligns `source` onto `target` (pairs by index): the returned transform maps
/// source points into the target frame.
///
/// Errors: [`Error::ShapeMismatch`] (lengths differ, weights of the wrong
/// length), [`Error::TooFew`] (fewer than 3 pairs with positive weight),
/// [`Error::NonFinite`], [`Error::InvalidArgument`] (negative weight),
/// [`Error::Degenerate`] (coincident or collinear points; the diagnostic value
/// is in the error).
pub fn align(
    source: &[Vector3<f64>],
    target: &[Vector3<f64>],
    opts: &AlignOptions,
) -> Result<Alignment> {
    align_rows(source, target, opts)
}

/// [`align`] on flat row-major `(N, 3)` slices (`[x0, y0, z0, x1, …]`), as
/// NumPy stores them; nothing is copied.
pub fn align_flat(source: &[f64], target: &[f64], opts: &AlignOptions) -> Result<Alignment> {
    check_flat(source, target)?;
    align_rows(&FlatRows(source), &FlatRows(target), opts)
}

/// [`align`] over any two row sources of equal length.
pub fn align_rows<A: Rows + ?Sized, B: Rows + ?Sized>(
    source: &A,
    target: &B,
    opts: &AlignOptions,
) -> Result<Alignment> {
    let (transform, diagnostics, _) = fit(source, target, opts)?;
    let mut residuals = vec![0.0; source.n_rows()];
    let rmse = residuals_into(
        &transform,
        source,
        target,
        opts.weights.as_deref(),
        &mut residuals,
    );
    Ok(Alignment {
        transform,
        residuals,
        rmse,
        diagnostics,
    })
}

/// An [`Alignment`] without the per-pair residuals ([`fit_flat`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Fit {
    /// `T_target_source`.
    pub transform: Sim3,
    /// `sqrt(Σ w·r² / Σ w)`, target units.
    pub rmse: f64,
    /// Conditioning of the problem.
    pub diagnostics: AlignDiagnostics,
}

/// [`align_flat`] without the per-pair residuals: one pass over the data
/// (the rms residual comes from the moments; see [`residuals_flat`] for the
/// residuals themselves).
pub fn fit_flat(source: &[f64], target: &[f64], opts: &AlignOptions) -> Result<Fit> {
    check_flat(source, target)?;
    let (transform, diagnostics, rmse) = fit(&FlatRows(source), &FlatRows(target), opts)?;
    Ok(Fit {
        transform,
        rmse,
        diagnostics,
    })
}

/// Per pair `‖target_i − T(source_i)‖` of flat row-major `(N, 3)` slices into
/// `out` (length N), in parallel for large inputs; returns their rms.
pub fn residuals_flat(
    transform: &Sim3,
    source: &[f64],
    target: &[f64],
    out: &mut [f64],
) -> Result<f64> {
    check_flat(source, target)?;
    let (a, b) = (FlatRows(source), FlatRows(target));
    for (what, n) in [("target", b.n_rows()), ("residuals", out.len())] {
        if n != a.n_rows() {
            return Err(Error::ShapeMismatch {
                what: what.into(),
                expected: format!("{} rows, one per source point", a.n_rows()),
                got: format!("{n}"),
            });
        }
    }
    Ok(residuals_into(transform, &a, &b, None, out))
}

fn check_flat(source: &[f64], target: &[f64]) -> Result<()> {
    for (what, s) in [("source", source), ("target", target)] {
        if s.len() % 3 != 0 {
            return Err(Error::ShapeMismatch {
                what: what.into(),
                expected: "(N, 3)".into(),
                got: format!("{} values", s.len()),
            });
        }
    }
    Ok(())
}

/// Checks the input, accumulates the moments and solves; returns the
/// transform, the diagnostics and the (weighted) rms residual.
fn fit<A: Rows + ?Sized, B: Rows + ?Sized>(
    source: &A,
    target: &B,
    opts: &AlignOptions,
) -> Result<(Sim3, AlignDiagnostics, f64)> {
    let n = source.n_rows();
    if target.n_rows() != n {
        return Err(Error::ShapeMismatch {
            what: "target".into(),
            expected: format!("({n}, 3), as many points as the source"),
            got: format!("({}, 3)", target.n_rows()),
        });
    }
    let weights = opts.weights.as_deref();
    if let Some(w) = weights {
        check_weights(w, n)?;
    } else if n < 3 {
        return Err(Error::TooFew {
            what: "point pairs".into(),
            need: 3,
            got: n,
        });
    }
    let prior = sample_prior(source, target, opts);
    let m = Moments::accumulate(source, target, weights, prior.as_ref());
    if !m.is_finite() {
        return Err(first_non_finite(source, target));
    }
    let (t, diagnostics) = solve(&m, opts)?;
    let (sse, magnitude) = m.residual_sum_of_squares(&(t.rotation_matrix() * t.scale));
    let sse = if sse.is_finite() && sse >= CLOSED_FORM_MIN_FRACTION * magnitude {
        sse
    } else {
        residual_sse(&t, source, target, weights)
    };
    let rmse = (sse / m.weight_sum).max(0.0).sqrt();
    Ok((t, diagnostics, rmse))
}

/// The fit of an even sample of the pairs (all of them when there are few),
/// as the guess the full moments are taken relative to; `None` when the
/// sample does not determine it (the full fit then still is exact, and its
/// rms residual may take one more pass).
fn sample_prior<A: Rows + ?Sized, B: Rows + ?Sized>(
    source: &A,
    target: &B,
    opts: &AlignOptions,
) -> Option<Prior> {
    let n = source.n_rows();
    let run = PRIOR_SAMPLES / PRIOR_BLOCKS;
    let starts: Vec<usize> = if n <= PRIOR_SAMPLES {
        vec![0]
    } else {
        (0..PRIOR_BLOCKS)
            .map(|k| k * (n - run) / (PRIOR_BLOCKS - 1))
            .collect()
    };
    let len = if n <= PRIOR_SAMPLES { n } else { run };
    let mut a = Vec::with_capacity(starts.len() * len);
    let mut b = Vec::with_capacity(starts.len() * len);
    let mut w = opts
        .weights
        .as_ref()
        .map(|_| Vec::with_capacity(starts.len() * len));
    for &lo in &starts {
        a.extend(source.rows(lo, lo + len).map(Vector3::from));
        b.extend(target.rows(lo, lo + len).map(Vector3::from));
        if let (Some(w), Some(all)) = (w.as_mut(), opts.weights.as_ref()) {
            w.extend_from_slice(&all[lo..lo + len]);
        }
    }
    if let Some(w) = &w {
        if w.iter().filter(|&&v| v > 0.0).count() < 3 {
            return None;
        }
    }
    let m = Moments::accumulate(a.as_slice(), b.as_slice(), w.as_deref(), None);
    if !m.is_finite() {
        return None;
    }
    let (t, _) = solve(&m, opts).ok()?;
    Some(Prior {
        m: t.rotation_matrix() * t.scale,
        t: t.translation,
    })
}

fn check_weights(w: &[f64], n: usize) -> Result<()> {
    if w.len() != n {
        return Err(Error::ShapeMismatch {
            what: "weights".into(),
            expected: format!("({n},), one per pair"),
            got: format!("({},)", w.len()),
        });
    }
    if let Some(i) = w.iter().position(|v| !v.is_finite()) {
        return Err(Error::NonFinite {
            what: "weights".into(),
            index: i,
        });
    }
    if let Some(i) = w.iter().position(|&v| v < 0.0) {
        return Err(Error::invalid(
            "weights",
            format!("must be >= 0, weight {i} is {}", w[i]),
        ));
    }
    let positive = w.iter().filter(|&&v| v > 0.0).count();
    if positive < 3 {
        return Err(Error::TooFew {
            what: "point pairs with a positive weight".into(),
            need: 3,
            got: positive,
        });
    }
    Ok(())
}

fn first_non_finite<A: Rows + ?Sized, B: Rows + ?Sized>(a: &A, b: &B) -> Error {
    if let Some(index) = first_bad_row(a) {
        return Error::NonFinite {
            what: "source".into(),
            index,
        };
    }
    if let Some(index) = first_bad_row(b) {
        return Error::NonFinite {
            what: "target".into(),
            index,
        };
    }
    Error::NonFinite {
        what: "point sums (overflow)".into(),
        index: 0,
    }
}

fn first_bad_row<R: Rows + ?Sized>(r: &R) -> Option<usize> {
    (0..r.n_rows()).find(|&i| r.row(i).iter().any(|v| !v.is_finite()))
}

/// The fit of running moments ([`Moments::running`] / [`Moments::push_weighted`]): the
/// transform and diagnostics [`align`] gives for the same pairs (up to the
/// rounding of the sums), refusing degenerate geometry the same way.
pub(crate) fn solve_running(m: &Moments, opts: &AlignOptions) -> Result<(Sim3, AlignDiagnostics)> {
    if m.n < 3 {
        return Err(Error::TooFew {
            what: "point pairs".into(),
            need: 3,
            got: m.n,
        });
    }
    if !m.is_finite() {
        return Err(Error::NonFinite {
            what: "point pairs (running moments)".into(),
            index: m.n,
        });
    }
    solve(m, opts)
}

/// From centred moments to the transform, refusing degenerate geometry.
fn solve(m: &Moments, opts: &AlignOptions) -> Result<(Sim3, AlignDiagnostics)> {
    let w = m.weight_sum;
    let (mean_a, mean_b) = (m.mean_a(), m.mean_b());
    // Centred second moments, per unit weight.
    let cov: Matrix3<f64> = m.centred_cross() / w; // Σ w âᵢ b̂ᵢᵀ / W
    let var_a = m.centred_aa() / w;
    let var_b = m.centred_bb() / w;
    let source_spread = var_a.max(0.0).sqrt();
    let target_spread = var_b.max(0.0).sqrt();

    let n_mat = horn::n_matrix(&cov);
    let (eigenvalues, q) = horn::largest_eigen(&n_mat);
    let lmax = eigenvalues[0].abs().max(eigenvalues[3].abs());
    let relative_eigen_gap = if lmax > 0.0 {
        (eigenvalues[0] - eigenvalues[1]) / lmax
    } else {
        0.0
    };
    let singular_values = umeyama::singular_values(&cov);
    let diagnostics = AlignDiagnostics {
        n: m.n,
        weight_sum: w,
        eigenvalues,
        relative_eigen_gap,
        singular_values,
        source_spread,
        target_spread,
        dof: None,
    };

    let rms_a = source_spread + mean_a.norm();
    let rms_b = target_spread + mean_b.norm();
    if source_spread <= MIN_RELATIVE_SPREAD * rms_a || source_spread == 0.0 {
        return Err(Error::Degenerate {
            reason: "all source points coincide: the scale and rotation are undefined \
                     (diagnostic: rms spread of the source points)"
                .into(),
            value: source_spread,
        });
    }
    if target_spread <= MIN_RELATIVE_SPREAD * rms_b || target_spread == 0.0 {
        return Err(Error::Degenerate {
            reason: "all target points coincide: the rotation is undefined and the scale zero \
                     (diagnostic: rms spread of the target points)"
                .into(),
            value: target_spread,
        });
    }
    if relative_eigen_gap.is_nan() || relative_eigen_gap <= MIN_RELATIVE_EIGEN_GAP {
        let collinear = singular_values[1] <= 1e-9 * singular_values[0];
        let reason = if collinear {
            "the points are collinear: the rotation about their line is undefined \
             (diagnostic: relative eigen-gap of Horn's N; singular values of the \
             cross-covariance are "
                .to_string()
        } else {
            "the rotation is not determined (diagnostic: relative eigen-gap of Horn's N; \
             singular values of the cross-covariance are "
                .to_string()
        };
        return Err(Error::Degenerate {
            reason: format!(
                "{reason}{:.3e}, {:.3e}, {:.3e})",
                singular_values[0], singular_values[1], singular_values[2]
            ),
            value: relative_eigen_gap,
        });
    }

    let rotation = match opts.method {
        AlignMethod::Horn => q,
        AlignMethod::Umeyama => umeyama::rotation(&cov)?,
    };
    let r = rotation.to_rotation_matrix().into_inner();
    let scale = if opts.scale {
        // Horn's asymmetric scale: Σ b̂·R(â) / Σ‖â‖² = tr(R·C) / var_a with
        // C = Σ â b̂ᵀ / W (the denominator over the SOURCE points).
        (r * cov).trace() / var_a
    } else {
        1.0
    };
    if !(scale.is_finite() && scale > 0.0) {
        return Err(Error::Degenerate {
            reason: "the best scale is not positive: the point sets do not correspond \
                     (diagnostic: the scale)"
                .into(),
            value: scale,
        });
    }
    let translation = mean_b - r * mean_a * scale;
    let t = Sim3::try_new(rotation, translation, scale)?;
    Ok((t, diagnostics))
}

/// `s·R` and `t` of a transform as plain arrays, for the residual loops.
fn affine(t: &Sim3) -> ([[f64; 3]; 3], [f64; 3]) {
    let m = t.rotation_matrix() * t.scale;
    (
        [
            [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
            [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
            [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
        ],
        [t.translation.x, t.translation.y, t.translation.z],
    )
}

/// `‖q − (m·p + t)‖²`.
#[inline(always)]
fn squared_error(m: &[[f64; 3]; 3], t: &[f64; 3], p: [f64; 3], q: [f64; 3]) -> f64 {
    let ex = m[0][0] * p[0] + m[0][1] * p[1] + m[0][2] * p[2] + t[0] - q[0];
    let ey = m[1][0] * p[0] + m[1][1] * p[1] + m[1][2] * p[2] + t[1] - q[1];
    let ez = m[2][0] * p[0] + m[2][1] * p[1] + m[2][2] * p[2] + t[2] - q[2];
    ex * ex + ey * ey + ez * ez
}

/// `Σ w·‖b_i − T(a_i)‖²`, in parallel for large inputs (nothing stored).
fn residual_sse<A: Rows + ?Sized, B: Rows + ?Sized>(
    t: &Sim3,
    a: &A,
    b: &B,
    weights: Option<&[f64]>,
) -> f64 {
    let (m, tr) = affine(t);
    let block = |lo: usize, hi: usize| -> f64 {
        let errors = a
            .rows(lo, hi)
            .zip(b.rows(lo, hi))
            .map(|(p, q)| squared_error(&m, &tr, p, q));
        match weights {
            None => errors.sum(),
            Some(w) => errors.zip(&w[lo..hi]).map(|(e, w)| e * w).sum(),
        }
    };
    let n = a.n_rows();
    if n <= RESIDUALS_PER_TASK {
        return block(0, n);
    }
    (0..n.div_ceil(RESIDUALS_PER_TASK))
        .into_par_iter()
        .with_max_len(1)
        .map(|c| {
            block(
                c * RESIDUALS_PER_TASK,
                ((c + 1) * RESIDUALS_PER_TASK).min(n),
            )
        })
        .sum()
}

/// Residual norms `‖b_i − T(a_i)‖` into `out` (length N) and their
/// (weighted) rms, in parallel for large inputs.
fn residuals_into<A: Rows + ?Sized, B: Rows + ?Sized>(
    t: &Sim3,
    a: &A,
    b: &B,
    weights: Option<&[f64]>,
    out: &mut [f64],
) -> f64 {
    let n = a.n_rows();
    let (m, tr) = affine(t);
    // Three simple loops over a cache-sized block (squared norms; their
    // weighted sum in independent lanes; square roots) vectorise better than one.
    let block = |start: usize, dst: &mut [f64]| -> f64 {
        let end = start + dst.len();
        for (d, (p, q)) in dst
            .iter_mut()
            .zip(a.rows(start, end).zip(b.rows(start, end)))
        {
            *d = squared_error(&m, &tr, p, q);
        }
        let sse = match weights {
            None => lane_sum(dst),
            Some(w) => {
                let mut acc = 0.0;
                for (e, w) in dst.iter().zip(&w[start..end]) {
                    acc += e * w;
                }
                acc
            }
        };
        for d in dst.iter_mut() {
            *d = d.sqrt();
        }
        sse
    };
    let sse: f64 = if n <= RESIDUALS_PER_TASK {
        block(0, out)
    } else {
        out.par_chunks_mut(RESIDUALS_PER_TASK)
            .with_max_len(1)
            .enumerate()
            .map(|(c, dst)| block(c * RESIDUALS_PER_TASK, dst))
            .sum()
    };
    let wsum = match weights {
        Some(w) => w.iter().sum(),
        None => n as f64,
    };
    (sse / wsum).max(0.0).sqrt()
}

/// Sum in eight independent lanes (no single dependency chain).
#[inline(always)]
fn lane_sum(values: &[f64]) -> f64 {
    let mut acc = [0.0; 8];
    let chunks = values.chunks_exact(8);
    let rest: f64 = chunks.remainder().iter().sum();
    for c in chunks {
        for (a, v) in acc.iter_mut().zip(c) {
            *a += v;
        }
    }
    acc.iter().sum::<f64>() + rest
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::UnitQuaternion;

    fn cloud(n: usize) -> Vec<Vector3<f64>> {
        (0..n)
            .map(|i| {
                let f = i as f64;
                Vector3::new((f * 0.37).sin() * 2.0, (f * 0.11).cos() - 0.5, f * 0.01)
            })
            .collect()
    }

    fn truth() -> Sim3 {
        Sim3::from_quaternion_xyzw([0.2, -0.1, 0.4, 0.85], Vector3::new(3.0, -1.0, 0.5), 15.49)
            .unwrap()
    }

    #[test]
    fn recovers_known_transform_both_methods() {
        let a = cloud(50);
        let t = truth();
        let b: Vec<_> = a.iter().map(|p| t.transform_point(p)).collect();
        for method in [AlignMethod::Horn, AlignMethod::Umeyama] {
            let opts = AlignOptions {
                method,
                ..Default::default()
            };
            let r = align(&a, &b, &opts).unwrap();
            assert!((r.transform.scale - 15.49).abs() < 1e-9, "{method:?}");
            assert!((r.transform.matrix() - t.matrix()).amax() < 1e-9);
            assert!(r.rmse < 1e-9);
            assert_eq!(r.residuals.len(), 50);
        }
    }

    #[test]
    fn scale_is_not_inverted() {
        // The paper's formula (denominator over the target) gives 1/s = 0.0646.
        let a = cloud(20);
        let t = truth();
        let b: Vec<_> = a.iter().map(|p| t.transform_point(p)).collect();
        let r = align(&a, &b, &AlignOptions::default()).unwrap();
        assert!((r.transform.scale - 15.49).abs() < 1e-9);
        let back = align(&b, &a, &AlignOptions::default()).unwrap();
        assert!((back.transform.scale - 1.0 / 15.49).abs() < 1e-12);
    }

    #[test]
    fn se3_keeps_unit_scale() {
        let a = cloud(10);
        let t = Sim3::try_new(
            UnitQuaternion::from_euler_angles(0.1, 0.2, 0.3),
            Vector3::new(1.0, 2.0, 3.0),
            1.0,
        )
        .unwrap();
        let b: Vec<_> = a.iter().map(|p| t.transform_point(p)).collect();
        let opts = AlignOptions {
            scale: false,
            ..Default::default()
        };
        let r = align(&a, &b, &opts).unwrap();
        assert_eq!(r.transform.scale, 1.0);
        assert!((r.transform.matrix() - t.matrix()).amax() < 1e-12);
    }

    #[test]
    fn refuses_degenerate() {
        let a = cloud(10);
        assert!(matches!(
            align(&a[..2], &a[..2], &AlignOptions::default()),
            Err(Error::TooFew { .. })
        ));
        assert!(matches!(
            align(&a, &a[..9], &AlignOptions::default()),
            Err(Error::ShapeMismatch { .. })
        ));
        let same = vec![Vector3::new(1.0, 2.0, 3.0); 10];
        assert!(matches!(
            align(&same, &a, &AlignOptions::default()),
            Err(Error::Degenerate { .. })
        ));
        let line: Vec<_> = (0..10)
            .map(|i| Vector3::new(1.0, 2.0, 3.0) * i as f64)
            .collect();
        let e = align(&line, &line, &AlignOptions::default()).unwrap_err();
        assert!(e.to_string().contains("collinear"), "{e}");
        let mut bad = a.clone();
        bad[7].y = f64::NAN;
        match align(&a, &bad, &AlignOptions::default()) {
            Err(Error::NonFinite { what, index }) => {
                assert_eq!((what.as_str(), index), ("target", 7))
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn weights_select_pairs() {
        let a = cloud(30);
        let t = truth();
        let mut b: Vec<_> = a.iter().map(|p| t.transform_point(p)).collect();
        b[3] += Vector3::new(100.0, 0.0, 0.0); // an outlier with weight 0
        let mut w = vec![1.0; 30];
        w[3] = 0.0;
        let opts = AlignOptions {
            weights: Some(w),
            ..Default::default()
        };
        let r = align(&a, &b, &opts).unwrap();
        assert!((r.transform.matrix() - t.matrix()).amax() < 1e-9);
        assert!((r.residuals[3] - 100.0).abs() < 1e-6);
        let opts = AlignOptions {
            weights: Some(vec![-1.0; 30]),
            ..Default::default()
        };
        assert!(align(&a, &b, &opts).is_err());
    }
}
