//! The conversion for Python: `convert(...) -> Conversion`.

use std::path::PathBuf;

use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;

use super::align::{fit_options, window_arg, FitDof, PyTrajectoryAlignment};
use super::cloud::{PyPointCloud, PyPointFilter};
use super::colmap::PyColmapModel;
use super::geometry::PySim3;
use super::imu::PyImuAlignment;
use super::io::PyLog;
use super::map::{PyGrid, PyOccupancyMap};
use super::reconstruction::{reading_options, reference_spec, PyReconstruction};
use super::trajectory::PyTrajectory;
use crate::io::gnss::GnssFormat;
use crate::io::log::ReadOptions;
use crate::io::mcap::WorldFlavor;
use crate::map::MapParams;
use crate::pipeline::gnss::{
    attach_gnss, parse_origin, GeoOutputs, GnssFile, GnssOptions, WithGnss,
};
use crate::pipeline::reconstruction::{attach_reference, open_input};
use crate::pipeline::{self, ConvertOptions, NativeModel};

/// `convert`'s `origin`: `"first"`, `"mean"`, or a `(lat, lon, alt)` position.
#[derive(FromPyObject)]
pub(crate) enum OriginArg {
    /// A rule (or `"LAT,LON,ALT"` text).
    Name(String),
    /// Degrees, degrees, metres above the ellipsoid.
    Position([f64; 3]),
}

/// The result of `convert`: the alignment, the world cloud, the report, the
/// octree, and methods that write each output.
#[pyclass(name = "Conversion", module = "slam2world._slam2world", frozen)]
pub struct PyConversion {
    /// The conversion, its octree moved into `octree`.
    inner: pipeline::Conversion,
    alignment: Option<Py<PyTrajectoryAlignment>>,
    imu_alignment: Option<Py<PyImuAlignment>>,
    octree: Option<Py<PyOccupancyMap>>,
    cloud: PyOnceLock<Py<PyPointCloud>>,
    report: PyOnceLock<Py<PyAny>>,
}

fn flavor_of(ros2: bool) -> WorldFlavor {
    if ros2 {
        WorldFlavor::Ros2
    } else {
        WorldFlavor::Foxglove
    }
}

/// Runs `f` with the GIL released and SIGINT/SIGTERM caught as a flag that
/// the core's long loops check: Ctrl-C stops the work (its outputs not
/// written) and raises `KeyboardInterrupt`.
pub(crate) fn interruptible<R: Send>(
    py: Python<'_>,
    f: impl FnOnce() -> crate::Result<R> + Send,
) -> crate::Result<R> {
    let _guard = crate::interrupt::Guard::new(crate::interrupt::Second::Flags);
    py.detach(f)
}

impl PyConversion {
    /// Runs `f` with the octree (the Python object's, which is the
    /// conversion's own) and the GIL released.
    fn with_octree<R: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&pipeline::Conversion, Option<&crate::map::OccupancyMap>) -> crate::Result<R>
            + Send,
    ) -> PyResult<R> {
        let inner = &self.inner;
        let _guard = crate::interrupt::Guard::new(crate::interrupt::Second::Flags);
        match &self.octree {
            // Under the map's read lock (other threads' inserts wait).
            Some(m) => Ok(m.get().read(py, |map| f(inner, Some(map)))?),
            None => Ok(py.detach(|| f(inner, None))?),
        }
    }
}

