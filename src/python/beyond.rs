//! Beyond one fit, for Python: `detect_stages`, `Stages`, `estimate_time_offset`,
//! `align_windowed`, `WindowedAlignment`, `estimate_body_from_cam`.

use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;

use super::convert::vec_f64;
use super::core::{PyAlignment, PyTrajectory};
use super::geometry::PySim3;
use crate::align::handeye::estimate_body_from_cam_trajectories;
use crate::align::stages::{detect_stages, Stages};
use crate::align::time_offset::{estimate_time_offset, TimeOffsetOptions};
use crate::align::windowed::{align_windowed, Window, WindowedAlignment, WindowedOptions};
use crate::error::Error;

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
    /// Rolling window, factors.
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
        return Ok(Window::Poses(w.extract()?));
    }
    match w.extract::<f64>() {
        Ok(d) => Ok(Window::Distance(d)),
        Err(_) => Err(Error::invalid(what, "expected an int (poses) or a float (metres)").into()),
    }
}

/// Windowed Sim(3) along the path: `window` an int (matched poses) or a float
/// (metres of reference path).
#[pyfunction(name = "align_windowed")]
#[pyo3(signature = (slam, reference, *, window=None, max_diff=0.01, offset=0.0, scale=true))]
fn align_windowed_py(
    py: Python<'_>,
    slam: PyRef<'_, PyTrajectory>,
    reference: PyRef<'_, PyTrajectory>,
    window: Option<&Bound<'_, PyAny>>,
    max_diff: f64,
    offset: f64,
    scale: bool,
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

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyStages>()?;
    m.add_class::<PyWindowedAlignment>()?;
    m.add_function(wrap_pyfunction!(detect_stages_py, m)?)?;
    m.add_function(wrap_pyfunction!(estimate_time_offset_py, m)?)?;
    m.add_function(wrap_pyfunction!(align_windowed_py, m)?)?;
    m.add_function(wrap_pyfunction!(estimate_body_from_cam_py, m)?)?;
    Ok(())
}
