//! `OccupancyMap` and its 2-D `Grid` for Python: numpy in and out, the GIL
//! released while inserting and querying.
//!
//! The map sits behind a read-write lock inside the (frozen) pyclass: threads
//! that insert into one map queue for it with the GIL released, instead of
//! failing on PyO3's borrow flag ("Already borrowed"), and queries run side
//! by side.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::{PoisonError, RwLock};

use numpy::{
    AllowTypeChange, IntoPyArray, PyArray1, PyArray2, PyArrayLike1, PyArrayMethods,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyInt};

use super::arrays::{c_slice, rows_f64, to_array2, vector3, Points};
use crate::error::Error;
use crate::io::mcap::grid_msgs::{self, CellValues};
use crate::io::nav2;
use crate::map::{Grid2d, MapParams, OccupancyMap, VoxelState, MAX_GRID_CELLS};

/// Voxel centres `occupied_centers()` / `free_centers()` return at most by
/// default (2^24: 384 MiB of `f64` centres).
const DEFAULT_MAX_VOXELS: u64 = 1 << 24;

/// An occupancy octree with OctoMap's semantics (`.bt` / `.ot` compatible).
#[pyclass(name = "OccupancyMap", module = "slam2world._slam2world", frozen)]
pub struct PyOccupancyMap {
    inner: RwLock<OccupancyMap>,
}

impl PyOccupancyMap {
    /// Runs `f` on the map under the read lock, the GIL released while
    /// waiting and working.
    pub(crate) fn read<R: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&OccupancyMap) -> R + Send,
    ) -> R {
        py.detach(|| f(&self.inner.read().unwrap_or_else(PoisonError::into_inner)))
    }

    /// Runs `f` on the map under the write lock (threads queue for it), the
    /// GIL released while waiting and working.
    fn write<R: Send>(&self, py: Python<'_>, f: impl FnOnce(&mut OccupancyMap) -> R + Send) -> R {
        py.detach(|| f(&mut self.inner.write().unwrap_or_else(PoisonError::into_inner)))
    }
}

/// A Python int as a count `>= 0`, or the project's error naming the
/// argument (not a bare `OverflowError`).
fn count_arg(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<u64> {
    if !obj.is_instance_of::<PyInt>() {
        return Err(
            Error::invalid(what, format!("expected an int, got {}", type_name(obj))).into(),
        );
    }
    let v: i128 = obj.extract().map_err(|_| {
        PyErr::from(Error::invalid(
            what,
            format!("{} is out of range", short_repr(obj)),
        ))
    })?;
    u64::try_from(v).map_err(|_| Error::invalid(what, format!("{v} is not a count >= 0")).into())
}

/// A Python int as a keyframe id (`int32`), naming the argument when it is not.
fn id_arg(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<i32> {
    if !obj.is_instance_of::<PyInt>() {
        return Err(Error::invalid(
            what,
            format!("keyframe id must be an int, got {}", type_name(obj)),
        )
        .into());
    }
    obj.extract::<i32>().map_err(|_| {
        Error::invalid(
            what,
            format!("keyframe id {} is outside int32", short_repr(obj)),
        )
        .into()
    })
}

fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "?".into())
}

/// `repr(obj)`, cut to 60 characters.
fn short_repr(obj: &Bound<'_, PyAny>) -> String {
    let r = obj
        .repr()
        .map(|r| r.to_string())
        .unwrap_or_else(|_| "?".into());
    if r.chars().count() > 60 {
        format!("{}...", r.chars().take(57).collect::<String>())
    } else {
        r
    }
}

