//! Alignment and trajectories for Python: `align`, `Alignment`, `Trajectory`,
//! `associate`, `align_trajectories`, `TrajectoryAlignment`, `scale_factors`.

use std::path::PathBuf;

use nalgebra::{UnitQuaternion, Vector3};
use numpy::{
    AllowTypeChange, IntoPyArray, PyArray1, PyArray2, PyArrayLike2, PyArrayMethods,
    PyUntypedArrayMethods, ToPyArray,
};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple};

use super::convert::{c_slice, rows_f64, to_array2, vec_f64};
use super::geometry::PySim3;
use crate::align::covariance::{covariance, Covariance};
use crate::align::extended::{
    align_trajectories_extended, ExtendedAlignment, ExtendedOptions, SkipInit,
};
use crate::align::robust::{align_robust, RobustOptions};
use crate::align::stages::Stages;
use crate::align::time_offset::TimeOffsetOptions;
use crate::align::{
    fit_flat, residuals_flat, AlignDiagnostics, AlignMethod, AlignOptions, Alignment,
};
use crate::error::Error;
use crate::geometry::unit_quaternion_xyzw;
use crate::trajectory::{
    associate, scale_factors, ApeStats, Trajectory, TrajectoryAlignOptions, TrajectoryAlignment,
};

/// Runs `f` on the row-major `(N, 3)` `f64` data of `obj`, borrowed without a
/// copy when it is a C-contiguous float64 array.
fn with_points<R>(
    obj: &Bound<'_, PyAny>,
    what: &str,
    f: impl FnOnce(&[f64]) -> PyResult<R>,
) -> PyResult<R> {
    let arr: PyArrayLike2<'_, f64, AllowTypeChange> = obj.extract().map_err(|_| {
        PyErr::from(Error::ShapeMismatch {
            what: what.into(),
            expected: "a 2-D array of shape (N, 3)".into(),
            got: "something else".into(),
        })
    })?;
    let shape = arr.shape();
    if shape[1] != 3 {
        return Err(Error::ShapeMismatch {
            what: what.into(),
            expected: "(N, 3)".into(),
            got: format!("{shape:?}"),
        }
        .into());
    }
    match c_slice(&arr) {
        Some(s) => f(s),
        None => {
            let v: Vec<f64> = arr.as_array().iter().copied().collect();
            f(&v)
        }
    }
}

