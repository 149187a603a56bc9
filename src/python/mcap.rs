//! MCAP logs for Python: `read_mcap(...) -> Log`, `write_world_mcap(...)`.

use std::path::PathBuf;

use numpy::ndarray::{Array1, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;

use super::convert::to_array2;
use super::geometry::PySim3;
use crate::geometry::Sim3;
use crate::io::mcap::{self as io_mcap, ReadOptions, WorldFlavor, WorldScene};
use crate::keyframe::Keyframe;

/// One keyframe read from a log: `pose` is `T_slam_cam`, per-pixel arrays are `(height, width)`.
#[pyclass(name = "LogKeyframe", module = "slam2world._slam2world", frozen)]
pub struct PyLogKeyframe {
    pub inner: Keyframe,
}

fn image<'py, T: numpy::Element + Copy>(
    py: Python<'py>,
    data: &[T],
    h: usize,
    w: usize,
    c: usize,
) -> PyResult<Bound<'py, PyArray3<T>>> {
    let a = Array3::from_shape_vec((h, w, c), data.to_vec())
        .map_err(|e| PyErr::from(crate::Error::invalid("image", e.to_string())))?;
    Ok(a.into_pyarray(py))
}

#[pymethods]
impl PyLogKeyframe {
    /// Keyframe id.
    #[getter]
    fn id(&self) -> i32 {
        self.inner.id
    }
    /// The message's own time, seconds.
    #[getter]
    fn timestamp(&self) -> f64 {
        self.inner.timestamp
    }
    /// `T_slam_cam` (LSD-SLAM camToWorld, with its scale).
    #[getter]
    fn pose(&self) -> PySim3 {
        PySim3::from(self.inner.pose)
    }
    /// `(fx, fy, cx, cy, width, height)`, pixels.
    #[getter]
    fn camera(&self) -> (f64, f64, f64, f64, u32, u32) {
        let c = &self.inner.camera;
        (c.fx, c.fy, c.cx, c.cy, c.width, c.height)
    }
    /// Inverse depth, `(height, width)` float32.
    #[getter]
    fn idepth<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let c = &self.inner.camera;
        to_array2(py, self.inner.idepth.clone(), c.width as usize)
    }
    /// Inverse-depth variance, `(height, width)` float32, or None.
    #[getter]
    fn idepth_var<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArray2<f32>>>> {
        let c = &self.inner.camera;
        match &self.inner.idepth_var {
            Some(v) => Ok(Some(to_array2(py, v.clone(), c.width as usize)?)),
            None => Ok(None),
        }
    }
    /// Colour, `(height, width, 3)` uint8 in the message's byte order, or None.
    #[getter]
    fn color<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArray3<u8>>>> {
        let c = &self.inner.camera;
        match &self.inner.color {
            Some(v) => Ok(Some(image(py, v, c.height as usize, c.width as usize, 3)?)),
            None => Ok(None),
        }
    }
    fn __repr__(&self) -> String {
        let c = &self.inner.camera;
        format!(
            "LogKeyframe(id={}, timestamp={}, {}x{})",
            self.inner.id, self.inner.timestamp, c.width, c.height
        )
    }
}

type Series<'py> = (
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray2<f64>>,
);

/// A log read by `read_mcap`.
#[pyclass(name = "Log", module = "slam2world._slam2world", frozen)]
pub struct PyLog {
    log: io_mcap::Log,
    keyframes: Vec<Py<PyLogKeyframe>>,
}

#[pymethods]
impl PyLog {
    /// The file read.
    #[getter]
    fn path(&self) -> PathBuf {
        self.log.path.clone()
    }
    /// Keyframes: latest version of each id, in order of first arrival.
    #[getter]
    fn keyframes(&self, py: Python<'_>) -> Vec<Py<PyLogKeyframe>> {
        self.keyframes.iter().map(|k| k.clone_ref(py)).collect()
    }
    /// Reference poses `T_world_body` as `(timestamps (N,), positions (N, 3),
    /// orientations (N, 4) x, y, z, w)`, or None.
    #[getter]
    fn reference<'py>(&self, py: Python<'py>) -> PyResult<Option<Series<'py>>> {
        let Some(r) = &self.log.reference else {
            return Ok(None);
        };
        let t = Array1::from_vec(r.timestamps.clone()).into_pyarray(py);
        let p: Vec<f64> = r.positions.iter().flat_map(|v| [v.x, v.y, v.z]).collect();
        let q: Vec<f64> = match &r.orientations {
            Some(o) => o
                .iter()
                .flat_map(|q| [q.coords[0], q.coords[1], q.coords[2], q.coords[3]])
                .collect(),
            None => r
                .timestamps
                .iter()
                .flat_map(|_| [0.0, 0.0, 0.0, 1.0])
                .collect(),
        };
        Ok(Some((t, to_array2(py, p, 3)?, to_array2(py, q, 4)?)))
    }
    /// Raw IMU as `(timestamps (N,), gyro (N, 3) rad/s, accel (N, 3) m/s²)`, or None.
    #[getter]
    fn imu<'py>(&self, py: Python<'py>) -> PyResult<Option<Series<'py>>> {
        let Some(s) = &self.log.imu else {
            return Ok(None);
        };
        let t = Array1::from_vec(s.timestamps.clone()).into_pyarray(py);
        let g: Vec<f64> = s.gyro.iter().flat_map(|v| [v.x, v.y, v.z]).collect();
        let a: Vec<f64> = s.accel.iter().flat_map(|v| [v.x, v.y, v.z]).collect();
        Ok(Some((t, to_array2(py, g, 3)?, to_array2(py, a, 3)?)))
    }
    /// Topic of the keyframes, or None.
    #[getter]
    fn keyframe_topic(&self) -> Option<String> {
        self.log.keyframe_topic.clone()
    }
    /// Topic of the graph updates, or None.
    #[getter]
    fn graph_topic(&self) -> Option<String> {
        self.log.graph_topic.clone()
    }
    /// Topic of the reference poses, or None.
    #[getter]
    fn reference_topic(&self) -> Option<String> {
        self.log.reference_topic.clone()
    }
    /// Topic of the IMU, or None.
    #[getter]
    fn imu_topic(&self) -> Option<String> {
        self.log.imu_topic.clone()
    }
    /// Keyframe poses overwritten by graph messages.
    #[getter]
    fn graph_updates(&self) -> usize {
        self.log.graph_updates
    }
    /// `(topic, schema name, message encoding, messages read)` for every topic.
    #[getter]
    fn topics(&self) -> Vec<(String, String, String, u64)> {
        self.log
            .topics
            .iter()
            .map(|t| {
                (
                    t.topic.clone(),
                    t.schema_name.clone(),
                    t.message_encoding.clone(),
                    t.count,
                )
            })
            .collect()
    }
    fn __repr__(&self) -> String {
        format!(
            "Log({:?}, keyframes={}, reference={}, imu={})",
            self.log.path.display().to_string(),
            self.log.keyframes.len(),
            self.log.reference.as_ref().map_or(0, |r| r.len()),
            self.log.imu.as_ref().map_or(0, |s| s.len()),
        )
    }
}

