//! Alignment with fewer degrees of freedom than Sim(3), and anchored fits.
//!
//! Pairs `(a_i, b_i)` (source `a`, e.g. SLAM or VIO positions; target `b`,
//! e.g. metric world positions, z up) are fitted by `T_b_a = (s, R, t)`
//! minimising `Σ w_i ‖b_i − (s·R·a_i + t)‖²` over the transforms the [`Dof`]
//! allows. With `ā`, `b̄` the weighted centroids (or, with
//! [`Anchor::First`], the first pair), `âᵢ = aᵢ − ā`, `b̂ᵢ = bᵢ − b̄` and the
//! cross-covariance `C = Σ wᵢ âᵢ b̂ᵢᵀ`, the closed forms are:
//!
//! - rotation about z only (`4dof`, `scale+4dof`): `Σ w b̂ᵀ·Rz(ψ)·â = tr(Rz(ψ)·C)
//!   = cos ψ·(C₀₀ + C₁₁) + sin ψ·(C₀₁ − C₁₀) + C₂₂` is largest at
//!   `ψ = atan2(C₀₁ − C₁₀, C₀₀ + C₁₁)` (rpg_trajectory_evaluation's
//!   `get_best_yaw`, written without its `π/2 − atan2(B, A)` detour);
//! - scale with the yaw (`scale+4dof`): for a fixed rotation the best scale is
//!   `s = tr(R·C) / Σ w‖â‖²` and the cost falls by `tr(R·C)² / Σ w‖â‖²`, so the
//!   yaw above (which maximises `tr(Rz·C)`) is also the yaw of the 5-DoF fit, and
//!   `s = (hypot(C₀₁ − C₁₀, C₀₀ + C₁₁) + C₂₂) / Σ w‖â‖²`;
//! - full rotation (`sim3`, `se3`): Horn's quaternion (or Umeyama's SVD) of `C`;
//! - translation `t = b̄ − s·R·ā`.
//!
//! Anchoring: `T(a₀) = b₀` forces `t = b₀ − s·R·a₀`, and the cost becomes
//! `Σ wᵢ ‖(bᵢ − b₀) − s·R·(aᵢ − a₀)‖²`: the same problem with the anchor in the
//! place of the centroids. Its exact constrained optimum is therefore the
//! closed form above with `ā = a₀`, `b̄ = b₀`.
//!
//! The yaw-only fits assume that both frames have z along gravity. They fit
//! the full-rotation Sim(3) of the same pairs as well and refuse
//! ([`Error::GravityTilted`]) when its rotation turns the source z axis more
//! than [`DofOptions::max_tilt_deg`] from the target z axis.

mod covariance;
mod robust;

pub use covariance::{covariance_dof, DofCovariance};
pub use robust::align_dof_robust;

use nalgebra::{Matrix3, UnitQuaternion, Vector3};

use super::{
    align, horn, umeyama, AlignDiagnostics, AlignMethod, AlignOptions, Alignment,
    MIN_RELATIVE_EIGEN_GAP, MIN_RELATIVE_SPREAD,
};
use crate::error::{Error, Result};
use crate::geometry::Sim3;

/// Tilt of the estimate's gravity, by the Sim(3) fit, above which a yaw-only
/// fit is refused by default, degrees.
pub const DEFAULT_MAX_TILT_DEG: f64 = crate::defaults::MAX_TILT_DEG;

/// Yaw determinacy ([`DofDiagnostics::yaw_determinacy`]) at or below which
/// the yaw is refused as undetermined.
pub const MIN_YAW_DETERMINACY: f64 = 1e-10;

