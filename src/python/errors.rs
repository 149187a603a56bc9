//! The one place where core errors become Python exceptions.
//!
//! Classes (module `slam2world._slam2world`, re-exported by `slam2world`):
//! - `Slam2WorldError(Exception)`: base of everything below;
//! - `InvalidInputError(Slam2WorldError, ValueError)`: shapes, NaN/inf, bad arguments, out-of-range queries;
//! - `DegenerateError(InvalidInputError)`: input whose geometry does not determine the answer;
//! - `FormatError(Slam2WorldError, ValueError)`: malformed files and logs;
//! - `FileError(Slam2WorldError, OSError)`: files that cannot be opened or written;
//!
//! and an interrupted run (SIGINT, SIGTERM) raises `KeyboardInterrupt`.

use pyo3::exceptions::{PyException, PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple, PyType};

use crate::error::Error;

const MODULE: &str = "slam2world._slam2world";

struct Classes {
    base: Py<PyType>,
    invalid: Py<PyType>,
    degenerate: Py<PyType>,
    format: Py<PyType>,
    file: Py<PyType>,
}

static CLASSES: PyOnceLock<Classes> = PyOnceLock::new();

fn make_class<'py>(
    py: Python<'py>,
    name: &str,
    doc: &str,
    bases: &[Bound<'py, PyType>],
) -> PyResult<Py<PyType>> {
    let dict = PyDict::new(py);
    dict.set_item("__module__", MODULE)?;
    dict.set_item("__doc__", doc)?;
    let bases = PyTuple::new(py, bases)?;
    let builtins = py.import("builtins")?;
    let cls = builtins.getattr("type")?.call1((name, bases, dict))?;
    Ok(cls.cast_into::<PyType>()?.unbind())
}

fn classes(py: Python<'_>) -> PyResult<&Classes> {
    CLASSES.get_or_try_init(py, || {
        let exc = py.get_type::<PyException>();
        let value = py.get_type::<PyValueError>();
        let os = py.get_type::<PyOSError>();
        let base = make_class(py, "Slam2WorldError", "Base class of every slam2world error.", &[exc])?;
        let b = base.bind(py).clone();
        let invalid = make_class(
            py,
            "InvalidInputError",
            "An argument of the wrong shape, a non-finite value, or a value outside its domain.",
            &[b.clone(), value.clone()],
        )?;
        let degenerate = make_class(
            py,
            "DegenerateError",
            "Input whose geometry does not determine the answer (coincident or collinear points, no motion).",
            &[invalid.bind(py).clone()],
        )?;
        let format = make_class(
            py,
            "FormatError",
            "A file or log whose content is malformed or of an unknown schema.",
            &[b.clone(), value],
        )?;
        let file = make_class(
            py,
            "FileError",
            "A file that cannot be opened, read or written.",
            &[b, os],
        )?;
        Ok(Classes {
            base,
            invalid,
            degenerate,
            format,
            file,
        })
    })
}

/// Adds the exception classes to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    let c = classes(py)?;
    m.add("Slam2WorldError", c.base.bind(py))?;
    m.add("InvalidInputError", c.invalid.bind(py))?;
    m.add("DegenerateError", c.degenerate.bind(py))?;
    m.add("FormatError", c.format.bind(py))?;
    m.add("FileError", c.file.bind(py))?;
    Ok(())
}

impl From<Error> for PyErr {
    fn from(err: Error) -> PyErr {
        Python::attach(|py| {
            let c = match classes(py) {
                Ok(c) => c,
                Err(e) => return e,
            };
            let cls = match &err {
                Error::ShapeMismatch { .. }
                | Error::NonFinite { .. }
                | Error::TooFew { .. }
                | Error::Unmatched { .. }
                | Error::InvalidArgument { .. }
                | Error::OutOfRange { .. }
                | Error::GravityTilted { .. }
                | Error::InvalidFix { .. }
                | Error::TooLarge { .. } => &c.invalid,
                Error::Degenerate { .. }
                | Error::StaticReference { .. }
                | Error::UnexplainedSpread { .. }
                | Error::NothingFitted { .. } => &c.degenerate,
                Error::Parse { .. }
                | Error::Mcap { .. }
                | Error::Decode { .. }
                | Error::BinaryFormat { .. }
                | Error::Reconstruction { .. }
                | Error::Bag { .. }
                | Error::Container { .. } => &c.format,
                Error::Io { source, .. } => {
                    // OSError(errno, strerror) keeps .errno usable; without an errno,
                    // the message alone (not "[Errno None] ...").
                    return match source.raw_os_error() {
                        Some(errno) => {
                            PyErr::from_type(c.file.bind(py).clone(), (errno, err.to_string()))
                        }
                        None => PyErr::from_type(c.file.bind(py).clone(), err.to_string()),
                    };
                }
                Error::Output { .. } => &c.file,
                Error::OutOfMemory { .. } => {
                    return pyo3::exceptions::PyMemoryError::new_err(err.to_string())
                }
                Error::Interrupted { .. } => {
                    return pyo3::exceptions::PyKeyboardInterrupt::new_err(err.to_string())
                }
            };
            PyErr::from_type(cls.bind(py).clone(), err.to_string())
        })
    }
}
