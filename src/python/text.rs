//! Trajectory files as SLAM systems write them, for Python: `read_trajectory`,
//! `TextInfo` and `match_time_units`.

use std::path::PathBuf;

use pyo3::prelude::*;

use super::arrays::vec_f64;
use super::trajectory::PyTrajectory;
use crate::io::text::{match_time_units, read_trajectory, Delimiter, TextInfo, TimeUnit};

/// What `read_trajectory` found out about a file.
#[pyclass(name = "TextInfo", module = "slam2world._slam2world", frozen)]
pub struct PyTextInfo {
    pub(crate) inner: TextInfo,
}

#[pymethods]
impl PyTextInfo {
    /// The unit the stamps were read in: "s", "ms", "us" or "ns".
    #[getter]
    fn unit(&self) -> &'static str {
        self.inner.unit.symbol()
    }
    /// True when the unit was detected, False when it was given.
    #[getter]
    fn unit_detected(&self) -> bool {
        self.inner.unit_detected
    }
    /// "whitespace" or "comma".
    #[getter]
    fn delimiter(&self) -> &'static str {
        match self.inner.delimiter {
            Delimiter::Whitespace => "whitespace",
            Delimiter::Comma => "comma",
        }
    }
    /// True when a header line was skipped.
    #[getter]
    fn header(&self) -> bool {
        self.inner.header
    }
    /// Rows dropped because their stamp repeated the previous one (the first is kept).
    #[getter]
    fn repeated_stamps(&self) -> usize {
        self.inner.repeated_stamps
    }
    fn __repr__(&self) -> String {
        format!(
            "TextInfo(unit={:?}, unit_detected={}, delimiter={:?}, header={}, repeated_stamps={})",
            self.unit(),
            if self.inner.unit_detected {
                "True"
            } else {
                "False"
            },
            self.delimiter(),
            if self.inner.header { "True" } else { "False" },
            self.inner.repeated_stamps
        )
    }
}

/// Reads a trajectory in TUM column order (DPVO, MASt3R-SLAM, DSO, ORB-SLAM3
/// files): the time unit detected ("s", "ms", "us", "ns", or `time_unit`),
/// commas accepted, repeated stamps dropped (first kept). Returns
/// `(Trajectory in seconds, TextInfo)`.
#[pyfunction(name = "read_trajectory")]
#[pyo3(signature = (path, *, time_unit=None))]
fn read_trajectory_py(
    py: Python<'_>,
    path: PathBuf,
    time_unit: Option<&str>,
) -> PyResult<(PyTrajectory, PyTextInfo)> {
    let unit = time_unit.map(TimeUnit::parse).transpose()?;
    let (t, info) = py.detach(|| read_trajectory(&path, unit))?;
    Ok((PyTrajectory { inner: t.into() }, PyTextInfo { inner: info }))
}

/// The units ("s", "ms", "us", "ns") of an estimate's and a reference's
/// stamps as written, each judged against the other: the combination whose
/// time spans overlap (the estimate's shifted by `offset` seconds), as
/// `slam2world align EST REF` reads two files. `est_unit` / `ref_unit` fix a
/// side. Returns `(est_unit, ref_unit)`; divide the stamps by 1, 1e3, 1e6 or
/// 1e9 for seconds.
#[pyfunction(name = "match_time_units")]
#[pyo3(signature = (est_stamps, ref_stamps, *, est_unit=None, ref_unit=None, offset=0.0))]
fn match_time_units_py(
    est_stamps: &Bound<'_, PyAny>,
    ref_stamps: &Bound<'_, PyAny>,
    est_unit: Option<&str>,
    ref_unit: Option<&str>,
    offset: f64,
) -> PyResult<(&'static str, &'static str)> {
    let est = vec_f64(est_stamps, "est_stamps", None)?;
    let reference = vec_f64(ref_stamps, "ref_stamps", None)?;
    if !offset.is_finite() {
        return Err(
            crate::Error::invalid("offset", format!("must be finite, got {offset}")).into(),
        );
    }
    let (ue, ur) = match_time_units(
        &est,
        &reference,
        est_unit.map(TimeUnit::parse).transpose()?,
        ref_unit.map(TimeUnit::parse).transpose()?,
        offset,
    );
    Ok((ue.symbol(), ur.symbol()))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyTextInfo>()?;
    m.add_function(wrap_pyfunction!(read_trajectory_py, m)?)?;
    m.add_function(wrap_pyfunction!(match_time_units_py, m)?)?;
    Ok(())
}
