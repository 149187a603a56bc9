//! COLMAP models for Python: `read_colmap`, `ColmapModel`, `ColmapCamera`,
//! the `ColmapImages` / `ColmapPoints3D` array summaries, `read_name_positions`.

use std::path::PathBuf;

use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;

use super::arrays::to_array2;
use super::cloud::PyPinholeCamera;
use super::geometry::PySim3;
use super::trajectory::PyTrajectory;
use crate::io::colmap::{
    read_colmap, read_name_positions, ColmapCamera, ColmapFormat, ColmapModel,
};

fn format_arg(format: Option<&str>) -> PyResult<Option<ColmapFormat>> {
    Ok(format.map(ColmapFormat::parse).transpose()?)
}

/// One camera: model name, size, every parameter in COLMAP's order.
#[pyclass(name = "ColmapCamera", module = "slam2world._slam2world", frozen)]
pub struct PyColmapCamera {
    inner: ColmapCamera,
}

#[pymethods]
impl PyColmapCamera {
    /// COLMAP's camera id.
    #[getter]
    fn id(&self) -> u32 {
        self.inner.id
    }
    /// The model name (`"OPENCV"`, `"SIMPLE_RADIAL"`, …).
    #[getter]
    fn model(&self) -> &'static str {
        self.inner.model.name()
    }
    #[getter]
    fn width(&self) -> u64 {
        self.inner.width
    }
    #[getter]
    fn height(&self) -> u64 {
        self.inner.height
    }
    /// The parameters (float64), distortion included.
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.params.clone().into_pyarray(py)
    }
    /// The pinhole part (f or fx, fy, cx, cy), principal point moved by −0.5 px
    /// to this project's pixel-centre convention; raises for a model without a
    /// focal length.
    fn pinhole(&self) -> PyResult<PyPinholeCamera> {
        Ok(PyPinholeCamera {
            inner: self.inner.pinhole()?,
        })
    }
    fn __repr__(&self) -> String {
        format!(
            "ColmapCamera(id={}, model={}, width={}, height={}, params={:?})",
            self.inner.id,
            self.inner.model.name(),
            self.inner.width,
            self.inner.height,
            self.inner.params
        )
    }
}

/// The images of a model as arrays, in the model's order.
#[pyclass(name = "ColmapImages", module = "slam2world._slam2world", frozen)]
pub struct PyColmapImages {
    /// Image ids (N,) uint32.
    #[pyo3(get)]
    ids: Py<PyArray1<u32>>,
    /// Camera ids (N,) uint32.
    #[pyo3(get)]
    camera_ids: Py<PyArray1<u32>>,
    /// Image names.
    #[pyo3(get)]
    names: Vec<String>,
    /// Camera centres `−Rᵀt` in the world frame (N, 3).
    #[pyo3(get)]
    centres: Py<PyArray2<f64>>,
    /// World-to-camera quaternions `(x, y, z, w)` (N, 4).
    #[pyo3(get)]
    quaternions: Py<PyArray2<f64>>,
    /// World-to-camera translations (N, 3).
    #[pyo3(get)]
    translations: Py<PyArray2<f64>>,
    /// Number of 2-D features of each image (N,).
    #[pyo3(get)]
    num_points2d: Py<PyArray1<u64>>,
    /// Number of those that observe a 3-D point (N,).
    #[pyo3(get)]
    num_observations: Py<PyArray1<u64>>,
}

#[pymethods]
impl PyColmapImages {
    fn __len__(&self) -> usize {
        self.names.len()
    }
}

/// The 3-D points of a model as arrays, in the model's order.
#[pyclass(name = "ColmapPoints3D", module = "slam2world._slam2world", frozen)]
pub struct PyColmapPoints3D {
    /// Point ids (N,) uint64.
    #[pyo3(get)]
    ids: Py<PyArray1<u64>>,
    /// Positions (N, 3), world frame.
    #[pyo3(get)]
    xyz: Py<PyArray2<f64>>,
    /// Colours (N, 3) uint8.
    #[pyo3(get)]
    rgb: Py<PyArray2<u8>>,
    /// Mean reprojection errors (N,), pixels.
    #[pyo3(get)]
    error: Py<PyArray1<f64>>,
    /// Track lengths (N,).
    #[pyo3(get)]
    track_lengths: Py<PyArray1<u64>>,
    len: usize,
}