/// The transforms a fit may choose from.
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    Hash,
    serde::Serialize,
    serde::Deserialize,
    schemars::JsonSchema,
)]
pub enum Dof {
    /// Rotation, translation and scale (7 DoF): monocular SLAM with unknown
    /// gravity and scale. Today's default; exactly [`align`].
    #[default]
    #[serde(rename = "sim3")]
    Sim3,
    /// Rotation and translation (6 DoF): a metric estimate whose orientation
    /// is unknown (stereo / RGB-D SLAM, lidar odometry).
    #[serde(rename = "se3")]
    Se3,
    /// Translation and a rotation about the z axis (yaw), 4 DoF: a metric,
    /// gravity-aligned estimate (visual-inertial odometry), whose roll and pitch
    /// are observable and must not be fitted away. z is gravity in both frames.
    #[serde(rename = "4dof")]
    FourDof,
    /// Translation, yaw and scale (5 DoF): monocular SLAM whose gravity is
    /// known but whose scale is not, e.g. after slam2world's raw-IMU
    /// initialisation ([`crate::imu`]). z is gravity in both frames.
    #[serde(rename = "scale+4dof")]
    ScaleFourDof,
}

impl Dof {
    /// Every choice, in the order of the documentation.
    pub const ALL: [Dof; 4] = [Dof::Sim3, Dof::Se3, Dof::FourDof, Dof::ScaleFourDof];

    /// The name the option takes (`"sim3"`, `"se3"`, `"4dof"`, `"scale+4dof"`).
    pub fn as_str(self) -> &'static str {
        match self {
            Dof::Sim3 => "sim3",
            Dof::Se3 => "se3",
            Dof::FourDof => "4dof",
            Dof::ScaleFourDof => "scale+4dof",
        }
    }

    /// Whether the scale is fitted (otherwise `s = 1`).
    pub fn has_scale(self) -> bool {
        matches!(self, Dof::Sim3 | Dof::ScaleFourDof)
    }

    /// Whether the rotation is a yaw about z (the frames share gravity).
    pub fn yaw_only(self) -> bool {
        matches!(self, Dof::FourDof | Dof::ScaleFourDof)
    }

    /// Number of fitted parameters: 7, 6, 4, 5.
    pub fn n_params(self) -> usize {
        match self {
            Dof::Sim3 => 7,
            Dof::Se3 => 6,
            Dof::FourDof => 4,
            Dof::ScaleFourDof => 5,
        }
    }

    /// The dof fitted when the scale is also switched by a flag (`scale:
    /// false`, `--no-scale`): `sim3` becomes `se3`; `scale+4dof` without scale
    /// is a contradiction ([`Error::InvalidArgument`]); the others stay.
    pub fn with_scale_flag(self, scale: bool) -> Result<Dof> {
        match (self, scale) {
            (Dof::Sim3, false) => Ok(Dof::Se3),
            (Dof::ScaleFourDof, false) => Err(Error::invalid(
                "scale",
                "scale=false (--no-scale) contradicts dof=\"scale+4dof\"; use dof=\"4dof\"",
            )),
            (d, _) => Ok(d),
        }
    }

    /// Fewest pairs that can determine the transform (3 non-collinear points
    /// for a full rotation, 2 horizontally apart for a yaw), anchor included.
    pub fn min_pairs(self) -> usize {
        if self.yaw_only() {
            2
        } else {
            3
        }
    }
}

impl std::fmt::Display for Dof {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for Dof {
    type Err = Error;
    /// `"sim3"`, `"se3"`, `"4dof"` or `"scale+4dof"`, any case.
    fn from_str(s: &str) -> Result<Self> {
        Dof::ALL
            .into_iter()
            .find(|d| d.as_str().eq_ignore_ascii_case(s))
            .ok_or_else(|| {
                Error::invalid(
                    "dof",
                    format!(
                        "expected one of \"sim3\", \"se3\", \"4dof\", \"scale+4dof\", got {s:?}"
                    ),
                )
            })
    }
}

/// Which pair, if any, the fit maps exactly.
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    Hash,
    serde::Serialize,
    serde::Deserialize,
    schemars::JsonSchema,
)]
pub enum Anchor {
    /// No pair is pinned: the plain least-squares fit.
    #[default]
    #[serde(rename = "none")]
    None,
    /// The first pair (index 0, whatever its weight): `T(a₀) = b₀` exactly, the
    /// rotation and scale fitted about that point as the [`Dof`] allows (the
    /// first pose of the aligned trajectory starts on the reference).
    #[serde(rename = "first")]
    First,
}