/// Reads an MCAP log (see the Rust `io::mcap::read_mcap`); the GIL is released.
#[pyfunction(name = "read_mcap")]
#[pyo3(signature = (path, *, keyframe_topic=None, graph_topic=None, pose_topic=None, imu_topic=None, tf_parent=None, tf_child=None))]
#[allow(clippy::too_many_arguments)]
fn read_mcap_py(
    py: Python<'_>,
    path: PathBuf,
    keyframe_topic: Option<String>,
    graph_topic: Option<String>,
    pose_topic: Option<String>,
    imu_topic: Option<String>,
    tf_parent: Option<String>,
    tf_child: Option<String>,
) -> PyResult<PyLog> {
    let options = ReadOptions {
        keyframe_topic,
        graph_topic,
        pose_topic,
        imu_topic,
        tf_parent,
        tf_child,
    };
    let mut log = py.detach(|| io_mcap::read_mcap(&path, &options))?;
    let kfs = std::mem::take(&mut log.keyframes);
    let keyframes = kfs
        .into_iter()
        .map(|k| Py::new(py, PyLogKeyframe { inner: k }))
        .collect::<PyResult<Vec<_>>>()?;
    Ok(PyLog { log, keyframes })
}

/// Writes `world.mcap`: points `(N, 3)` in the world frame, optional colours
/// `(N, 3)` uint8, `transform` = `T_world_slam`. Foxglove schemas, or ROS 2
/// PointCloud2 + TFMessage with `ros2=True`.
#[pyfunction(name = "write_world_mcap")]
#[pyo3(signature = (path, points, colors=None, *, transform=None, stamp=0.0, ros2=false))]
fn write_world_mcap_py(
    py: Python<'_>,
    path: PathBuf,
    points: &Bound<'_, PyAny>,
    colors: Option<numpy::PyReadonlyArray2<'_, u8>>,
    transform: Option<PySim3>,
    stamp: f64,
    ros2: bool,
) -> PyResult<()> {
    let pts: Vec<f32> = super::convert::rows_f64(points, "points", 3)?
        .into_iter()
        .map(|v| v as f32)
        .collect();
    let cols: Option<Vec<u8>> = match &colors {
        Some(c) => {
            let shape = c.shape().to_vec();
            if shape.len() != 2 || shape[1] != 3 || shape[0] * 3 != pts.len() {
                return Err(crate::Error::ShapeMismatch {
                    what: "colors".into(),
                    expected: format!("({}, 3) uint8", pts.len() / 3),
                    got: format!("{shape:?}"),
                }
                .into());
            }
            Some(c.as_array().iter().copied().collect())
        }
        None => None,
    };
    let t = transform.map(|t| t.inner).unwrap_or_else(Sim3::identity);
    let flavor = if ros2 {
        WorldFlavor::Ros2
    } else {
        WorldFlavor::Foxglove
    };
    py.detach(|| {
        let scene = WorldScene {
            points: &pts,
            colors: cols.as_deref(),
            t_world_slam: t,
            slam_trajectory: None,
            reference: None,
            stamp,
            world_frame: "world",
            slam_frame: "slam",
        };
        io_mcap::write_world_mcap(&path, &scene, flavor)
    })?;
    Ok(())
}

/// Adds the MCAP classes and functions to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyLog>()?;
    m.add_class::<PyLogKeyframe>()?;
    m.add_function(wrap_pyfunction!(read_mcap_py, m)?)?;
    m.add_function(wrap_pyfunction!(write_world_mcap_py, m)?)?;
    Ok(())
}
