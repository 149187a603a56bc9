//! Scale and gravity with no second sensor, for Python: `ground_plane`,
//! `metric_from_height`, `height_profile`, `scale_from_distance`, `planar_motion`,
//! `level_frame` and their results.

use nalgebra::Vector3;
use numpy::{PyArray1, ToPyArray};
use pyo3::prelude::*;

use super::arrays::{vec_f64, vector3, vectors};
use super::geometry::PySim3;
use super::trajectory::PyTrajectory;
use crate::align::ground::{
    fit_ground_plane, height_profile, metric_from_height, CameraHeight, GroundOptions, GroundPlane,
    HeightScale,
};
use crate::align::priors::{level_frame, planar_motion, scale_from_distance, PlanarMotion};
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
    /// Standard deviation of `height(x)` from the plane's own uncertainty
    /// (a block jackknife over its points, and how far the plane of its
    /// whole inlier band lies from that of its core), SLAM units.
    fn height_sigma(&self, x: &Bound<'_, PyAny>) -> PyResult<f64> {
        Ok(self.inner.height_sigma(&vector3(x, "x")?))
    }
    /// Standard deviation of the normal's direction, degrees.
    #[getter]
    fn tilt_sigma_deg(&self) -> f64 {
        self.inner.tilt_sigma_deg()
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
    /// Relative standard deviation of the scale from the plane and the
    /// scatter of the cameras' heights (not counting the given heights' own
    /// uncertainty: see `scale_sigma_with`).
    #[getter]
    fn scale_sigma(&self) -> f64 {
        self.inner.scale_sigma
    }
    /// Relative standard deviation of the scale when the given heights are
    /// uncertain by `relative` (their sigma over their value).
    fn scale_sigma_with(&self, relative: f64) -> f64 {
        self.inner.scale_sigma_with(relative)
    }
    fn __repr__(&self) -> String {
        format!(
            "HeightScale(scale={:.9} ± {:.2} %, height_rms={:.4})",
            self.inner.scale,
            100.0 * self.inner.scale_sigma,
            self.inner.height_rms
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

/// The scale along the run per window of `window` consecutive cameras (half
/// overlapping), from the ground plane of each window's points and the
/// cameras' `height` (metres): point `i` of `points` (N×3) was seen from
/// camera `owner[i]`. A dict of arrays, one entry per window: `first`,
/// `last` (camera indices, inclusive), `time` (mean stamp), `scale` (NaN
/// where no ground was found), `inliers`, and `reason` (None, or why the
/// window has no scale).
#[pyfunction(name = "height_profile")]
#[pyo3(
    signature = (points, owner, cameras, height, window, *, max_up_angle_deg=Some(defaults::GROUND_MAX_UP_ANGLE_DEG), min_inliers=defaults::GROUND_MIN_INLIERS, large_share=defaults::GROUND_LARGE_SHARE, max_below=defaults::GROUND_MAX_BELOW),
    text_signature = "(points, owner, cameras, height, window, *, max_up_angle_deg=35.0, min_inliers=30, large_share=0.25, max_below=0.05)"
)]
#[allow(clippy::too_many_arguments)]
fn height_profile_py<'py>(
    py: Python<'py>,
    points: &Bound<'_, PyAny>,
    owner: &Bound<'_, PyAny>,
    cameras: &PyTrajectory,
    height: f64,
    window: usize,
    max_up_angle_deg: Option<f64>,
    min_inliers: usize,
    large_share: f64,
    max_below: f64,
) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
    let pts: Vec<Vector3<f64>> = vectors(points, "points")?;
    let own: Vec<usize> = owner.extract().map_err(|_| {
        crate::error::Error::invalid("owner", "expected a camera index (int >= 0) per point")
    })?;
    let opts = GroundOptions {
        max_up_angle_deg,
        min_inliers,
        large_share,
        max_below,
        ..GroundOptions::default()
    };
    let cams = cameras.inner.clone();
    let windows = py.detach(|| height_profile(&pts, &own, &cams, height, window, &opts))?;
    let d = pyo3::types::PyDict::new(py);
    let ints = |f: fn(&crate::align::ground::ProfileWindow) -> usize| -> Vec<i64> {
        windows.iter().map(|w| f(w) as i64).collect()
    };
    d.set_item("first", ints(|w| w.first).to_pyarray(py))?;
    d.set_item("last", ints(|w| w.last).to_pyarray(py))?;
    d.set_item(
        "time",
        windows
            .iter()
            .map(|w| w.time)
            .collect::<Vec<_>>()
            .to_pyarray(py),
    )?;
    d.set_item(
        "scale",
        windows
            .iter()
            .map(|w| w.scale.unwrap_or(f64::NAN))
            .collect::<Vec<_>>()
            .to_pyarray(py),
    )?;
    d.set_item("inliers", ints(|w| w.inliers).to_pyarray(py))?;
    d.set_item(
        "reason",
        windows.iter().map(|w| w.reason.clone()).collect::<Vec<_>>(),
    )?;
    Ok(d)
}

