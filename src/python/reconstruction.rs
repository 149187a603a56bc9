//! Reconstructions for Python: `read_reconstruction(path) -> Reconstruction`
//! (COLMAP / GLOMAP models, DROID-SLAM folders, trajectory files + PLY), the
//! recording a conversion reads, and the reading options `convert` shares.

use std::path::PathBuf;

use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;

use super::cloud::{PyKeyframe, PyPinholeCamera, PyPointCloud};
use super::colmap::PyColmapModel;
use super::text::PyTextInfo;
use super::trajectory::PyTrajectory;
use crate::io::colmap::ColmapFormat;
use crate::io::droid::DepthFilter;
use crate::io::text::TimeUnit;
use crate::pipeline::native::{NativeModel, ReconstructionKind, ReferenceFormat};
use crate::pipeline::reconstruction::{
    attach_reference, read_reconstruction, ReconstructionOptions, ReferenceSpec,
};
use crate::pipeline::Recording;

/// The reading options from the Python arguments.
pub(crate) fn reading_options(
    time_unit: Option<&str>,
    cloud: Option<PathBuf>,
    colmap_format: Option<&str>,
    depth_filter: bool,
    depth_threshold: f64,
    depth_min_count: u32,
    min_disparity_ratio: f64,
) -> PyResult<ReconstructionOptions> {
    Ok(ReconstructionOptions {
        time_unit: time_unit.map(TimeUnit::parse).transpose()?,
        cloud,
        colmap_format: colmap_format.map(ColmapFormat::parse).transpose()?,
        depth_filter: depth_filter.then(|| DepthFilter {
            threshold: depth_threshold,
            min_count: depth_min_count,
            min_disparity_ratio,
            ..DepthFilter::default()
        }),
    })
}

/// The reference file from the Python arguments (`None` without a path).
pub(crate) fn reference_spec(
    reference: Option<PathBuf>,
    reference_format: Option<&str>,
    reference_time_unit: Option<&str>,
) -> PyResult<Option<ReferenceSpec>> {
    let format = reference_format
        .map(str::parse::<ReferenceFormat>)
        .transpose()?;
    let time_unit = reference_time_unit.map(TimeUnit::parse).transpose()?;
    match reference {
        Some(path) => Ok(Some(ReferenceSpec {
            path,
            format,
            time_unit,
        })),
        None if format.is_some() || time_unit.is_some() => Err(crate::Error::invalid(
            "reference",
            "reference_format / reference_time_unit need a reference file",
        )
        .into()),
        None => Ok(None),
    }
}

/// A reconstruction as read: frames (`T_slam_cam`) with names and cameras,
/// keyframes with depth, the cloud in the SLAM frame, the input's own model,
/// and what the readers found out.
#[pyclass(name = "Reconstruction", module = "slam2world._slam2world", frozen)]
pub struct PyReconstruction {
    pub(crate) rec: Recording,
    keyframes: PyOnceLock<Vec<Py<PyKeyframe>>>,
}

impl PyReconstruction {
    pub(crate) fn new(rec: Recording) -> Self {
        PyReconstruction {
            rec,
            keyframes: PyOnceLock::new(),
        }
    }
}

