//! Alignment for Python: `align` (every degree of freedom of `align/dof/`,
//! anchored or not), `Alignment`, `align_trajectories`,
//! `TrajectoryAlignment`, and the fits beyond one closed form —
//! `detect_stages` / `Stages`, `estimate_time_offset`, `align_windowed` /
//! `WindowedAlignment`, `estimate_body_from_cam`.

use numpy::{IntoPyArray, PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple};

use super::arrays::{to_array2, vec_f64, vectors, with_points};
use super::geometry::PySim3;
use super::trajectory::{index_arrays, PyTrajectory};
use crate::align::checks::FitChecks;
use crate::align::covariance::{covariance, Covariance};
use crate::align::dof::{
    align_dof, align_dof_robust, covariance_dof, Anchor, Dof, DofDiagnostics, DofOptions,
};
use crate::align::handeye::estimate_body_from_cam_trajectories;
use crate::align::robust::{align_robust, RobustOptions};
use crate::align::stages::{detect_stages, Stages};
use crate::align::time_offset::{estimate_time_offset, TimeOffsetOptions};
use crate::align::trajectories::{
    align_trajectories, ApeStats, SkipInit, TrajectoryAlignOptions, TrajectoryAlignment,
};
use crate::align::windowed::{align_windowed, Window, WindowedAlignment, WindowedOptions};
use crate::align::{
    fit_flat, residuals_flat, AlignDiagnostics, AlignMethod, AlignOptions, Alignment,
};
use crate::defaults;
use crate::error::Error;
use crate::trajectory::Association;

fn diagnostics_dict<'py>(py: Python<'py>, d: &AlignDiagnostics) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    dict.set_item("n", d.n)?;
    dict.set_item("weight_sum", d.weight_sum)?;
    dict.set_item("eigenvalues", d.eigenvalues.to_vec())?;
    dict.set_item("relative_eigen_gap", d.relative_eigen_gap)?;
    dict.set_item("singular_values", d.singular_values.to_vec())?;
    dict.set_item("source_spread", d.source_spread)?;
    dict.set_item("target_spread", d.target_spread)?;
    if let Some(x) = &d.dof {
        dict.set_item("dof", dof_diagnostics_dict(py, x)?)?;
    }
    Ok(dict)
}

/// The result of `align`: `transform` maps source points into the target frame.
#[pyclass(name = "Alignment", module = "slam2world._slam2world", frozen)]
pub struct PyAlignment {
    transform: crate::geometry::Sim3,
    rmse: f64,
    /// Filled with the fit, or on first request from the input arrays.
    residuals: PyOnceLock<Py<PyArray1<f64>>>,
    diagnostics: AlignDiagnostics,
    inliers: Option<Py<PyArray1<bool>>>,
    covariance: CovarianceSource,
}

/// Where an alignment's covariance (and its residuals, when not computed with
/// the fit) come from: computed with the fit, or on request from the input
/// arrays (so that a plain `align` reads its input once and pays nothing for
/// what is not asked for).
pub(crate) enum CovarianceSource {
    Known(Option<Box<Covariance>>),
    Lazy {
        source: Py<PyAny>,
        target: Py<PyAny>,
        weights: Option<Vec<f64>>,
        scale: bool,
    },
}

impl PyAlignment {
    pub(crate) fn new(py: Python<'_>, a: Alignment) -> Self {
        let residuals = PyOnceLock::new();
        // A new cell is empty: this cannot fail.
        let _ = residuals.set(py, a.residuals.into_pyarray(py).unbind());
        PyAlignment {
            transform: a.transform,
            rmse: a.rmse,
            residuals,
            diagnostics: a.diagnostics,
            inliers: None,
            covariance: CovarianceSource::Known(None),
        }
    }

    pub(crate) fn with_extras(
        py: Python<'_>,
        a: Alignment,
        inliers: Option<Vec<bool>>,
        covariance: Option<Covariance>,
    ) -> Self {
        let mut p = PyAlignment::new(py, a);
        p.inliers = inliers.map(|m| m.into_pyarray(py).unbind());
        p.covariance = CovarianceSource::Known(covariance.map(Box::new));
        p
    }

    fn covariance_value(&self, py: Python<'_>) -> PyResult<Covariance> {
        match &self.covariance {
            CovarianceSource::Known(Some(c)) => Ok((**c).clone()),
            CovarianceSource::Known(None) => Err(Error::Degenerate {
                reason: "no covariance for this fit (the positions alone do not determine it, or it was not computed)".into(),
                value: 0.0,
            }
            .into()),
            CovarianceSource::Lazy {
                source,
                target,
                weights,
                scale,
            } => {
                let a = vectors(source.bind(py), "source")?;
                let b = vectors(target.bind(py), "target")?;
                let t = self.transform;
                Ok(py.detach(|| covariance(&t, &a, &b, weights.as_deref(), *scale))?)
            }
        }
    }
}

