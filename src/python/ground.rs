//! Scale and gravity with no second sensor, for Python: `ground_plane`,
//! `metric_from_height` and their results.

use nalgebra::Vector3;
use numpy::{PyArray1, ToPyArray};
use pyo3::prelude::*;

use super::arrays::{vec_f64, vector3, vectors};
use super::geometry::PySim3;
use super::trajectory::PyTrajectory;
use crate::align::ground::{
    fit_ground_plane, metric_from_height, CameraHeight, GroundOptions, GroundPlane, HeightScale,
};
use crate::defaults;

/// The ground plane of a cloud (`ground_plane`): the points `x` with
/// `normal · x + offset = 0`, the normal towards the cameras.
#[pyclass(name = "GroundPlane", module = "slam2world._slam2world", frozen)]
pub struct PyGroundPlane {
    inner: GroundPlane,
}

#[pymethods]
impl PyGroundPlane {
    /// Unit normal, towards the cameras ("up"), shape (3,).
    #[getter]
    fn normal<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.normal.as_slice().to_pyarray(py)
    }
    /// `normal · x + offset` is the height of `x` (SLAM units).
    #[getter]
    fn offset(&self) -> f64 {
        self.inner.offset
    }
    /// Points within `threshold` of the plane.
    #[getter]
    fn inliers(&self) -> usize {
        self.inner.inliers
    }
    /// Points fitted (the finite ones).
    #[getter]
    fn n_points(&self) -> usize {
        self.inner.n_points
    }
    /// Robust standard deviation of the inliers' distances (SLAM units).
    #[getter]
    fn spread(&self) -> f64 {
        self.inner.spread
    }
    /// The inlier threshold (three spreads of the first surface found).
    #[getter]
    fn threshold(&self) -> f64 {
        self.inner.threshold
    }
    /// Share of the points more than three spreads under the plane.
    #[getter]
    fn below(&self) -> f64 {
        self.inner.below
    }
    /// Share of the cameras above the plane.
    #[getter]
    fn cameras_above(&self) -> f64 {
        self.inner.cameras_above
    }
    /// Degrees between the normal and the cameras' mean "image up" (None
    /// without orientations).
    #[getter]
    fn tilt_from_cameras_deg(&self) -> Option<f64> {
        self.inner.tilt_from_cameras_deg
    }
    /// The strongest other plane under the cameras: (inliers, height over
    /// this one), or None.
    #[getter]
    fn runner_up(&self) -> Option<(usize, f64)> {
        self.inner.runner_up
    }
    /// Height of the point `x` above the plane (SLAM units).
    fn height(&self, x: &Bound<'_, PyAny>) -> PyResult<f64> {
        Ok(self.inner.height(&vector3(x, "x")?))
    }
    fn __repr__(&self) -> String {
        let n = self.inner.normal;
        format!(
            "GroundPlane(normal=[{:.6}, {:.6}, {:.6}], offset={:.6}, inliers={} of {}, spread={:.3e})",
            n.x, n.y, n.z, self.inner.offset, self.inner.inliers, self.inner.n_points, self.inner.spread
        )
    }
}

/// The metric frame from a ground plane and the cameras' heights
/// (`metric_from_height`).
#[pyclass(name = "HeightScale", module = "slam2world._slam2world", frozen)]
pub struct PyHeightScale {
    inner: HeightScale,
}

#[pymethods]
impl PyHeightScale {
    /// `T_world_slam`: z up, the origin on the ground under the first
    /// camera, x along its heading.
    #[getter]
    fn transform(&self) -> PySim3 {
        self.inner.t_world_slam.into()
    }
    /// Metres per SLAM unit.
    #[getter]
    fn scale(&self) -> f64 {
        self.inner.scale
    }
    /// The cameras' heights above the plane, SLAM units, shape (N,).
    #[getter]
    fn heights<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.heights.to_pyarray(py)
    }
    /// Rms of the given heights less the fitted ones, metres.
    #[getter]
    fn height_rms(&self) -> f64 {
        self.inner.height_rms
    }
    fn __repr__(&self) -> String {
        format!(
            "HeightScale(scale={:.9}, height_rms={:.4})",
            self.inner.scale, self.inner.height_rms
        )
    }
}

/// The ground plane of `points` (N×3, SLAM frame) under `cameras` (their
/// positions; their orientations bound the plane's tilt to `max_up_angle_deg`
/// from the cameras' mean "image up", None: no bound). Raises
/// `DegenerateError` with the reason when no plane is the ground.
#[pyfunction(name = "ground_plane")]
#[pyo3(
    signature = (points, cameras, *, max_up_angle_deg=Some(defaults::GROUND_MAX_UP_ANGLE_DEG), min_inliers=defaults::GROUND_MIN_INLIERS, large_share=defaults::GROUND_LARGE_SHARE, max_below=defaults::GROUND_MAX_BELOW),
    text_signature = "(points, cameras, *, max_up_angle_deg=35.0, min_inliers=30, large_share=0.25, max_below=0.05)"
)]
fn ground_plane_py(
    py: Python<'_>,
    points: &Bound<'_, PyAny>,
    cameras: &PyTrajectory,
    max_up_angle_deg: Option<f64>,
    min_inliers: usize,
    large_share: f64,
    max_below: f64,
) -> PyResult<PyGroundPlane> {
    let pts: Vec<Vector3<f64>> = vectors(points, "points")?;
    let opts = GroundOptions {
        max_up_angle_deg,
        min_inliers,
        large_share,
        max_below,
        ..GroundOptions::default()
    };
    let cams = cameras.inner.clone();
    let inner = py.detach(|| fit_ground_plane(&pts, &cams, &opts))?;
    Ok(PyGroundPlane { inner })
}

/// Scale and gravity from `plane` and the cameras' height above it, metres:
/// one number (every pose; the median fitted), one number with
/// `first=True` (the first pose only), or one per pose.
#[pyfunction(name = "metric_from_height")]
#[pyo3(signature = (plane, cameras, height, *, first=false))]
fn metric_from_height_py(
    plane: &PyGroundPlane,
    cameras: &PyTrajectory,
    height: &Bound<'_, PyAny>,
    first: bool,
) -> PyResult<PyHeightScale> {
    let h = match height.extract::<f64>() {
        Ok(v) if first => CameraHeight::First(v),
        Ok(v) => CameraHeight::Constant(v),
        Err(_) => CameraHeight::PerPose(vec_f64(height, "height", None)?),
    };
    let inner = metric_from_height(&plane.inner, &cameras.inner, &h)?;
    Ok(PyHeightScale { inner })
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyGroundPlane>()?;
    m.add_class::<PyHeightScale>()?;
    m.add_function(wrap_pyfunction!(ground_plane_py, m)?)?;
    m.add_function(wrap_pyfunction!(metric_from_height_py, m)?)?;
    Ok(())
}
