//! `PinholeCamera`, `Keyframe`, `PointFilter`, `PointCloud`, `backproject`,
//! `read_ply` and `read_xyz_text` for Python.
//!
//! A `PointCloud` keeps its arrays as NumPy arrays, made read-only: the getters
//! return them without a copy, and `transformed` shares the colours and ids.

use std::path::PathBuf;
use std::sync::Arc;

use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{
    AllowTypeChange, IntoPyArray, PyArray1, PyArray2, PyArray3, PyArrayDyn, PyArrayLike1,
    PyArrayLike2, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods,
};
use pyo3::prelude::*;

use super::arrays::{c_slice, Points};
use super::geometry::PySim3;
use crate::cloud::{self, PointCloud, PointFilter};
use crate::error::Error;
use crate::geometry::{PinholeCamera, Sim3};
use crate::io::ply;
use crate::keyframe::Keyframe;
use crate::pipeline::Recording;

fn shape_err(what: &str, expected: String, got: String) -> PyErr {
    Error::ShapeMismatch {
        what: what.into(),
        expected,
        got,
    }
    .into()
}

/// Marks a NumPy array read-only.
fn freeze<T>(a: &Bound<'_, T>) -> PyResult<()> {
    a.as_any().getattr("flags")?.setattr("writeable", false)
}

/// A distortion-free pinhole camera (pixels; x right, y down, z forward).
#[pyclass(
    name = "PinholeCamera",
    module = "slam2world._slam2world",
    frozen,
    from_py_object
)]
#[derive(Clone)]
pub struct PyPinholeCamera {
    pub inner: PinholeCamera,
}

#[pymethods]
impl PyPinholeCamera {
    #[new]
    fn new(
        fx: f64,
        fy: f64,
        cx: f64,
        cy: f64,
        #[pyo3(from_py_with = super::arrays::uint::width)] width: u32,
        #[pyo3(from_py_with = super::arrays::uint::height)] height: u32,
    ) -> PyResult<Self> {
        Ok(PyPinholeCamera {
            inner: PinholeCamera::try_new(fx, fy, cx, cy, width, height)?,
        })
    }

    /// Principal point at the image centre, square pixels, horizontal field of view in degrees.
    #[staticmethod]
    fn from_hfov(
        #[pyo3(from_py_with = super::arrays::uint::width)] width: u32,
        #[pyo3(from_py_with = super::arrays::uint::height)] height: u32,
        hfov_deg: f64,
    ) -> PyResult<Self> {
        Ok(PyPinholeCamera {
            inner: PinholeCamera::from_hfov(width, height, hfov_deg)?,
        })
    }

    #[getter]
    fn fx(&self) -> f64 {
        self.inner.fx
    }
    #[getter]
    fn fy(&self) -> f64 {
        self.inner.fy
    }
    #[getter]
    fn cx(&self) -> f64 {
        self.inner.cx
    }
    #[getter]
    fn cy(&self) -> f64 {
        self.inner.cy
    }
    #[getter]
    fn width(&self) -> u32 {
        self.inner.width
    }
    #[getter]
    fn height(&self) -> u32 {
        self.inner.height
    }

    fn __repr__(&self) -> String {
        let c = &self.inner;
        format!(
            "PinholeCamera(fx={}, fy={}, cx={}, cy={}, width={}, height={})",
            c.fx, c.fy, c.cx, c.cy, c.width, c.height
        )
    }
}

/// A keyframe: pose `T_slam_cam`, camera, inverse depth (H, W) and optional
/// variance (H, W) and colour (H, W) or (H, W, 3) uint8.
#[pyclass(name = "Keyframe", module = "slam2world._slam2world", frozen)]
pub struct PyKeyframe {
    pub inner: SharedKeyframe,
}

/// The keyframe of a [`PyKeyframe`]: its own, or one of a log's, shared with
/// the log rather than copied (megabytes a keyframe); either reads as a
/// [`Keyframe`]. A shared one keeps the log's recording alive.
pub enum SharedKeyframe {
    /// A keyframe of its own.
    Own(Keyframe),
    /// Keyframe `k` of a log's recording.
    InLog(Arc<Recording>, usize),
}

impl From<Keyframe> for SharedKeyframe {
    fn from(k: Keyframe) -> Self {
        SharedKeyframe::Own(k)
    }
}

