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

/// A shape as NumPy prints it: `(4, 4)`, `(3,)`, `()`.
pub fn shape_text(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|n| n.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

fn shape_err(what: &str, expected: &str, shape: &[usize]) -> PyErr {
    Error::ShapeMismatch {
        what: what.into(),
        expected: expected.into(),
        got: shape_text(shape),
    }
    .into()
}

/// What an argument that is not the array asked for is, for the error: its
/// shape when NumPy gives it one (`(4,)`, `(2, 3, 3)`, `()` for a number),
/// else its type (`a str`, a ragged list).
pub fn given(obj: &Bound<'_, PyAny>) -> String {
    // A string is no array of numbers, whatever shape numpy gives it (`()`).
    let text = obj.is_instance_of::<pyo3::types::PyString>()
        || obj.is_instance_of::<pyo3::types::PyBytes>();
    let shape = (!text)
        .then(|| {
            obj.getattr("shape").ok().or_else(|| {
                let np = obj.py().import("numpy").ok()?;
                np.call_method1("shape", (obj,)).ok()
            })
        })
        .flatten();
    match shape.and_then(|s| s.extract::<Vec<usize>>().ok()) {
        Some(s) => format!("shape {}", shape_text(&s)),
        None => {
            let t = obj
                .get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_else(|_| "?".into());
            format!("a {t} (not an array of numbers)")
        }
    }
}

/// Any array-like as an `(N, cols)` row-major `f64` vector (copied).
pub fn rows_f64(obj: &Bound<'_, PyAny>, what: &str, cols: usize) -> PyResult<Vec<f64>> {
    rows_f64_as(obj, what, cols, &format!("(N, {cols})"))
}

/// [`rows_f64`] whose error says `expected` (e.g. `(3, 3)` for a matrix).
fn rows_f64_as(
    obj: &Bound<'_, PyAny>,
    what: &str,
    cols: usize,
    expected: &str,
) -> PyResult<Vec<f64>> {
    let arr: PyArrayLike2<'_, f64, AllowTypeChange> = match obj.extract() {
        Ok(a) => a,
        Err(_) => {
            return Err(Error::ShapeMismatch {
                what: what.into(),
                expected: format!("a 2-D array of shape {expected}"),
                got: given(obj),
            }
            .into())
        }
    };
    let shape = arr.shape().to_vec();
    if shape[1] != cols {
        return Err(shape_err(what, expected, &shape));
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
    let arr: PyArrayLike1<'_, f64, AllowTypeChange> = match obj.extract() {
        Ok(a) => a,
        Err(_) => {
            return Err(Error::ShapeMismatch {
                what: what.into(),
                expected: match len {
                    Some(n) => format!("a 1-D array of shape ({n},)"),
                    None => "a 1-D array".into(),
                },
                got: given(obj),
            }
            .into())
        }
    };
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
    let v = rows_f64_as(obj, what, 3, "(3, 3)")?;
    if v.len() != 9 {
        return Err(shape_err(what, "(3, 3)", &[v.len() / 3, 3]));
    }
    Ok(Matrix3::from_row_slice(&v))
}

/// A 4×4 matrix from a row-major array-like.
pub fn matrix4(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Matrix4<f64>> {
    let v = rows_f64_as(obj, what, 4, "(4, 4)")?;
    if v.len() != 16 {
        return Err(shape_err(what, "(4, 4)", &[v.len() / 4, 4]));
    }
    Ok(Matrix4::from_row_slice(&v))
}

/// A Python int as an unsigned integer argument: a negative or too large
/// value is an `InvalidInputError` naming the argument and the range (PyO3
/// alone raises a bare `OverflowError`); a value that is no int keeps
/// PyO3's `TypeError` (which names the argument).
pub fn uint_arg<T>(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<T>
where
    T: TryFrom<i128> + num_max::Max,
{
    let v: i128 = match obj.extract() {
        Ok(v) => v,
        Err(e) if e.is_instance_of::<pyo3::exceptions::PyOverflowError>(obj.py()) => {
            return Err(Error::invalid(
                what,
                format!(
                    "expected an integer from 0 to {}, got a larger one",
                    T::MAX_TEXT
                ),
            )
            .into())
        }
        Err(e) => return Err(e),
    };
    T::try_from(v).map_err(|_| {
        Error::invalid(
            what,
            format!("expected an integer from 0 to {}, got {v}", T::MAX_TEXT),
        )
        .into()
    })
}

/// [`uint_arg`] that takes `None` as `None`.
pub fn opt_uint_arg<T>(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Option<T>>
where
    T: TryFrom<i128> + num_max::Max,
{
    if obj.is_none() {
        Ok(None)
    } else {
        uint_arg(obj, what).map(Some)
    }
}

/// The largest value of the unsigned types [`uint_arg`] gives, as text.
pub mod num_max {
    /// The largest value, as text.
    pub trait Max {
        /// `u32::MAX` etc. as text.
        const MAX_TEXT: &'static str;
    }
    impl Max for u8 {
        const MAX_TEXT: &'static str = "255";
    }
    impl Max for u32 {
        const MAX_TEXT: &'static str = "4294967295";
    }
    impl Max for u64 {
        const MAX_TEXT: &'static str = "18446744073709551615";
    }
    impl Max for usize {
        const MAX_TEXT: &'static str = if usize::BITS == 64 {
            "18446744073709551615"
        } else {
            "4294967295"
        };
    }
}

/// Extractors of unsigned arguments by name, for `#[pyo3(from_py_with = ...)]`
/// (the function does not learn the argument's name otherwise).
pub mod uint {
    use super::{opt_uint_arg, uint_arg};
    use pyo3::prelude::*;

    macro_rules! named {
        ($($f:ident: $t:ty = $name:literal;)*) => {$(
            #[doc = concat!("The argument `", $name, "`.")]
            pub fn $f(obj: &Bound<'_, PyAny>) -> PyResult<$t> {
                uint_arg(obj, $name)
            }
        )*};
    }
    macro_rules! named_opt {
        ($($f:ident: $t:ty = $name:literal;)*) => {$(
            #[doc = concat!("The argument `", $name, "` (or None).")]
            pub fn $f(obj: &Bound<'_, PyAny>) -> PyResult<Option<$t>> {
                opt_uint_arg(obj, $name)
            }
        )*};
    }
    named! {
        width: u32 = "width";
        height: u32 = "height";
        min_near_support: u32 = "min_near_support";
        sparsify: u32 = "sparsify";
        seed: u64 = "seed";
        min_count: u32 = "min_count";
        reduced: usize = "reduced";
        zone: u8 = "zone";
    }
    named_opt! {
        cut_first_keyframes: usize = "cut_first_keyframes";
        n_to_align: usize = "n_to_align";
        opt_zone: u8 = "zone";
    }
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
            Points::F64(obj.extract().map_err(|_| {
                PyErr::from(Error::ShapeMismatch {
                    what: what.into(),
                    expected: "a 2-D array of shape (N, 3)".into(),
                    got: given(obj),
                })
            })?)
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
            got: given(obj),
        })
    })?;
    let shape = arr.shape();
    if shape[1] != 3 {
        return Err(Error::ShapeMismatch {
            what: what.into(),
            expected: "(N, 3)".into(),
            got: shape_text(shape),
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