/// `intervals(level)` as a dict: `scale` (lo, hi), `translation` (3, 2),
/// `rotation_half_width_deg` (3,), `sigma` (per-axis residual sd).
pub(crate) fn intervals_dict<'py>(
    py: Python<'py>,
    c: &Covariance,
    level: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let (lo, hi) = c.scale_interval(level)?;
    d.set_item("level", level)?;
    d.set_item("scale", (lo, hi))?;
    let t = c.translation_intervals(level)?;
    d.set_item(
        "translation",
        t.iter().map(|p| (p.0, p.1)).collect::<Vec<_>>(),
    )?;
    let r = c.rotation_half_widths(level)?;
    d.set_item(
        "rotation_half_width_deg",
        r.iter().map(|x| x.to_degrees()).collect::<Vec<_>>(),
    )?;
    d.set_item("sigma", c.sigma2.sqrt())?;
    Ok(d)
}

pub(crate) fn covariance_array<'py>(
    py: Python<'py>,
    c: &Covariance,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let v: Vec<f64> = (0..7)
        .flat_map(|i| (0..7).map(move |j| (i, j)))
        .map(|(i, j)| c.matrix[(i, j)])
        .collect();
    to_array2(py, v, 7)
}

#[pymethods]
impl PyAlignment {
    /// `T_target_source` (`T_world_slam` for SLAM onto world points).
    #[getter]
    fn transform(&self) -> PySim3 {
        self.transform.into()
    }

    /// Root mean square residual, target units (weighted when weights were given).
    #[getter]
    fn rmse(&self) -> f64 {
        self.rmse
    }

    /// Per pair `‖target_i − T(source_i)‖`, shape (N,) (computed on first
    /// access from the arrays given to `align`, which are kept, not copied).
    #[getter]
    fn residuals(&self, py: Python<'_>) -> PyResult<Py<PyArray1<f64>>> {
        let r = self.residuals.get_or_try_init(py, || {
            let CovarianceSource::Lazy { source, target, .. } = &self.covariance else {
                return Err(PyErr::from(Error::invalid(
                    "residuals",
                    "neither computed with the fit nor kept inputs to compute them from",
                )));
            };
            let t = self.transform;
            with_points(source.bind(py), "source", |s| {
                with_points(target.bind(py), "target", |b| {
                    // NumPy allocates (huge pages for large arrays); filled
                    // without the GIL.
                    let out = PyArray1::<f64>::zeros(py, s.len() / 3, false);
                    {
                        let mut rw = out.readwrite();
                        let dst = rw
                            .as_slice_mut()
                            .map_err(|e| PyErr::from(Error::invalid("residuals", e.to_string())))?;
                        py.detach(|| residuals_flat(&t, s, b, dst))?;
                    }
                    Ok(out.unbind())
                })
            })
        })?;
        Ok(r.clone_ref(py))
    }

    /// Conditioning: `n`, `weight_sum`, `eigenvalues` (Horn's N, largest first),
    /// `relative_eigen_gap`, `singular_values` (cross-covariance), `source_spread`,
    /// `target_spread` (rms distance to the centroid); `dof` (a dict) for the
    /// fits with a yaw (`dof="4dof"`, `"scale+4dof"`) or an anchor.
    #[getter]
    fn diagnostics<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        diagnostics_dict(py, &self.diagnostics)
    }

    /// Per pair: inlier of a robust fit, shape (N,); None for a plain fit.
    #[getter]
    fn inliers(&self, py: Python<'_>) -> Option<Py<PyArray1<bool>>> {
        self.inliers.as_ref().map(|m| m.clone_ref(py))
    }

    /// First-order covariance (7, 7) over (rotation vector rad, translation,
    /// log scale), from the residuals.
    #[getter]
    fn covariance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let c = self.covariance_value(py)?;
        covariance_array(py, &c)
    }

    /// Central `level` confidence interval of the scale, `(lo, hi)`.
    #[pyo3(signature = (level=0.95))]
    fn scale_interval(&self, py: Python<'_>, level: f64) -> PyResult<(f64, f64)> {
        Ok(self.covariance_value(py)?.scale_interval(level)?)
    }

    /// Central `level` intervals of every parameter (see `scale_interval`).
    #[pyo3(signature = (level=0.95))]
    fn intervals<'py>(&self, py: Python<'py>, level: f64) -> PyResult<Bound<'py, PyDict>> {
        let c = self.covariance_value(py)?;
        intervals_dict(py, &c, level)
    }

    fn __repr__(&self) -> String {
        let t = &self.transform;
        let q = t.quaternion_xyzw();
        format!(
            "Alignment(scale={:.9}, quaternion=[{:.6}, {:.6}, {:.6}, {:.6}], translation=[{:.6}, {:.6}, {:.6}], rmse={:.6e}, n={})",
            t.scale, q[0], q[1], q[2], q[3], t.translation.x, t.translation.y,
            t.translation.z, self.rmse, self.diagnostics.n
        )
    }
}

