//! The synthetic experiment for Python: `simulate(...)`, `evaluate(...)`,
//! `point_distances(...)`.

use std::sync::Arc;

use nalgebra::{UnitQuaternion, Vector3};
use numpy::ndarray::{Array1, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::arrays::{c_slice, rows_f64, to_array2, vec_f64, Points};
use super::cloud::PyKeyframe;
use super::geometry::PySim3;
use super::trajectory::PyTrajectory;
use crate::error::Error;
use crate::sim::{self, SimConfig, Simulation};
use crate::trajectory::Trajectory;

/// One simulated run of the paper's experiment (read-only). Every array
/// property returns a new NumPy array.
#[pyclass(name = "Simulation", module = "slam2world._slam2world", frozen)]
pub struct PySimulation {
    pub inner: Arc<Simulation>,
}

fn positions_array<'py>(
    py: Python<'py>,
    p: &[Vector3<f64>],
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    to_array2(py, p.iter().flat_map(|v| [v.x, v.y, v.z]).collect(), 3)
}

fn quaternions_array<'py>(
    py: Python<'py>,
    q: Option<&Vec<UnitQuaternion<f64>>>,
) -> PyResult<Option<Bound<'py, PyArray2<f64>>>> {
    q.map(|q| to_array2(py, q.iter().flat_map(|q| [q.i, q.j, q.k, q.w]).collect(), 4))
        .transpose()
}

fn times_array<'py>(py: Python<'py>, t: &[f64]) -> Bound<'py, PyArray1<f64>> {
    Array1::from(t.to_vec()).into_pyarray(py)
}

impl PySimulation {
    fn per_keyframe<'py, T: numpy::Element + Copy>(
        &self,
        py: Python<'py>,
        get: impl Fn(&crate::keyframe::Keyframe) -> Option<&[T]>,
        channels: usize,
    ) -> PyResult<Bound<'py, PyArray3<T>>> {
        let s = &self.inner;
        let (w, h) = (s.camera.width as usize, s.camera.height as usize);
        let mut data = Vec::with_capacity(s.keyframes.len() * w * h * channels);
        for kf in &s.keyframes {
            match get(kf) {
                Some(v) => data.extend_from_slice(v),
                None => {
                    return Err(Error::invalid("keyframe", "a per-pixel array is missing").into())
                }
            }
        }
        let a = Array3::from_shape_vec((s.keyframes.len(), h, w * channels), data)
            .map_err(|e| PyErr::from(Error::invalid("keyframe arrays", e.to_string())))?;
        Ok(a.into_pyarray(py))
    }
}

