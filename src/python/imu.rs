//! Raw IMU and the inertial initialisation for Python: `ImuSamples`,
//! `ImuAlignment`, `imu_initialize`.

use std::path::PathBuf;

use nalgebra::Vector3;
use numpy::ndarray::Array1;
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::arrays::{rows_f64, to_array2, vec_f64};
use super::geometry::PySim3;
use super::trajectory::PyTrajectory;
use crate::imu::{imu_initialize, ImuAlignment, ImuInitOptions, ImuSamples};

fn vectors(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<Vector3<f64>>> {
    let v = rows_f64(obj, what, 3)?;
    Ok(v.chunks_exact(3)
        .map(|r| Vector3::new(r[0], r[1], r[2]))
        .collect())
}

fn rows<'py>(py: Python<'py>, v: &[Vector3<f64>]) -> PyResult<Bound<'py, PyArray2<f64>>> {
    to_array2(py, v.iter().flat_map(|p| [p.x, p.y, p.z]).collect(), 3)
}

fn vec3<'py>(py: Python<'py>, v: &Vector3<f64>) -> Bound<'py, PyArray1<f64>> {
    Array1::from_vec(vec![v.x, v.y, v.z]).into_pyarray(py)
}

/// Raw IMU samples in the IMU (body) frame: times (N,) seconds, strictly
/// increasing; gyro (N, 3) rad/s; accel (N, 3) m/s² (specific force).
#[pyclass(name = "ImuSamples", module = "slam2world._slam2world", frozen)]
pub struct PyImuSamples {
    pub inner: ImuSamples,
}

#[pymethods]
impl PyImuSamples {
    #[new]
    fn new(
        timestamps: &Bound<'_, PyAny>,
        gyro: &Bound<'_, PyAny>,
        accel: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        let t = vec_f64(timestamps, "timestamps", None)?;
        let g = vectors(gyro, "gyro")?;
        let a = vectors(accel, "accel")?;
        Ok(PyImuSamples {
            inner: ImuSamples::try_new(t, g, a)?,
        })
    }

    /// Reads EuRoC `imu0/data.csv` content (ns; gyro rad/s; accel m/s²).
    #[staticmethod]
    fn read_euroc(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let inner = py.detach(|| crate::io::text::read_euroc_imu(&path))?;
        Ok(PyImuSamples { inner })
    }

    /// Times, seconds, shape (N,).
    #[getter]
    fn timestamps<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        Array1::from_vec(self.inner.timestamps.clone()).into_pyarray(py)
    }

    /// Angular rate, rad/s, shape (N, 3).
    #[getter]
    fn gyro<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        rows(py, &self.inner.gyro)
    }

    /// Specific force, m/s², shape (N, 3).
    #[getter]
    fn accel<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        rows(py, &self.inner.accel)
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }

    fn __repr__(&self) -> String {
        let ts = &self.inner.timestamps;
        match (ts.first(), ts.last()) {
            (Some(a), Some(b)) => format!("ImuSamples(n={}, t=[{a:.6}, {b:.6}] s)", ts.len()),
            _ => "ImuSamples(n=0)".into(),
        }
    }
}

/// The result of `imu_initialize`: `transform` is `T_world_slam` (world z up,
/// the first keyframe's IMU at the origin with zero heading).
#[pyclass(name = "ImuAlignment", module = "slam2world._slam2world", frozen)]
pub struct PyImuAlignment {
    inner: ImuAlignment,
}

impl From<ImuAlignment> for PyImuAlignment {
    fn from(inner: ImuAlignment) -> Self {
        PyImuAlignment { inner }
    }
}