/// `anchor=None|"none"|"first"` as the core's anchor.
fn anchor_arg(anchor: Option<&str>) -> PyResult<Anchor> {
    Ok(match anchor {
        None => Anchor::None,
        Some(a) => a.parse()?,
    })
}

/// Closed-form alignment of `(N, 3)` source points onto `(N, 3)` target
/// points with `dof` (`"sim3"`; `"se3"`, also `scale=False`; `"4dof"`:
/// translation + yaw about z; `"scale+4dof"`) and `anchor` (None or
/// `"first"`: the first pair mapped exactly). A yaw-only fit raises
/// `InvalidInputError` when the Sim(3) fit tilts the source z axis more than
/// `max_tilt_deg` (None: no check). `covariance` is over the Sim(3)
/// parameters, zero where the dof fixes one. The GIL is released.
#[pyfunction(name = "align")]
#[pyo3(signature = (source, target, *, scale=true, dof="sim3", anchor=None, weights=None, method="horn", max_tilt_deg=Some(defaults::MAX_TILT_DEG), robust=None, inlier_threshold=None, loss="huber"),
       text_signature = "(source, target, *, scale=True, dof='sim3', anchor=None, weights=None, \
                         method='horn', max_tilt_deg=2.0, robust=None, inlier_threshold=None, \
                         loss='huber')")]
#[allow(clippy::too_many_arguments)]
fn align_py(
    py: Python<'_>,
    source: &Bound<'_, PyAny>,
    target: &Bound<'_, PyAny>,
    scale: bool,
    dof: &str,
    anchor: Option<&str>,
    weights: Option<&Bound<'_, PyAny>>,
    method: &str,
    max_tilt_deg: Option<f64>,
    robust: Option<&str>,
    inlier_threshold: Option<f64>,
    loss: &str,
) -> PyResult<PyAlignment> {
    let dof = dof.parse::<Dof>()?.with_scale_flag(scale)?;
    let anchor = anchor_arg(anchor)?;
    let method: AlignMethod = method.parse()?;
    let weights = match weights {
        Some(w) => Some(vec_f64(w, "weights", None)?),
        None => None,
    };
    let robust = robust_arg(robust, inlier_threshold, loss)?;
    if !matches!(dof, Dof::Sim3 | Dof::Se3) || anchor != Anchor::None {
        return align_dof_py(
            py,
            source,
            target,
            DofOptions {
                dof,
                anchor,
                weights,
                method,
                max_tilt_deg,
            },
            robust,
        );
    }
    let scale = dof.has_scale();
    let opts = AlignOptions {
        scale,
        method,
        weights,
    };
    if let Some(ropts) = robust {
        let a = vectors(source, "source")?;
        let b = vectors(target, "target")?;
        let (fit, cov) = py.detach(|| -> crate::error::Result<_> {
            let r = align_robust(&a, &b, &opts, &ropts)?;
            let w: Vec<f64> = r.inliers.iter().map(|&x| f64::from(u8::from(x))).collect();
            let cov = covariance(&r.alignment.transform, &a, &b, Some(&w), scale).ok();
            Ok((r, cov))
        })?;
        return Ok(PyAlignment::with_extras(
            py,
            fit.alignment,
            Some(fit.inliers),
            cov,
        ));
    }
    let lazy = CovarianceSource::Lazy {
        source: source.clone().unbind(),
        target: target.clone().unbind(),
        weights: opts.weights.clone(),
        scale,
    };
    let fit = with_points(source, "source", |s| {
        with_points(target, "target", |t| {
            Ok(py.detach(|| fit_flat(s, t, &opts))?)
        })
    })?;
    Ok(PyAlignment {
        transform: fit.transform,
        rmse: fit.rmse,
        residuals: PyOnceLock::new(),
        diagnostics: fit.diagnostics,
        inliers: None,
        covariance: lazy,
    })
}

/// `align` with another dof or an anchor (`align/dof/`): residuals and the
/// covariance (mapped onto the Sim(3) parameters) computed with the fit.
fn align_dof_py(
    py: Python<'_>,
    source: &Bound<'_, PyAny>,
    target: &Bound<'_, PyAny>,
    opts: DofOptions,
    robust: Option<RobustOptions>,
) -> PyResult<PyAlignment> {
    let a = vectors(source, "source")?;
    let b = vectors(target, "target")?;
    let (dof, anchor) = (opts.dof, opts.anchor);
    let (alignment, inliers, cov) = py.detach(|| -> crate::error::Result<_> {
        let (alignment, inliers, w) = match &robust {
            Some(ropts) => {
                let r = align_dof_robust(&a, &b, &opts, ropts)?;
                let w: Vec<f64> = r.inliers.iter().map(|&x| f64::from(u8::from(x))).collect();
                (r.alignment, Some(r.inliers), Some(w))
            }
            None => (align_dof(&a, &b, &opts)?, None, opts.weights.clone()),
        };
        let cov = covariance_dof(&alignment.transform, &a, &b, w.as_deref(), dof, anchor)
            .ok()
            .map(|c| c.to_sim3());
        Ok((alignment, inliers, cov))
    })?;
    Ok(PyAlignment::with_extras(py, alignment, inliers, cov))
}