impl Anchor {
    /// The name the option takes (`"none"`, `"first"`).
    pub fn as_str(self) -> &'static str {
        match self {
            Anchor::None => "none",
            Anchor::First => "first",
        }
    }
}

impl std::fmt::Display for Anchor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for Anchor {
    type Err = Error;
    /// `"none"` or `"first"`, any case.
    fn from_str(s: &str) -> Result<Self> {
        [Anchor::None, Anchor::First]
            .into_iter()
            .find(|a| a.as_str().eq_ignore_ascii_case(s))
            .ok_or_else(|| {
                Error::invalid(
                    "anchor",
                    format!("expected \"none\" or \"first\", got {s:?}"),
                )
            })
    }
}

/// Options of [`align_dof`].
#[derive(Clone, Debug, PartialEq)]
pub struct DofOptions {
    /// The transforms to choose from.
    pub dof: Dof,
    /// The pair pinned exactly, if any.
    pub anchor: Anchor,
    /// One non-negative weight per pair (`None`: all 1). At least
    /// [`Dof::min_pairs`] pairs must have a positive weight (the anchor counts
    /// whatever its weight).
    pub weights: Option<Vec<f64>>,
    /// Rotation solver of the full-rotation fits (`sim3`, `se3` and the
    /// gravity check).
    pub method: AlignMethod,
    /// Largest tilt of the estimate's gravity (degrees, by the Sim(3) fit)
    /// that a yaw-only fit accepts; `None`: no check. Ignored by `sim3` / `se3`.
    pub max_tilt_deg: Option<f64>,
}

impl Default for DofOptions {
    fn default() -> Self {
        DofOptions {
            dof: Dof::Sim3,
            anchor: Anchor::None,
            weights: None,
            method: AlignMethod::Horn,
            max_tilt_deg: Some(DEFAULT_MAX_TILT_DEG),
        }
    }
}

impl DofOptions {
    /// The options of the plain [`align`] for `sim3` / `se3`.
    fn align_options(&self) -> AlignOptions {
        AlignOptions {
            scale: self.dof.has_scale(),
            method: self.method,
            weights: self.weights.clone(),
        }
    }
}

/// What a fit of [`align_dof`] adds to [`AlignDiagnostics`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, schemars::JsonSchema)]
pub struct DofDiagnostics {
    /// The degrees of freedom fitted.
    pub dof: Dof,
    /// The anchor used.
    pub anchor: Anchor,
    /// Weighted rms horizontal (x, y) distance of the source points to their
    /// centroid (to the anchor when anchored), source units. 0: no yaw.
    pub source_horizontal_spread: f64,
    /// The same for the target points, target units.
    pub target_horizontal_spread: f64,
    /// `max_ψ Σ w b̂ₕ·Rz(ψ)âₕ / sqrt(Σ w‖âₕ‖² · Σ w‖b̂ₕ‖²)` over the horizontal
    /// parts `âₕ`, `b̂ₕ`, in [0, 1]: 1 when the horizontal motions agree up to a
    /// yaw and scale, near 0 when they say nothing about the yaw (the relative
    /// curvature of the cost in the yaw).
    pub yaw_determinacy: f64,
    /// Angle between the source z axis mapped by the full-rotation Sim(3) fit
    /// of the same pairs and the target z axis, degrees (for `sim3` / `se3`,
    /// that of the fit itself); `None` when that fit is degenerate (e.g.
    /// collinear points: the tilt is not observable).
    pub gravity_tilt_deg: Option<f64>,
}