/// `(N, 3)` points as `f32` (OctoMap's point type), copied only when needed.
fn points_f32(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<f32>> {
    Ok(match Points::extract(obj, what)? {
        Points::F32(a) => match c_slice(&a) {
            Some(s) => s.to_vec(),
            None => a.as_array().iter().copied().collect(),
        },
        Points::F64(a) => a.as_array().iter().map(|&v| v as f32).collect(),
    })
}

fn origin_f32(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<[f32; 3]> {
    let v = vector3(obj, what)?;
    Ok([v.x as f32, v.y as f32, v.z as f32])
}

fn arr3(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<[f64; 3]> {
    let v = vector3(obj, what)?;
    Ok([v.x, v.y, v.z])
}

fn query_points(obj: &Bound<'_, PyAny>) -> PyResult<Vec<[f64; 3]>> {
    let v = rows_f64(obj, "points", 3)?;
    Ok(v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

fn centers_array(py: Python<'_>, c: Vec<[f64; 3]>) -> PyResult<Bound<'_, PyArray2<f64>>> {
    to_array2(py, c.into_iter().flatten().collect(), 3)
}

type Leaves<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray1<f64>>);

fn leaves_arrays(py: Python<'_>, l: Vec<([f64; 3], f64)>) -> PyResult<Leaves<'_>> {
    let sizes: Vec<f64> = l.iter().map(|x| x.1).collect();
    let c: Vec<f64> = l.into_iter().flat_map(|x| x.0).collect();
    Ok((to_array2(py, c, 3)?, sizes.into_pyarray(py)))
}

#[pymethods]
impl PyOccupancyMap {
    #[new]
    #[pyo3(signature = (resolution, *, prob_hit=0.7, prob_miss=0.4, clamp_min=0.1192, clamp_max=0.971, max_range=None))]
    fn new(
        resolution: f64,
        prob_hit: f64,
        prob_miss: f64,
        clamp_min: f64,
        clamp_max: f64,
        max_range: Option<f64>,
    ) -> PyResult<Self> {
        let inner = OccupancyMap::try_new(MapParams {
            resolution,
            prob_hit,
            prob_miss,
            clamp_min,
            clamp_max,
            max_range,
        })?;
        Ok(PyOccupancyMap::from_core(inner))
    }

    /// Inserts one scan of `(N, 3)` points (metres) seen from `origin`;
    /// returns the numbers of voxels updated as (free, occupied).
    fn insert(
        &self,
        py: Python<'_>,
        points: &Bound<'_, PyAny>,
        origin: &Bound<'_, PyAny>,
    ) -> PyResult<(usize, usize)> {
        let pts = points_f32(points, "points")?;
        let o = origin_f32(origin, "origin")?;
        let u = self.write(py, |m| m.insert_scan(&pts, o))?;
        Ok((u.free, u.occupied))
    }

    /// Inserts a converted cloud, each point seen from its keyframe's camera
    /// centre: `keyframe_ids` (N,) int, `origins` maps id to a 3-vector.
    fn insert_keyframes(
        &self,
        py: Python<'_>,
        points: &Bound<'_, PyAny>,
        keyframe_ids: &Bound<'_, PyAny>,
        origins: &Bound<'_, PyDict>,
    ) -> PyResult<(usize, usize)> {
        let pts = points_f32(points, "points")?;
        let ids: PyArrayLike1<'_, i64, AllowTypeChange> = keyframe_ids.extract().map_err(|_| {
            PyErr::from(Error::invalid(
                "keyframe_ids",
                "expected a 1-D integer array",
            ))
        })?;
        let ids: Vec<i32> = ids
            .as_array()
            .iter()
            .map(|&v| {
                i32::try_from(v)
                    .map_err(|_| Error::invalid("keyframe_ids", format!("{v} is out of range")))
            })
            .collect::<Result<_, _>>()?;
        let mut o = BTreeMap::new();
        for (k, v) in origins.iter() {
            let id = id_arg(&k, "origins")?;
            o.insert(id, origin_f32(&v, "origins")?);
        }
        let u = self.write(py, |m| m.insert_keyframes(&pts, &ids, &o))?;
        Ok((u.free, u.occupied))
    }

    /// State per point: -1 unknown, 0 free, 1 occupied.
    fn state<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<i8>>> {
        let q = query_points(points)?;
        let out: Vec<i8> = self.read(py, |m| q.iter().map(|p| m.state(*p) as i8).collect());
        Ok(out.into_pyarray(py))
    }

    /// Occupancy probability per point, NaN where unknown.
    fn occupancy<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let q = query_points(points)?;
        let out: Vec<f64> = self.read(py, |m| {
            q.iter()
                .map(|p| m.occupancy(*p).unwrap_or(f64::NAN))
                .collect()
        });
        Ok(out.into_pyarray(py))
    }

    /// Centres (M, 3) of every occupied voxel at full resolution (pruned
    /// leaves expanded); refused with InvalidInputError beyond `max_voxels`
    /// (default 2^24), counted before anything is allocated.
    #[pyo3(signature = (*, max_voxels=None))]
    fn occupied_centers<'py>(
        &self,
        py: Python<'py>,
        max_voxels: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.centers(py, VoxelState::Occupied, max_voxels)
    }

    /// Centres (M, 3) of every free voxel at full resolution, bounded as
    /// `occupied_centers`.
    #[pyo3(signature = (*, max_voxels=None))]
    fn free_centers<'py>(
        &self,
        py: Python<'py>,
        max_voxels: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.centers(py, VoxelState::Free, max_voxels)
    }

    /// Number of occupied voxels at full resolution (pruned leaves counted
    /// by their volume).
    fn count_occupied(&self, py: Python<'_>) -> u64 {
        self.read(py, |m| m.count_voxels(VoxelState::Occupied))
    }

    /// Number of free voxels at full resolution.
    fn count_free(&self, py: Python<'_>) -> u64 {
        self.read(py, |m| m.count_voxels(VoxelState::Free))
    }

    /// Occupied leaves as (centres (M, 3), edge lengths (M,)).
    fn occupied_leaves<'py>(&self, py: Python<'py>) -> PyResult<Leaves<'py>> {
        let l = self.read(py, |m| m.leaves(VoxelState::Occupied));
        leaves_arrays(py, l)
    }

    /// Free leaves as (centres (M, 3), edge lengths (M,)).
    fn free_leaves<'py>(&self, py: Python<'py>) -> PyResult<Leaves<'py>> {
        let l = self.read(py, |m| m.leaves(VoxelState::Free));
        leaves_arrays(py, l)
    }

    /// The 2-D occupancy grid of the voxels whose centres lie in
    /// [z_min, z_max] (metres, world z, both inclusive): per cell the
    /// probability of the most occupied voxel of its column and the height of
    /// the highest occupied one. `resolution`: the map's (default) or a whole
    /// multiple of it. At most `max_cells` cells (default 2^24).
    #[pyo3(signature = (z_min, z_max, resolution=None, *, max_cells=None))]
    fn grid(
        &self,
        py: Python<'_>,
        z_min: f64,
        z_max: f64,
        resolution: Option<f64>,
        max_cells: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyGrid> {
        let limit = match max_cells {
            Some(v) => count_arg(v, "max_cells")?,
            None => MAX_GRID_CELLS,
        };
        let g = self.read(py, |m| m.grid_bounded(z_min, z_max, resolution, limit))?;
        PyGrid::from_core(py, g)
    }

    /// Centre of the first occupied voxel along the ray, or None.
    #[pyo3(signature = (origin, direction, max_range=None, ignore_unknown=false))]
    fn cast_ray<'py>(
        &self,
        py: Python<'py>,
        origin: &Bound<'py, PyAny>,
        direction: &Bound<'py, PyAny>,
        max_range: Option<f64>,
        ignore_unknown: bool,
    ) -> PyResult<Option<Bound<'py, PyArray1<f64>>>> {
        let o = arr3(origin, "origin")?;
        let d = arr3(direction, "direction")?;
        if let Some(m) = max_range {
            if !(m.is_finite() && m > 0.0) {
                return Err(
                    Error::invalid("max_range", format!("{m} is not a positive length")).into(),
                );
            }
        }
        let hit = self.read(py, |m| m.cast_ray(o, d, max_range, ignore_unknown))?;
        Ok(hit.map(|h| h.to_vec().into_pyarray(py)))
    }

    /// Whether a sphere (centre, radius in metres) touches an occupied voxel.
    fn collides_sphere(
        &self,
        py: Python<'_>,
        center: &Bound<'_, PyAny>,
        radius: f64,
    ) -> PyResult<bool> {
        let c = arr3(center, "center")?;
        Ok(self.read(py, |m| m.collides_sphere(c, radius))?)
    }

    /// Whether an axis-aligned box (centre, half extents in metres) touches an
    /// occupied voxel.
    fn collides_box(
        &self,
        py: Python<'_>,
        center: &Bound<'_, PyAny>,
        half_extents: &Bound<'_, PyAny>,
    ) -> PyResult<bool> {
        let c = arr3(center, "center")?;
        let h = arr3(half_extents, "half_extents")?;
        Ok(self.read(py, |m| m.collides_box(c, h))?)
    }

    /// Whether the segment a → b, swept by a sphere of `radius`, avoids every
    /// occupied voxel (unknown space counts as free).
    #[pyo3(signature = (a, b, radius=0.0))]
    fn segment_is_free(
        &self,
        py: Python<'_>,
        a: &Bound<'_, PyAny>,
        b: &Bound<'_, PyAny>,
        radius: f64,
    ) -> PyResult<bool> {
        let a = arr3(a, "a")?;
        let b = arr3(b, "b")?;
        Ok(self.read(py, |m| m.segment_is_free(a, b, radius))?)
    }

    /// Writes an OctoMap `.bt` file (maximum-likelihood tree).
    fn write_bt(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        Ok(self.read(py, |m| m.write_bt(&path))?)
    }

    /// Writes an OctoMap `.ot` file (full log-odds tree).
    fn write_ot(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        Ok(self.read(py, |m| m.write_ot(&path))?)
    }

    /// Reads an OctoMap `.bt` file (default sensor model, the file's resolution).
    #[staticmethod]
    fn read_bt(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        read_bt(py, path)
    }

    /// Voxel edge length (metres).
    #[getter]
    fn resolution(&self, py: Python<'_>) -> f64 {
        self.read(py, |m| m.resolution())
    }

    /// Number of leaves.
    #[getter]
    fn num_leaf_nodes(&self, py: Python<'_>) -> usize {
        self.read(py, |m| m.num_leaf_nodes())
    }

    /// Number of nodes, inner and leaf.
    #[getter]
    fn num_nodes(&self, py: Python<'_>) -> usize {
        self.read(py, |m| m.num_nodes())
    }

    /// Heap bytes held by the tree.
    #[getter]
    fn memory_bytes(&self, py: Python<'_>) -> usize {
        self.read(py, |m| m.memory_bytes())
    }

    /// Whether two maps have the same parameters and the same tree, node for node.
    fn __eq__(&self, py: Python<'_>, other: &Bound<'_, PyAny>) -> bool {
        let Ok(other) = other.cast::<PyOccupancyMap>() else {
            return false;
        };
        let other = other.get();
        if std::ptr::eq(self, other) {
            return true;
        }
        // One lock at a time (two held together could deadlock against
        // writers queued on both maps).
        let key = |m: &OccupancyMap| (*m.params(), m.tree_bits());
        self.read(py, key) == other.read(py, key)
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        self.read(py, |m| {
            format!(
                "OccupancyMap(resolution={}, num_nodes={})",
                m.resolution(),
                m.num_nodes()
            )
        })
    }
}