impl std::ops::Deref for SharedKeyframe {
    type Target = Keyframe;
    fn deref(&self) -> &Keyframe {
        match self {
            SharedKeyframe::Own(k) => k,
            SharedKeyframe::InLog(r, k) => &r.keyframes[*k],
        }
    }
}

/// An (H, W) image as a row-major float32 vector.
fn image_f32(obj: &Bound<'_, PyAny>, what: &str, h: usize, w: usize) -> PyResult<Vec<f32>> {
    let a: PyArrayLike2<'_, f32, AllowTypeChange> = obj.extract().map_err(|_| {
        shape_err(
            what,
            format!("a 2-D array ({h}, {w})"),
            super::arrays::given(obj),
        )
    })?;
    if a.shape() != [h, w] {
        return Err(shape_err(
            what,
            format!("({h}, {w})"),
            super::arrays::shape_text(a.shape()),
        ));
    }
    Ok(match c_slice(&a) {
        Some(s) => s.to_vec(),
        None => a.as_array().iter().copied().collect(),
    })
}

/// An (H, W) or (H, W, 3) uint8 image as 3 bytes a pixel (grey replicated).
fn image_rgb(obj: &Bound<'_, PyAny>, h: usize, w: usize) -> PyResult<Vec<u8>> {
    let expected = || format!("a uint8 array ({h}, {w}) or ({h}, {w}, 3)");
    let a = obj
        .cast::<PyArrayDyn<u8>>()
        .map_err(|_| shape_err("color", expected(), "not a uint8 array".into()))?
        .readonly();
    let v: Vec<u8> = match c_slice(&a) {
        Some(s) => s.to_vec(),
        None => a.as_array().iter().copied().collect(),
    };
    match a.shape() {
        [hh, ww] if *hh == h && *ww == w => Ok(v.iter().flat_map(|&g| [g, g, g]).collect()),
        [hh, ww, 3] if *hh == h && *ww == w => Ok(v),
        s => Err(shape_err("color", expected(), format!("{s:?}"))),
    }
}

#[pymethods]
impl PyKeyframe {
    #[new]
    #[pyo3(signature = (id, timestamp, pose, camera, idepth, idepth_var=None, color=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        id: i32,
        timestamp: f64,
        pose: PySim3,
        camera: PyPinholeCamera,
        idepth: &Bound<'_, PyAny>,
        idepth_var: Option<&Bound<'_, PyAny>>,
        color: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let (h, w) = (camera.inner.height as usize, camera.inner.width as usize);
        let idepth = image_f32(idepth, "idepth", h, w)?;
        let var = idepth_var
            .map(|v| image_f32(v, "idepth_var", h, w))
            .transpose()?;
        let color = color.map(|c| image_rgb(c, h, w)).transpose()?;
        Ok(PyKeyframe {
            inner: Keyframe::try_new(id, timestamp, pose.inner, camera.inner, idepth, var, color)?
                .into(),
        })
    }

    #[getter]
    fn id(&self) -> i32 {
        self.inner.id
    }
    /// Seconds.
    #[getter]
    fn timestamp(&self) -> f64 {
        self.inner.timestamp
    }
    /// `T_slam_cam`.
    #[getter]
    fn pose(&self) -> PySim3 {
        self.inner.pose.into()
    }
    #[getter]
    fn camera(&self) -> PyPinholeCamera {
        PyPinholeCamera {
            inner: self.inner.camera,
        }
    }
    /// Inverse depth (H, W) float32 (a copy).
    #[getter]
    fn idepth<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        self.image(py, self.inner.idepth.clone())
    }
    /// Variance of the inverse depth (H, W) float32 (a copy), or None.
    #[getter]
    fn idepth_var<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArray2<f32>>>> {
        self.inner
            .idepth_var
            .clone()
            .map(|v| self.image(py, v))
            .transpose()
    }
    /// Colour (H, W, 3) uint8 (a copy), or None.
    #[getter]
    fn color<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArray3<u8>>>> {
        let (h, w) = self.hw();
        self.inner
            .color
            .clone()
            .map(|c| {
                Array3::from_shape_vec((h, w, 3), c)
                    .map(|a| a.into_pyarray(py))
                    .map_err(|e| Error::invalid("color", e.to_string()).into())
            })
            .transpose()
    }

    fn __repr__(&self) -> String {
        let (h, w) = self.hw();
        format!(
            "Keyframe(id={}, timestamp={}, {}x{}, variance={}, color={})",
            self.inner.id,
            self.inner.timestamp,
            w,
            h,
            self.inner.idepth_var.is_some(),
            self.inner.color.is_some()
        )
    }
}