fn vectors(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<Vector3<f64>>> {
    let v = rows_f64(obj, what, 3)?;
    Ok(v.chunks_exact(3)
        .map(|r| Vector3::new(r[0], r[1], r[2]))
        .collect())
}

fn flat(v: &[Vector3<f64>]) -> Vec<f64> {
    v.iter().flat_map(|p| [p.x, p.y, p.z]).collect()
}

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
        dict.set_item("dof", super::align_dof::dof_diagnostics_dict(py, x)?)?;
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
    /// fits of `align_dof` with a yaw or an anchor.
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

/// Closed-form Sim(3) (or SE(3) with `scale=False`) alignment of `(N, 3)`
/// source points onto `(N, 3)` target points; the GIL is released.
#[pyfunction(name = "align")]
#[pyo3(signature = (source, target, *, scale=true, weights=None, method="horn", robust=None, inlier_threshold=None, loss="huber"))]
#[allow(clippy::too_many_arguments)]
fn align_py(
    py: Python<'_>,
    source: &Bound<'_, PyAny>,
    target: &Bound<'_, PyAny>,
    scale: bool,
    weights: Option<&Bound<'_, PyAny>>,
    method: &str,
    robust: Option<&str>,
    inlier_threshold: Option<f64>,
    loss: &str,
) -> PyResult<PyAlignment> {
    let method: AlignMethod = method.parse()?;
    let weights = match weights {
        Some(w) => Some(vec_f64(w, "weights", None)?),
        None => None,
    };
    let opts = AlignOptions {
        scale,
        method,
        weights,
    };
    if let Some(ropts) = robust_arg(robust, inlier_threshold, loss)? {
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

/// Timestamped positions (seconds, metres) with optional orientations `(x, y, z, w)`.
#[pyclass(name = "Trajectory", module = "slam2world._slam2world", frozen)]
pub struct PyTrajectory {
    pub inner: Trajectory,
}

#[pymethods]
impl PyTrajectory {
    #[new]
    #[pyo3(signature = (timestamps, positions, orientations=None))]
    fn new(
        timestamps: &Bound<'_, PyAny>,
        positions: &Bound<'_, PyAny>,
        orientations: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let t = vec_f64(timestamps, "timestamps", None)?;
        let p = vectors(positions, "positions")?;
        let o = match orientations {
            None => None,
            Some(o) => {
                let v = rows_f64(o, "orientations", 4)?;
                let q: Result<Vec<UnitQuaternion<f64>>, Error> = v
                    .chunks_exact(4)
                    .enumerate()
                    .map(|(i, r)| {
                        unit_quaternion_xyzw([r[0], r[1], r[2], r[3]])
                            .map_err(|e| Error::invalid("orientations", format!("row {i}: {e}")))
                    })
                    .collect();
                Some(q?)
            }
        };
        Ok(PyTrajectory {
            inner: Trajectory::try_new(t, p, o)?,
        })
    }

    /// Reads a TUM file (`timestamp tx ty tz qx qy qz qw`).
    #[staticmethod]
    fn read_tum(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let inner = py.detach(|| Trajectory::read_tum(&path))?;
        Ok(PyTrajectory { inner })
    }

    /// Reads EuRoC ground truth CSV (ns, x, y, z, qw, qx, qy, qz, …).
    #[staticmethod]
    fn read_euroc(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let inner = py.detach(|| Trajectory::read_euroc(&path))?;
        Ok(PyTrajectory { inner })
    }

    /// Writes a TUM file (atomically: a temporary file renamed into place).
    fn write_tum(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        Ok(py.detach(|| self.inner.write_tum(&path))?)
    }

    /// Times, seconds, shape (N,).
    #[getter]
    fn timestamps<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.timestamps.to_pyarray(py)
    }

    /// Positions, shape (N, 3).
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        to_array2(py, flat(&self.inner.positions), 3)
    }

    /// Orientations `(x, y, z, w)`, shape (N, 4), or None.
    #[getter]
    fn orientations<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArray2<f64>>>> {
        match &self.inner.orientations {
            None => Ok(None),
            Some(o) => {
                let v: Vec<f64> = o
                    .iter()
                    .flat_map(|q| [q.coords[0], q.coords[1], q.coords[2], q.coords[3]])
                    .collect();
                Ok(Some(to_array2(py, v, 4)?))
            }
        }
    }

    /// Poses at `times` (lerp + slerp); raises outside the covered range or
    /// inside a gap longer than `max_gap` seconds.
    #[pyo3(signature = (times, max_gap=0.1))]
    fn interpolate(&self, times: &Bound<'_, PyAny>, max_gap: f64) -> PyResult<Self> {
        let t = vec_f64(times, "times", None)?;
        Ok(PyTrajectory {
            inner: self.inner.interpolate(&t, max_gap)?,
        })
    }

    /// Like `interpolate`, but skips the times it cannot answer: returns
    /// `(trajectory, kept, missing)` with index arrays into `times`.
    #[pyo3(signature = (times, max_gap=0.1))]
    fn interpolate_where_covered<'py>(
        &self,
        py: Python<'py>,
        times: &Bound<'py, PyAny>,
        max_gap: f64,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let t = vec_f64(times, "times", None)?;
        let r = self.inner.interpolate_where_covered(&t, max_gap)?;
        let kept: Vec<i64> = r.kept.iter().map(|&i| i as i64).collect();
        let missing: Vec<i64> = r.missing.iter().map(|&i| i as i64).collect();
        let traj = Bound::new(
            py,
            PyTrajectory {
                inner: r.trajectory,
            },
        )?;
        PyTuple::new(
            py,
            [
                traj.into_any(),
                kept.into_pyarray(py).into_any(),
                missing.into_pyarray(py).into_any(),
            ],
        )
    }

    /// Poses mapped by `transform` (`T_world_slam · T_slam_cam`).
    fn transformed(&self, transform: PyRef<'_, PySim3>) -> Self {
        PyTrajectory {
            inner: self.inner.transformed(&transform.inner),
        }
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }

    fn __repr__(&self) -> String {
        let t = &self.inner.timestamps;
        match (t.first(), t.last()) {
            (Some(a), Some(b)) => format!(
                "Trajectory({} poses, {a:.6}..{b:.6} s, orientations={})",
                t.len(),
                self.inner.orientations.is_some()
            ),
            _ => "Trajectory(0 poses)".into(),
        }
    }

    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let py = slf.py();
        let this = slf.get();
        let args = (
            this.timestamps(py),
            this.positions(py)?,
            this.orientations(py)?,
        );
        PyTuple::new(
            py,
            [
                slf.get_type().into_any(),
                args.into_pyobject(py)?.into_any(),
            ],
        )
    }
}