#[pymethods]
impl PyColmapPoints3D {
    fn __len__(&self) -> usize {
        self.len
    }
}

/// A COLMAP / GLOMAP sparse model (cameras, images, points3D, rigs, frames).
#[pyclass(name = "ColmapModel", module = "slam2world._slam2world", frozen)]
pub struct PyColmapModel {
    pub inner: ColmapModel,
}

#[pymethods]
impl PyColmapModel {
    /// `"bin"` or `"txt"`: the flavour it was read from.
    #[getter]
    fn format(&self) -> &'static str {
        self.inner.format.extension()
    }

    /// The cameras.
    #[getter]
    fn cameras(&self) -> Vec<PyColmapCamera> {
        self.inner
            .cameras
            .iter()
            .map(|c| PyColmapCamera { inner: c.clone() })
            .collect()
    }

    /// The images as arrays.
    #[getter]
    fn images(&self, py: Python<'_>) -> PyResult<PyColmapImages> {
        let im = &self.inner.images;
        let mut centres = Vec::with_capacity(3 * im.len());
        let mut quats = Vec::with_capacity(4 * im.len());
        let mut trans = Vec::with_capacity(3 * im.len());
        for i in im {
            let c = i.centre();
            centres.extend([c.x, c.y, c.z]);
            let [w, x, y, z] = i.cam_from_world.qvec;
            quats.extend([x, y, z, w]);
            trans.extend(i.cam_from_world.tvec);
        }
        Ok(PyColmapImages {
            ids: im
                .iter()
                .map(|i| i.id)
                .collect::<Vec<_>>()
                .into_pyarray(py)
                .unbind(),
            camera_ids: im
                .iter()
                .map(|i| i.camera_id)
                .collect::<Vec<_>>()
                .into_pyarray(py)
                .unbind(),
            names: im.iter().map(|i| i.name.clone()).collect(),
            centres: to_array2(py, centres, 3)?.unbind(),
            quaternions: to_array2(py, quats, 4)?.unbind(),
            translations: to_array2(py, trans, 3)?.unbind(),
            num_points2d: im
                .iter()
                .map(|i| i.points2d.len() as u64)
                .collect::<Vec<_>>()
                .into_pyarray(py)
                .unbind(),
            num_observations: im
                .iter()
                .map(|i| i.points2d.iter().filter(|p| p.point3d_id.is_some()).count() as u64)
                .collect::<Vec<_>>()
                .into_pyarray(py)
                .unbind(),
        })
    }

    /// The 3-D points as arrays.
    #[getter(points3D)]
    fn points3d(&self, py: Python<'_>) -> PyResult<PyColmapPoints3D> {
        let p = &self.inner.points3d;
        Ok(PyColmapPoints3D {
            ids: p
                .iter()
                .map(|q| q.id)
                .collect::<Vec<_>>()
                .into_pyarray(py)
                .unbind(),
            xyz: to_array2(py, p.iter().flat_map(|q| q.xyz).collect(), 3)?.unbind(),
            rgb: to_array2(py, p.iter().flat_map(|q| q.rgb).collect(), 3)?.unbind(),
            error: p
                .iter()
                .map(|q| q.error)
                .collect::<Vec<_>>()
                .into_pyarray(py)
                .unbind(),
            track_lengths: p
                .iter()
                .map(|q| q.track.len() as u64)
                .collect::<Vec<_>>()
                .into_pyarray(py)
                .unbind(),
            len: p.len(),
        })
    }

    /// Number of rigs, or None for a model without `rigs.*`.
    #[getter]
    fn num_rigs(&self) -> Option<usize> {
        self.inner.rigs.as_ref().map(Vec::len)
    }

    /// Number of frames, or None for a model without `frames.*`.
    #[getter]
    fn num_frames(&self) -> Option<usize> {
        self.inner.frames.as_ref().map(Vec::len)
    }

    /// Number of observations (track elements over all points).
    #[getter]
    fn num_observations(&self) -> usize {
        self.inner.num_observations()
    }

    /// The model with its world moved by `transform` (T_new_old): points and
    /// camera centres carried, rig lever arms scaled, cameras untouched.
    fn transformed(&self, py: Python<'_>, transform: PySim3) -> Self {
        let t = transform.inner;
        PyColmapModel {
            inner: py.detach(|| self.inner.transformed(&t)),
        }
    }

    /// Writes the model into the folder `path` (`format`: "bin" / "txt",
    /// default the flavour it was read from), atomically.
    #[pyo3(signature = (path, format=None))]
    fn write(&self, py: Python<'_>, path: PathBuf, format: Option<&str>) -> PyResult<()> {
        let f = format_arg(format)?;
        Ok(py.detach(|| self.inner.write(&path, f))?)
    }

    /// `(names, centres (N, 3))`: each image's camera centre, for an alignment by name.
    fn camera_centres<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Vec<String>, Bound<'py, PyArray2<f64>>)> {
        let c = self.inner.camera_centres();
        let flat = c
            .iter()
            .flat_map(|n| [n.position.x, n.position.y, n.position.z])
            .collect();
        Ok((
            c.into_iter().map(|n| n.name).collect(),
            to_array2(py, flat, 3)?,
        ))
    }

    /// The images as a trajectory of T_world_cam poses timed by their names
    /// (nanosecond or seconds stamps, as EuRoC and TUM name images).
    fn trajectory(&self) -> PyResult<PyTrajectory> {
        Ok(PyTrajectory {
            inner: self.inner.trajectory_by_name_time()?.into(),
        })
    }

    fn __repr__(&self) -> String {
        let m = &self.inner;
        format!(
            "ColmapModel(format={}, cameras={}, images={}, points3D={}, rigs={:?}, frames={:?})",
            m.format.extension(),
            m.cameras.len(),
            m.images.len(),
            m.points3d.len(),
            m.rigs.as_ref().map(Vec::len),
            m.frames.as_ref().map(Vec::len)
        )
    }
}

