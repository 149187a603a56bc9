//! Alignment with other degrees of freedom for Python: `align_dof`, wrapping
//! `crate::align::dof` and returning the `Alignment` class of `core.rs`.

use nalgebra::Vector3;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::align::{robust_arg, PyAlignment};
use super::arrays::{rows_f64, vec_f64};
use crate::align::dof::{
    align_dof, align_dof_robust, covariance_dof, Anchor, Dof, DofDiagnostics, DofOptions,
    DEFAULT_MAX_TILT_DEG,
};
use crate::align::AlignMethod;

fn vectors(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<Vector3<f64>>> {
    let v = rows_f64(obj, what, 3)?;
    Ok(v.chunks_exact(3)
        .map(|r| Vector3::new(r[0], r[1], r[2]))
        .collect())
}

/// The `dof` entry of `Alignment.diagnostics`: `dof`, `anchor`,
/// `source_horizontal_spread`, `target_horizontal_spread`, `yaw_determinacy`,
/// `gravity_tilt_deg` (None when not observable).
pub(crate) fn dof_diagnostics_dict<'py>(
    py: Python<'py>,
    d: &DofDiagnostics,
) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    dict.set_item("dof", d.dof.as_str())?;
    dict.set_item("anchor", d.anchor.as_str())?;
    dict.set_item("source_horizontal_spread", d.source_horizontal_spread)?;
    dict.set_item("target_horizontal_spread", d.target_horizontal_spread)?;
    dict.set_item("yaw_determinacy", d.yaw_determinacy)?;
    dict.set_item("gravity_tilt_deg", d.gravity_tilt_deg)?;
    Ok(dict)
}

/// Aligns `(N, 3)` source points onto `(N, 3)` target points with `dof`
/// (`"sim3"`, `"se3"`, `"4dof"`: translation + yaw about z, `"scale+4dof"`)
/// and `anchor` (None or `"first"`: the first pair mapped exactly). A yaw-only
/// fit raises `InvalidInputError` when the Sim(3) fit tilts the source z axis
/// more than `max_tilt_deg` (None: no check). `covariance` is over the Sim(3)
/// parameters, zero where the dof fixes one. The GIL is released.
#[pyfunction(name = "align_dof")]
#[pyo3(signature = (source, target, *, dof="4dof", anchor=None, weights=None, method="horn", max_tilt_deg=Some(DEFAULT_MAX_TILT_DEG), robust=None, inlier_threshold=None, loss="huber"),
       text_signature = "(source, target, *, dof='4dof', anchor=None, weights=None, method='horn', \
                         max_tilt_deg=2.0, robust=None, inlier_threshold=None, loss='huber')")]
#[allow(clippy::too_many_arguments)]
fn align_dof_py(
    py: Python<'_>,
    source: &Bound<'_, PyAny>,
    target: &Bound<'_, PyAny>,
    dof: &str,
    anchor: Option<&str>,
    weights: Option<&Bound<'_, PyAny>>,
    method: &str,
    max_tilt_deg: Option<f64>,
    robust: Option<&str>,
    inlier_threshold: Option<f64>,
    loss: &str,
) -> PyResult<PyAlignment> {
    let dof: Dof = dof.parse()?;
    let anchor: Anchor = match anchor {
        None => Anchor::None,
        Some(a) => a.parse()?,
    };
    let method: AlignMethod = method.parse()?;
    let weights = match weights {
        Some(w) => Some(vec_f64(w, "weights", None)?),
        None => None,
    };
    let robust = robust_arg(robust, inlier_threshold, loss)?;
    let a = vectors(source, "source")?;
    let b = vectors(target, "target")?;
    let opts = DofOptions {
        dof,
        anchor,
        weights,
        method,
        max_tilt_deg,
    };
    let (alignment, inliers, cov) = py.detach(|| -> crate::error::Result<_> {
        let (alignment, inliers, w) = match &robust {
            Some(ropts) => {
                let r = align_dof_robust(&a, &b, &opts, ropts)?;
                let w: Vec<f64> = r.inliers.iter().map(|&x| f64::from(u8::from(x))).collect();
                (r.alignment, Some(r.inliers), Some(w))
            }
            None => (align_dof(&a, &b, &opts)?, None, opts.weights.clone()),
        };
        let cov = covariance_dof(&alignment.transform, &a, &b, w.as_deref(), dof, anchor)
            .ok()
            .map(|c| c.to_sim3());
        Ok((alignment, inliers, cov))
    })?;
    Ok(PyAlignment::with_extras(py, alignment, inliers, cov))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(align_dof_py, m)?)?;
    Ok(())
}
