//! Trajectories for Python: `Trajectory` (reading and writing TUM / EuRoC /
//! KITTI files), `associate`, `scale_factors`; `transforms.json` scenes.

use std::path::PathBuf;
use std::sync::Arc;

use nalgebra::UnitQuaternion;
use numpy::{IntoPyArray, PyArray1, PyArray2, ToPyArray};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use super::arrays::{flat, rows_f64, to_array2, vec_f64, vectors};
use super::geometry::PySim3;
use crate::error::Error;
use crate::geometry::unit_quaternion_xyzw;
use crate::io::{kitti, text, transforms};
use crate::trajectory::{associate, scale_factors, Trajectory};

/// Timestamped positions (seconds, metres) with optional orientations `(x, y, z, w)`.
#[pyclass(name = "Trajectory", module = "slam2world._slam2world", frozen)]
pub struct PyTrajectory {
    /// Shared with the `Log` (or conversion) it came from: reading
    /// `log.reference` copies no poses.
    pub inner: Arc<Trajectory>,
}

#[pymethods]
impl PyTrajectory {
    #[new]
    #[pyo3(signature = (timestamps, positions, orientations=None))]
    fn new(
        timestamps: &Bound<'_, PyAny>,
        positions: &Bound<'_, PyAny>,
        orientations: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let t = vec_f64(timestamps, "timestamps", None)?;
        let p = vectors(positions, "positions")?;
        let o = match orientations {
            None => None,
            Some(o) => {
                let v = rows_f64(o, "orientations", 4)?;
                let q: Result<Vec<UnitQuaternion<f64>>, Error> = v
                    .chunks_exact(4)
                    .enumerate()
                    .map(|(i, r)| {
                        unit_quaternion_xyzw([r[0], r[1], r[2], r[3]])
                            .map_err(|e| Error::invalid("orientations", format!("row {i}: {e}")))
                    })
                    .collect();
                Some(q?)
            }
        };
        Ok(PyTrajectory {
            inner: Trajectory::try_new(t, p, o)?.into(),
        })
    }

    /// Reads a TUM file (`timestamp tx ty tz qx qy qz qw`).
    #[staticmethod]
    fn read_tum(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let inner = py.detach(|| text::read_tum(&path))?;
        Ok(PyTrajectory {
            inner: inner.into(),
        })
    }

    /// Reads EuRoC ground truth CSV (ns, x, y, z, qw, qx, qy, qz, …).
    #[staticmethod]
    fn read_euroc(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let inner = py.detach(|| text::read_euroc(&path))?;
        Ok(PyTrajectory {
            inner: inner.into(),
        })
    }

    /// Writes a TUM file (atomically: a temporary file renamed into place).
    fn write_tum(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        Ok(py.detach(|| text::write_tum(&self.inner, &path))?)
    }

    /// Reads a KITTI pose file (the 12 numbers of `[R | t]` a line). Stamps:
    /// `times`, a `times.txt` path or an array of seconds (one a pose); or
    /// `rate`, poses per second; or neither, the pose index (pose i at i s).
    #[staticmethod]
    #[pyo3(signature = (path, *, times=None, rate=None))]
    fn read_kitti(
        py: Python<'_>,
        path: PathBuf,
        times: Option<&Bound<'_, PyAny>>,
        rate: Option<f64>,
    ) -> PyResult<Self> {
        let stamps = match (times, rate) {
            (Some(_), Some(_)) => {
                return Err(Error::invalid("times", "give times or rate, not both").into())
            }
            (Some(t), None) => match t.extract::<PathBuf>() {
                Ok(p) => kitti::KittiStamps::Times(py.detach(|| kitti::read_times(&p))?),
                Err(_) => kitti::KittiStamps::Times(vec_f64(t, "times", None)?),
            },
            (None, Some(r)) => kitti::KittiStamps::Rate(r),
            (None, None) => kitti::KittiStamps::Index,
        };
        let inner = py.detach(|| kitti::read_kitti(&path, &stamps))?;
        Ok(PyTrajectory {
            inner: inner.into(),
        })
    }