/// The result of `align_trajectories`: the transform `T_world_slam`, the APE
/// statistics over all matched pairs (metres) and the pairs.
#[pyclass(
    name = "TrajectoryAlignment",
    module = "slam2world._slam2world",
    frozen
)]
pub struct PyTrajectoryAlignment {
    alignment: Py<PyAlignment>,
    transform: crate::geometry::Sim3,
    ape: ApeStats,
    pairs: Vec<(usize, usize)>,
    residuals: Py<PyArray1<f64>>,
    offset: f64,
    fit_start: usize,
    skip_reason: String,
    stages: Option<Stages>,
    inliers: Option<Py<PyArray1<bool>>>,
    covariance: Option<Covariance>,
    dof: Dof,
    anchor: Anchor,
    association: Association,
    quality: crate::align::checks::FitQuality,
}

#[pymethods]
impl PyTrajectoryAlignment {
    /// Degrees of freedom fitted (`"se3"` for `"sim3"` with `scale=False`).
    #[getter]
    fn dof(&self) -> &'static str {
        self.dof.as_str()
    }
    /// The anchor: `"none"` or `"first"` (the first fitted pair mapped exactly).
    #[getter]
    fn anchor(&self) -> &'static str {
        self.anchor.as_str()
    }
    /// The pairing rule: `"evo"` or `"one_to_one"`.
    #[getter]
    fn association(&self) -> &'static str {
        self.association.as_str()
    }
    /// The figures of the fit-quality refusals: `reference_spread` (m, rms
    /// about the centroid), `reference_noise` (m, or None), `noise_source`
    /// (`"stated"`, `"second_differences"` or None), `spread_over_noise`,
    /// `residual_over_spread`, `scale_change` (`|s − 1|`).
    #[getter]
    fn quality<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let q = &self.quality;
        let d = PyDict::new(py);
        d.set_item("reference_spread", q.reference_spread)?;
        d.set_item("reference_noise", q.reference_noise)?;
        d.set_item(
            "noise_source",
            q.noise_source.map(|n| match n {
                crate::align::checks::NoiseSource::Stated => "stated",
                crate::align::checks::NoiseSource::SecondDifferences => "second_differences",
            }),
        )?;
        d.set_item("spread_over_noise", q.spread_over_noise)?;
        d.set_item("residual_over_spread", q.residual_over_spread)?;
        d.set_item("scale_change", q.scale_change)?;
        Ok(d)
    }
    /// `T_world_slam`: maps SLAM positions onto the reference.
    #[getter]
    fn transform(&self) -> PySim3 {
        self.transform.into()
    }
    /// The fit itself (over the fitted pairs: after the start-up cut, the first
    /// `n_to_align` when given, the inliers of a robust fit).
    #[getter]
    fn alignment(&self, py: Python<'_>) -> Py<PyAlignment> {
        self.alignment.clone_ref(py)
    }
    /// APE root mean square, metres.
    #[getter]
    fn rmse(&self) -> f64 {
        self.ape.rmse
    }
    /// APE mean, metres.
    #[getter]
    fn mean(&self) -> f64 {
        self.ape.mean
    }
    /// APE median, metres.
    #[getter]
    fn median(&self) -> f64 {
        self.ape.median
    }
    /// APE population standard deviation, metres.
    #[getter]
    fn std(&self) -> f64 {
        self.ape.std
    }
    /// Smallest APE, metres.
    #[getter]
    fn min(&self) -> f64 {
        self.ape.min
    }
    /// Largest APE, metres.
    #[getter]
    fn max(&self) -> f64 {
        self.ape.max
    }
    /// Number of matched pairs.
    #[getter]
    fn n_pairs(&self) -> usize {
        self.ape.n_pairs
    }
    /// `(idx_slam, idx_reference)` index arrays of the matched pairs.
    #[getter]
    fn pairs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        index_arrays(py, &self.pairs)
    }
    /// Per pair APE `‖p_ref − T(p_slam)‖`, metres, in the order of `pairs`.
    #[getter]
    fn residuals(&self, py: Python<'_>) -> Py<PyArray1<f64>> {
        self.residuals.clone_ref(py)
    }

    /// Seconds added to the SLAM stamps (given plus estimated).
    #[getter]
    fn offset(&self) -> f64 {
        self.offset
    }
    /// Index of the first fitted pair (`skip_init` dropped those before).
    #[getter]
    fn fit_start(&self) -> usize {
        self.fit_start
    }
    /// Why the pairs before `fit_start` were dropped.
    #[getter]
    fn skip_reason(&self) -> &str {
        &self.skip_reason
    }
    /// The start-up stages (with `skip_init="auto"`), else None.
    #[getter]
    fn stages(&self) -> Option<PyStages> {
        self.stages.clone().map(PyStages::from)
    }
    /// Per fitted pair: inlier of the robust fit, or None.
    #[getter]
    fn inliers(&self, py: Python<'_>) -> Option<Py<PyArray1<bool>>> {
        self.inliers.as_ref().map(|m| m.clone_ref(py))
    }
    /// First-order covariance (7, 7) over (rotation vector, translation, log scale).
    #[getter]
    fn covariance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        covariance_array(py, self.covariance_checked()?)
    }
    /// Central `level` confidence interval of the scale, `(lo, hi)`.
    #[pyo3(signature = (level=0.95))]
    fn scale_interval(&self, level: f64) -> PyResult<(f64, f64)> {
        Ok(self.covariance_checked()?.scale_interval(level)?)
    }
    /// Central `level` intervals of every parameter.
    #[pyo3(signature = (level=0.95))]
    fn intervals<'py>(&self, py: Python<'py>, level: f64) -> PyResult<Bound<'py, PyDict>> {
        intervals_dict(py, self.covariance_checked()?, level)
    }

    fn __repr__(&self) -> String {
        format!(
            "TrajectoryAlignment(scale={:.9}, rmse={:.6}, mean={:.6}, median={:.6}, n_pairs={})",
            self.transform.scale, self.ape.rmse, self.ape.mean, self.ape.median, self.ape.n_pairs
        )
    }
}

