//! PyO3 bindings (feature `python`): thin wrappers over the core, each file
//! named after the core module it wraps (`align.rs` wraps `align/`, `io.rs`
//! wraps `io/`, `pipeline.rs` wraps `pipeline/`, …), one error mapping
//! (`errors.rs`, for `error.rs`), array conversion in `arrays.rs`.

use pyo3::prelude::*;

mod align;
mod arrays;
mod cli;
mod cloud;
mod colmap;
mod defaults;
mod droid;
mod errors;
mod geo;
mod geometry;
mod ground;
mod imu;
mod io;
mod live;
mod map;
mod pipeline;
mod reconstruction;
mod session;
mod sim;
mod text;
mod trajectory;

#[pymodule]
fn _slam2world(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    errors::register(m)?;
    geometry::register(m)?;
    ground::register(m)?;
    sim::register(m)?;
    map::register(m)?;
    trajectory::register(m)?;
    align::register(m)?;
    cloud::register(m)?;
    cli::register(m)?;
    io::register(m)?;
    pipeline::register(m)?;
    imu::register(m)?;
    defaults::register(m)?;
    colmap::register(m)?;
    droid::register(m)?;
    text::register(m)?;
    reconstruction::register(m)?;
    geo::register(m)?;
    session::register(m)?;
    live::register(m)?;
    Ok(())
}