impl PyOccupancyMap {
    /// Wraps a map built in Rust (e.g. by `convert`).
    pub(crate) fn from_core(inner: OccupancyMap) -> Self {
        PyOccupancyMap {
            inner: RwLock::new(inner),
        }
    }

    fn centers<'py>(
        &self,
        py: Python<'py>,
        state: VoxelState,
        max_voxels: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let limit = match max_voxels {
            Some(v) => count_arg(v, "max_voxels")?,
            None => DEFAULT_MAX_VOXELS,
        };
        let c = self.read(py, |m| m.try_voxel_centers(state, limit))?;
        centers_array(py, c)
    }
}

/// A 2-D occupancy grid projected from an `OccupancyMap` (see
/// `OccupancyMap.grid`). Arrays are `(height, width)`, row 0 at the lowest y
/// (`nav_msgs/OccupancyGrid` order; `numpy.flipud` gives image order), built
/// once and read-only.
#[pyclass(name = "Grid", module = "slam2world._slam2world", frozen)]
pub struct PyGrid {
    resolution: f64,
    origin: [f64; 2],
    width: usize,
    height: usize,
    z_band: [f64; 2],
    probability: Py<PyArray2<f32>>,
    top_z: Py<PyArray2<f32>>,
}

/// A new read-only `(height, width)` array over `data` (no copy).
fn grid_layer(py: Python<'_>, data: Vec<f32>, width: usize) -> PyResult<Py<PyArray2<f32>>> {
    let a = if width == 0 {
        to_array2(py, Vec::new(), 0)?
    } else {
        to_array2(py, data, width)?
    };
    let kw = PyDict::new(py);
    kw.set_item("write", false)?;
    a.call_method("setflags", (), Some(&kw))?;
    Ok(a.unbind())
}