impl PyTrajectoryAlignment {
    fn covariance_checked(&self) -> PyResult<&Covariance> {
        self.covariance.as_ref().ok_or_else(|| {
            Error::Degenerate {
                reason: "no covariance for this fit (the positions alone do not determine it, or it was not computed)".into(),
                value: 0.0,
            }
            .into()
        })
    }
}

fn skip_init_arg(obj: Option<&Bound<'_, PyAny>>) -> PyResult<SkipInit> {
    let Some(o) = obj else {
        return Ok(SkipInit::None);
    };
    if o.is_none() {
        return Ok(SkipInit::None);
    }
    if let Ok(s) = o.extract::<String>() {
        if s.eq_ignore_ascii_case("auto") {
            return Ok(SkipInit::Auto);
        }
    } else if o.is_instance_of::<pyo3::types::PyInt>() {
        return Ok(SkipInit::First(super::arrays::uint_arg(o, "skip_init")?));
    }
    Err(Error::invalid("skip_init", "expected None, \"auto\" or a pair count >= 0").into())
}

/// `robust=None|"ransac"`, `inlier_threshold` (only with `"ransac"`) and
/// `loss` (`"huber"` or `"cauchy"`) as the core's robust options.
pub(crate) fn robust_arg(
    robust: Option<&str>,
    inlier_threshold: Option<f64>,
    loss: &str,
) -> PyResult<Option<RobustOptions>> {
    match robust {
        None if inlier_threshold.is_some() => {
            Err(Error::invalid("inlier_threshold", "only with robust=\"ransac\"").into())
        }
        None => Ok(None),
        Some(r) if r.eq_ignore_ascii_case("ransac") => Ok(Some(RobustOptions {
            inlier_threshold,
            loss: loss.parse()?,
            ..Default::default()
        })),
        Some(r) => {
            Err(Error::invalid("robust", format!("expected None or \"ransac\", got {r:?}")).into())
        }
    }
}

/// The keyword options of a trajectory fit (`align_trajectories`, `convert`)
/// as the core's [`TrajectoryAlignOptions`].
#[allow(clippy::too_many_arguments)]
pub(crate) fn fit_options(
    max_diff: f64,
    offset: f64,
    scale: bool,
    n_to_align: Option<usize>,
    method: &str,
    skip_init: Option<&Bound<'_, PyAny>>,
    robust: Option<&str>,
    inlier_threshold: Option<f64>,
    loss: &str,
    use_orientations: bool,
    estimate_offset: bool,
    max_offset: f64,
    body_from_cam: Option<crate::geometry::Sim3>,
    dof: FitDof<'_>,
) -> PyResult<TrajectoryAlignOptions> {
    let opts = TrajectoryAlignOptions {
        max_diff,
        offset,
        scale,
        dof: dof.dof.parse()?,
        anchor: anchor_arg(dof.anchor)?,
        max_tilt_deg: dof.max_tilt_deg,
        association: dof.association.parse()?,
        checks: FitChecks {
            enabled: dof.fit_checks,
            reference_noise: dof.reference_noise,
            ..FitChecks::default()
        },
        n_to_align,
        method: method.parse()?,
        skip_init: skip_init_arg(skip_init)?,
        robust: robust_arg(robust, inlier_threshold, loss)?,
        use_orientations,
        estimate_offset: estimate_offset.then(|| TimeOffsetOptions {
            max_offset,
            ..Default::default()
        }),
        body_from_cam,
    };
    opts.check()?;
    Ok(opts)
}