#[pymethods]
impl PyImuAlignment {
    /// `T_world_slam`.
    #[getter]
    fn transform(&self) -> PySim3 {
        self.inner.transform.into()
    }
    /// Metres per SLAM unit.
    #[getter]
    fn scale(&self) -> f64 {
        self.inner.scale
    }
    /// Standard deviation of the scale.
    #[getter]
    fn scale_sigma(&self) -> f64 {
        self.inner.scale_sigma
    }
    /// Gravity in SLAM axes, m/s², shape (3,).
    #[getter]
    fn gravity_slam<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        vec3(py, &self.inner.gravity_slam)
    }
    /// Standard deviation of the gravity direction, rad.
    #[getter]
    fn gravity_sigma(&self) -> f64 {
        self.inner.gravity_sigma
    }
    /// Gyroscope bias, rad/s, shape (3,).
    #[getter]
    fn gyro_bias<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        vec3(py, &self.inner.gyro_bias)
    }
    /// Standard deviation of each gyroscope-bias component, rad/s, shape (3,).
    #[getter]
    fn gyro_bias_sigma<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        vec3(py, &self.inner.gyro_bias_sigma)
    }
    /// Accelerometer bias, m/s², shape (3,) (zeros when not estimated).
    #[getter]
    fn accel_bias<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        vec3(py, &self.inner.accel_bias)
    }
    /// Standard deviation of each accelerometer-bias component, m/s², shape (3,).
    #[getter]
    fn accel_bias_sigma<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        vec3(py, &self.inner.accel_bias_sigma)
    }
    /// Times of the keyframes used, seconds, shape (K,).
    #[getter]
    fn timestamps<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        Array1::from_vec(self.inner.timestamps.clone()).into_pyarray(py)
    }
    /// IMU velocity at each keyframe used, world frame, m/s, shape (K, 3).
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        rows(py, &self.inner.velocities)
    }
    /// `n_keyframes`, `n_dropped`, `n_skipped`, `duration` (s), `excitation`
    /// (m/s²), `initial_scale`, `initial_gravity_norm` (m/s²), `rotation_rms`
    /// (rad), `position_rms` (m), `velocity_rms` (m/s), `variance_factor`,
    /// `relative_scale_sigma`.
    #[getter]
    fn diagnostics<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = &self.inner.diagnostics;
        let dict = PyDict::new(py);
        dict.set_item("n_keyframes", d.n_keyframes)?;
        dict.set_item("n_dropped", d.n_dropped)?;
        dict.set_item("n_skipped", d.n_skipped)?;
        dict.set_item("duration", d.duration)?;
        dict.set_item("excitation", d.excitation)?;
        dict.set_item("initial_scale", d.initial_scale)?;
        dict.set_item("initial_gravity_norm", d.initial_gravity_norm)?;
        dict.set_item("rotation_rms", d.rotation_rms)?;
        dict.set_item("position_rms", d.position_rms)?;
        dict.set_item("velocity_rms", d.velocity_rms)?;
        dict.set_item("variance_factor", d.variance_factor)?;
        dict.set_item("relative_scale_sigma", d.relative_scale_sigma)?;
        Ok(dict)
    }

    fn __repr__(&self) -> String {
        let a = &self.inner;
        let g = a.gravity_slam;
        format!(
            "ImuAlignment(scale={:.6} ± {:.2e}, gravity_slam=[{:.4}, {:.4}, {:.4}], gravity_sigma={:.3e} rad, n_keyframes={})",
            a.scale, a.scale_sigma, g.x, g.y, g.z, a.gravity_sigma, a.diagnostics.n_keyframes
        )
    }
}

/// Metric scale, gravity direction, biases and keyframe velocities of SLAM
/// keyframes (`T_slam_cam`, orientations required) from raw IMU samples; the
/// GIL is released.
#[pyfunction(name = "imu_initialize")]
#[pyo3(signature = (
    keyframes, imu, *, imu_from_cam=None, gravity=9.81, time_offset=0.0,
    estimate_accel_bias=true, accel_bias_prior=0.2, keyframe_position_sigma=0.01,
    keyframe_rotation_sigma=2e-3, gyro_noise_density=1.6968e-4,
    accel_noise_density=2.0e-3, accel_random_walk=3.0e-3, min_interval=0.5,
    max_gap=0.05, min_duration=2.0, min_excitation=0.05, max_relative_scale_sigma=0.05
))]
#[allow(clippy::too_many_arguments)]
fn imu_initialize_py(
    py: Python<'_>,
    keyframes: PyRef<'_, PyTrajectory>,
    imu: PyRef<'_, PyImuSamples>,
    imu_from_cam: Option<PyRef<'_, PySim3>>,
    gravity: f64,
    time_offset: f64,
    estimate_accel_bias: bool,
    accel_bias_prior: f64,
    keyframe_position_sigma: f64,
    keyframe_rotation_sigma: f64,
    gyro_noise_density: f64,
    accel_noise_density: f64,
    accel_random_walk: f64,
    min_interval: f64,
    max_gap: f64,
    min_duration: f64,
    min_excitation: f64,
    max_relative_scale_sigma: f64,
) -> PyResult<PyImuAlignment> {
    let opts = ImuInitOptions {
        imu_from_cam: imu_from_cam.map_or_else(crate::geometry::Sim3::identity, |t| t.inner),
        time_offset,
        gravity,
        estimate_accel_bias,
        accel_bias_prior,
        gyro_noise_density,
        accel_noise_density,
        accel_random_walk,
        keyframe_position_sigma,
        keyframe_rotation_sigma,
        min_interval,
        max_gap,
        min_duration,
        min_excitation,
        max_relative_scale_sigma,
        ..ImuInitOptions::default()
    };
    let (kf, samples) = (&keyframes.inner, &imu.inner);
    let inner = py.detach(|| imu_initialize(kf, samples, &opts))?;
    Ok(PyImuAlignment { inner })
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyImuSamples>()?;
    m.add_class::<PyImuAlignment>()?;
    m.add_function(wrap_pyfunction!(imu_initialize_py, m)?)?;
    Ok(())
}