#[pymethods]
impl PySimulation {
    /// The parameters of the run, keyed by name.
    #[getter]
    fn config<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        if let Ok(serde_json::Value::Object(map)) = serde_json::to_value(&self.inner.config) {
            for (k, v) in map {
                match v {
                    serde_json::Value::Array(a) => {
                        let xs: Vec<f64> = a.iter().filter_map(|x| x.as_f64()).collect();
                        d.set_item(k, xs)?;
                    }
                    v if v.is_u64() => d.set_item(k, v.as_u64())?,
                    v => d.set_item(k, v.as_f64())?,
                }
            }
        }
        Ok(d)
    }

    /// Camera intrinsics `(fx, fy, cx, cy, width, height)` (pixels).
    #[getter]
    fn camera(&self) -> (f64, f64, f64, f64, u32, u32) {
        let c = self.inner.camera;
        (c.fx, c.fy, c.cx, c.cy, c.width, c.height)
    }

    /// The true `T_world_slam` (SLAM units into world metres).
    #[getter]
    fn t_world_slam(&self) -> PySim3 {
        self.inner.truth.t_world_slam.into()
    }

    /// The keyframes as `Keyframe` objects (a copy of every per-pixel array).
    #[getter]
    fn keyframes(&self) -> Vec<PyKeyframe> {
        self.inner
            .keyframes
            .iter()
            .map(|k| PyKeyframe {
                inner: k.clone().into(),
            })
            .collect()
    }

    /// Keyframe poses `T_slam_cam` as a trajectory (SLAM frame, seconds).
    #[getter]
    fn keyframe_trajectory(&self) -> PyResult<PyTrajectory> {
        Ok(PyTrajectory {
            inner: self.inner.keyframe_trajectory()?.into(),
        })
    }

    /// Tracked `T_slam_cam` of every frame (60 Hz) as a trajectory.
    #[getter]
    fn slam_trajectory(&self) -> PyTrajectory {
        PyTrajectory {
            inner: self.inner.slam_frames.clone().into(),
        }
    }

    /// Reference `T_world_body` (body = camera) as a trajectory.
    #[getter]
    fn reference(&self) -> PyTrajectory {
        PyTrajectory {
            inner: self.inner.reference.clone().into(),
        }
    }

    /// True `T_world_cam` at the frame times as a trajectory.
    #[getter]
    fn true_trajectory(&self) -> PyTrajectory {
        PyTrajectory {
            inner: self.inner.truth.camera.clone().into(),
        }
    }

    /// Keyframe ids (= frame index), shape (K,).
    #[getter]
    fn keyframe_ids<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i32>> {
        Array1::from(
            self.inner
                .keyframes
                .iter()
                .map(|k| k.id)
                .collect::<Vec<_>>(),
        )
        .into_pyarray(py)
    }

    /// Keyframe times, seconds, shape (K,).
    #[getter]
    fn keyframe_timestamps<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let t: Vec<f64> = self.inner.keyframes.iter().map(|k| k.timestamp).collect();
        times_array(py, &t)
    }

    /// Keyframe poses `T_slam_cam` (their scale is LSD-SLAM's depth normalisation).
    #[getter]
    fn keyframe_poses(&self) -> Vec<PySim3> {
        self.inner.keyframes.iter().map(|k| k.pose.into()).collect()
    }

    /// Normalised inverse depth (mean 1 per keyframe, 0 = none), shape (K, H, W), float32.
    #[getter]
    fn keyframe_idepth<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f32>>> {
        self.per_keyframe(py, |k| Some(&k.idepth[..]), 1)
    }

    /// Variance of the inverse depth, shape (K, H, W), float32.
    #[getter]
    fn keyframe_idepth_var<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f32>>> {
        self.per_keyframe(py, |k| k.idepth_var.as_deref(), 1)
    }

    /// Rendered grey image of each keyframe, shape (K, H, W), uint8.
    #[getter]
    fn keyframe_intensity<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<u8>>> {
        let s = &self.inner;
        let (w, h) = (s.camera.width as usize, s.camera.height as usize);
        let mut data = Vec::with_capacity(s.keyframes.len() * w * h);
        for kf in &s.keyframes {
            match &kf.color {
                Some(c) => data.extend(c.chunks_exact(3).map(|p| p[0])),
                None => data.extend(std::iter::repeat_n(0u8, w * h)),
            }
        }
        let a = Array3::from_shape_vec((s.keyframes.len(), h, w), data)
            .map_err(|e| PyErr::from(Error::invalid("keyframe images", e.to_string())))?;
        Ok(a.into_pyarray(py))
    }

    /// Times of the tracked frames (60 Hz), seconds, shape (N,).
    #[getter]
    fn slam_timestamps<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        times_array(py, &self.inner.slam_frames.timestamps)
    }

    /// Tracked camera positions in the SLAM frame, shape (N, 3).
    #[getter]
    fn slam_positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        positions_array(py, &self.inner.slam_frames.positions)
    }

    /// Tracked `R_slam_cam` as quaternions (x, y, z, w), shape (N, 4).
    #[getter]
    fn slam_orientations<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<Option<Bound<'py, PyArray2<f64>>>> {
        quaternions_array(py, self.inner.slam_frames.orientations.as_ref())
    }

    /// Reference (IMU) times, seconds, shape (M,).
    #[getter]
    fn reference_timestamps<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        times_array(py, &self.inner.reference.timestamps)
    }

    /// Reference positions `T_world_body` (metres, body = camera), shape (M, 3).
    #[getter]
    fn reference_positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        positions_array(py, &self.inner.reference.positions)
    }

    /// Reference orientations `R_world_body` (x, y, z, w), shape (M, 4).
    #[getter]
    fn reference_orientations<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<Option<Bound<'py, PyArray2<f64>>>> {
        quaternions_array(py, self.inner.reference.orientations.as_ref())
    }

    /// Raw IMU sample times, seconds, shape (M,).
    #[getter]
    fn imu_timestamps<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        times_array(py, &self.inner.imu.timestamps)
    }

    /// Gyroscope, rad/s, body frame, shape (M, 3).
    #[getter]
    fn gyro<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        positions_array(py, &self.inner.imu.gyro)
    }

    /// Accelerometer (specific force), m/s², body frame, shape (M, 3).
    #[getter]
    fn accel<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        positions_array(py, &self.inner.imu.accel)
    }

    /// True camera centres at the frame times (metres, world), shape (N, 3).
    #[getter]
    fn true_positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        positions_array(py, &self.inner.truth.camera.positions)
    }

    /// True `R_world_cam` at the frame times (x, y, z, w), shape (N, 4).
    #[getter]
    fn true_orientations<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<Option<Bound<'py, PyArray2<f64>>>> {
        quaternions_array(py, self.inner.truth.camera.orientations.as_ref())
    }

    /// Scale error `λ_k` of each frame-to-frame step of the tracking, shape (N-1,).
    #[getter]
    fn scale_errors<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        times_array(py, &self.inner.truth.scale_errors)
    }

    /// `(converge_start, stable_start)`: frame indices where the stages begin.
    #[getter]
    fn stages(&self) -> (usize, usize) {
        (
            self.inner.config.converge_start,
            self.inner.config.stable_start,
        )
    }

    /// Lower corners of the cubes (metres), shape (C, 3).
    #[getter]
    fn cube_min<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        positions_array(py, &self.inner.truth.scene.cube_min)
    }

    /// Edge length of the cubes, metres.
    #[getter]
    fn cube_size(&self) -> f64 {
        self.inner.truth.scene.cube_size
    }

    /// Half sizes of the ground plane along x and y, metres.
    #[getter]
    fn plane_half(&self) -> (f64, f64) {
        let p = self.inner.truth.scene.plane_half;
        (p[0], p[1])
    }

    fn __repr__(&self) -> String {
        let s = &self.inner;
        format!(
            "Simulation(seed={}, frames={}, keyframes={}, imu_samples={}, scale={:.4})",
            s.config.seed,
            s.slam_frames.len(),
            s.keyframes.len(),
            s.imu.len(),
            s.truth.t_world_slam.scale
        )
    }
}

