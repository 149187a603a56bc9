//! MCAP logs for Python: `read_mcap(...) -> Log`, `write_world_mcap(...)`.

use std::path::PathBuf;

use numpy::PyUntypedArrayMethods;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;

use super::beyond::window_arg;
use super::cloud::{PyKeyframe, PyPointCloud, PyPointFilter};
use super::core::{extended_options, PyTrajectory, PyTrajectoryAlignment};
use super::geometry::PySim3;
use super::imu::PyImuSamples;
use super::map::PyOccupancyMap;
use crate::geometry::Sim3;
use crate::io::mcap::{self as io_mcap, ReadOptions, WorldFlavor, WorldScene};
use crate::pipeline::{self, ConvertOptions};
use crate::trajectory::TrajectoryAlignOptions;

/// A log read by `read_mcap`.
#[pyclass(name = "Log", module = "slam2world._slam2world", frozen)]
pub struct PyLog {
    log: io_mcap::Log,
    /// The Python objects of the keyframes, made on first access.
    keyframes: PyOnceLock<Vec<Py<PyKeyframe>>>,
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
    fn keyframes(&self, py: Python<'_>) -> PyResult<Vec<Py<PyKeyframe>>> {
        let list = self.keyframes.get_or_try_init(py, || {
            self.log
                .keyframes
                .iter()
                .map(|k| Py::new(py, PyKeyframe { inner: k.clone() }))
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
    let log = py.detach(|| io_mcap::read_mcap(&path, &options))?;
    Ok(PyLog {
        log,
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

/// The result of `convert`: the alignment, the world cloud, the report, and
/// methods that write each output.
#[pyclass(name = "Conversion", module = "slam2world._slam2world", frozen)]
pub struct PyConversion {
    inner: pipeline::Conversion,
    alignment: Py<PyTrajectoryAlignment>,
    cloud: PyOnceLock<Py<PyPointCloud>>,
}

fn flavor_of(ros2: bool) -> WorldFlavor {
    if ros2 {
        WorldFlavor::Ros2
    } else {
        WorldFlavor::Foxglove
    }
}

#[pymethods]
impl PyConversion {
    /// The fit: `.transform` is `T_world_slam`; APE statistics over all pairs.
    #[getter]
    fn alignment(&self, py: Python<'_>) -> Py<PyTrajectoryAlignment> {
        self.alignment.clone_ref(py)
    }
    /// `T_world_slam`.
    #[getter]
    fn transform(&self) -> PySim3 {
        PySim3::from(self.inner.transform())
    }
    /// The world cloud (metres, world frame).
    #[getter]
    fn cloud(&self, py: Python<'_>) -> PyResult<Py<PyPointCloud>> {
        let c = self.cloud.get_or_try_init(py, || {
            Py::new(py, PyPointCloud::from_core(py, self.inner.cloud.clone())?)
        })?;
        Ok(c.clone_ref(py))
    }
    /// The keyframe trajectory in the world frame.
    #[getter]
    fn slam_trajectory(&self) -> PyTrajectory {
        PyTrajectory {
            inner: self.inner.slam_trajectory.clone(),
        }
    }
    /// The report (as `report.json` holds it) as a dict.
    #[getter]
    fn report(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let text = serde_json::to_string(&self.inner.report)
            .map_err(|e| PyErr::from(crate::Error::invalid("report", e.to_string())))?;
        Ok(py.import("json")?.call_method1("loads", (text,))?.unbind())
    }
    /// Writes `world.mcap` (Foxglove schemas, or ROS 2 with `ros2=True`).
    #[pyo3(signature = (path, *, ros2=false))]
    fn write_world_mcap(&self, py: Python<'_>, path: PathBuf, ros2: bool) -> PyResult<()> {
        py.detach(|| self.inner.write_world_mcap(&path, flavor_of(ros2)))?;
        Ok(())
    }
    /// The occupancy octree of the world cloud (world frame), or None when
    /// `convert` was not given `octree_resolution`. Each access returns a new
    /// copy: changing it does not change what `write_bt` / `write_all` write.
    #[getter]
    fn octree(&self) -> Option<PyOccupancyMap> {
        self.inner
            .octree
            .as_ref()
            .map(|m| PyOccupancyMap::from_core(m.clone()))
    }
    /// Writes the octree as an OctoMap `.bt` file; InvalidInputError without one.
    fn write_bt(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| self.inner.write_bt(&path))?;
        Ok(())
    }
    /// Writes the world cloud as binary PLY.
    fn write_ply(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| self.inner.write_ply(&path))?;
        Ok(())
    }
    /// Writes `report.json`.
    fn write_report(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| self.inner.write_report(&path))?;
        Ok(())
    }
    /// Writes `world.mcap`, `cloud.ply`, `report.json` and, with an octree,
    /// `map.bt` into `directory`.
    #[pyo3(signature = (directory, *, ros2=false))]
    fn write_all(&self, py: Python<'_>, directory: PathBuf, ros2: bool) -> PyResult<()> {
        py.detach(|| self.inner.write_all(&directory, flavor_of(ros2)))?;
        Ok(())
    }
}

/// Aligns a log's keyframes with its reference and builds the world cloud.
/// `log_or_path` is a `Log` or a path (read with the topic arguments);
/// `filter=None` means the LSD-SLAM viewer's defaults. `octree_resolution`
/// (metres) also builds the occupancy octree, each keyframe's points inserted
/// from its camera centre; `octree_max_range` (metres) truncates its rays.
/// Without reference poses and with raw IMU (`imu_topic`, found by schema when
/// None), `T_world_slam` comes from the IMU (`imu_from_cam` = `T_imu_cam`);
/// with both, the report's `imu` entry compares them.
/// The options beyond one fit are those of `align_trajectories` (start-up cut,
/// robust fit, orientations, time offset, extrinsic `T_body_cam`);
/// `compare_windowed` (an int: matched poses, a float: metres of path) adds a
/// windowed fit to the report, and `windowed_cloud=True` carries each keyframe
/// (points, camera centre, world pose) with it instead of the single Sim(3).
/// `Conversion.alignment` carries the inliers,
/// stages, offset and covariance.
#[pyfunction(name = "convert")]
#[pyo3(signature = (log_or_path, *, keyframe_topic=None, graph_topic=None, pose_topic=None, tf_parent=None, tf_child=None, max_diff=0.01, offset=0.0, n_to_align=None, scale=true, filter=None, octree_resolution=None, octree_max_range=None, skip_init=None, robust=None, inlier_threshold=None, loss="huber", use_orientations=false, estimate_offset=false, max_offset=0.5, body_from_cam=None, compare_windowed=None, windowed_cloud=false, imu_topic=None, imu_from_cam=None))]
#[allow(clippy::too_many_arguments)]
fn convert_py(
    py: Python<'_>,
    log_or_path: &Bound<'_, PyAny>,
    keyframe_topic: Option<String>,
    graph_topic: Option<String>,
    pose_topic: Option<String>,
    tf_parent: Option<String>,
    tf_child: Option<String>,
    max_diff: f64,
    offset: f64,
    n_to_align: Option<usize>,
    scale: bool,
    filter: Option<PyRef<'_, PyPointFilter>>,
    octree_resolution: Option<f64>,
    octree_max_range: Option<f64>,
    skip_init: Option<&Bound<'_, PyAny>>,
    robust: Option<&str>,
    inlier_threshold: Option<f64>,
    loss: &str,
    use_orientations: bool,
    estimate_offset: bool,
    max_offset: f64,
    body_from_cam: Option<PyRef<'_, PySim3>>,
    compare_windowed: Option<&Bound<'_, PyAny>>,
    windowed_cloud: bool,
    imu_topic: Option<String>,
    imu_from_cam: Option<PyRef<'_, super::geometry::PySim3>>,
) -> PyResult<PyConversion> {
    let beyond = extended_options(
        skip_init,
        robust,
        inlier_threshold,
        loss,
        use_orientations,
        estimate_offset.then_some(max_offset),
        body_from_cam.map(|b| b.inner),
    )?;
    let compare_windowed = match compare_windowed {
        Some(w) if !w.is_none() => Some(window_arg(w, "compare_windowed")?),
        _ => None,
    };
    let opts = ConvertOptions {
        read: ReadOptions {
            keyframe_topic,
            graph_topic,
            pose_topic,
            imu_topic,
            tf_parent,
            tf_child,
        },
        align: TrajectoryAlignOptions {
            max_diff,
            offset,
            first_n: n_to_align,
            scale,
            ..TrajectoryAlignOptions::default()
        },
        filter: filter.map(|f| f.inner).unwrap_or_default(),
        beyond,
        compare_windowed,
        windowed_cloud,
        imu: crate::imu::ImuInitOptions {
            imu_from_cam: imu_from_cam.map_or_else(crate::geometry::Sim3::identity, |t| t.inner),
            ..crate::imu::ImuInitOptions::default()
        },
        octree_resolution,
        octree_max_range,
    };
    let conversion = if let Ok(log) = log_or_path.cast::<PyLog>() {
        let log = log.get();
        py.detach(|| pipeline::convert(&log.log, &opts))?
    } else {
        let path: PathBuf = log_or_path.extract().map_err(|_| {
            PyErr::from(crate::Error::invalid(
                "log_or_path",
                "expected a Log or a path (str or os.PathLike)",
            ))
        })?;
        py.detach(|| pipeline::convert_file(&path, &opts))?
    };
    let alignment = Py::new(
        py,
        PyTrajectoryAlignment::from_extended(py, conversion.alignment.clone())?,
    )?;
    Ok(PyConversion {
        inner: conversion,
        alignment,
        cloud: PyOnceLock::new(),
    })
}

/// Adds the MCAP classes and functions to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyLog>()?;
    m.add_class::<PyConversion>()?;
    m.add_function(wrap_pyfunction!(convert_py, m)?)?;
    m.add_function(wrap_pyfunction!(read_mcap_py, m)?)?;
    m.add_function(wrap_pyfunction!(write_world_mcap_py, m)?)?;
    Ok(())
}