impl PyGrid {
    pub(crate) fn from_core(py: Python<'_>, g: Grid2d) -> PyResult<Self> {
        Ok(PyGrid {
            resolution: g.resolution,
            origin: g.origin,
            width: g.width,
            height: g.height,
            z_band: g.z_band,
            probability: grid_layer(py, g.probability, g.width)?,
            top_z: grid_layer(py, g.top_z, g.width)?,
        })
    }

    /// The core grid (a copy of the layers), for the writers.
    fn to_core(&self, py: Python<'_>) -> PyResult<Grid2d> {
        let layer = |a: &Py<PyArray2<f32>>| -> PyResult<Vec<f32>> {
            let r = a.bind(py).readonly();
            Ok(match c_slice(&r) {
                Some(s) => s.to_vec(),
                None => r.as_array().iter().copied().collect(),
            })
        };
        Ok(Grid2d {
            resolution: self.resolution,
            origin: self.origin,
            width: self.width,
            height: self.height,
            z_band: self.z_band,
            probability: layer(&self.probability)?,
            top_z: layer(&self.top_z)?,
        })
    }

    /// `(height, width)` booleans of `keep(probability)` (NaN never kept).
    fn mask<'py>(
        &self,
        py: Python<'py>,
        keep: impl Fn(f32) -> bool,
    ) -> PyResult<Bound<'py, PyArray2<bool>>> {
        let r = self.probability.bind(py).readonly();
        let v: Vec<bool> = r
            .as_array()
            .iter()
            .map(|&p| !p.is_nan() && keep(p))
            .collect();
        let shape = r.shape().to_vec();
        let a = v.into_pyarray(py);
        a.reshape([shape[0], shape[1]])
    }
}