    /// Writes a KITTI pose file (atomically); with `times`, the stamps too,
    /// as a `times.txt` at that path (KITTI files hold none).
    #[pyo3(signature = (path, *, times=None))]
    fn write_kitti(&self, py: Python<'_>, path: PathBuf, times: Option<PathBuf>) -> PyResult<()> {
        py.detach(|| -> crate::error::Result<()> {
            kitti::write_kitti(&self.inner, &path)?;
            if let Some(t) = &times {
                crate::io::atomic::write_bytes_atomic(t, &kitti::times_bytes(&self.inner))?;
            }
            Ok(())
        })?;
        Ok(())
    }

    /// Times, seconds, shape (N,).
    #[getter]
    fn timestamps<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.timestamps.to_pyarray(py)
    }

    /// Positions, shape (N, 3).
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        to_array2(py, flat(&self.inner.positions), 3)
    }

    /// Orientations `(x, y, z, w)`, shape (N, 4), or None.
    #[getter]
    fn orientations<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArray2<f64>>>> {
        match &self.inner.orientations {
            None => Ok(None),
            Some(o) => {
                let v: Vec<f64> = o
                    .iter()
                    .flat_map(|q| [q.coords[0], q.coords[1], q.coords[2], q.coords[3]])
                    .collect();
                Ok(Some(to_array2(py, v, 4)?))
            }
        }
    }

    /// Poses at `times` (lerp + slerp); raises outside the covered range or
    /// inside a gap longer than `max_gap` seconds.
    #[pyo3(signature = (times, max_gap=0.1))]
    fn interpolate(&self, times: &Bound<'_, PyAny>, max_gap: f64) -> PyResult<Self> {
        let t = vec_f64(times, "times", None)?;
        Ok(PyTrajectory {
            inner: self.inner.interpolate(&t, max_gap)?.into(),
        })
    }

    /// Like `interpolate`, but skips the times it cannot answer: returns
    /// `(trajectory, kept, missing)` with index arrays into `times`.
    #[pyo3(signature = (times, max_gap=0.1))]
    fn interpolate_where_covered<'py>(
        &self,
        py: Python<'py>,
        times: &Bound<'py, PyAny>,
        max_gap: f64,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let t = vec_f64(times, "times", None)?;
        let r = self.inner.interpolate_where_covered(&t, max_gap)?;
        let kept: Vec<i64> = r.kept.iter().map(|&i| i as i64).collect();
        let missing: Vec<i64> = r.missing.iter().map(|&i| i as i64).collect();
        let traj = Bound::new(
            py,
            PyTrajectory {
                inner: r.trajectory.into(),
            },
        )?;
        PyTuple::new(
            py,
            [
                traj.into_any(),
                kept.into_pyarray(py).into_any(),
                missing.into_pyarray(py).into_any(),
            ],
        )
    }

    /// Poses mapped by `transform` (`T_world_slam · T_slam_cam`).
    fn transformed(&self, transform: PyRef<'_, PySim3>) -> Self {
        PyTrajectory {
            inner: self.inner.transformed(&transform.inner).into(),
        }
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }

    fn __repr__(&self) -> String {
        let t = &self.inner.timestamps;
        match (t.first(), t.last()) {
            (Some(a), Some(b)) => format!(
                "Trajectory({} poses, {a:.6}..{b:.6} s, orientations={})",
                t.len(),
                self.inner.orientations.is_some()
            ),
            _ => "Trajectory(0 poses)".into(),
        }
    }

    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let py = slf.py();
        let this = slf.get();
        let args = (
            this.timestamps(py),
            this.positions(py)?,
            this.orientations(py)?,
        );
        PyTuple::new(
            py,
            [
                slf.get_type().into_any(),
                args.into_pyobject(py)?.into_any(),
            ],
        )
    }
}

