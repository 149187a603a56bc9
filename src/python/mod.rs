//! PyO3 bindings (feature `python`): thin wrappers over the core, one error
//! mapping (`errors.rs`), array conversion in `convert.rs`.

use pyo3::prelude::*;

mod cli;
mod convert;
mod errors;
mod geometry;
mod map;

#[pymodule]
fn _slam2world(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    errors::register(m)?;
    geometry::register(m)?;
    map::register(m)?;
    cli::register(m)?;
    Ok(())
}