fn index_arrays<'py>(py: Python<'py>, pairs: &[(usize, usize)]) -> PyResult<Bound<'py, PyTuple>> {
    let a: Vec<i64> = pairs.iter().map(|&(i, _)| i as i64).collect();
    let b: Vec<i64> = pairs.iter().map(|&(_, j)| j as i64).collect();
    PyTuple::new(py, [a.into_pyarray(py), b.into_pyarray(py)])
}

/// Indices `(idx_a, idx_b)` of poses matched by time as evo does (`offset`
/// seconds added to `b`'s stamps; nearest stamp within `max_diff`).
#[pyfunction(name = "associate")]
#[pyo3(signature = (a, b, *, max_diff=0.01, offset=0.0))]
fn associate_py<'py>(
    py: Python<'py>,
    a: PyRef<'py, PyTrajectory>,
    b: PyRef<'py, PyTrajectory>,
    max_diff: f64,
    offset: f64,
) -> PyResult<Bound<'py, PyTuple>> {
    let pairs = associate(&a.inner, &b.inner, max_diff, offset);
    index_arrays(py, &pairs)
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
}

#[pymethods]
impl PyTrajectoryAlignment {
    /// `T_world_slam`: maps SLAM positions onto the reference.
    #[getter]
    fn transform(&self) -> PySim3 {
        self.transform.into()
    }
    /// The fit itself (over the first `first_n` pairs when given).
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
    fn stages(&self) -> Option<super::beyond::PyStages> {
        self.stages.clone().map(super::beyond::PyStages::from)
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
    } else if let Ok(n) = o.extract::<usize>() {
        return Ok(SkipInit::First(n));
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

/// The keyword options beyond one fit (`align_trajectories`, `convert`) as
/// the core's [`ExtendedOptions`]; `max_offset` (seconds) is `Some` when the
/// time offset is to be estimated.
pub(crate) fn extended_options(
    skip_init: Option<&Bound<'_, PyAny>>,
    robust: Option<&str>,
    inlier_threshold: Option<f64>,
    loss: &str,
    use_orientations: bool,
    max_offset: Option<f64>,
    body_from_cam: Option<crate::geometry::Sim3>,
) -> PyResult<ExtendedOptions> {
    Ok(ExtendedOptions {
        skip_init: skip_init_arg(skip_init)?,
        robust: robust_arg(robust, inlier_threshold, loss)?,
        use_orientations,
        estimate_offset: max_offset.map(|max_offset| TimeOffsetOptions {
            max_offset,
            ..Default::default()
        }),
        body_from_cam,
    })
}

/// Associates by time, fits `T_world_slam` on the positions (the first
/// `first_n` pairs when given) and reports the APE over all pairs. The
/// keyword options beyond `method` are those of the extended fit: start-up
/// cut (`skip_init`), robust fit, orientations, time offset, extrinsic.
#[pyfunction(name = "align_trajectories")]
#[pyo3(signature = (slam, reference, *, max_diff=0.01, offset=0.0, scale=true, first_n=None, method="horn", skip_init=None, robust=None, inlier_threshold=None, loss="huber", use_orientations=false, estimate_offset=false, max_offset=0.5, body_from_cam=None))]
#[allow(clippy::too_many_arguments)]
fn align_trajectories_py(
    py: Python<'_>,
    slam: PyRef<'_, PyTrajectory>,
    reference: PyRef<'_, PyTrajectory>,
    max_diff: f64,
    offset: f64,
    scale: bool,
    first_n: Option<usize>,
    method: &str,
    skip_init: Option<&Bound<'_, PyAny>>,
    robust: Option<&str>,
    inlier_threshold: Option<f64>,
    loss: &str,
    use_orientations: bool,
    estimate_offset: bool,
    max_offset: f64,
    body_from_cam: Option<PyRef<'_, PySim3>>,
) -> PyResult<PyTrajectoryAlignment> {
    let opts = TrajectoryAlignOptions {
        max_diff,
        offset,
        scale,
        first_n,
        method: method.parse()?,
    };
    let ext = extended_options(
        skip_init,
        robust,
        inlier_threshold,
        loss,
        use_orientations,
        estimate_offset.then_some(max_offset),
        body_from_cam.map(|b| b.inner),
    )?;
    let (s, r) = (&slam.inner, &reference.inner);
    let out = py.detach(|| align_trajectories_extended(s, r, &opts, &ext))?;
    PyTrajectoryAlignment::from_extended(py, out)
}

impl PyTrajectoryAlignment {
    /// Wraps a core extended fit (also used by `convert` in `mcap.rs`).
    pub(crate) fn from_extended(py: Python<'_>, out: ExtendedAlignment) -> PyResult<Self> {
        let TrajectoryAlignment {
            alignment,
            pairs,
            ape,
            errors,
        } = out.trajectory;
        let transform = alignment.transform;
        let inliers = out.inliers;
        Ok(PyTrajectoryAlignment {
            alignment: Py::new(
                py,
                PyAlignment::with_extras(py, alignment, inliers.clone(), out.covariance.clone()),
            )?,
            transform,
            ape,
            pairs,
            residuals: errors.into_pyarray(py).unbind(),
            offset: out.offset,
            fit_start: out.fit_start,
            skip_reason: out.skip_reason,
            stages: out.stages,
            inliers: inliers.map(|m| m.into_pyarray(py).unbind()),
            covariance: out.covariance,
        })
    }
}

/// The paper's frame-to-frame factors `p_k = ‖t'_{k+1} − t'_k‖² / ‖t_{k+1} − t_k‖²`
/// (`t'` reference, `t` SLAM), shape (N−1,); about `s²`.
#[pyfunction(name = "scale_factors")]
fn scale_factors_py<'py>(
    py: Python<'py>,
    slam_positions: &Bound<'py, PyAny>,
    reference_positions: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let s = vectors(slam_positions, "slam_positions")?;
    let r = vectors(reference_positions, "reference_positions")?;
    Ok(scale_factors(&s, &r)?.into_pyarray(py))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyAlignment>()?;
    m.add_class::<PyTrajectory>()?;
    m.add_class::<PyTrajectoryAlignment>()?;
    m.add_function(wrap_pyfunction!(align_py, m)?)?;
    m.add_function(wrap_pyfunction!(associate_py, m)?)?;
    m.add_function(wrap_pyfunction!(align_trajectories_py, m)?)?;
    m.add_function(wrap_pyfunction!(scale_factors_py, m)?)?;
    Ok(())
}