/// Aligns `source` onto `target` (pairs by index) with the degrees of freedom
/// and anchor of `opts`; the transform maps source points into the target
/// frame. `sim3` / `se3` without anchor are exactly [`align`] (whose
/// diagnostics have no [`AlignDiagnostics::dof`]).
///
/// Errors: those of [`align`] ([`Error::ShapeMismatch`], [`Error::TooFew`],
/// [`Error::NonFinite`], [`Error::InvalidArgument`]); [`Error::Degenerate`]
/// (coincident points; collinear points for a full rotation; no horizontal
/// motion, or horizontal motions that do not correlate, for a yaw; the figure
/// is in the error); [`Error::GravityTilted`] for a yaw-only fit of an
/// estimate whose gravity is tilted above `max_tilt_deg`.
pub fn align_dof(
    source: &[Vector3<f64>],
    target: &[Vector3<f64>],
    opts: &DofOptions,
) -> Result<Alignment> {
    check_max_tilt(opts.max_tilt_deg)?;
    if opts.anchor == Anchor::None && !opts.dof.yaw_only() {
        return align(source, target, &opts.align_options());
    }
    let a = fit_alignment(
        source,
        target,
        opts.weights.as_deref(),
        opts.dof,
        opts.anchor,
        opts.method,
    )?;
    check_gravity(&a, opts)?;
    Ok(a)
}

/// One window of the windowed fitter (`align::windowed::windowed_fits_with`):
/// the `dof` fit of the window's pairs with its weights, without anchor and
/// without the gravity check (the single fit over the run checks it once).
pub fn fit_window(
    source: &[Vector3<f64>],
    target: &[Vector3<f64>],
    weights: Vec<f64>,
    dof: Dof,
    method: AlignMethod,
) -> Result<Sim3> {
    if dof.yaw_only() {
        let m = PairMoments::checked(source, target, Some(&weights), dof, Anchor::None)?;
        Ok(solve(&m, dof, method)?.0)
    } else {
        let opts = AlignOptions {
            scale: dof.has_scale(),
            method,
            weights: Some(weights),
        };
        Ok(align(source, target, &opts)?.transform)
    }
}

fn check_max_tilt(max_tilt_deg: Option<f64>) -> Result<()> {
    match max_tilt_deg {
        Some(t) if !(t.is_finite() && t >= 0.0) => Err(Error::invalid(
            "max_tilt_deg",
            format!("must be finite and >= 0 degrees, got {t}"),
        )),
        _ => Ok(()),
    }
}

/// [`Error::GravityTilted`] when a yaw-only fit's Sim(3) tilt exceeds the threshold.
fn check_gravity(a: &Alignment, opts: &DofOptions) -> Result<()> {
    let (Some(threshold_deg), true) = (opts.max_tilt_deg, opts.dof.yaw_only()) else {
        return Ok(());
    };
    let tilt = a.diagnostics.dof.as_ref().and_then(|d| d.gravity_tilt_deg);
    match tilt {
        Some(angle_deg) if angle_deg > threshold_deg => Err(Error::GravityTilted {
            dof: opts.dof.as_str().into(),
            angle_deg,
            threshold_deg,
        }),
        _ => Ok(()),
    }
}

/// The checked fit with residuals, rmse and the dof diagnostics (no gravity
/// threshold): the closed form of the module doc.
fn fit_alignment(
    source: &[Vector3<f64>],
    target: &[Vector3<f64>],
    weights: Option<&[f64]>,
    dof: Dof,
    anchor: Anchor,
    method: AlignMethod,
) -> Result<Alignment> {
    let m = PairMoments::checked(source, target, weights, dof, anchor)?;
    let (transform, diagnostics) = solve(&m, dof, method)?;
    let residuals: Vec<f64> = source
        .iter()
        .zip(target)
        .map(|(a, b)| (b - transform.transform_point(a)).norm())
        .collect();
    let sse: f64 = match weights {
        None => residuals.iter().map(|r| r * r).sum(),
        Some(w) => residuals.iter().zip(w).map(|(r, w)| w * r * r).sum(),
    };
    let rmse = (sse / m.weight_sum).max(0.0).sqrt();
    Ok(Alignment {
        transform,
        residuals,
        rmse,
        diagnostics,
    })
}

