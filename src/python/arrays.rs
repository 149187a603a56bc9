//! Array conversion at the Python boundary: shapes checked, the argument named
//! in the error, C-contiguous data read without a copy where possible.

use nalgebra::{Matrix3, Matrix4, Vector3};
use numpy::ndarray::Array2;
use numpy::ndarray::Dimension;
use numpy::{
    AllowTypeChange, Element, IntoPyArray, PyArray2, PyArrayLike1, PyArrayLike2, PyArrayMethods,
    PyReadonlyArray, PyUntypedArrayMethods,
};
use pyo3::prelude::*;

use crate::error::Error;

/// The array's data as one row-major slice, or `None` when it is not
/// C-contiguous (`as_slice` also accepts Fortran order, whose slice would be
/// read column by column).
pub fn c_slice<'a, T: Element, D: Dimension>(a: &'a PyReadonlyArray<'_, T, D>) -> Option<&'a [T]> {
    if a.is_c_contiguous() {
        a.as_slice().ok()
    } else {
        None
    }
}

fn shape_err(what: &str, expected: &str, shape: &[usize]) -> PyErr {
    Error::ShapeMismatch {
        what: what.into(),
        expected: expected.into(),
        got: format!("{shape:?}"),
    }
    .into()
}

/// Any array-like as an `(N, cols)` row-major `f64` vector (copied).
pub fn rows_f64(obj: &Bound<'_, PyAny>, what: &str, cols: usize) -> PyResult<Vec<f64>> {
    let arr: PyArrayLike2<'_, f64, AllowTypeChange> = obj
        .extract()
        .map_err(|_| shape_err(what, &format!("a 2-D array of shape (N, {cols})"), &[]))?;
    let shape = arr.shape().to_vec();
    if shape[1] != cols {
        return Err(shape_err(what, &format!("(N, {cols})"), &shape));
    }
    let v: Vec<f64> = match c_slice(&arr) {
        Some(s) => s.to_vec(),
        None => arr.as_array().iter().copied().collect(),
    };
    crate::error::check_rows(what, &v, cols)?;
    Ok(v)
}

/// Any array-like as a 1-D `f64` vector (copied), optionally of a fixed length.
pub fn vec_f64(obj: &Bound<'_, PyAny>, what: &str, len: Option<usize>) -> PyResult<Vec<f64>> {
    let arr: PyArrayLike1<'_, f64, AllowTypeChange> = obj
        .extract()
        .map_err(|_| shape_err(what, "a 1-D array", &[]))?;
    let v: Vec<f64> = arr.as_array().iter().copied().collect();
    if let Some(n) = len {
        if v.len() != n {
            return Err(shape_err(what, &format!("({n},)"), &[v.len()]));
        }
    }
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(Error::NonFinite {
            what: what.into(),
            index: i,
        }
        .into());
    }
    Ok(v)
}

/// A 3-vector.
pub fn vector3(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vector3<f64>> {
    let v = vec_f64(obj, what, Some(3))?;
    Ok(Vector3::new(v[0], v[1], v[2]))
}

/// A 3×3 matrix from a row-major array-like.
pub fn matrix3(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Matrix3<f64>> {
    let v = rows_f64(obj, what, 3)?;
    if v.len() != 9 {
        return Err(shape_err(what, "(3, 3)", &[v.len() / 3, 3]));
    }
    Ok(Matrix3::from_row_slice(&v))
}

/// A 4×4 matrix from a row-major array-like.
pub fn matrix4(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Matrix4<f64>> {
    let v = rows_f64(obj, what, 4)?;
    if v.len() != 16 {
        return Err(shape_err(what, "(4, 4)", &[v.len() / 4, 4]));
    }
    Ok(Matrix4::from_row_slice(&v))
}

/// A row-major `(rows, cols)` `f64` buffer as a new NumPy array (no copy).
pub fn to_array2<'py, T: numpy::Element>(
    py: Python<'py>,
    data: Vec<T>,
    cols: usize,
) -> PyResult<Bound<'py, PyArray2<T>>> {
    let rows = data.len().checked_div(cols).unwrap_or(0);
    let a = Array2::from_shape_vec((rows, cols), data)
        .map_err(|e| PyErr::from(Error::invalid("array", e.to_string())))?;
    Ok(a.into_pyarray(py))
}

/// A nalgebra matrix as a row-major NumPy array.
pub fn matrix_to_array<'py, const R: usize, const C: usize>(
    py: Python<'py>,
    m: &nalgebra::SMatrix<f64, R, C>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let mut v = Vec::with_capacity(R * C);
    for r in 0..R {
        for c in 0..C {
            v.push(m[(r, c)]);
        }
    }
    to_array2(py, v, C)
}

/// Points as given: `float32` stays `float32`, anything else becomes `float64`.
pub enum Points<'py> {
    /// `float32` input, read without a copy.
    F32(numpy::PyReadonlyArray2<'py, f32>),
    /// `float64` (or converted) input.
    F64(PyArrayLike2<'py, f64, AllowTypeChange>),
}

impl<'py> Points<'py> {
    /// Extracts an `(N, 3)` point array.
    pub fn extract(obj: &Bound<'py, PyAny>, what: &str) -> PyResult<Self> {
        let p = if let Ok(a) = obj.cast::<PyArray2<f32>>() {
            Points::F32(a.readonly())
        } else {
            Points::F64(
                obj.extract()
                    .map_err(|_| shape_err(what, "a 2-D array of shape (N, 3)", &[]))?,
            )
        };
        let shape = match &p {
            Points::F32(a) => a.shape().to_vec(),
            Points::F64(a) => a.shape().to_vec(),
        };
        if shape[1] != 3 {
            return Err(shape_err(what, "(N, 3)", &shape));
        }
        Ok(p)
    }
}

/// Runs `f` on the row-major `(N, 3)` `f64` data of `obj`, borrowed without a
/// copy when it is a C-contiguous float64 array.
pub(crate) fn with_points<R>(
    obj: &Bound<'_, PyAny>,
    what: &str,
    f: impl FnOnce(&[f64]) -> PyResult<R>,
) -> PyResult<R> {
    let arr: PyArrayLike2<'_, f64, AllowTypeChange> = obj.extract().map_err(|_| {
        PyErr::from(Error::ShapeMismatch {
            what: what.into(),
            expected: "a 2-D array of shape (N, 3)".into(),
            got: "something else".into(),
        })
    })?;
    let shape = arr.shape();
    if shape[1] != 3 {
        return Err(Error::ShapeMismatch {
            what: what.into(),
            expected: "(N, 3)".into(),
            got: format!("{shape:?}"),
        }
        .into());
    }
    match c_slice(&arr) {
        Some(s) => f(s),
        None => {
            let v: Vec<f64> = arr.as_array().iter().copied().collect();
            f(&v)
        }
    }
}

pub(crate) fn vectors(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<Vector3<f64>>> {
    let v = rows_f64(obj, what, 3)?;
    Ok(v.chunks_exact(3)
        .map(|r| Vector3::new(r[0], r[1], r[2]))
        .collect())
}

pub(crate) fn flat(v: &[Vector3<f64>]) -> Vec<f64> {
    v.iter().flat_map(|p| [p.x, p.y, p.z]).collect()
}
