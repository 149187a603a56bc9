//! DROID-SLAM reconstruction folders for Python: `read_droid`,
//! `DroidReconstruction`, `depth_consistency_counts`, `filter_consistent`.

use std::path::PathBuf;

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2};
use pyo3::prelude::*;

use super::cloud::PyKeyframe;
use crate::error::Error;
use crate::io::droid::{depth_consistency_counts, filter_consistent, read_droid, DepthFilter};
use crate::keyframe::Keyframe;

/// What `read_droid` found: keyframes on the disparity grid and that grid's
/// relation to the images.
#[pyclass(
    name = "DroidReconstruction",
    module = "slam2world._slam2world",
    frozen
)]
pub struct PyDroidReconstruction {
    keyframes: Vec<Keyframe>,
    /// Image size `(height, width)`, pixels.
    #[pyo3(get)]
    image_size: (u32, u32),
    /// Image pixels per disparity pixel (8 for `disps`, 1 for `disps_up`).
    #[pyo3(get)]
    downsample: u32,
}

#[pymethods]
impl PyDroidReconstruction {
    /// The keyframes: pose T_slam_cam, camera scaled to the disparity grid,
    /// idepth = disparity, RGB colour, id = index, timestamp = tstamps[i].
    #[getter]
    fn keyframes(&self) -> Vec<PyKeyframe> {
        self.keyframes
            .iter()
            .map(|k| PyKeyframe {
                inner: k.clone().into(),
            })
            .collect()
    }

    fn __len__(&self) -> usize {
        self.keyframes.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "DroidReconstruction(keyframes={}, image_size={:?}, downsample={})",
            self.keyframes.len(),
            self.image_size,
            self.downsample
        )
    }
}

/// Reads a DROID-SLAM reconstruction folder (tstamps, images, poses, disps,
/// intrinsics `.npy`).
#[pyfunction(name = "read_droid")]
fn read_droid_py(py: Python<'_>, path: PathBuf) -> PyResult<PyDroidReconstruction> {
    let r = py.detach(|| read_droid(&path))?;
    Ok(PyDroidReconstruction {
        keyframes: r.keyframes,
        image_size: r.image_size,
        downsample: r.downsample,
    })
}

fn keyframes_arg(keyframes: &Bound<'_, PyAny>) -> PyResult<Vec<Keyframe>> {
    let mut out = Vec::new();
    for item in keyframes.try_iter()? {
        let item = item?;
        let kf = item.cast::<PyKeyframe>().map_err(|_| {
            PyErr::from(Error::invalid(
                "keyframes",
                format!("item {} is not a Keyframe", out.len()),
            ))
        })?;
        out.push(kf.get().inner.clone());
    }
    Ok(out)
}

fn filter_arg(
    threshold: f64,
    min_count: u32,
    min_disparity_ratio: f64,
    neighbours: Option<Vec<isize>>,
) -> DepthFilter {
    let d = DepthFilter::default();
    DepthFilter {
        threshold,
        min_count,
        min_disparity_ratio,
        neighbours: neighbours.unwrap_or(d.neighbours),
    }
}

/// For each keyframe, an (H, W) uint32 array: how many neighbouring keyframes
/// see each pixel at a consistent depth (DROID-SLAM's `depth_filter`).
#[pyfunction(name = "depth_consistency_counts")]
#[pyo3(signature = (keyframes, *, threshold=0.005, neighbours=None))]
fn depth_consistency_counts_py<'py>(
    py: Python<'py>,
    keyframes: &Bound<'py, PyAny>,
    threshold: f64,
    neighbours: Option<Vec<isize>>,
) -> PyResult<Vec<Bound<'py, PyArray2<u32>>>> {
    let kfs = keyframes_arg(keyframes)?;
    let f = filter_arg(threshold, 2, 0.0, neighbours);
    let counts = py.detach(|| depth_consistency_counts(&kfs, &f))?;
    kfs.iter()
        .zip(counts)
        .map(|(k, c)| {
            Array2::from_shape_vec((k.camera.height as usize, k.camera.width as usize), c)
                .map(|a| a.into_pyarray(py))
                .map_err(|e| Error::invalid("counts", e.to_string()).into())
        })
        .collect()
}

/// The keyframes with every pixel that fails DROID-SLAM's viewer filter set to
/// idepth 0 (fewer than `min_count` consistent neighbours, or a disparity at
/// most `min_disparity_ratio` × the keyframe's mean).
#[pyfunction(name = "filter_consistent")]
#[pyo3(signature = (keyframes, *, threshold=0.005, min_count=2, min_disparity_ratio=0.5, neighbours=None))]
fn filter_consistent_py(
    py: Python<'_>,
    keyframes: &Bound<'_, PyAny>,
    threshold: f64,
    #[pyo3(from_py_with = super::arrays::uint::min_count)] min_count: u32,
    min_disparity_ratio: f64,
    neighbours: Option<Vec<isize>>,
) -> PyResult<Vec<PyKeyframe>> {
    let kfs = keyframes_arg(keyframes)?;
    let f = filter_arg(threshold, min_count, min_disparity_ratio, neighbours);
    let out = py.detach(|| filter_consistent(&kfs, &f))?;
    Ok(out
        .into_iter()
        .map(|k| PyKeyframe { inner: k.into() })
        .collect())
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyDroidReconstruction>()?;
    m.add_function(wrap_pyfunction!(read_droid_py, m)?)?;
    m.add_function(wrap_pyfunction!(depth_consistency_counts_py, m)?)?;
    m.add_function(wrap_pyfunction!(filter_consistent_py, m)?)?;
    Ok(())
}
