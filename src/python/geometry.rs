//! `Sim3` for Python.

use nalgebra::Vector3;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, ToPyArray};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use super::arrays::{c_slice, matrix3, matrix4, matrix_to_array, vec_f64, vector3, Points};
use crate::geometry::{rotation_from_matrix, PointScalar, Sim3};

/// A similarity transform `p ↦ s·R·p + t`; `T_a_b` maps frame-b coordinates into frame a.
#[pyclass(
    name = "Sim3",
    module = "slam2world._slam2world",
    frozen,
    from_py_object
)]
#[derive(Clone)]
pub struct PySim3 {
    pub inner: Sim3,
}

impl From<Sim3> for PySim3 {
    fn from(inner: Sim3) -> Self {
        PySim3 { inner }
    }
}

fn apply_typed<T: PointScalar + numpy::Element>(
    py: Python<'_>,
    t: &Sim3,
    src: &[T],
) -> PyResult<Py<PyAny>> {
    // The core allocates the output (huge-page hint, written once, no zero
    // fill) in parallel without the GIL; NumPy takes the vector over, no copy.
    let out = py.detach(|| t.transform_points(src))?;
    let n = out.len() / 3;
    let arr = Array2::from_shape_vec((n, 3), out)
        .map_err(|e| PyErr::from(crate::error::Error::invalid("points", e.to_string())))?;
    Ok(arr.into_pyarray(py).into_any().unbind())
}

/// Maps `(N, 3)` points, keeping float32 as float32; the GIL is released.
pub fn apply_points(py: Python<'_>, t: &Sim3, points: &Bound<'_, PyAny>) -> PyResult<Py<PyAny>> {
    match Points::extract(points, "points")? {
        Points::F32(a) => match c_slice(&a) {
            Some(s) => apply_typed(py, t, s),
            None => apply_typed(
                py,
                t,
                &contiguous(a.as_array().iter().copied(), a.as_array().len())?,
            ),
        },
        Points::F64(a) => match c_slice(&a) {
            Some(s) => apply_typed(py, t, s),
            None => apply_typed(
                py,
                t,
                &contiguous(a.as_array().iter().copied(), a.as_array().len())?,
            ),
        },
    }
}

/// A contiguous copy of a strided array's `n` values: `MemoryError` (not an
/// abort) when it does not fit (a broadcast view of 120 M rows is 2.9 GB).
fn contiguous<T>(values: impl Iterator<Item = T>, n: usize) -> PyResult<Vec<T>> {
    let mut v = crate::buffer::try_with_capacity("points (a contiguous copy)", n)?;
    v.extend(values);
    Ok(v)
}

#[pymethods]
impl PySim3 {
    #[new]
    #[pyo3(signature = (rotation=None, translation=None, scale=1.0))]
    fn new(
        rotation: Option<&Bound<'_, PyAny>>,
        translation: Option<&Bound<'_, PyAny>>,
        scale: f64,
    ) -> PyResult<Self> {
        let r = match rotation {
            Some(r) => rotation_from_matrix(&matrix3(r, "rotation")?)?,
            None => nalgebra::UnitQuaternion::identity(),
        };
        let t = match translation {
            Some(t) => vector3(t, "translation")?,
            None => Vector3::zeros(),
        };
        Ok(Sim3::try_new(r, t, scale)?.into())
    }

    /// The identity transform.
    #[staticmethod]
    fn identity() -> Self {
        Sim3::identity().into()
    }

    /// From a 4×4 matrix `[[sR, t], [0, 1]]`.
    #[staticmethod]
    fn from_matrix(m: &Bound<'_, PyAny>) -> PyResult<Self> {
        Ok(Sim3::from_matrix(&matrix4(m, "matrix")?)?.into())
    }

    /// From a quaternion `(x, y, z, w)` (normalised here), a translation and a scale.
    #[staticmethod]
    #[pyo3(signature = (quaternion, translation=None, scale=1.0))]
    fn from_quaternion(
        quaternion: &Bound<'_, PyAny>,
        translation: Option<&Bound<'_, PyAny>>,
        scale: f64,
    ) -> PyResult<Self> {
        let q = vec_f64(quaternion, "quaternion", Some(4))?;
        let t = match translation {
            Some(t) => vector3(t, "translation")?,
            None => Vector3::zeros(),
        };
        Ok(Sim3::from_quaternion_xyzw([q[0], q[1], q[2], q[3]], t, scale)?.into())
    }

    /// From LSD-SLAM's `camToWorld` `[qx, qy, qz, qw, tx, ty, tz]` (scale = ‖q‖).
    #[staticmethod]
    fn from_lsd_slam(cam_to_world: &Bound<'_, PyAny>) -> PyResult<Self> {
        let v = vec_f64(cam_to_world, "cam_to_world", Some(7))?;
        let a: [f64; 7] = [v[0], v[1], v[2], v[3], v[4], v[5], v[6]];
        Ok(Sim3::from_lsd_slam(&a)?.into())
    }

    /// LSD-SLAM's `camToWorld` layout: `[s·qx, s·qy, s·qz, s·qw, tx, ty, tz]`.
    fn to_lsd_slam<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.to_lsd_slam().to_pyarray(py)
    }

    /// Rotation matrix `R`, shape (3, 3).
    #[getter]
    fn rotation<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        matrix_to_array(py, &self.inner.rotation_matrix())
    }

    /// Rotation as a unit quaternion `(x, y, z, w)` with `w ≥ 0`.
    #[getter]
    fn quaternion<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.quaternion_xyzw().to_pyarray(py)
    }

    /// Translation `t`, shape (3,).
    #[getter]
    fn translation<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.translation.as_slice().to_pyarray(py)
    }

    /// Scale `s`.
    #[getter]
    fn scale(&self) -> f64 {
        self.inner.scale
    }

    /// The 4×4 matrix `[[sR, t], [0, 1]]`.
    fn matrix<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        matrix_to_array(py, &self.inner.matrix())
    }

    /// The inverse transform.
    fn inverse(&self) -> Self {
        self.inner.inverse().into()
    }

    fn __matmul__(&self, other: PyRef<'_, PySim3>) -> Self {
        (self.inner * other.inner).into()
    }

    /// Maps `(N, 3)` points; float32 in gives float32 out, anything else float64.
    fn apply(&self, py: Python<'_>, points: &Bound<'_, PyAny>) -> PyResult<Py<PyAny>> {
        apply_points(py, &self.inner, points)
    }

    fn __repr__(&self) -> String {
        let q = self.inner.quaternion_xyzw();
        let t = self.inner.translation;
        format!(
            "Sim3(quaternion=[{:.6}, {:.6}, {:.6}, {:.6}], translation=[{:.6}, {:.6}, {:.6}], scale={:.9})",
            q[0], q[1], q[2], q[3], t.x, t.y, t.z, self.inner.scale
        )
    }

    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let py = slf.py();
        let this = slf.get();
        let args = (this.rotation(py)?, this.translation(py), this.inner.scale);
        PyTuple::new(
            py,
            [
                slf.get_type().into_any(),
                args.into_pyobject(py)?.into_any(),
            ],
        )
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySim3>()?;
    Ok(())
}
