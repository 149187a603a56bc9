//! `Session`: the online conversion (wraps `pipeline/session.rs`).

use nalgebra::{Matrix3, Quaternion, UnitQuaternion, Vector3};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::cloud::{PyKeyframe, PyPointFilter};
use super::geo::origin_arg;
use super::geometry::PySim3;
use super::live::PyWorldServer;
use super::map::{PyGrid, PyOccupancyMap};
use crate::align::trajectories::TrajectoryAlignOptions;
use crate::geo::{FixStatus, GnssFix, Origin};
use crate::io::atomic::OutputSet;
use crate::io::mcap::WorldFlavor;
use crate::live::{ServeOptions, WorldServer};
use crate::map::{GridParams, MapParams};
use crate::pipeline::gnss::GnssOptions;
use crate::pipeline::live_world::SessionWorld;
use crate::pipeline::outputs::WORLD_MCAP;
use crate::pipeline::report::{to_json_bytes, FollowReport};
use crate::pipeline::session::{Session, SessionOptions, UpdateTiming};

fn vec3(what: &str, v: [f64; 3]) -> PyResult<Vector3<f64>> {
    let v = Vector3::from(v);
    if v.iter().all(|x| x.is_finite()) {
        Ok(v)
    } else {
        Err(crate::Error::NonFinite {
            what: what.into(),
            index: 0,
        }
        .into())
    }
}

fn timing_dict<'py>(py: Python<'py>, t: &UpdateTiming) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("fit_s", t.fit_s)?;
    d.set_item("backproject_s", t.backproject_s)?;
    d.set_item("insert_s", t.insert_s)?;
    d.set_item("inserted", t.inserted)?;
    d.set_item("rebuilt", t.rebuilt)?;
    Ok(d)
}

/// The online conversion: push what a SLAM log holds as it arrives (tracked
/// frames, keyframes, graph updates, reference poses or GNSS fixes, IMU
/// samples);
/// `state()` says the start-up stage decided on the data so far,
/// `transform()` gives `T_world_slam` once the stable stage is reached (None
/// before; `state()["reason"]` says why), `map()` and `grid()` the occupancy
/// map kept up to date. `finish()` after the last push makes the map equal
/// the batch `convert(..., skip_init="auto")` octree of the same data.
#[pyclass(name = "Session", module = "slam2world._slam2world")]
pub struct PySession {
    inner: Session,
    live: Option<LiveServe>,
}

/// A session's world on a Foxglove WebSocket (`Session.serve`): handed to
/// the server after every update, then written into a private folder (the
/// server's `path`).
struct LiveServe {
    server: Py<PyWorldServer>,
    world: SessionWorld,
    report: FollowReport,
    /// Holds `world.mcap`; removed with the session.
    dir: tempfile::TempDir,
}

impl PySession {
    /// After a push that was published: the ground refit it left for later
    /// (only while serving: `Session::defer_refits`), published in turn;
    /// returns the push's timing `t` with the refit's added.
    fn catch_up(&mut self, py: Python<'_>, t: UpdateTiming) -> PyResult<UpdateTiming> {
        if !self.inner.has_deferred() {
            return Ok(t);
        }
        let c = self.inner.catch_up()?;
        self.publish(py, None, false, &c)?;
        Ok(t.then(c))
    }

    /// After an update: the world as it stands to the clients of `serve`
    /// (nothing without one, or once it is stopped; nothing before the
    /// transform is known). `id`: the keyframe pushed (None: not one, a
    /// graph update), `finished`: after `finish()`.
    fn publish(
        &mut self,
        py: Python<'_>,
        id: Option<i32>,
        finished: bool,
        t: &UpdateTiming,
    ) -> PyResult<()> {
        let Some(live) = self.live.as_mut() else {
            return Ok(());
        };
        if !live.server.borrow(py).is_running() {
            self.live = None;
            return Ok(());
        }
        let id = id.unwrap_or(live.report.last_keyframe);
        let latency = t.total_s();
        live.report.update(&self.inner, id, 0.0, t, latency);
        live.report.finished = finished;
        let state = to_json_bytes(&live.report)?;
        let path = live.dir.path().join(WORLD_MCAP);
        let session = &self.inner;
        let world = &mut live.world;
        let built = py.detach(|| -> crate::Result<Option<std::sync::Arc<Vec<u8>>>> {
            Ok(match world.build(session, state)? {
                Some(w) => Some(w.bytes()?),
                None => None,
            })
        })?;
        let Some(bytes) = built else {
            return Ok(());
        };
        // The clients first; then the file the server names.
        live.server.borrow(py).publish(bytes.clone());
        py.detach(|| {
            let mut set = OutputSet::new();
            set.write_bytes(&path, &bytes)?;
            set.commit().map(|_| ())
        })?;
        Ok(())
    }
}