/// Runs the paper's synthetic experiment. `reduced = k` divides frames,
/// keyframes, stage boundaries, path length and image size by `k`;
/// `noiseless` switches every error off; any other keyword sets the
/// `SimConfig` field of that name. The GIL is released while it runs.
#[pyfunction(name = "simulate")]
#[pyo3(signature = (*, seed=0, noiseless=false, reduced=1, **params))]
fn simulate_py(
    py: Python<'_>,
    #[pyo3(from_py_with = super::arrays::uint::seed)] seed: u64,
    noiseless: bool,
    #[pyo3(from_py_with = super::arrays::uint::reduced)] reduced: usize,
    params: Option<&Bound<'_, PyDict>>,
) -> PyResult<PySimulation> {
    let mut cfg = SimConfig {
        seed,
        ..SimConfig::default()
    }
    .reduced(reduced);
    if noiseless {
        cfg = cfg.noiseless();
    }
    if let Some(p) = params {
        for (k, v) in p.iter() {
            let name: String = k.extract()?;
            let value: f64 = v
                .extract()
                .map_err(|_| PyErr::from(Error::invalid(name.clone(), "must be a number")))?;
            cfg.set(&name, value)?;
        }
    }
    let sim = py.detach(|| sim::simulate(&cfg))?;
    Ok(PySimulation {
        inner: Arc::new(sim),
    })
}

fn with_points<R>(points: &Bound<'_, PyAny>, f: impl FnOnce(&[f32]) -> R) -> PyResult<R> {
    Ok(match Points::extract(points, "points")? {
        Points::F32(a) => match c_slice(&a) {
            Some(s) => f(s),
            None => f(&a.as_array().iter().copied().collect::<Vec<f32>>()),
        },
        Points::F64(a) => f(&a.as_array().iter().map(|&v| v as f32).collect::<Vec<f32>>()),
    })
}

/// Distance of each world point (N, 3) to the nearest true surface, metres, shape (N,).
#[pyfunction]
fn point_distances<'py>(
    py: Python<'py>,
    simulation: &PySimulation,
    points: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let scene = &simulation.inner.truth.scene;
    let d = with_points(points, |p| {
        py.detach(|| sim::evaluate::point_distances(scene, p))
    })??;
    Ok(Array1::from(d).into_pyarray(py))
}

/// Scores a conversion: world points (N, 3) made with `transform` (the
/// estimated `T_world_slam`) and a SLAM-frame trajectory (`timestamps` (M,),
/// `positions` (M, 3); the keyframes when omitted). Returns
/// `{"cloud": {...}, "transform": {...}, "ape": {...}}` of floats (metres, degrees).
#[pyfunction]
#[pyo3(signature = (simulation, points, transform, *, timestamps=None, positions=None))]
fn evaluate<'py>(
    py: Python<'py>,
    simulation: &PySimulation,
    points: &Bound<'py, PyAny>,
    transform: &PySim3,
    timestamps: Option<&Bound<'py, PyAny>>,
    positions: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let s = &simulation.inner;
    let traj = match (timestamps, positions) {
        (Some(t), Some(p)) => {
            let t = vec_f64(t, "timestamps", None)?;
            let p = rows_f64(p, "positions", 3)?;
            let p = p
                .chunks_exact(3)
                .map(|c| Vector3::new(c[0], c[1], c[2]))
                .collect();
            Trajectory::try_new(t, p, None)?
        }
        (None, None) => s.keyframe_trajectory()?,
        _ => {
            return Err(Error::invalid("timestamps / positions", "give both or neither").into());
        }
    };
    let est = transform.inner;
    let e = with_points(points, |p| {
        py.detach(|| sim::evaluate(&s.truth, p, &est, &traj))
    })??;
    let json = serde_json::to_value(e)
        .map_err(|e| PyErr::from(Error::invalid("evaluation", e.to_string())))?;
    let out = PyDict::new(py);
    if let serde_json::Value::Object(map) = json {
        for (k, v) in map {
            let d = PyDict::new(py);
            if let serde_json::Value::Object(inner) = v {
                for (ik, iv) in inner {
                    if iv.is_u64() {
                        d.set_item(ik, iv.as_u64())?;
                    } else {
                        d.set_item(ik, iv.as_f64())?;
                    }
                }
            }
            out.set_item(k, d)?;
        }
    }
    Ok(out)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySimulation>()?;
    m.add_function(wrap_pyfunction!(simulate_py, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(point_distances, m)?)?;
    Ok(())
}
