//! `OccupancyMap` for Python: numpy in and out, the GIL released while
//! inserting and querying.

use std::collections::BTreeMap;
use std::path::PathBuf;

use numpy::{AllowTypeChange, IntoPyArray, PyArray1, PyArray2, PyArrayLike1};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::arrays::{c_slice, rows_f64, to_array2, vector3, Points};
use crate::error::Error;
use crate::map::{MapParams, OccupancyMap, VoxelState};

/// An occupancy octree with OctoMap's semantics (`.bt` / `.ot` compatible).
#[pyclass(name = "OccupancyMap", module = "slam2world._slam2world")]
pub struct PyOccupancyMap {
    inner: OccupancyMap,
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
        Ok(PyOccupancyMap { inner })
    }

    /// Inserts one scan of `(N, 3)` points (metres) seen from `origin`;
    /// returns the numbers of voxels updated as (free, occupied).
    fn insert(
        &mut self,
        py: Python<'_>,
        points: &Bound<'_, PyAny>,
        origin: &Bound<'_, PyAny>,
    ) -> PyResult<(usize, usize)> {
        let pts = points_f32(points, "points")?;
        let o = origin_f32(origin, "origin")?;
        let inner = &mut self.inner;
        let u = py.detach(|| inner.insert_scan(&pts, o))?;
        Ok((u.free, u.occupied))
    }

    /// Inserts a converted cloud, each point seen from its keyframe's camera
    /// centre: `keyframe_ids` (N,) int, `origins` maps id to a 3-vector.
    fn insert_keyframes(
        &mut self,
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
            let id: i32 = k.extract()?;
            o.insert(id, origin_f32(&v, "origins")?);
        }
        let inner = &mut self.inner;
        let u = py.detach(|| inner.insert_keyframes(&pts, &ids, &o))?;
        Ok((u.free, u.occupied))
    }

    /// State per point: -1 unknown, 0 free, 1 occupied.
    fn state<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<i8>>> {
        let q = query_points(points)?;
        let out: Vec<i8> = py.detach(|| q.iter().map(|p| self.inner.state(*p) as i8).collect());
        Ok(out.into_pyarray(py))
    }

    /// Occupancy probability per point, NaN where unknown.
    fn occupancy<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let q = query_points(points)?;
        let out: Vec<f64> = py.detach(|| {
            q.iter()
                .map(|p| self.inner.occupancy(*p).unwrap_or(f64::NAN))
                .collect()
        });
        Ok(out.into_pyarray(py))
    }

    /// Centres (M, 3) of every occupied voxel at full resolution.
    fn occupied_centers<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let c = py.detach(|| self.inner.voxel_centers(VoxelState::Occupied));
        centers_array(py, c)
    }

    /// Centres (M, 3) of every free voxel at full resolution.
    fn free_centers<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let c = py.detach(|| self.inner.voxel_centers(VoxelState::Free));
        centers_array(py, c)
    }

    /// Occupied leaves as (centres (M, 3), edge lengths (M,)).
    fn occupied_leaves<'py>(&self, py: Python<'py>) -> PyResult<Leaves<'py>> {
        let l = py.detach(|| self.inner.leaves(VoxelState::Occupied));
        leaves_arrays(py, l)
    }

    /// Free leaves as (centres (M, 3), edge lengths (M,)).
    fn free_leaves<'py>(&self, py: Python<'py>) -> PyResult<Leaves<'py>> {
        let l = py.detach(|| self.inner.leaves(VoxelState::Free));
        leaves_arrays(py, l)
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
        let hit = py.detach(|| self.inner.cast_ray(o, d, max_range, ignore_unknown))?;
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
        Ok(py.detach(|| self.inner.collides_sphere(c, radius))?)
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
        Ok(py.detach(|| self.inner.collides_box(c, h))?)
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
        Ok(py.detach(|| self.inner.segment_is_free(a, b, radius))?)
    }

    /// Writes an OctoMap `.bt` file (maximum-likelihood tree).
    fn write_bt(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        Ok(py.detach(|| self.inner.write_bt(&path))?)
    }

    /// Writes an OctoMap `.ot` file (full log-odds tree).
    fn write_ot(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        Ok(py.detach(|| self.inner.write_ot(&path))?)
    }

    /// Reads an OctoMap `.bt` file (default sensor model, the file's resolution).
    #[staticmethod]
    fn read_bt(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        read_bt(py, path)
    }

    /// Voxel edge length (metres).
    #[getter]
    fn resolution(&self) -> f64 {
        self.inner.resolution()
    }

    /// Number of leaves.
    #[getter]
    fn num_leaf_nodes(&self) -> usize {
        self.inner.num_leaf_nodes()
    }

    /// Number of nodes, inner and leaf.
    #[getter]
    fn num_nodes(&self) -> usize {
        self.inner.num_nodes()
    }

    /// Heap bytes held by the tree.
    #[getter]
    fn memory_bytes(&self) -> usize {
        self.inner.memory_bytes()
    }

    fn __repr__(&self) -> String {
        format!(
            "OccupancyMap(resolution={}, num_nodes={})",
            self.inner.resolution(),
            self.inner.num_nodes()
        )
    }
}

impl PyOccupancyMap {
    /// Wraps a map built in Rust (e.g. by `convert`).
    pub(crate) fn from_core(inner: OccupancyMap) -> Self {
        PyOccupancyMap { inner }
    }

    /// The core map.
    pub(crate) fn core(&self) -> &OccupancyMap {
        &self.inner
    }
}

/// Reads an OctoMap `.bt` file.
#[pyfunction(name = "read_bt")]
fn read_bt(py: Python<'_>, path: PathBuf) -> PyResult<PyOccupancyMap> {
    let inner = py.detach(|| OccupancyMap::read_bt(&path, MapParams::new(0.1)))?;
    Ok(PyOccupancyMap { inner })
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyOccupancyMap>()?;
    m.add_function(wrap_pyfunction!(read_bt, m)?)?;
    Ok(())
}