/// The keyword options of a trajectory fit beyond the classic ones: degrees
/// of freedom, anchor, pairing rule, tilt limit, fit-quality checks.
pub(crate) struct FitDof<'a> {
    pub dof: &'a str,
    pub anchor: Option<&'a str>,
    pub association: &'a str,
    pub max_tilt_deg: Option<f64>,
    pub reference_noise: Option<f64>,
    pub fit_checks: bool,
}

/// Associates by time, fits `T_world_slam` on the positions (the first
/// `n_to_align` pairs after the start-up cut when given) and reports the APE
/// over all pairs. The keyword options beyond `method`: start-up cut
/// (`skip_init`), robust fit, orientations, time offset, extrinsic; `dof`
/// and `anchor` as `align`'s (`anchor="first"` pins the first fitted pair),
/// `association` (`"evo"`, or `"one_to_one"`: the TUM benchmark's rule),
/// `max_tilt_deg` (the gravity check of a yaw-only fit); `reference_noise`
/// (metres, 3-D rms; None: estimated) and `fit_checks` for the fit-quality
/// refusals (a static reference, a fit that explains none of the
/// reference's spread, a scale left at 1), which raise `DegenerateError`.
#[pyfunction(name = "align_trajectories")]
#[pyo3(signature = (slam, reference, *, max_diff=0.01, offset=0.0, scale=true, n_to_align=None, method="horn", skip_init=None, robust=None, inlier_threshold=None, loss="huber", use_orientations=false, estimate_offset=false, max_offset=0.5, body_from_cam=None, dof="sim3", anchor=None, association="evo", max_tilt_deg=Some(defaults::MAX_TILT_DEG), reference_noise=None, fit_checks=true),
       text_signature = "(slam, reference, *, max_diff=0.01, offset=0.0, scale=True, n_to_align=None, \
                         method='horn', skip_init=None, robust=None, inlier_threshold=None, \
                         loss='huber', use_orientations=False, estimate_offset=False, \
                         max_offset=0.5, body_from_cam=None, dof='sim3', anchor=None, \
                         association='evo', max_tilt_deg=2.0, reference_noise=None, \
                         fit_checks=True)")]
#[allow(clippy::too_many_arguments)]
fn align_trajectories_py(
    py: Python<'_>,
    slam: PyRef<'_, PyTrajectory>,
    reference: PyRef<'_, PyTrajectory>,
    max_diff: f64,
    offset: f64,
    scale: bool,
    #[pyo3(from_py_with = super::arrays::uint::n_to_align)] n_to_align: Option<usize>,
    method: &str,
    skip_init: Option<&Bound<'_, PyAny>>,
    robust: Option<&str>,
    inlier_threshold: Option<f64>,
    loss: &str,
    use_orientations: bool,
    estimate_offset: bool,
    max_offset: f64,
    body_from_cam: Option<PyRef<'_, PySim3>>,
    dof: &str,
    anchor: Option<&str>,
    association: &str,
    max_tilt_deg: Option<f64>,
    reference_noise: Option<f64>,
    fit_checks: bool,
) -> PyResult<PyTrajectoryAlignment> {
    let opts = fit_options(
        max_diff,
        offset,
        scale,
        n_to_align,
        method,
        skip_init,
        robust,
        inlier_threshold,
        loss,
        use_orientations,
        estimate_offset,
        max_offset,
        body_from_cam.map(|b| b.inner),
        FitDof {
            dof,
            anchor,
            association,
            max_tilt_deg,
            reference_noise,
            fit_checks,
        },
    )?;
    let (s, r) = (&slam.inner, &reference.inner);
    let out = py.detach(|| align_trajectories(s, r, &opts))?;
    PyTrajectoryAlignment::new(py, out)
}

impl PyTrajectoryAlignment {
    /// Wraps a core trajectory fit (also used by `convert`).
    pub(crate) fn new(py: Python<'_>, out: TrajectoryAlignment) -> PyResult<Self> {
        let transform = out.transform();
        let TrajectoryAlignment {
            alignment,
            pairs,
            ape,
            errors,
            offset,
            stages,
            fit_start,
            skip_reason,
            inliers,
            covariance,
            dof,
            anchor,
            association,
            quality,
            ..
        } = out;
        Ok(PyTrajectoryAlignment {
            alignment: Py::new(
                py,
                PyAlignment::with_extras(py, alignment, inliers.clone(), covariance.clone()),
            )?,
            transform,
            ape,
            pairs,
            residuals: errors.into_pyarray(py).unbind(),
            offset,
            fit_start,
            skip_reason,
            stages,
            inliers: inliers.map(|m| m.into_pyarray(py).unbind()),
            covariance,
            dof,
            anchor,
            association,
            quality,
        })
    }
}

