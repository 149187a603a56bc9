//! Live in Foxglove, for Python: `serve` and the `WorldServer` it returns.

use std::path::PathBuf;

use pyo3::prelude::*;

use crate::live::{ServeOptions, WorldServer};

/// A conversion's `world.mcap` on a Foxglove WebSocket (`serve`): open
/// `url` in Foxglove ("Open connection", Foxglove WebSocket). Serves until
/// `stop()`, the end of a `with` block, or its collection.
#[pyclass(name = "WorldServer", module = "slam2world._slam2world")]
pub struct PyWorldServer {
    inner: Option<WorldServer>,
    url: String,
    port: u16,
    path: PathBuf,
    topics: Vec<String>,
}

#[pymethods]
impl PyWorldServer {
    /// `ws://HOST:PORT`.
    #[getter]
    fn url(&self) -> String {
        self.url.clone()
    }
    /// The port it listens on (the one taken, when 0 was asked).
    #[getter]
    fn port(&self) -> u16 {
        self.port
    }
    /// The file served (a session's: the world last served, written after
    /// it went out).
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }
    /// The topics served, in the order they were first served.
    #[getter]
    fn topics(&self) -> Vec<String> {
        match &self.inner {
            Some(s) => s.topics(),
            None => self.topics.clone(),
        }
    }
    /// True until `stop()`.
    #[getter]
    fn running(&self) -> bool {
        self.is_running()
    }
    /// Clients connected now.
    fn client_count(&self) -> usize {
        self.inner.as_ref().map_or(0, |s| s.client_count())
    }
    /// Stops serving (the port is free when it returns); again: nothing.
    fn stop(&mut self, py: Python<'_>) {
        self.shut(py);
    }
    fn __enter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }
    fn __exit__(
        &mut self,
        py: Python<'_>,
        _exc_type: Option<&Bound<'_, PyAny>>,
        _exc: Option<&Bound<'_, PyAny>>,
        _tb: Option<&Bound<'_, PyAny>>,
    ) -> bool {
        self.shut(py);
        false
    }
    fn __repr__(&self) -> String {
        format!(
            "WorldServer(url={:?}, path={:?}, topics={}, running={})",
            self.url,
            self.path.display().to_string(),
            self.topics.len(),
            if self.inner.is_some() {
                "True"
            } else {
                "False"
            }
        )
    }
}

impl PyWorldServer {
    /// A Python handle of `s`.
    pub(crate) fn from_core(s: WorldServer) -> Self {
        PyWorldServer {
            url: s.url(),
            port: s.port(),
            path: s.path().to_path_buf(),
            topics: s.topics(),
            inner: Some(s),
        }
    }

    /// The world as it now stands to every client (nothing once stopped).
    pub(crate) fn publish(&self, world: std::sync::Arc<Vec<u8>>) {
        if let Some(s) = &self.inner {
            s.publish(world);
        }
    }

    /// True until stopped.
    pub(crate) fn is_running(&self) -> bool {
        self.inner.is_some()
    }

    /// Stops serving (the port is free when it returns); again: nothing.
    pub(crate) fn shut(&mut self, py: Python<'_>) {
        if let Some(s) = self.inner.take() {
            self.topics = s.topics();
            py.detach(|| s.stop());
        }
    }
}

/// Serves `world` (a conversion's output folder, or its `world.mcap`) on a
/// Foxglove WebSocket at `host:port` (this machine only by default; port 0
/// takes a free one): every channel of the file advertised as it is, its
/// messages sent to each client that subscribes. Raises `InvalidInputError`
/// for an address that cannot be bound or a folder without `world.mcap`,
/// `FileError` / `FormatError` for the file.
#[pyfunction(name = "serve")]
#[pyo3(signature = (world, *, host="127.0.0.1", port=8765))]
fn serve_py(py: Python<'_>, world: PathBuf, host: &str, port: u16) -> PyResult<PyWorldServer> {
    let opts = ServeOptions {
        host: host.to_string(),
        port,
    };
    let s = py.detach(|| WorldServer::start(&world, &opts))?;
    Ok(PyWorldServer::from_core(s))
}

/// The Foxglove layout of the metric world (JSON): a 3-D panel in the
/// `world` frame with the cloud, the paths, the voxels and the grid, the
/// session's state and a plot of its fit and latency; it fits `world.mcap`,
/// `serve`, `follow --serve` and `Session.serve` alike (Foxglove: Layouts,
/// Import from file).
#[pyfunction]
fn foxglove_layout() -> &'static str {
    crate::live::FOXGLOVE_LAYOUT
}

/// Adds `serve`, `WorldServer` and `foxglove_layout` to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyWorldServer>()?;
    m.add_function(wrap_pyfunction!(foxglove_layout, m)?)?;
    m.add_function(wrap_pyfunction!(serve_py, m)?)?;
    Ok(())
}