/// The plane a ground robot's cameras ride in (`planar_motion`).
#[pyclass(name = "PlanarMotion", module = "slam2world._slam2world", frozen)]
pub struct PyPlanarMotion {
    inner: PlanarMotion,
}

#[pymethods]
impl PyPlanarMotion {
    /// Unit normal, towards the cameras' "image up", shape (3,).
    #[getter]
    fn normal<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.normal.as_slice().to_pyarray(py)
    }
    /// `normal · x + offset` is the height of `x` over the cameras' plane.
    #[getter]
    fn offset(&self) -> f64 {
        self.inner.offset
    }
    /// Rms distance of the camera centres from the plane, SLAM units.
    #[getter]
    fn rms(&self) -> f64 {
        self.inner.rms
    }
    /// Rms spread of the centres along the plane's narrower axis, SLAM units.
    #[getter]
    fn extent(&self) -> f64 {
        self.inner.extent
    }
    /// Degrees of tilt a slope as large as the out-of-plane spread could
    /// hide: `atan(rms / extent)`.
    #[getter]
    fn tilt_bound_deg(&self) -> f64 {
        self.inner.tilt_bound_deg
    }
    /// Standard error of the normal, degrees, for independent errors.
    #[getter]
    fn sigma_deg(&self) -> f64 {
        self.inner.sigma_deg
    }
    /// Camera centres fitted.
    #[getter]
    fn n(&self) -> usize {
        self.inner.n
    }
    fn __repr__(&self) -> String {
        let n = self.inner.normal;
        format!(
            "PlanarMotion(normal=[{:.6}, {:.6}, {:.6}], rms={:.3e}, tilt_bound_deg={:.3}, n={})",
            n.x, n.y, n.z, self.inner.rms, self.inner.tilt_bound_deg, self.inner.n
        )
    }
}

/// The plane `cameras`' centres ride in, its normal "up" by their
/// orientations. Raises `DegenerateError` when they do not ride in one
/// (more tilt than `max_tilt_bound_deg` could hide: a line, a hand-held
/// camera, stairs) and `ValueError` without orientations.
#[pyfunction(name = "planar_motion")]
#[pyo3(
    signature = (cameras, *, max_tilt_bound_deg=defaults::PLANAR_MAX_TILT_BOUND_DEG),
    text_signature = "(cameras, *, max_tilt_bound_deg=3.0)"
)]
fn planar_motion_py(cameras: &PyTrajectory, max_tilt_bound_deg: f64) -> PyResult<PyPlanarMotion> {
    let inner = planar_motion(&cameras.inner, max_tilt_bound_deg)?;
    Ok(PyPlanarMotion { inner })
}

/// Metres per SLAM unit that put poses `a` and `b` (indices) of `cameras`
/// `metres` apart.
#[pyfunction(name = "scale_from_distance")]
fn scale_from_distance_py(
    cameras: &PyTrajectory,
    a: usize,
    b: usize,
    metres: f64,
) -> PyResult<f64> {
    Ok(scale_from_distance(&cameras.inner, a, b, metres)?.scale)
}

/// `T_world_slam` with z along `up` (SLAM frame), `scale` metres per unit,
/// the first camera over the origin at `first_height` metres and x along
/// its heading.
#[pyfunction(name = "level_frame")]
#[pyo3(signature = (up, cameras, scale, first_height=0.0))]
fn level_frame_py(
    up: &Bound<'_, PyAny>,
    cameras: &PyTrajectory,
    scale: f64,
    first_height: f64,
) -> PyResult<PySim3> {
    let u = vector3(up, "up")?;
    let Some(u) = u.try_normalize(1e-300) else {
        return Err(crate::error::Error::invalid("up", "must be a nonzero vector").into());
    };
    if !(scale.is_finite() && scale > 0.0 && first_height.is_finite()) {
        return Err(crate::error::Error::invalid(
            "scale",
            format!("scale must be > 0 and first_height finite, got {scale} and {first_height}"),
        )
        .into());
    }
    Ok(level_frame(&u, &cameras.inner, scale, first_height).into())
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyGroundPlane>()?;
    m.add_class::<PyHeightScale>()?;
    m.add_class::<PyPlanarMotion>()?;
    m.add_function(wrap_pyfunction!(planar_motion_py, m)?)?;
    m.add_function(wrap_pyfunction!(height_profile_py, m)?)?;
    m.add_function(wrap_pyfunction!(scale_from_distance_py, m)?)?;
    m.add_function(wrap_pyfunction!(level_frame_py, m)?)?;
    m.add_function(wrap_pyfunction!(ground_plane_py, m)?)?;
    m.add_function(wrap_pyfunction!(metric_from_height_py, m)?)?;
    Ok(())
}