/// The start-up stages of a run, indices into the scale factors `p_k`.
#[pyclass(
    name = "Stages",
    module = "slam2world._slam2world",
    frozen,
    skip_from_py_object
)]
#[derive(Clone)]
pub struct PyStages {
    inner: Stages,
}

impl From<Stages> for PyStages {
    fn from(inner: Stages) -> Self {
        PyStages { inner }
    }
}

#[pymethods]
impl PyStages {
    /// First factor of the converging stretch.
    #[getter]
    fn converging_start(&self) -> usize {
        self.inner.converging_start
    }
    /// First factor of the stable stage (fit from here).
    #[getter]
    fn stable_start(&self) -> usize {
        self.inner.stable_start
    }
    /// Number of factors.
    #[getter]
    fn n(&self) -> usize {
        self.inner.n
    }
    /// The stable level of `p_k` (≈ s²).
    #[getter]
    fn stable_level(&self) -> f64 {
        self.inner.stable_level
    }
    /// Robust per-sample standard deviation of `ln p_k` once stable.
    #[getter]
    fn noise(&self) -> f64 {
        self.inner.noise
    }
    /// Factors per block (the stages are fitted to block medians of `ln p_k`).
    #[getter]
    fn window(&self) -> usize {
        self.inner.window
    }
    /// One line saying what the stages are and why.
    fn describe(&self) -> String {
        self.inner.describe()
    }
    fn __repr__(&self) -> String {
        format!(
            "Stages(converging_start={}, stable_start={}, n={}, stable_level={:.6})",
            self.inner.converging_start,
            self.inner.stable_start,
            self.inner.n,
            self.inner.stable_level
        )
    }
}

/// Finds the start-up stages in the frame-to-frame scale factors `p_k` (N,).
#[pyfunction(name = "detect_stages")]
fn detect_stages_py(p_k: &Bound<'_, PyAny>) -> PyResult<PyStages> {
    let p = vec_f64(p_k, "p_k", None)?;
    Ok(detect_stages(&p)?.into())
}

/// Seconds to add to the SLAM stamps so that the motion matches the reference
/// best (searched within ±`max_offset`).
#[pyfunction(name = "estimate_time_offset")]
#[pyo3(signature = (slam, reference, *, max_offset=0.5, max_gap=0.1, scale=true))]
fn estimate_time_offset_py(
    py: Python<'_>,
    slam: PyRef<'_, PyTrajectory>,
    reference: PyRef<'_, PyTrajectory>,
    max_offset: f64,
    max_gap: f64,
    scale: bool,
) -> PyResult<f64> {
    let opts = TimeOffsetOptions {
        max_offset,
        max_gap,
        scale,
        ..Default::default()
    };
    let (s, r) = (&slam.inner, &reference.inner);
    Ok(py.detach(|| estimate_time_offset(s, r, &opts))?.offset)
}

/// Per-pose `T_world_slam` of a windowed (drift-aware) alignment.
#[pyclass(name = "WindowedAlignment", module = "slam2world._slam2world", frozen)]
pub struct PyWindowedAlignment {
    inner: WindowedAlignment,
    single: Py<PyAlignment>,
}

#[pymethods]
impl PyWindowedAlignment {
    /// SLAM stamps (seconds) of the matched poses.
    #[getter]
    fn times<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.times.clone().into_pyarray(py)
    }
    /// `T_world_slam` at each of `times`.
    #[getter]
    fn transforms(&self) -> Vec<PySim3> {
        self.inner.transforms.iter().map(|t| (*t).into()).collect()
    }
    /// Scale of each local transform, shape (N,).
    #[getter]
    fn scales<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let v: Vec<f64> = self.inner.transforms.iter().map(|t| t.scale).collect();
        v.into_pyarray(py)
    }
    /// Per pose `‖p_ref − T(t)·p_slam‖`, metres.
    #[getter]
    fn residuals<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.residuals.clone().into_pyarray(py)
    }
    /// rms of `residuals`, metres.
    #[getter]
    fn rmse(&self) -> f64 {
        self.inner.rmse
    }
    /// The single Sim(3) over every pair, for comparison.
    #[getter]
    fn single(&self, py: Python<'_>) -> Py<PyAlignment> {
        self.single.clone_ref(py)
    }
    /// `T_world_slam` at SLAM time `t` (blend of the neighbouring transforms).
    fn transform_at(&self, t: f64) -> PySim3 {
        self.inner.transform_at(t).into()
    }
    /// `transform_at` for each time, as a list.
    fn transforms_at(&self, times: &Bound<'_, PyAny>) -> PyResult<Vec<PySim3>> {
        let t = vec_f64(times, "times", None)?;
        Ok(t.iter()
            .map(|&x| self.inner.transform_at(x).into())
            .collect())
    }
    fn __repr__(&self) -> String {
        format!(
            "WindowedAlignment({} poses, rmse={:.6}, single rmse={:.6})",
            self.inner.times.len(),
            self.inner.rmse,
            self.inner.global.rmse
        )
    }
}

