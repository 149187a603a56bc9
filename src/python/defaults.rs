//! `DEFAULTS`: the defaults of [`crate::defaults`] as a dict, so that a test
//! can check the signatures and the stub against the Rust constants.

use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::defaults::{Value, TABLE};

/// Adds `DEFAULTS` (parameter name → default) to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let d = PyDict::new(m.py());
    for (name, v) in TABLE {
        match v {
            Value::Float(x) => d.set_item(name, x)?,
            Value::Int(x) => d.set_item(name, x)?,
            Value::Str(x) => d.set_item(name, x)?,
        }
    }
    m.add("DEFAULTS", d)?;
    Ok(())
}
