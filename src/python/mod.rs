//! PyO3 bindings (feature `python`): thin wrappers over the core, one error
//! mapping (`errors.rs`), array conversion in `convert.rs`.

use pyo3::prelude::*;

mod beyond;
mod cli;
mod cloud;
mod convert;
mod core;
mod errors;
mod geo;
mod geometry;
mod imu;
mod map;
mod mcap;
mod sim;

#[pymodule]
fn _slam2world(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    errors::register(m)?;
    geometry::register(m)?;
    sim::register(m)?;
    map::register(m)?;
    core::register(m)?;
    beyond::register(m)?;
    cloud::register(m)?;
    cli::register(m)?;
    mcap::register(m)?;
    imu::register(m)?;
    geo::register(m)?;
    Ok(())
}