impl PyKeyframe {
    fn hw(&self) -> (usize, usize) {
        (
            self.inner.camera.height as usize,
            self.inner.camera.width as usize,
        )
    }

    fn image<'py>(&self, py: Python<'py>, v: Vec<f32>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        Array2::from_shape_vec(self.hw(), v)
            .map(|a| a.into_pyarray(py))
            .map_err(|e| Error::invalid("image", e.to_string()).into())
    }
}

/// The LSD-SLAM viewer's point filters; `PointFilter()` gives its run-time defaults,
/// `PointFilter.none()` keeps every pixel with a positive inverse depth.
#[pyclass(
    name = "PointFilter",
    module = "slam2world._slam2world",
    frozen,
    eq,
    from_py_object
)]
#[derive(Clone, PartialEq)]
pub struct PyPointFilter {
    pub inner: PointFilter,
}

#[pymethods]
impl PyPointFilter {
    #[new]
    #[pyo3(signature = (
        scaled_depth_var=1e-3,
        abs_depth_var=1e-1,
        min_near_support=7,
        sparsify=1,
        cut_first_keyframes=Some(5),
        skip_border=true,
        seed=0
    ),
    text_signature = "(scaled_depth_var=0.001, abs_depth_var=0.1, min_near_support=7, sparsify=1, \
                      cut_first_keyframes=5, skip_border=True, seed=0)")]
    fn new(
        scaled_depth_var: f32,
        abs_depth_var: f32,
        #[pyo3(from_py_with = super::arrays::uint::min_near_support)] min_near_support: u32,
        #[pyo3(from_py_with = super::arrays::uint::sparsify)] sparsify: u32,
        #[pyo3(from_py_with = super::arrays::uint::cut_first_keyframes)]
        cut_first_keyframes: Option<usize>,
        skip_border: bool,
        #[pyo3(from_py_with = super::arrays::uint::seed)] seed: u64,
    ) -> PyResult<Self> {
        let inner = PointFilter {
            scaled_depth_var,
            abs_depth_var,
            min_near_support,
            sparsify,
            cut_first_keyframes,
            skip_border,
            seed,
        };
        inner.validate()?;
        Ok(PyPointFilter { inner })
    }

    /// Every rule off: keeps every pixel with a finite inverse depth > 0.
    #[staticmethod]
    fn none() -> Self {
        PyPointFilter {
            inner: PointFilter::none(),
        }
    }

    #[getter]
    fn scaled_depth_var(&self) -> f32 {
        self.inner.scaled_depth_var
    }
    #[getter]
    fn abs_depth_var(&self) -> f32 {
        self.inner.abs_depth_var
    }
    #[getter]
    fn min_near_support(&self) -> u32 {
        self.inner.min_near_support
    }
    #[getter]
    fn sparsify(&self) -> u32 {
        self.inner.sparsify
    }
    #[getter]
    fn cut_first_keyframes(&self) -> Option<usize> {
        self.inner.cut_first_keyframes
    }
    #[getter]
    fn skip_border(&self) -> bool {
        self.inner.skip_border
    }
    #[getter]
    fn seed(&self) -> u64 {
        self.inner.seed
    }

    fn __repr__(&self) -> String {
        let f = &self.inner;
        let cut = f
            .cut_first_keyframes
            .map_or("None".to_string(), |n| n.to_string());
        format!(
            "PointFilter(scaled_depth_var={}, abs_depth_var={}, min_near_support={}, sparsify={}, \
             cut_first_keyframes={cut}, skip_border={}, seed={})",
            f.scaled_depth_var,
            f.abs_depth_var,
            f.min_near_support,
            f.sparsify,
            if f.skip_border { "True" } else { "False" },
            f.seed
        )
    }
}

/// Points (N, 3) float32, colours (N, 3) uint8 or None, source keyframe ids (N,)
/// int32 (-1 when unknown). The arrays are read-only.
#[pyclass(name = "PointCloud", module = "slam2world._slam2world", frozen)]
pub struct PyPointCloud {
    points: Py<PyArray2<f32>>,
    colors: Option<Py<PyArray2<u8>>>,
    keyframe_ids: Py<PyArray1<i32>>,
}