pub(crate) fn index_arrays<'py>(
    py: Python<'py>,
    pairs: &[(usize, usize)],
) -> PyResult<Bound<'py, PyTuple>> {
    let a: Vec<i64> = pairs.iter().map(|&(i, _)| i as i64).collect();
    let b: Vec<i64> = pairs.iter().map(|&(_, j)| j as i64).collect();
    PyTuple::new(py, [a.into_pyarray(py), b.into_pyarray(py)])
}

/// Indices `(idx_a, idx_b)` of poses matched by time as evo does (`offset`
/// seconds added to `b`'s stamps; nearest stamp within `max_diff`).
#[pyfunction(name = "associate")]
#[pyo3(signature = (a, b, *, max_diff=0.01, offset=0.0))]
fn associate_py<'py>(
    py: Python<'py>,
    a: PyRef<'py, PyTrajectory>,
    b: PyRef<'py, PyTrajectory>,
    max_diff: f64,
    offset: f64,
) -> PyResult<Bound<'py, PyTuple>> {
    let pairs = associate(&a.inner, &b.inner, max_diff, offset);
    index_arrays(py, &pairs)
}

/// The paper's frame-to-frame factors `p_k = ‖t'_{k+1} − t'_k‖² / ‖t_{k+1} − t_k‖²`
/// (`t'` reference, `t` SLAM), shape (N−1,); about `s²`.
#[pyfunction(name = "scale_factors")]
fn scale_factors_py<'py>(
    py: Python<'py>,
    slam_positions: &Bound<'py, PyAny>,
    reference_positions: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let s = vectors(slam_positions, "slam_positions")?;
    let r = vectors(reference_positions, "reference_positions")?;
    Ok(scale_factors(&s, &r)?.into_pyarray(py))
}

/// Reads a nerfstudio / instant-ngp `transforms.json`: the camera poses
/// (OpenGL cameras turned to the project's: y down, looking along +z),
/// stamped by the frames' file names when every one is a stamp, else by the
/// frame order; and the `file_path` of each pose, in the trajectory's order.
#[pyfunction(name = "read_transforms")]
fn read_transforms_py(py: Python<'_>, path: PathBuf) -> PyResult<(PyTrajectory, Vec<String>)> {
    let (traj, names) = py.detach(|| -> crate::error::Result<_> {
        let scene = transforms::read_transforms(&path)?;
        let names = scene
            .stamped()
            .1
            .iter()
            .map(|f| f.file_path.clone())
            .collect();
        Ok((scene.trajectory()?, names))
    })?;
    Ok((PyTrajectory { inner: traj.into() }, names))
}

/// Writes the `transforms.json` at `source` to `path` (atomically) with every
/// `transform_matrix` carried by `transform` and every other key kept.
#[pyfunction(name = "write_transforms")]
fn write_transforms_py(
    py: Python<'_>,
    source: PathBuf,
    path: PathBuf,
    transform: &PySim3,
) -> PyResult<()> {
    let t = transform.inner;
    py.detach(|| -> crate::error::Result<()> {
        let mut outputs = crate::io::atomic::OutputSet::new().with_inputs([&source]);
        outputs.check_output(&path)?;
        let bytes = transforms::read_transforms(&source)?.carried_bytes(&t)?;
        outputs.write_bytes(&path, &bytes)?;
        outputs.commit()?;
        Ok(())
    })?;
    Ok(())
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyTrajectory>()?;
    m.add_function(wrap_pyfunction!(read_transforms_py, m)?)?;
    m.add_function(wrap_pyfunction!(write_transforms_py, m)?)?;
    m.add_function(wrap_pyfunction!(associate_py, m)?)?;
    m.add_function(wrap_pyfunction!(scale_factors_py, m)?)?;
    Ok(())
}