/// Weighted sums of the pairs about their reference points (the centroids,
/// or the anchor pair).
struct PairMoments {
    n: usize,
    anchor: Anchor,
    /// `Σ w` over every pair (the anchor's included).
    weight_sum: f64,
    /// `ā`, `b̄`: the weighted centroids, or `a₀`, `b₀`.
    ref_a: Vector3<f64>,
    ref_b: Vector3<f64>,
    /// `C = Σ w â b̂ᵀ` (`cross[(i, j)] = Σ w âᵢ b̂ⱼ`).
    cross: Matrix3<f64>,
    /// `Σ w ‖â‖²`, `Σ w ‖b̂‖²`.
    aa: f64,
    bb: f64,
    /// `Σ w (âx² + ây²)`, `Σ w (b̂x² + b̂y²)`.
    aa_h: f64,
    bb_h: f64,
}

impl PairMoments {
    /// Checks shapes, weights and finiteness, then sums (two passes: the
    /// reference points first, so that the products are of centred values).
    fn checked(
        source: &[Vector3<f64>],
        target: &[Vector3<f64>],
        weights: Option<&[f64]>,
        dof: Dof,
        anchor: Anchor,
    ) -> Result<Self> {
        let n = source.len();
        if target.len() != n {
            return Err(Error::ShapeMismatch {
                what: "target".into(),
                expected: format!("({n}, 3), as many points as the source"),
                got: format!("({}, 3)", target.len()),
            });
        }
        let need = dof.min_pairs();
        let used = match weights {
            Some(w) => {
                check_weights(w, n)?;
                let skip = usize::from(anchor == Anchor::First);
                let positive = w.iter().skip(skip).filter(|&&v| v > 0.0).count();
                positive + skip.min(n)
            }
            None => n,
        };
        if used < need {
            return Err(Error::TooFew {
                what: if weights.is_some() {
                    format!("point pairs with a positive weight for a {dof} fit")
                } else {
                    format!("point pairs for a {dof} fit")
                },
                need,
                got: used,
            });
        }
        for (what, pts) in [("source", source), ("target", target)] {
            if let Some(index) = pts.iter().position(|p| !p.iter().all(|v| v.is_finite())) {
                return Err(Error::NonFinite {
                    what: what.into(),
                    index,
                });
            }
        }
        let w = |i: usize| weights.map_or(1.0, |w| w[i]);
        let weight_sum: f64 = (0..n).map(w).sum();
        let (ref_a, ref_b) = match anchor {
            Anchor::First => (source[0], target[0]),
            Anchor::None => {
                let mut sa = Vector3::zeros();
                let mut sb = Vector3::zeros();
                for i in 0..n {
                    sa += source[i] * w(i);
                    sb += target[i] * w(i);
                }
                (sa / weight_sum, sb / weight_sum)
            }
        };
        let mut m = PairMoments {
            n,
            anchor,
            weight_sum,
            ref_a,
            ref_b,
            cross: Matrix3::zeros(),
            aa: 0.0,
            bb: 0.0,
            aa_h: 0.0,
            bb_h: 0.0,
        };
        for i in 0..n {
            let wi = w(i);
            if wi == 0.0 {
                continue;
            }
            let a = source[i] - ref_a;
            let b = target[i] - ref_b;
            m.cross += a * b.transpose() * wi;
            m.aa += wi * a.norm_squared();
            m.bb += wi * b.norm_squared();
            m.aa_h += wi * (a.x * a.x + a.y * a.y);
            m.bb_h += wi * (b.x * b.x + b.y * b.y);
        }
        if !(m.cross.iter().all(|v| v.is_finite()) && m.aa.is_finite() && m.bb.is_finite()) {
            return Err(Error::NonFinite {
                what: "point sums (overflow)".into(),
                index: 0,
            });
        }
        Ok(m)
    }
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
    Ok(())
}