/// Reads a COLMAP model folder (`format`: "bin" / "txt" when both are present).
#[pyfunction(name = "read_colmap")]
#[pyo3(signature = (path, format=None))]
fn read_colmap_py(py: Python<'_>, path: PathBuf, format: Option<&str>) -> PyResult<PyColmapModel> {
    let f = format_arg(format)?;
    Ok(PyColmapModel {
        inner: py.detach(|| read_colmap(&path, f))?,
    })
}

/// Reads a `name x y z` reference file (COLMAP model_aligner's; CSV and one
/// header line accepted): `(names, positions (N, 3))`.
#[pyfunction(name = "read_name_positions")]
fn read_name_positions_py(
    py: Python<'_>,
    path: PathBuf,
) -> PyResult<(Vec<String>, Bound<'_, PyArray2<f64>>)> {
    let r = py.detach(|| read_name_positions(&path))?;
    let flat = r
        .iter()
        .flat_map(|n| [n.position.x, n.position.y, n.position.z])
        .collect();
    Ok((
        r.into_iter().map(|n| n.name).collect(),
        to_array2(py, flat, 3)?,
    ))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyColmapModel>()?;
    m.add_class::<PyColmapCamera>()?;
    m.add_class::<PyColmapImages>()?;
    m.add_class::<PyColmapPoints3D>()?;
    m.add_function(wrap_pyfunction!(read_colmap_py, m)?)?;
    m.add_function(wrap_pyfunction!(read_name_positions_py, m)?)?;
    Ok(())
}