/// A window given as an int (matched poses) or a float (metres of reference
/// path); `what` names the argument in the error (`align_windowed`, `convert`).
pub(crate) fn window_arg(w: &Bound<'_, PyAny>, what: &str) -> PyResult<Window> {
    if w.is_instance_of::<pyo3::types::PyInt>() {
        return Ok(Window::Poses(super::arrays::uint_arg(w, what)?));
    }
    match w.extract::<f64>() {
        Ok(d) => Ok(Window::Distance(d)),
        Err(_) => Err(Error::invalid(what, "expected an int (poses) or a float (metres)").into()),
    }
}

/// Windowed Sim(3) along the path: `window` an int (matched poses) or a float
/// (metres of reference path); every fit with `dof` (as `align`'s), the
/// stamps paired by `association` (`"evo"` or `"one_to_one"`).
#[pyfunction(name = "align_windowed")]
#[pyo3(signature = (slam, reference, *, window=None, max_diff=0.01, offset=0.0, scale=true, dof="sim3", association="evo"))]
#[allow(clippy::too_many_arguments)]
fn align_windowed_py(
    py: Python<'_>,
    slam: PyRef<'_, PyTrajectory>,
    reference: PyRef<'_, PyTrajectory>,
    window: Option<&Bound<'_, PyAny>>,
    max_diff: f64,
    offset: f64,
    scale: bool,
    dof: &str,
    association: &str,
) -> PyResult<PyWindowedAlignment> {
    let window = match window {
        None => Window::default(),
        Some(w) => window_arg(w, "window")?,
    };
    let opts = WindowedOptions {
        window,
        max_diff,
        offset,
        scale,
        dof: dof.parse()?,
        association: association.parse()?,
        ..WindowedOptions::default()
    };
    let (s, r) = (&slam.inner, &reference.inner);
    let inner = py.detach(|| align_windowed(s, r, &opts))?;
    let single = Py::new(py, PyAlignment::new(py, inner.global.clone()))?;
    Ok(PyWindowedAlignment { inner, single })
}

/// Hand-eye with scale: estimates `T_body_cam` (metres) from SLAM camera poses
/// and reference body poses (both with orientations); returns
/// `(body_from_cam, alignment, rotation_rmse_rad)`.
#[pyfunction(name = "estimate_body_from_cam")]
#[pyo3(signature = (slam, reference, *, max_diff=0.01, offset=0.0))]
fn estimate_body_from_cam_py(
    py: Python<'_>,
    slam: PyRef<'_, PyTrajectory>,
    reference: PyRef<'_, PyTrajectory>,
    max_diff: f64,
    offset: f64,
) -> PyResult<(PySim3, PyAlignment, f64)> {
    let (s, r) = (&slam.inner, &reference.inner);
    let (he, _) = py.detach(|| estimate_body_from_cam_trajectories(s, r, max_diff, offset))?;
    Ok((
        he.body_from_cam.into(),
        PyAlignment::new(py, he.alignment),
        he.rotation_rmse,
    ))
}

/// The `dof` entry of `Alignment.diagnostics`: `dof`, `anchor`,
/// `source_horizontal_spread`, `target_horizontal_spread`, `yaw_determinacy`,
/// `gravity_tilt_deg` (None when not observable).
pub(crate) fn dof_diagnostics_dict<'py>(
    py: Python<'py>,
    d: &DofDiagnostics,
) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    dict.set_item("dof", d.dof.as_str())?;
    dict.set_item("anchor", d.anchor.as_str())?;
    dict.set_item("source_horizontal_spread", d.source_horizontal_spread)?;
    dict.set_item("target_horizontal_spread", d.target_horizontal_spread)?;
    dict.set_item("yaw_determinacy", d.yaw_determinacy)?;
    dict.set_item("gravity_tilt_deg", d.gravity_tilt_deg)?;
    Ok(dict)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyAlignment>()?;
    m.add_class::<PyTrajectoryAlignment>()?;
    m.add_class::<PyStages>()?;
    m.add_class::<PyWindowedAlignment>()?;
    m.add_function(wrap_pyfunction!(align_py, m)?)?;
    m.add_function(wrap_pyfunction!(align_trajectories_py, m)?)?;
    m.add_function(wrap_pyfunction!(detect_stages_py, m)?)?;
    m.add_function(wrap_pyfunction!(estimate_time_offset_py, m)?)?;
    m.add_function(wrap_pyfunction!(align_windowed_py, m)?)?;
    m.add_function(wrap_pyfunction!(estimate_body_from_cam_py, m)?)?;
    Ok(())
}