#[pymethods]
impl PySession {
    #[new]
    #[pyo3(signature = (*, max_diff=0.01, offset=0.0, scale=true, filter=None, octree_resolution=0.1, octree_max_range=Some(10.0), prob_hit=0.7, prob_miss=0.4, clamp_min=0.1192, clamp_max=0.971, stable_hold=5.0, rebuild_tolerance=None, origin=None, gnss_weights=true, gnss_max_gap=None, camera_height=None),
           text_signature = "(*, max_diff=0.01, offset=0.0, scale=True, filter=None, octree_resolution=0.1, \
                             octree_max_range=10.0, prob_hit=0.7, prob_miss=0.4, clamp_min=0.1192, \
                             clamp_max=0.971, stable_hold=5.0, rebuild_tolerance=None, origin='first', \
                             gnss_weights=True, gnss_max_gap=None, camera_height=None)")]
    #[allow(clippy::too_many_arguments)]
    fn new(
        max_diff: f64,
        offset: f64,
        scale: bool,
        filter: Option<PyRef<'_, PyPointFilter>>,
        octree_resolution: f64,
        octree_max_range: Option<f64>,
        prob_hit: f64,
        prob_miss: f64,
        clamp_min: f64,
        clamp_max: f64,
        stable_hold: f64,
        rebuild_tolerance: Option<f64>,
        origin: Option<&Bound<'_, PyAny>>,
        gnss_weights: bool,
        gnss_max_gap: Option<f64>,
        camera_height: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let camera_height = match camera_height {
            Some(h) if !h.is_none() => Some(super::pipeline::height_spec(h)?),
            _ => None,
        };
        let opts = SessionOptions {
            align: TrajectoryAlignOptions {
                max_diff,
                offset,
                scale,
                ..TrajectoryAlignOptions::default()
            },
            filter: filter.map(|f| f.inner).unwrap_or_default(),
            map: MapParams {
                resolution: octree_resolution,
                prob_hit,
                prob_miss,
                clamp_min,
                clamp_max,
                max_range: octree_max_range,
            },
            stable_hold,
            rebuild_tolerance: rebuild_tolerance.unwrap_or(0.5 * octree_resolution),
            gnss: GnssOptions {
                origin: match origin {
                    Some(o) => origin_arg(o)?,
                    None => Origin::First,
                },
                lever_arm: None,
                weights: gnss_weights,
                max_gap: gnss_max_gap,
            },
            camera_height,
        };
        Ok(PySession {
            inner: Session::new(opts)?,
            live: None,
        })
    }

    /// A reference pose `T_world_body`: time (s), position (m), orientation
    /// `(x, y, z, w)` or None. In increasing time.
    #[pyo3(signature = (time, position, orientation_xyzw=None))]
    fn push_reference(
        &mut self,
        time: f64,
        position: [f64; 3],
        orientation_xyzw: Option<[f64; 4]>,
    ) -> PyResult<()> {
        let p = vec3("position", position)?;
        let q = orientation_xyzw
            .map(|[x, y, z, w]| UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z)));
        Ok(self.inner.push_reference(time, p, q)?)
    }

    /// A tracked frame: the SLAM's `T_slam_cam` at `time` as published live.
    fn push_frame(&mut self, time: f64, pose: PyRef<'_, PySim3>) -> PyResult<()> {
        Ok(self.inner.push_frame(time, &pose.inner)?)
    }

    /// A keyframe (replaces one of the same id); returns the update's timing
    /// (`fit_s`, `backproject_s`, `insert_s`, `inserted`, `rebuilt`).
    fn push_keyframe<'py>(
        &mut self,
        py: Python<'py>,
        keyframe: PyRef<'_, PyKeyframe>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let kf = keyframe.inner.clone();
        let id = kf.id;
        let t = self.inner.push_keyframe(kf)?;
        self.publish(py, Some(id), false, &t)?;
        let t = self.catch_up(py, t)?;
        timing_dict(py, &t)
    }

    /// A graph update: `(id, T_slam_cam)` pairs; returns the update's timing.
    fn push_graph_update<'py>(
        &mut self,
        py: Python<'py>,
        poses: Vec<(i32, PyRef<'_, PySim3>)>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let poses: Vec<(i32, crate::geometry::Sim3)> =
            poses.iter().map(|(id, p)| (*id, p.inner)).collect();
        let t = self.inner.push_graph_update(&poses)?;
        self.publish(py, None, false, &t)?;
        let t = self.catch_up(py, t)?;
        timing_dict(py, &t)
    }

    /// An IMU sample (kept; not used online yet).
    fn push_imu(&mut self, time: f64, gyro: [f64; 3], accel: [f64; 3]) -> PyResult<()> {
        Ok(self
            .inner
            .push_imu(time, vec3("gyro", gyro)?, vec3("accel", accel)?)?)
    }

    /// A GNSS fix: time (s), WGS84 latitude and longitude (degrees), height
    /// above the ellipsoid (m), the ENU position covariance (3×3, m²) when
    /// known, and whether the receiver had a fix (a fix without one is
    /// dropped and counted). The first fix puts the world frame (ENU at it,
    /// or at the session's `origin`); fixes come in increasing time, and a
    /// session takes fixes or reference poses, not both.
    #[pyo3(signature = (time, latitude, longitude, altitude, covariance=None, has_fix=true))]
    #[allow(clippy::too_many_arguments)]
    fn push_fix(
        &mut self,
        time: f64,
        latitude: f64,
        longitude: f64,
        altitude: f64,
        covariance: Option<[[f64; 3]; 3]>,
        has_fix: bool,
    ) -> PyResult<()> {
        let fix = GnssFix {
            time,
            lat: latitude,
            lon: longitude,
            alt: altitude,
            covariance: covariance.map(|c| Matrix3::from_fn(|i, j| c[i][j])),
            status: if has_fix {
                FixStatus::Single
            } else {
                FixStatus::NoFix
            },
        };
        Ok(self.inner.push_fix(&fix)?)
    }

    /// After the last push: pairs what still waits, updates the fit and makes
    /// the map exact; returns the update's timing.
    fn finish<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let t = self.inner.finish()?;
        self.publish(py, Some(-1), true, &t)?;
        timing_dict(py, &t)
    }

    /// Serves the session's metric world on a Foxglove WebSocket at
    /// `host:port` (this machine only by default; port 0 takes a free one)
    /// as `follow --serve` does: after every keyframe, graph update and
    /// `finish()`, once the transform is known, the world cloud (bounded for
    /// a viewer), the keyframe and reference paths, `world → slam`, the
    /// occupied voxels, the 2-D grid between `grid=(z_min, z_max)` when
    /// given, and the state (`follow`'s report) as JSON, in Foxglove schemas
    /// or ROS 2 messages (`ros2=True`). The cloud is sent whole at each
    /// update, at most `points` points (16 bytes each: lower it for a slow
    /// link). Returns the `WorldServer`; its
    /// `stop()` ends the serving (the session goes on). A session serves
    /// once at a time: a second call stops the first server. Each update
    /// hands the world to the server, then writes it to the server's
    /// `path`. With a camera height, a keyframe that calls for a ground
    /// refit goes out carried by the transform the session had, and the
    /// refitted world right after it, within the same push.
    #[pyo3(signature = (port=8765, *, host="127.0.0.1", grid=None, ros2=false, points=500_000))]
    fn serve(
        &mut self,
        py: Python<'_>,
        port: u16,
        host: &str,
        grid: Option<(f64, f64)>,
        ros2: bool,
        points: usize,
    ) -> PyResult<Py<PyWorldServer>> {
        if points == 0 {
            return Err(crate::Error::invalid("points", "must be at least 1").into());
        }
        let grid = grid.map(|(lo, hi)| GridParams::new(lo, hi));
        if let Some(g) = &grid {
            g.check()?;
        }
        if let Some(old) = self.live.take() {
            old.server.borrow_mut(py).shut(py);
        }
        let dir = tempfile::Builder::new()
            .prefix("slam2world-serve-")
            .tempdir()
            .map_err(|e| crate::Error::io(std::env::temp_dir(), e))?;
        let opts = ServeOptions {
            host: host.to_string(),
            port,
        };
        let path = dir.path().join(WORLD_MCAP);
        let server = py.detach(|| WorldServer::live(&path, &opts))?;
        let server = Py::new(py, PyWorldServer::from_core(server))?;
        let flavor = if ros2 {
            WorldFlavor::Ros2
        } else {
            WorldFlavor::Foxglove
        };
        // A keyframe's points go out before the ground refit it may call for.
        self.inner.defer_refits(true);
        self.live = Some(LiveServe {
            server: server.clone_ref(py),
            world: SessionWorld::new(self.inner.options().filter, points, grid, flavor),
            report: FollowReport::new(std::path::Path::new("Session")),
            dir,
        });
        // What the session holds already goes out at once.
        let t = self.inner.last_update();
        self.publish(py, None, false, &t)?;
        Ok(server)
    }

    /// The stage (`waiting`, `start`, `converging`, `stable`), why, and what
    /// the session holds.
    fn state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.inner.state();
        let d = PyDict::new(py);
        d.set_item("stage", s.stage.name())?;
        d.set_item("reason", s.reason)?;
        d.set_item("time", s.time)?;
        d.set_item("stable_reported_at", s.stable_reported_at)?;
        d.set_item("stable_time", s.stable_time)?;
        d.set_item("converging_time", s.converging_time)?;
        d.set_item("frames", s.frames)?;
        d.set_item("frames_matched", s.frames_matched)?;
        d.set_item("keyframes", s.keyframes)?;
        d.set_item("keyframes_matched", s.keyframes_matched)?;
        d.set_item("pairs_fitted", s.pairs_fitted)?;
        d.set_item("keyframes_inserted", s.keyframes_inserted)?;
        d.set_item("points", s.points)?;
        d.set_item("rebuilds", s.rebuilds)?;
        d.set_item("fixes", s.fixes)?;
        d.set_item("fixes_dropped", s.fixes_dropped)?;
        d.set_item("enu_origin", s.enu_origin.map(|g| (g.lat, g.lon, g.alt)))?;
        Ok(d)
    }

    /// `T_world_slam` once stable, else None (`state()["reason"]` says why).
    fn transform(&self) -> Option<PySim3> {
        self.inner
            .transform()
            .ok()
            .map(|t| PySim3::from(t.transform))
    }

    /// The 7×7 covariance of `T_world_slam` over `(δθ ×3, δt ×3, ln s)`, or None.
    fn transform_covariance<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<Option<Bound<'py, numpy::PyArray2<f64>>>> {
        let Some(c) = self.inner.transform().ok().and_then(|t| t.covariance) else {
            return Ok(None);
        };
        let rows: Vec<Vec<f64>> = (0..7)
            .map(|i| (0..7).map(|j| c.matrix[(i, j)]).collect())
            .collect();
        Ok(Some(numpy::PyArray2::from_vec2(py, &rows).map_err(
            |e| PyErr::from(crate::Error::invalid("covariance", e.to_string())),
        )?))
    }

    /// A copy of the occupancy map (world frame), or None before the transform.
    fn map(&self) -> Option<PyOccupancyMap> {
        self.inner.map().cloned().map(PyOccupancyMap::from_core)
    }

    /// The 2-D occupancy grid of the map (see `OccupancyMap.grid`).
    #[pyo3(signature = (z_min, z_max, resolution=None))]
    fn grid(
        &self,
        py: Python<'_>,
        z_min: f64,
        z_max: f64,
        resolution: Option<f64>,
    ) -> PyResult<PyGrid> {
        let g = self.inner.grid(z_min, z_max, resolution)?;
        PyGrid::from_core(py, g)
    }

    fn __repr__(&self) -> String {
        let s = self.inner.state();
        format!(
            "Session(stage={:?}, keyframes={}, frames={}, points={})",
            s.stage.name(),
            s.keyframes,
            s.frames,
            s.points
        )
    }
}

/// Adds `Session` to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySession>()?;
    Ok(())
}