impl PyPointCloud {
    /// Wraps a core cloud's buffers as read-only NumPy arrays without copying.
    pub fn from_core(py: Python<'_>, c: PointCloud) -> PyResult<Self> {
        let n = c.len();
        let bad =
            |e: numpy::ndarray::ShapeError| PyErr::from(Error::invalid("cloud", e.to_string()));
        let points = Array2::from_shape_vec((n, 3), c.points)
            .map_err(bad)?
            .into_pyarray(py);
        freeze(&points)?;
        let colors = match c.colors {
            Some(col) => {
                let a = Array2::from_shape_vec((n, 3), col)
                    .map_err(bad)?
                    .into_pyarray(py);
                freeze(&a)?;
                Some(a.unbind())
            }
            None => None,
        };
        let ids = Array1::from_vec(c.keyframe_ids).into_pyarray(py);
        freeze(&ids)?;
        Ok(PyPointCloud {
            points: points.unbind(),
            colors,
            keyframe_ids: ids.unbind(),
        })
    }

    /// The points as a read-only view (C-contiguous by construction).
    fn points_view<'py>(&self, py: Python<'py>) -> PyReadonlyArray2<'py, f32> {
        self.points.bind(py).readonly()
    }
}

#[pymethods]
impl PyPointCloud {
    #[new]
    #[pyo3(signature = (points, colors=None, keyframe_ids=None))]
    fn new(
        py: Python<'_>,
        points: &Bound<'_, PyAny>,
        colors: Option<&Bound<'_, PyAny>>,
        keyframe_ids: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let pts: Vec<f32> = match Points::extract(points, "points")? {
            Points::F32(a) => a.as_array().iter().copied().collect(),
            Points::F64(a) => a.as_array().iter().map(|&v| v as f32).collect(),
        };
        let colors = match colors {
            Some(c) => {
                let a = c
                    .cast::<PyArray2<u8>>()
                    .map_err(|_| {
                        shape_err("colors", "a uint8 array (N, 3)".into(), "not one".into())
                    })?
                    .readonly();
                if a.shape()[1] != 3 {
                    return Err(shape_err(
                        "colors",
                        "(N, 3)".into(),
                        format!("{:?}", a.shape()),
                    ));
                }
                Some(a.as_array().iter().copied().collect())
            }
            None => None,
        };
        let ids = match keyframe_ids {
            Some(i) => {
                let a: PyArrayLike1<'_, i32, AllowTypeChange> = i.extract().map_err(|_| {
                    shape_err(
                        "keyframe_ids",
                        "a 1-D integer array".into(),
                        "not one".into(),
                    )
                })?;
                Some(a.as_array().to_vec())
            }
            None => None,
        };
        Self::from_core(py, PointCloud::try_new(pts, colors, ids)?)
    }

    /// (N, 3) float32, read-only.
    #[getter]
    fn points<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f32>> {
        self.points.bind(py).clone()
    }

    /// (N, 3) uint8 or None, read-only.
    #[getter]
    fn colors<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<u8>>> {
        self.colors.as_ref().map(|c| c.bind(py).clone())
    }

    /// (N,) int32, read-only.
    #[getter]
    fn keyframe_ids<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i32>> {
        self.keyframe_ids.bind(py).clone()
    }

    fn __len__(&self, py: Python<'_>) -> usize {
        self.points.bind(py).shape()[0]
    }

    /// The cloud carried by `transform` (GIL released); colours and ids are shared.
    fn transformed(&self, py: Python<'_>, transform: PyRef<'_, PySim3>) -> PyResult<Self> {
        let t = transform.inner;
        let view = self.points_view(py);
        let src = view.as_slice()?;
        let out = py.detach(|| t.transform_points(src))?;
        let n = out.len() / 3;
        let pts = Array2::from_shape_vec((n, 3), out)
            .map_err(|e| PyErr::from(Error::invalid("cloud", e.to_string())))?
            .into_pyarray(py);
        freeze(&pts)?;
        Ok(PyPointCloud {
            points: pts.unbind(),
            colors: self.colors.as_ref().map(|c| c.clone_ref(py)),
            keyframe_ids: self.keyframe_ids.clone_ref(py),
        })
    }

    /// Writes a binary little-endian PLY (x y z float, red green blue uchar when
    /// there are colours), atomically; the GIL is released.
    fn write_ply(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let view = self.points_view(py);
        let pts = view.as_slice()?;
        let cview = self.colors.as_ref().map(|c| c.bind(py).readonly());
        let cols = cview.as_ref().map(|c| c.as_slice()).transpose()?;
        py.detach(|| ply::write_ply_parts(&path, pts, cols))?;
        Ok(())
    }

    /// Writes LAS 1.4 (LAZ for a `.laz` path) of the cloud taken as ENU metres
    /// at `origin` (lat, lon, alt), in `crs` "utm" (the origin's zone unless
    /// `zone` is given) or "ecef", with its CRS record; returns the EPSG code.
    #[pyo3(signature = (path, *, origin, crs="utm", zone=None, hemisphere=None))]
    fn write_las(
        &self,
        py: Python<'_>,
        path: PathBuf,
        origin: &Bound<'_, PyAny>,
        crs: &str,
        #[pyo3(from_py_with = super::arrays::uint::opt_zone)] zone: Option<u8>,
        hemisphere: Option<&str>,
    ) -> PyResult<u16> {
        let colors = self.colors.as_ref().map(|c| c.bind(py).readonly());
        super::geo::write_las(
            py,
            self.points_view(py),
            colors,
            path,
            origin,
            crs,
            zone,
            hemisphere,
        )
    }

    /// Writes a binary PCD (x y z, rgb packed as PCL does), atomically.
    fn write_pcd(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let colors = self.colors.as_ref().map(|c| c.bind(py).readonly());
        super::geo::write_pcd(py, self.points_view(py), colors, path)
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        format!(
            "PointCloud({} points, colors={})",
            self.__len__(py),
            self.colors.is_some()
        )
    }
}