/// Checks an occupancy threshold argument: a probability in (0, 1].
fn threshold_arg(what: &str, t: f64) -> PyResult<f64> {
    if t > 0.0 && t <= 1.0 {
        Ok(t)
    } else {
        Err(Error::invalid(what, format!("{t} is not a probability in (0, 1]")).into())
    }
}

#[pymethods]
impl PyGrid {
    /// Occupancy probability per cell, (height, width) float32, NaN unknown.
    #[getter]
    fn probability<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f32>> {
        self.probability.bind(py).clone()
    }

    /// Centre height (metres) of the highest occupied voxel per cell,
    /// (height, width) float32, NaN where none.
    #[getter]
    fn top_z<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f32>> {
        self.top_z.bind(py).clone()
    }

    /// (x, y) of the lower-left corner of cell [0, 0], world frame, metres.
    #[getter]
    fn origin(&self) -> (f64, f64) {
        (self.origin[0], self.origin[1])
    }

    /// Cell edge length (metres).
    #[getter]
    fn resolution(&self) -> f64 {
        self.resolution
    }

    /// Number of columns (cells along x).
    #[getter]
    fn width(&self) -> usize {
        self.width
    }

    /// Number of rows (cells along y).
    #[getter]
    fn height(&self) -> usize {
        self.height
    }

    /// The band (z_min, z_max) of voxel centres projected (metres).
    #[getter]
    fn z_band(&self) -> (f64, f64) {
        (self.z_band[0], self.z_band[1])
    }