/// Angle between `R·ẑ` and `ẑ`, degrees.
pub(crate) fn tilt_deg(r: &UnitQuaternion<f64>) -> f64 {
    let z = r * Vector3::z();
    z.xy().norm().atan2(z.z).to_degrees()
}

/// The rotation `Rz(ψ)`.
fn yaw_rotation(psi: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), psi)
}

/// The closed form for `dof` from the moments, refusing degenerate geometry;
/// the diagnostics carry the gravity tilt of the full-rotation Sim(3) of the
/// same moments.
fn solve(m: &PairMoments, dof: Dof, method: AlignMethod) -> Result<(Sim3, AlignDiagnostics)> {
    let (transform, mut diagnostics) = solve_inner(m, dof, method)?;
    let tilt = if dof.yaw_only() {
        solve_inner(m, Dof::Sim3, method)
            .ok()
            .map(|(t, _)| tilt_deg(&t.rotation))
    } else {
        Some(tilt_deg(&transform.rotation))
    };
    if let Some(d) = diagnostics.dof.as_mut() {
        d.gravity_tilt_deg = tilt;
    }
    Ok((transform, diagnostics))
}

fn solve_inner(m: &PairMoments, dof: Dof, method: AlignMethod) -> Result<(Sim3, AlignDiagnostics)> {
    let w = m.weight_sum;
    let cov = m.cross / w;
    let var_a = m.aa / w;
    let source_spread = var_a.max(0.0).sqrt();
    let target_spread = (m.bb / w).max(0.0).sqrt();
    let source_horizontal_spread = (m.aa_h / w).max(0.0).sqrt();
    let target_horizontal_spread = (m.bb_h / w).max(0.0).sqrt();

    let (eigenvalues, q) = horn::largest_eigen(&horn::n_matrix(&cov));
    let lmax = eigenvalues[0].abs().max(eigenvalues[3].abs());
    let relative_eigen_gap = if lmax > 0.0 {
        (eigenvalues[0] - eigenvalues[1]) / lmax
    } else {
        0.0
    };
    let singular_values = umeyama::singular_values(&cov);
    // tr(Rz(ψ)·C) = cos ψ·yaw_cos + sin ψ·yaw_sin + C₂₂.
    let yaw_sin = m.cross[(0, 1)] - m.cross[(1, 0)];
    let yaw_cos = m.cross[(0, 0)] + m.cross[(1, 1)];
    let yaw_peak = yaw_sin.hypot(yaw_cos);
    let h_norm = (m.aa_h * m.bb_h).sqrt();
    let yaw_determinacy = if h_norm > 0.0 { yaw_peak / h_norm } else { 0.0 };
    let diagnostics = AlignDiagnostics {
        n: m.n,
        weight_sum: w,
        eigenvalues,
        relative_eigen_gap,
        singular_values,
        source_spread,
        target_spread,
        dof: Some(DofDiagnostics {
            dof,
            anchor: m.anchor,
            source_horizontal_spread,
            target_horizontal_spread,
            yaw_determinacy,
            gravity_tilt_deg: None,
        }),
    };

    let about = match m.anchor {
        Anchor::None => "coincide",
        Anchor::First => "coincide with the anchor (the first pair)",
    };
    let rms_a = source_spread + m.ref_a.norm();
    let rms_b = target_spread + m.ref_b.norm();
    if source_spread <= MIN_RELATIVE_SPREAD * rms_a || source_spread == 0.0 {
        return Err(Error::Degenerate {
            reason: format!(
                "all source points {about}: the scale and rotation are undefined \
                 (diagnostic: rms spread of the source points)"
            ),
            value: source_spread,
        });
    }
    if target_spread <= MIN_RELATIVE_SPREAD * rms_b || target_spread == 0.0 {
        return Err(Error::Degenerate {
            reason: format!(
                "all target points {about}: the rotation is undefined and the scale zero \
                 (diagnostic: rms spread of the target points)"
            ),
            value: target_spread,
        });
    }

    let (rotation, scale) = if dof.yaw_only() {
        for (what, h, rms) in [
            ("source", source_horizontal_spread, rms_a),
            ("target", target_horizontal_spread, rms_b),
        ] {
            if h <= MIN_RELATIVE_SPREAD * rms || h == 0.0 {
                return Err(Error::Degenerate {
                    reason: format!(
                        "the {what} points do not move horizontally: the yaw about z is \
                         undefined (diagnostic: horizontal rms spread of the {what} points)"
                    ),
                    value: h,
                });
            }
        }
        if yaw_determinacy.is_nan() || yaw_determinacy <= MIN_YAW_DETERMINACY {
            return Err(Error::Degenerate {
                reason: "the horizontal motions of source and target do not correlate: the \
                         yaw about z is not determined (diagnostic: yaw determinacy)"
                    .into(),
                value: yaw_determinacy,
            });
        }
        let rotation = yaw_rotation(yaw_sin.atan2(yaw_cos));
        let scale = if dof.has_scale() {
            // tr(Rz(ψ*)·C) / Σ w‖â‖² (per unit weight both).
            (yaw_peak / w + cov[(2, 2)]) / var_a
        } else {
            1.0
        };
        (rotation, scale)
    } else {
        if relative_eigen_gap.is_nan() || relative_eigen_gap <= MIN_RELATIVE_EIGEN_GAP {
            let collinear = singular_values[1] <= 1e-9 * singular_values[0];
            let what = if collinear {
                "the points are collinear: the rotation about their line is undefined"
            } else {
                "the rotation is not determined"
            };
            return Err(Error::Degenerate {
                reason: format!(
                    "{what} (diagnostic: relative eigen-gap of Horn's N; singular values of \
                     the cross-covariance are {:.3e}, {:.3e}, {:.3e})",
                    singular_values[0], singular_values[1], singular_values[2]
                ),
                value: relative_eigen_gap,
            });
        }
        let rotation = match method {
            AlignMethod::Horn => q,
            AlignMethod::Umeyama => umeyama::rotation(&cov)?,
        };
        let scale = if dof.has_scale() {
            (rotation.to_rotation_matrix().into_inner() * cov).trace() / var_a
        } else {
            1.0
        };
        (rotation, scale)
    };
    if !(scale.is_finite() && scale > 0.0) {
        return Err(Error::Degenerate {
            reason: "the best scale is not positive: the point sets do not correspond \
                     (diagnostic: the scale)"
                .into(),
            value: scale,
        });
    }
    let translation = m.ref_b - rotation * m.ref_a * scale;
    Ok((Sim3::try_new(rotation, translation, scale)?, diagnostics))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for d in Dof::ALL {
            assert_eq!(d.as_str().parse::<Dof>().unwrap(), d);
            assert_eq!(d.as_str().to_uppercase().parse::<Dof>().unwrap(), d);
        }
        let e = "6dof".parse::<Dof>().unwrap_err().to_string();
        assert!(
            e.contains("\"scale+4dof\"") && e.contains("\"6dof\""),
            "{e}"
        );
        assert_eq!("First".parse::<Anchor>().unwrap(), Anchor::First);
        assert!("last".parse::<Anchor>().is_err());
    }

    #[test]
    fn tilt_of_known_rotations() {
        let r = UnitQuaternion::from_euler_angles(3f64.to_radians(), 0.0, 1.0);
        assert!((tilt_deg(&r) - 3.0).abs() < 1e-12);
        assert!(tilt_deg(&yaw_rotation(2.5)).abs() < 1e-14);
    }
}
