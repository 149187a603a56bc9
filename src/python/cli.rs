//! The console script `slam2world` of the wheel runs the same clap code as the binary.

use pyo3::prelude::*;

/// Runs the command line with `argv` (program name first; `str` or `bytes`,
/// paths that are not UTF-8 included, as `sys.argv` holds them); returns the
/// exit code. A run stopped by Ctrl-C (exit code 130) raises
/// `KeyboardInterrupt` once its outputs are cleaned up; one that ends on it
/// as it should (`serve`) returns 0.
#[pyfunction]
fn run_cli(py: Python<'_>, argv: Vec<std::ffi::OsString>) -> PyResult<i32> {
    let code = py.detach(|| crate::cli::main_with_args(argv));
    // Python's own SIGINT handler ran too (it is chained): this raises its
    // KeyboardInterrupt, unless the command ended well on the signal (`serve`
    // stops on Ctrl-C).
    let signals = py.check_signals();
    if !(code == 0 && crate::interrupt::received().is_some()) {
        signals?;
    }
    if code == crate::interrupt::exit_code(crate::interrupt::SIGINT) {
        return Err(pyo3::exceptions::PyKeyboardInterrupt::new_err(
            "interrupted by SIGINT: no output written",
        ));
    }
    Ok(code)
}

/// Runs `slam2world convert …` (`argv`, program name first) as the command
/// line does, raising its error as the typed exception of
/// `slam2world.errors` instead of printing it: the per-log work of
/// `slam2world.batch`.
#[pyfunction]
fn convert_cli(py: Python<'_>, argv: Vec<std::ffi::OsString>) -> PyResult<()> {
    let r = py.detach(|| crate::cli::run_convert_args(argv));
    py.check_signals()?;
    r.map_err(PyErr::from)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(run_cli, m)?)?;
    m.add_function(wrap_pyfunction!(convert_cli, m)?)?;
    Ok(())
}