    /// Cells whose probability is at least `threshold` (the octree's own
    /// rule, 0.5, by default; compared in float32, the cells' type),
    /// (height, width) bool.
    #[pyo3(signature = (threshold=0.5))]
    fn occupied<'py>(
        &self,
        py: Python<'py>,
        threshold: f64,
    ) -> PyResult<Bound<'py, PyArray2<bool>>> {
        let t = threshold_arg("threshold", threshold)? as f32;
        self.mask(py, |p| p >= t)
    }

    /// Known cells whose probability is below `threshold`, (height, width) bool.
    #[pyo3(signature = (threshold=0.5))]
    fn free<'py>(&self, py: Python<'py>, threshold: f64) -> PyResult<Bound<'py, PyArray2<bool>>> {
        let t = threshold_arg("threshold", threshold)? as f32;
        self.mask(py, |p| p < t)
    }

    /// Writes nav2 `map_server` files: for a folder, `map.pgm`, `map.yaml` and
    /// `map_height.npy` in it; otherwise `path` is a prefix (`out/floor` ->
    /// `out/floor.pgm`, ...). Cells of probability >= `occupied_threshold`
    /// are occupied. Returns the (image, yaml, height) paths.
    #[pyo3(signature = (path, *, occupied_threshold=0.5))]
    fn write_nav2(
        &self,
        py: Python<'_>,
        path: PathBuf,
        occupied_threshold: f64,
    ) -> PyResult<(PathBuf, PathBuf, PathBuf)> {
        let g = self.to_core(py)?;
        let f = py.detach(|| nav2::write_nav2(&g, &path, occupied_threshold))?;
        Ok((f.image, f.yaml, f.height))
    }

    /// One message of the grid: `kind` "ros1" / "ros2" (nav_msgs/OccupancyGrid,
    /// cells in percent, or trinary 0 / 100 when `occupied_threshold` is
    /// given) or "foxglove" (foxglove.Grid with probability and top_z).
    /// Returns (schema name, schema encoding, schema data, message encoding,
    /// message bytes), as an MCAP channel carries them.
    #[pyo3(signature = (kind, *, stamp=0.0, frame_id="world", occupied_threshold=None))]
    #[allow(clippy::type_complexity)]
    fn encode<'py>(
        &self,
        py: Python<'py>,
        kind: &str,
        stamp: f64,
        frame_id: &str,
        occupied_threshold: Option<f64>,
    ) -> PyResult<(
        &'static str,
        &'static str,
        Bound<'py, PyBytes>,
        &'static str,
        Bound<'py, PyBytes>,
    )> {
        let values = match occupied_threshold {
            Some(t) => CellValues::Trinary {
                occupied: threshold_arg("occupied_threshold", t)?,
            },
            None => CellValues::Probability,
        };
        let g = self.to_core(py)?;
        let (schema, encoding, data) = match kind {
            "ros1" => (
                grid_msgs::ROS1_OCCUPANCY_GRID,
                "ros1",
                grid_msgs::occupancy_grid_ros1(&g, 0, stamp, frame_id, values)?,
            ),
            "ros2" => (
                grid_msgs::ROS2_OCCUPANCY_GRID,
                "cdr",
                grid_msgs::occupancy_grid_cdr(&g, stamp, frame_id, values)?,
            ),
            "foxglove" => {
                if occupied_threshold.is_some() {
                    return Err(Error::invalid(
                        "occupied_threshold",
                        "foxglove.Grid carries the probability itself",
                    )
                    .into());
                }
                (
                    grid_msgs::FOXGLOVE_GRID,
                    "protobuf",
                    grid_msgs::foxglove_grid(&g, stamp, frame_id)?,
                )
            }
            other => {
                return Err(Error::invalid(
                    "kind",
                    format!("'{other}' is not one of 'ros1', 'ros2', 'foxglove'"),
                )
                .into())
            }
        };
        Ok((
            schema.0,
            schema.1,
            PyBytes::new(py, schema.2),
            encoding,
            PyBytes::new(py, &data),
        ))
    }

    fn __repr__(&self) -> String {
        format!(
            "Grid(width={}, height={}, resolution={}, origin=({}, {}), z_band=({}, {}))",
            self.width,
            self.height,
            self.resolution,
            self.origin[0],
            self.origin[1],
            self.z_band[0],
            self.z_band[1]
        )
    }
}

/// Reads an OctoMap `.bt` file.
#[pyfunction(name = "read_bt")]
fn read_bt(py: Python<'_>, path: PathBuf) -> PyResult<PyOccupancyMap> {
    let inner = py.detach(|| OccupancyMap::read_bt(&path, MapParams::new(0.1)))?;
    Ok(PyOccupancyMap::from_core(inner))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyOccupancyMap>()?;
    m.add_class::<PyGrid>()?;
    m.add_function(wrap_pyfunction!(read_bt, m)?)?;
    Ok(())
}