#[pymethods]
impl PyConversion {
    /// The fit to the reference poses: `.transform` is `T_world_slam`; APE
    /// statistics over all pairs, inliers, stages, offset, covariance. None
    /// when `T_world_slam` came from the raw IMU (see `imu_alignment`).
    #[getter]
    fn alignment(&self, py: Python<'_>) -> Option<Py<PyTrajectoryAlignment>> {
        self.alignment.as_ref().map(|a| a.clone_ref(py))
    }
    /// The inertial initialisation that gave `T_world_slam` (no reference
    /// poses), else None.
    #[getter]
    fn imu_alignment(&self, py: Python<'_>) -> Option<Py<PyImuAlignment>> {
        self.imu_alignment.as_ref().map(|a| a.clone_ref(py))
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
    /// The SLAM poses in the world frame.
    #[getter]
    fn slam_trajectory(&self) -> PyTrajectory {
        PyTrajectory {
            inner: self.inner.slam_trajectory.clone().into(),
        }
    }
    /// The report (as `report.json` holds it) as a dict, made on first access;
    /// the same dict each time.
    #[getter]
    fn report(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        let r = self.report.get_or_try_init(py, || -> PyResult<Py<PyAny>> {
            let text = serde_json::to_string(&self.inner.report)
                .map_err(|e| PyErr::from(crate::Error::invalid("report", e.to_string())))?;
            Ok(py.import("json")?.call_method1("loads", (text,))?.unbind())
        })?;
        Ok(r.clone_ref(py))
    }
    /// The occupancy octree of the world cloud (world frame), or None when
    /// `convert` was not given `octree_resolution`. The same object each
    /// time, and the map `write_bt` / `write_all` write: insertions into it
    /// show in what they write.
    #[getter]
    fn octree(&self, py: Python<'_>) -> Option<Py<PyOccupancyMap>> {
        self.octree.as_ref().map(|m| m.clone_ref(py))
    }
    /// The ENU origin `(lat, lon, alt)` (degrees, metres above the WGS84
    /// ellipsoid) when the reference was GNSS (the world frame is ENU there),
    /// else None.
    #[getter]
    fn enu_origin(&self) -> Option<(f64, f64, f64)> {
        self.inner.enu.map(|f| {
            let o = f.origin();
            (o.lat, o.lon, o.alt)
        })
    }
    /// Writes the world cloud as LAS 1.4 (LAZ when the path ends in `.laz`)
    /// with its CRS record: `crs="utm"` (the zone of the ENU origin) or
    /// `"ecef"`; needs a GNSS reference. Returns the EPSG code written.
    #[pyo3(signature = (path, *, crs=None))]
    fn write_las(&self, py: Python<'_>, path: PathBuf, crs: Option<&str>) -> PyResult<u16> {
        let crs = crs
            .map(|c| crate::geo::GeoCrs::parse(c, None))
            .transpose()?;
        let inner = &self.inner;
        Ok(interruptible(py, || inner.write_las(&path, crs))?.epsg)
    }
    /// Writes the world cloud as binary PCD (world-frame float32 metres).
    fn write_pcd(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let inner = &self.inner;
        Ok(interruptible(py, || inner.write_pcd(&path))?)
    }
    /// The 2-D occupancy grid projected from the octree (`convert(...,
    /// grid=(z_min, z_max))`), or None.
    #[getter]
    fn grid(&self, py: Python<'_>) -> PyResult<Option<PyGrid>> {
        self.inner
            .grid
            .as_ref()
            .map(|(g, _)| PyGrid::from_core(py, g.clone()))
            .transpose()
    }
    /// Writes `world.mcap` (Foxglove schemas, or ROS 2 with `ros2=True`).
    #[pyo3(signature = (path, *, ros2=false))]
    fn write_world_mcap(&self, py: Python<'_>, path: PathBuf, ros2: bool) -> PyResult<()> {
        self.with_octree(py, |c, m| {
            c.write_world_mcap_with(&path, flavor_of(ros2), m)
        })
    }
    /// Writes the octree as an OctoMap `.bt` file; InvalidInputError without one.
    fn write_bt(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        self.with_octree(py, |_, m| pipeline::outputs::write_bt(m, &path))
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
    /// Writes `report.html`: the summary, the paths, the errors, the cloud
    /// (at most `max_points`, every n-th) and the octree's occupied voxels (at
    /// most `max_cubes` cubes, coarser levels beyond) in one self-contained page.
    #[pyo3(signature = (path, *, max_points=300_000, max_cubes=200_000))]
    fn write_html(
        &self,
        py: Python<'_>,
        path: PathBuf,
        max_points: usize,
        max_cubes: usize,
    ) -> PyResult<()> {
        let opts = pipeline::outputs::HtmlOptions {
            demo: None,
            figures: pipeline::figures::FigureOptions {
                max_points,
                max_voxels: max_cubes,
            },
        };
        self.with_octree(py, |c, m| c.write_html_with(&path, m, &opts))
    }
    /// The input's own model in the world frame (a COLMAP model carried by
    /// `T_world_slam`: metres, gravity up), else None.
    #[getter]
    fn model(&self) -> Option<PyColmapModel> {
        self.inner
            .native
            .as_ref()
            .and_then(NativeModel::colmap)
            .map(|m| PyColmapModel { inner: m.clone() })
    }
    /// Writes the SLAM poses in the world frame (T_world_cam) as a TUM file.
    fn write_tum(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| self.inner.write_tum(&path))?;
        Ok(())
    }
    /// Writes the input's own model in the world frame into the folder `path`
    /// (`format` "bin" / "txt", default the input's); InvalidInputError when
    /// the input had none.
    #[pyo3(signature = (path, format=None))]
    fn write_model(&self, py: Python<'_>, path: PathBuf, format: Option<&str>) -> PyResult<()> {
        let f = format
            .map(crate::io::colmap::ColmapFormat::parse)
            .transpose()?;
        py.detach(|| self.inner.write_model(&path, f))?;
        Ok(())
    }
    /// Writes `world.mcap`, `cloud.ply`, `trajectory.txt`, `report.json`, `report.html`,
    /// with an octree `map.bt`, and with a model of the input's own `model/`
    /// into `directory`, as one set (written aside, then moved in).
    #[pyo3(signature = (directory, *, ros2=false))]
    fn write_all(&self, py: Python<'_>, directory: PathBuf, ros2: bool) -> PyResult<()> {
        self.with_octree(py, |c, m| {
            c.write_all_with(&directory, flavor_of(ros2), m).map(|_| ())
        })
    }
}

/// An end of `known_distance`: a pose's index (int), stamp (float,
/// seconds) or image name (str), or a map point (three floats, SLAM frame).
fn distance_end(p: &Bound<'_, PyAny>) -> PyResult<crate::pipeline::prior::DistanceEnd> {
    use crate::pipeline::prior::DistanceEnd;
    if let Ok(i) = p.extract::<usize>() {
        return Ok(DistanceEnd::Index(i));
    }
    if let Ok(t) = p.extract::<f64>() {
        return Ok(DistanceEnd::Stamp(t));
    }
    if let Ok(name) = p.extract::<String>() {
        return Ok(DistanceEnd::Name(name));
    }
    let point = super::arrays::vector3(p, "known_distance")?;
    if !point.iter().all(|v| v.is_finite()) {
        return Err(crate::error::Error::invalid(
            "known_distance",
            "a map point's coordinates must be finite",
        )
        .into());
    }
    Ok(DistanceEnd::Point(point))
}

/// The prior of `convert`'s `camera_height`, `known_distance` and
/// `planar_motion`, if any.
fn prior_options(
    camera_height: Option<&Bound<'_, PyAny>>,
    camera_height_sigma: Option<f64>,
    known_distance: Option<(Bound<'_, PyAny>, Bound<'_, PyAny>, f64)>,
    planar_motion: bool,
) -> PyResult<Option<crate::pipeline::prior::PriorOptions>> {
    use crate::pipeline::prior::{DistanceSpec, PriorOptions};

    let camera_height = camera_height
        .filter(|h| !h.is_none())
        .map(height_spec)
        .transpose()?;
    let known_distance = match known_distance {
        Some((a, b, metres)) => Some(DistanceSpec {
            a: distance_end(&a)?,
            b: distance_end(&b)?,
            metres,
        }),
        None => None,
    };
    Ok(PriorOptions::from_parts(
        camera_height,
        camera_height_sigma,
        known_distance,
        planar_motion,
    )?)
}

/// `camera_height`: metres at every pose (a number), `"first:M"` (the
/// first pose's), or a path to a `stamp height` file.
pub(crate) fn height_spec(h: &Bound<'_, PyAny>) -> PyResult<crate::pipeline::prior::HeightSpec> {
    use crate::pipeline::prior::HeightSpec;
    if let Ok(v) = h.extract::<f64>() {
        if !(v.is_finite() && v > 0.0) {
            return Err(crate::error::Error::invalid(
                "camera_height",
                format!("must be a positive number of metres, got {v}"),
            )
            .into());
        }
        return Ok(HeightSpec::Constant(v));
    }
    if let Ok(s) = h.extract::<String>() {
        return Ok(s.parse::<HeightSpec>()?);
    }
    let p: PathBuf = h.extract().map_err(|_| {
        crate::error::Error::invalid(
            "camera_height",
            "expected metres (a number), \"first:M\" or a path to a `stamp height` file",
        )
    })?;
    Ok(HeightSpec::File(p))
}

/// Aligns a log's keyframes or a reconstruction's frames with a metric
/// reference and builds the world cloud. `log_or_path` is a `Log`, a
/// `Reconstruction` or a path: a log of any container (MCAP, ROS 1 bag,
/// rosbag2 folder or `.db3`, read with the topic arguments; `est_topic`: SLAM
/// poses without depth instead of keyframes) or a
/// reconstruction (COLMAP / GLOMAP model folder, DROID-SLAM folder, TUM-order
/// trajectory file with its PLY; read with `time_unit`, `cloud`,
/// `colmap_format` and DROID-SLAM's depth filter `depth_*`,
/// `min_disparity_ratio`, see `read_reconstruction`). `reference` is a file
/// of poses by time (TUM order, time unit detected unless
/// `reference_time_unit`; EuRoC CSV) or of positions by image name
/// (`name x y z`), `reference_format` ("names", "tum", "euroc") detected
/// unless given; a log's own reference is replaced by it.
/// `filter=None` means the LSD-SLAM viewer's defaults. `octree_resolution`
/// (metres) also builds the occupancy octree, each keyframe's points inserted
/// from its camera centre, with OctoMap's `prob_hit`, `prob_miss`,
/// `clamp_min`, `clamp_max`; `octree_max_range` (metres) truncates its rays.
/// Without reference poses and with raw IMU (`imu_topic`, found by schema when
/// None), `T_world_slam` comes from the IMU (`imu_from_cam` = `T_imu_cam`,
/// `gravity` m/s²); with both, the report's `imu` entry compares them.
/// The fit's options are those of `align_trajectories` (start-up cut,
/// robust fit, orientations, time offset, extrinsic `T_body_cam`);
/// `compare_windowed` (an int: matched poses, a float: metres of path) adds a
/// windowed fit to the report, and `windowed_cloud=True` carries each keyframe
/// (points, camera centre, world pose) with it instead of the single Sim(3).
/// `level` is the confidence level of the report's intervals. `dof`,
/// `anchor`, `association`, `max_tilt_deg`, `reference_noise` and
/// `fit_checks` are `align_trajectories`'s (degrees of freedom, pinned first
/// pair, pairing rule, gravity check, fit-quality refusals). `grid=(z_min,
/// z_max)` (metres, world z; needs `octree_resolution`) projects the octree to
/// a 2-D occupancy grid (`Conversion.grid`; `write_all` adds nav2's
/// `map.pgm` + `map.yaml`, `map_height.npy` and a grid channel in
/// `world.mcap`), cells of `grid_resolution` (a whole multiple of the
/// octree's; default the octree's), occupied from `grid_threshold`.
/// With no reference sensor, `camera_height` (metres at every pose, a
/// string `"first:M"` for the first pose's, or the path of a `stamp height`
/// file) gives `T_world_slam` from the ground plane of the SLAM cloud and
/// the cameras' height over it (`camera_height_sigma`: its uncertainty,
/// metres, counted in the report's scale sigma); `known_distance=(a, b,
/// metres)` (poses by index, stamp or image name, or map points as three
/// SLAM coordinates) gives the scale instead, and
/// `planar_motion=True` takes "up" from the plane the cameras ride in
/// (`Conversion.report["prior"]`); with a sensor, the report compares the
/// prior with it.
#[pyfunction(name = "convert")]
#[pyo3(signature = (log_or_path, *, keyframe_topic=None, graph_topic=None, pose_topic=None, est_topic=None, tf_parent=None, tf_child=None, max_diff=0.01, offset=0.0, n_to_align=None, scale=true, method="horn", filter=None, octree_resolution=None, octree_max_range=None, prob_hit=0.7, prob_miss=0.4, clamp_min=0.1192, clamp_max=0.971, skip_init=None, robust=None, inlier_threshold=None, loss="huber", use_orientations=false, estimate_offset=false, max_offset=0.5, body_from_cam=None, compare_windowed=None, windowed_cloud=false, imu_topic=None, imu_from_cam=None, gravity=9.81, level=0.95, dof="sim3", anchor=None, association="evo", max_tilt_deg=Some(crate::defaults::MAX_TILT_DEG), reference_noise=None, fit_checks=true, reference=None, reference_format=None, reference_time_unit=None, time_unit=None, cloud=None, colmap_format=None, depth_filter=true, depth_threshold=0.005, depth_min_count=2, min_disparity_ratio=0.5, gnss=None, gnss_format=None, geoid_offset=0.0, gnss_topic=None, origin=OriginArg::Name(crate::defaults::ORIGIN.into()), lever_arm=None, gnss_weights=true, gnss_max_gap=None, las=None, laz=false, pcd=false, crs=crate::defaults::CRS, grid=None, grid_resolution=None, grid_threshold=0.5, camera_height=None, camera_height_sigma=None, known_distance=None, planar_motion=false),
       text_signature = "(log_or_path, *, keyframe_topic=None, graph_topic=None, pose_topic=None, \
                         est_topic=None, tf_parent=None, tf_child=None, max_diff=0.01, offset=0.0, n_to_align=None, \
                         scale=True, method='horn', filter=None, octree_resolution=None, \
                         octree_max_range=None, prob_hit=0.7, prob_miss=0.4, clamp_min=0.1192, \
                         clamp_max=0.971, skip_init=None, robust=None, inlier_threshold=None, \
                         loss='huber', use_orientations=False, estimate_offset=False, max_offset=0.5, \
                         body_from_cam=None, compare_windowed=None, windowed_cloud=False, \
                         imu_topic=None, imu_from_cam=None, gravity=9.81, level=0.95, dof='sim3', \
                         anchor=None, association='evo', max_tilt_deg=2.0, reference_noise=None, \
                         fit_checks=True, reference=None, reference_format=None, \
                         reference_time_unit=None, time_unit=None, cloud=None, colmap_format=None, \
                         depth_filter=True, depth_threshold=0.005, depth_min_count=2, \
                         min_disparity_ratio=0.5, gnss=None, gnss_format=None, geoid_offset=0.0, \
                         gnss_topic=None, origin='first', lever_arm=None, gnss_weights=True, \
                         gnss_max_gap=None, las=None, laz=False, pcd=False, crs='utm', grid=None, \
                         grid_resolution=None, grid_threshold=0.5, camera_height=None, \
                         camera_height_sigma=None, known_distance=None, planar_motion=False)")]