#[pymethods]
impl PyReconstruction {
    /// The folder or file read.
    #[getter]
    fn path(&self) -> PathBuf {
        self.rec.source.path.clone()
    }
    /// `"colmap"`, `"droid"` or `"trajectory"`.
    #[getter]
    fn kind(&self) -> &'static str {
        self.rec
            .source
            .reconstruction
            .as_ref()
            .map_or("unknown", |r| r.kind.name())
    }
    /// The COLMAP flavour (`"bin"` / `"txt"`), else None.
    #[getter]
    fn flavour(&self) -> Option<&'static str> {
        match self.rec.source.reconstruction.as_ref()?.kind {
            ReconstructionKind::Colmap(f) => Some(f.extension()),
            _ => None,
        }
    }
    /// Frame poses without depth (`T_slam_cam`, by time), or None (DROID-SLAM
    /// has keyframes instead).
    #[getter]
    fn frames(&self) -> Option<PyTrajectory> {
        self.rec.frames.as_ref().map(|t| PyTrajectory {
            inner: t.clone().into(),
        })
    }
    /// The image name of each frame, or None.
    #[getter]
    fn names(&self) -> Option<Vec<String>> {
        if self.rec.frame_info.is_empty() {
            return None;
        }
        self.rec.frame_info.iter().map(|f| f.name.clone()).collect()
    }
    /// The pinhole part of each frame's camera (None where the model has
    /// none), or None without frame cameras.
    #[getter]
    fn cameras(&self) -> Option<Vec<Option<PyPinholeCamera>>> {
        if self.rec.frame_info.is_empty() {
            return None;
        }
        Some(
            self.rec
                .frame_info
                .iter()
                .map(|f| f.camera.map(|inner| PyPinholeCamera { inner }))
                .collect(),
        )
    }
    /// Keyframes with inverse depth (DROID-SLAM, depth-filtered as read).
    #[getter]
    fn keyframes(&self, py: Python<'_>) -> PyResult<Vec<Py<PyKeyframe>>> {
        let list = self.keyframes.get_or_try_init(py, || {
            self.rec
                .keyframes
                .iter()
                .map(|k| {
                    Py::new(
                        py,
                        PyKeyframe {
                            inner: k.clone().into(),
                        },
                    )
                })
                .collect::<PyResult<Vec<_>>>()
        })?;
        Ok(list.iter().map(|k| k.clone_ref(py)).collect())
    }
    /// Points in the SLAM frame that come without keyframes (COLMAP points3D,
    /// a trajectory's PLY), or None.
    #[getter]
    fn cloud(&self, py: Python<'_>) -> PyResult<Option<PyPointCloud>> {
        self.rec
            .cloud
            .clone()
            .map(|c| PyPointCloud::from_core(py, c))
            .transpose()
    }
    /// The input's own model (COLMAP), else None.
    #[getter]
    fn model(&self) -> Option<PyColmapModel> {
        self.rec
            .native
            .as_ref()
            .and_then(NativeModel::colmap)
            .map(|m| PyColmapModel { inner: m.clone() })
    }
    /// Reference poses or positions attached (`with_reference`), else None.
    #[getter]
    fn reference(&self) -> Option<PyTrajectory> {
        self.rec
            .reference
            .as_ref()
            .map(|r| PyTrajectory { inner: r.clone() })
    }
    /// What the trajectory reader found out (unit, delimiter, …), for
    /// trajectory files, else None.
    #[getter]
    fn text_info(&self) -> Option<PyTextInfo> {
        self.rec
            .source
            .reconstruction
            .as_ref()?
            .slam_text
            .map(|inner| PyTextInfo { inner })
    }
    /// How the frame stamps were made.
    #[getter]
    fn frame_times(&self) -> &'static str {
        self.rec
            .source
            .reconstruction
            .as_ref()
            .map_or("", |r| r.frame_times.describe())
    }
    /// Decisions the reader made.
    #[getter]
    fn notes(&self) -> Vec<String> {
        self.rec
            .source
            .reconstruction
            .as_ref()
            .map_or_else(Vec::new, |r| r.notes.clone())
    }
    /// The same reconstruction with a metric reference: poses by time (TUM
    /// order, EuRoC CSV) or positions by image name (`name x y z`), the format
    /// detected unless given (`"names"`, `"tum"`, `"euroc"`).
    #[pyo3(signature = (reference, *, reference_format=None, reference_time_unit=None))]
    fn with_reference(
        &self,
        py: Python<'_>,
        reference: PathBuf,
        reference_format: Option<&str>,
        reference_time_unit: Option<&str>,
    ) -> PyResult<PyReconstruction> {
        let spec = reference_spec(Some(reference), reference_format, reference_time_unit)?;
        let mut rec = self.rec.clone();
        if let Some(spec) = spec {
            py.detach(|| attach_reference(&mut rec, &spec))?;
        }
        Ok(PyReconstruction::new(rec))
    }
    fn __len__(&self) -> usize {
        match &self.rec.frames {
            Some(f) if self.rec.keyframes.is_empty() => f.len(),
            _ => self.rec.keyframes.len(),
        }
    }
    fn __repr__(&self) -> String {
        format!(
            "Reconstruction({:?}, kind={}, frames={}, points={}, reference={})",
            self.rec.source.path.display().to_string(),
            self.kind(),
            self.__len__(),
            self.rec.cloud.as_ref().map_or(0, |c| c.len()),
            self.rec.reference.as_ref().map_or(0, |r| r.len()),
        )
    }
}

/// Reads a reconstruction, its kind found from the path's contents: a COLMAP
/// / GLOMAP model folder, a DROID-SLAM folder (keyframes through DROID-SLAM's
/// depth filter unless `depth_filter=False`), or a trajectory file in TUM
/// column order (time unit detected unless `time_unit` is given) with the
/// PLY of the same stem beside it (or `cloud`).
#[pyfunction(name = "read_reconstruction")]
#[pyo3(signature = (path, *, time_unit=None, cloud=None, colmap_format=None, depth_filter=true, depth_threshold=0.005, depth_min_count=2, min_disparity_ratio=0.5))]
#[allow(clippy::too_many_arguments)]
fn read_reconstruction_py(
    py: Python<'_>,
    path: PathBuf,
    time_unit: Option<&str>,
    cloud: Option<PathBuf>,
    colmap_format: Option<&str>,
    depth_filter: bool,
    depth_threshold: f64,
    depth_min_count: u32,
    min_disparity_ratio: f64,
) -> PyResult<PyReconstruction> {
    let opts = reading_options(
        time_unit,
        cloud,
        colmap_format,
        depth_filter,
        depth_threshold,
        depth_min_count,
        min_disparity_ratio,
    )?;
    let rec = py.detach(|| read_reconstruction(&path, &opts))?;
    Ok(PyReconstruction::new(rec))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyReconstruction>()?;
    m.add_function(wrap_pyfunction!(read_reconstruction_py, m)?)?;
    Ok(())
}