/// Keyframes into 3-D points with the viewer's filters (`filter=None`: defaults).
/// `transform` (T_world_slam) puts them in the world frame in the same pass;
/// `transforms` gives one T_world_slam per keyframe instead. GIL released.
#[pyfunction(name = "backproject")]
#[pyo3(signature = (keyframes, filter=None, *, transform=None, transforms=None))]
fn backproject_py(
    py: Python<'_>,
    keyframes: &Bound<'_, PyAny>,
    filter: Option<PyPointFilter>,
    transform: Option<PySim3>,
    transforms: Option<Vec<PySim3>>,
) -> PyResult<PyPointCloud> {
    let mut bound = Vec::new();
    for item in keyframes.try_iter()? {
        let item = item?;
        let kf = item.cast::<PyKeyframe>().map_err(|_| {
            PyErr::from(Error::invalid(
                "keyframes",
                format!("item {} is not a Keyframe", bound.len()),
            ))
        })?;
        bound.push(kf.clone());
    }
    let refs: Vec<&Keyframe> = bound.iter().map(|b| &*b.get().inner).collect();
    let filter = filter.map(|f| f.inner).unwrap_or_default();
    let cloud = match (transform, transforms) {
        (Some(_), Some(_)) => {
            return Err(
                Error::invalid("transform", "give `transform` or `transforms`, not both").into(),
            )
        }
        (t, None) => {
            let t = t.map(|t| t.inner);
            py.detach(|| cloud::backproject(&refs, &filter, t.as_ref()))?
        }
        (None, Some(ts)) => {
            let ts: Vec<Sim3> = ts.into_iter().map(|t| t.inner).collect();
            py.detach(|| cloud::backproject_per_keyframe(&refs, &filter, &ts))?
        }
    };
    PyPointCloud::from_core(py, cloud)
}

/// Reads the vertices of a PLY file (ascii or binary; the LSD-SLAM viewer's `pc.ply`).
#[pyfunction(name = "read_ply")]
fn read_ply_py(py: Python<'_>, path: PathBuf) -> PyResult<PyPointCloud> {
    let c = py.detach(|| ply::read_ply(&path))?;
    PyPointCloud::from_core(py, c)
}

/// Reads whitespace-separated `x y z` lines (ORB-SLAM's `MapPoints.txt`).
#[pyfunction(name = "read_xyz_text")]
fn read_xyz_text_py(py: Python<'_>, path: PathBuf) -> PyResult<PyPointCloud> {
    let c = py.detach(|| ply::read_xyz_text(&path))?;
    PyPointCloud::from_core(py, c)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyPinholeCamera>()?;
    m.add_class::<PyKeyframe>()?;
    m.add_class::<PyPointFilter>()?;
    m.add_class::<PyPointCloud>()?;
    m.add_function(wrap_pyfunction!(backproject_py, m)?)?;
    m.add_function(wrap_pyfunction!(read_ply_py, m)?)?;
    m.add_function(wrap_pyfunction!(read_xyz_text_py, m)?)?;
    Ok(())
}