#[allow(clippy::too_many_arguments)]
fn convert_py(
    py: Python<'_>,
    log_or_path: &Bound<'_, PyAny>,
    keyframe_topic: Option<String>,
    graph_topic: Option<String>,
    pose_topic: Option<String>,
    est_topic: Option<String>,
    tf_parent: Option<String>,
    tf_child: Option<String>,
    max_diff: f64,
    offset: f64,
    #[pyo3(from_py_with = super::arrays::uint::n_to_align)] n_to_align: Option<usize>,
    scale: bool,
    method: &str,
    filter: Option<PyRef<'_, PyPointFilter>>,
    octree_resolution: Option<f64>,
    octree_max_range: Option<f64>,
    prob_hit: f64,
    prob_miss: f64,
    clamp_min: f64,
    clamp_max: f64,
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
    imu_from_cam: Option<PyRef<'_, PySim3>>,
    gravity: f64,
    level: f64,
    dof: &str,
    anchor: Option<&str>,
    association: &str,
    max_tilt_deg: Option<f64>,
    reference_noise: Option<f64>,
    fit_checks: bool,
    reference: Option<PathBuf>,
    reference_format: Option<&str>,
    reference_time_unit: Option<&str>,
    time_unit: Option<&str>,
    cloud: Option<PathBuf>,
    colmap_format: Option<&str>,
    depth_filter: bool,
    depth_threshold: f64,
    depth_min_count: u32,
    min_disparity_ratio: f64,
    gnss: Option<PathBuf>,
    gnss_format: Option<&str>,
    geoid_offset: f64,
    gnss_topic: Option<String>,
    origin: OriginArg,
    lever_arm: Option<[f64; 3]>,
    gnss_weights: bool,
    gnss_max_gap: Option<f64>,
    las: Option<bool>,
    laz: bool,
    pcd: bool,
    crs: &str,
    grid: Option<(f64, f64)>,
    grid_resolution: Option<f64>,
    grid_threshold: f64,
    camera_height: Option<&Bound<'_, PyAny>>,
    camera_height_sigma: Option<f64>,
    known_distance: Option<(Bound<'_, PyAny>, Bound<'_, PyAny>, f64)>,
    planar_motion: bool,
) -> PyResult<PyConversion> {
    let prior = prior_options(
        camera_height,
        camera_height_sigma,
        known_distance,
        planar_motion,
    )?;
    let gnss_file = match gnss {
        Some(path) => Some(GnssFile {
            path,
            format: gnss_format.map(GnssFormat::parse).transpose()?,
            geoid_offset,
        }),
        None => None,
    };
    let origin = match origin {
        OriginArg::Name(name) => parse_origin(&name)?,
        OriginArg::Position(v) => {
            crate::geo::Origin::Given(crate::geo::Geodetic::try_new(v[0], v[1], v[2])?)
        }
    };
    let gnss_options = GnssOptions {
        origin,
        lever_arm: lever_arm.map(nalgebra::Vector3::from),
        weights: gnss_weights,
        max_gap: gnss_max_gap,
    };
    let geo_outputs = GeoOutputs {
        las,
        laz,
        pcd,
        crs: crate::geo::GeoCrs::parse(crs, None)?,
    };
    let reference = reference_spec(reference, reference_format, reference_time_unit)?;
    let reading = reading_options(
        time_unit,
        cloud,
        colmap_format,
        depth_filter,
        depth_threshold,
        depth_min_count,
        min_disparity_ratio,
    )?;
    let align = fit_options(
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
            est_topic,
            gnss_topic,
        },
        align,
        filter: filter.map(|f| f.inner).unwrap_or_default(),
        compare_windowed,
        windowed_cloud,
        imu: crate::imu::ImuInitOptions {
            imu_from_cam: imu_from_cam.map_or_else(crate::geometry::Sim3::identity, |t| t.inner),
            gravity,
            ..crate::imu::ImuInitOptions::default()
        },
        map: octree_resolution.map(|resolution| MapParams {
            resolution,
            prob_hit,
            prob_miss,
            clamp_min,
            clamp_max,
            max_range: octree_max_range,
        }),
        grid: grid.map(|(z_min, z_max)| crate::map::GridParams {
            z_min,
            z_max,
            resolution: grid_resolution,
            occupied_threshold: grid_threshold,
        }),
        confidence: level,
        gnss: gnss_options,
        geo_outputs,
        prior,
    };
    // A recording in memory, with the reference file attached to a copy.
    let with_reference = |rec: &pipeline::Recording| -> crate::Result<pipeline::Conversion> {
        if reference.is_none() && gnss_file.is_none() {
            return pipeline::convert(rec, &opts);
        }
        let mut rec = rec.clone();
        if let Some(spec) = &reference {
            attach_reference(&mut rec, spec)?;
        }
        if let Some(file) = &gnss_file {
            attach_gnss(&mut rec, file)?;
        }
        pipeline::convert(&rec, &opts)
    };
    let mut conversion = if let Ok(log) = log_or_path.cast::<PyLog>() {
        let log = log.get();
        interruptible(py, || with_reference(&log.log))?
    } else if let Ok(r) = log_or_path.cast::<PyReconstruction>() {
        let r = r.get();
        interruptible(py, || with_reference(&r.rec))?
    } else {
        let path: PathBuf = log_or_path.extract().map_err(|_| {
            PyErr::from(crate::Error::invalid(
                "log_or_path",
                "expected a Log, a Reconstruction or a path (str or os.PathLike)",
            ))
        })?;
        interruptible(py, || {
            opts.check()?;
            let src = open_input(&path, &opts.read, &reading, reference.as_ref())?;
            match gnss_file.clone() {
                Some(file) => pipeline::convert_source(&WithGnss { inner: src, file }, &opts),
                None => pipeline::convert_source(&*src, &opts),
            }
        })?
    };
    let alignment = match &conversion.world {
        pipeline::WorldFrame::Poses(p) => Some(Py::new(
            py,
            PyTrajectoryAlignment::new(py, p.alignment.clone())?,
        )?),
        pipeline::WorldFrame::Imu(_) | pipeline::WorldFrame::Prior(_) => None,
    };
    let imu_alignment = match &conversion.world {
        pipeline::WorldFrame::Imu(a) => Some(Py::new(py, PyImuAlignment::from((**a).clone()))?),
        pipeline::WorldFrame::Poses(_) | pipeline::WorldFrame::Prior(_) => None,
    };
    let octree = match conversion.octree.take() {
        Some(m) => Some(Py::new(py, PyOccupancyMap::from_core(m))?),
        None => None,
    };
    Ok(PyConversion {
        inner: conversion,
        alignment,
        imu_alignment,
        octree,
        cloud: PyOnceLock::new(),
        report: PyOnceLock::new(),
    })
}

/// Adds the conversion to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyConversion>()?;
    m.add_function(wrap_pyfunction!(convert_py, m)?)?;
    Ok(())
}
