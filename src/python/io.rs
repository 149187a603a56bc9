//! Logs for Python: `read_log(...) -> Log` (every container), `read_mcap(...)`,
//! `write_world_mcap(...)`.

use std::path::PathBuf;
use std::sync::Arc;

use numpy::PyUntypedArrayMethods;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;

use super::cloud::{PyKeyframe, SharedKeyframe};
use super::geometry::PySim3;
use super::imu::PyImuSamples;
use super::trajectory::PyTrajectory;
use crate::geometry::Sim3;
use crate::io::log::{read_log, ReadOptions};
use crate::io::mcap::{self as io_mcap, WorldFlavor, WorldScene};
use crate::pipeline::Recording;

/// A log read by `read_log` or `read_mcap`: the recording a conversion reads.
#[pyclass(name = "Log", module = "slam2world._slam2world", frozen)]
pub struct PyLog {
    pub(crate) log: Arc<Recording>,
    /// The Python objects of the keyframes, made on first access.
    keyframes: PyOnceLock<Vec<Py<PyKeyframe>>>,
}

#[pymethods]
impl PyLog {
    /// The file (or rosbag2 folder) read.
    #[getter]
    fn path(&self) -> PathBuf {
        self.log.source.path.clone()
    }
    /// The container: `mcap`, `ros1 bag`, `rosbag2 folder` or `rosbag2 db3`.
    #[getter]
    fn format(&self) -> String {
        self.log.source.format.clone()
    }
    /// SLAM poses without depth (`T_slam_cam`) from `est_topic`, or None.
    #[getter]
    fn frames(&self) -> Option<PyTrajectory> {
        self.log.frames.as_ref().map(|f| PyTrajectory {
            inner: f.clone().into(),
        })
    }
    /// Topic of the SLAM poses without depth, or None.
    #[getter]
    fn est_topic(&self) -> Option<String> {
        self.log.source.est_topic.clone()
    }
    /// Keyframes: latest version of each id, in order of first arrival.
    #[getter]
    fn keyframes(&self, py: Python<'_>) -> PyResult<Vec<Py<PyKeyframe>>> {
        let list = self.keyframes.get_or_try_init(py, || {
            // Shared with the log, not copied: a keyframe's arrays are copied
            // only when asked for as numpy arrays.
            (0..self.log.keyframes.len())
                .map(|k| {
                    let inner = SharedKeyframe::InLog(self.log.clone(), k);
                    Py::new(py, PyKeyframe { inner })
                })
                .collect::<PyResult<Vec<_>>>()
        })?;
        Ok(list.iter().map(|k| k.clone_ref(py)).collect())
    }
    /// Reference poses `T_world_body`, or None.
    #[getter]
    fn reference(&self) -> Option<PyTrajectory> {
        self.log
            .reference
            .as_ref()
            .map(|r| PyTrajectory { inner: r.clone() })
    }
    /// Raw IMU samples (timestamps s, gyro rad/s, accel m/s², IMU frame), or None;
    /// ready for `imu_initialize`.
    #[getter]
    fn imu(&self) -> Option<PyImuSamples> {
        self.log.imu.clone().map(|inner| PyImuSamples { inner })
    }
    /// GNSS fixes (the log's NavSatFix / LocationFix topic), or None.
    #[getter]
    fn gnss(&self) -> Option<super::geo::PyGnssFixes> {
        self.log
            .gnss
            .clone()
            .map(|inner| super::geo::PyGnssFixes { inner })
    }
    /// Topic of the GNSS fixes, or None.
    #[getter]
    fn gnss_topic(&self) -> Option<String> {
        self.log.source.gnss_topic.clone()
    }
    /// Topic of the keyframes, or None.
    #[getter]
    fn keyframe_topic(&self) -> Option<String> {
        self.log.source.keyframe_topic.clone()
    }
    /// Topic of the graph updates, or None.
    #[getter]
    fn graph_topic(&self) -> Option<String> {
        self.log.source.graph_topic.clone()
    }
    /// Topic of the reference poses, or None.
    #[getter]
    fn reference_topic(&self) -> Option<String> {
        self.log.source.reference_topic.clone()
    }
    /// Topic of the IMU, or None.
    #[getter]
    fn imu_topic(&self) -> Option<String> {
        self.log.source.imu_topic.clone()
    }
    /// Keyframe poses overwritten by graph messages.
    #[getter]
    fn graph_updates(&self) -> usize {
        self.log.source.graph_updates
    }
    /// `(topic, schema name, message encoding, messages read)` for every topic.
    #[getter]
    fn topics(&self) -> Vec<(String, String, String, u64)> {
        self.log
            .source
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
            self.log.source.path.display().to_string(),
            self.log.keyframes.len(),
            self.log.reference.as_ref().map_or(0, |r| r.len()),
            self.log.imu.as_ref().map_or(0, |s| s.len()),
        )
    }
}

/// Reads an MCAP log (see the Rust `io::read_mcap`); the GIL is released.
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
        est_topic: None,
        gnss_topic: None,
    };
    let log = py.detach(|| crate::io::read_mcap(&path, &options))?;
    Ok(PyLog {
        log: Arc::new(Recording::from(log)),
        keyframes: PyOnceLock::new(),
    })
}

/// Reads a log of any container, found from its bytes: MCAP, ROS 1 bag,
/// rosbag2 folder (or its `metadata.yaml`) or `.db3` (see the Rust
/// `io::read_log`); the GIL is released.
#[pyfunction(name = "read_log")]
#[pyo3(signature = (path, *, keyframe_topic=None, graph_topic=None, pose_topic=None, imu_topic=None, tf_parent=None, tf_child=None, est_topic=None, gnss_topic=None))]
#[allow(clippy::too_many_arguments)]
fn read_log_py(
    py: Python<'_>,
    path: PathBuf,
    keyframe_topic: Option<String>,
    graph_topic: Option<String>,
    pose_topic: Option<String>,
    imu_topic: Option<String>,
    tf_parent: Option<String>,
    tf_child: Option<String>,
    est_topic: Option<String>,
    gnss_topic: Option<String>,
) -> PyResult<PyLog> {
    let options = ReadOptions {
        keyframe_topic,
        graph_topic,
        pose_topic,
        imu_topic,
        tf_parent,
        tf_child,
        est_topic,
        gnss_topic,
    };
    let log = py.detach(|| read_log(&path, &options))?;
    Ok(PyLog {
        log: Arc::new(Recording::from(log)),
        keyframes: PyOnceLock::new(),
    })
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
    let pts: Vec<f32> = super::arrays::rows_f64(points, "points", 3)?
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
            cloud: crate::io::spill::CloudRef::Memory(&pts, cols.as_deref()),
            t_world_slam: t,
            slam_trajectory: None,
            reference: None,
            stamp,
            world_frame: "world",
            slam_frame: "slam",
            frames: &[],
        };
        io_mcap::write_world_mcap(&path, &scene, flavor)
    })?;
    Ok(())
}

/// Adds the log classes and functions to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyLog>()?;
    m.add_function(wrap_pyfunction!(read_mcap_py, m)?)?;
    m.add_function(wrap_pyfunction!(read_log_py, m)?)?;
    m.add_function(wrap_pyfunction!(write_world_mcap_py, m)?)?;
    Ok(())
}
