//! Bindings of `crate::geo` (geodesy, UTM, GNSS fixes), `io::gnss` and the
//! georeferenced writers (`io::las`, `io::pcd`; methods of `PointCloud`).
//!
//! Arrays: latitudes, longitudes, heights `(N,)` float64 (degrees, degrees,
//! metres above the WGS84 ellipsoid); ENU / ECEF / UTM `(N, 3)` float64 metres.

use std::path::PathBuf;

use nalgebra::{Matrix3, Vector3};
use numpy::{
    AllowTypeChange, IntoPyArray, PyArray1, PyArray2, PyArray3, PyArrayLike1, PyArrayLike3,
    PyReadonlyArray2, PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use rayon::prelude::*;

use super::arrays::{rows_f64, to_array2};
use super::trajectory::PyTrajectory;
use crate::error::Error;
use crate::geo::{
    self, EnuFrame, FixStatus, GeoCrs, Geodetic, GnssFixes, Hemisphere, Origin, TimeBase, UtmZone,
};
use crate::io::gnss::{read_gnss, GnssFormat};

fn shape_err(what: &str, expected: &str, got: String) -> PyErr {
    Error::ShapeMismatch {
        what: what.into(),
        expected: expected.into(),
        got,
    }
    .into()
}

/// A 1-D float64 array-like (NaN kept: the geodetic checks name the index).
fn column(obj: &Bound<'_, PyAny>, what: &str, len: Option<usize>) -> PyResult<Vec<f64>> {
    let a: PyArrayLike1<'_, f64, AllowTypeChange> = obj
        .extract()
        .map_err(|_| shape_err(what, "a 1-D float array (N,)", "not one".into()))?;
    let v = a.as_array().to_vec();
    if let Some(n) = len {
        if v.len() != n {
            return Err(shape_err(
                what,
                &format!("({n},)"),
                format!("({},)", v.len()),
            ));
        }
    }
    Ok(v)
}

/// `lat`, `lon`, `alt` columns into checked geodetic positions.
fn geodetic_columns(
    lat: &Bound<'_, PyAny>,
    lon: &Bound<'_, PyAny>,
    alt: &Bound<'_, PyAny>,
) -> PyResult<Vec<Geodetic>> {
    let lat = column(lat, "lat", None)?;
    let n = lat.len();
    let lon = column(lon, "lon", Some(n))?;
    let alt = column(alt, "alt", Some(n))?;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        geo::geodesy::check_geodetic("position", i, lat[i], lon[i], alt[i])?;
        out.push(Geodetic {
            lat: lat[i],
            lon: lon[i],
            alt: alt[i],
        });
    }
    Ok(out)
}

fn vectors(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<Vector3<f64>>> {
    let v = rows_f64(obj, what, 3)?;
    Ok(v.chunks_exact(3)
        .map(|c| Vector3::new(c[0], c[1], c[2]))
        .collect())
}

fn rows_out<'py>(py: Python<'py>, v: &[Vector3<f64>]) -> PyResult<Bound<'py, PyArray2<f64>>> {
    to_array2(py, v.iter().flat_map(|p| [p.x, p.y, p.z]).collect(), 3)
}

type Columns<'py> = (
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
);

fn columns_out<'py>(py: Python<'py>, g: &[Geodetic]) -> Columns<'py> {
    (
        g.iter().map(|g| g.lat).collect::<Vec<_>>().into_pyarray(py),
        g.iter().map(|g| g.lon).collect::<Vec<_>>().into_pyarray(py),
        g.iter().map(|g| g.alt).collect::<Vec<_>>().into_pyarray(py),
    )
}

/// A position `(lat, lon, alt)`.
fn position(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Geodetic> {
    let v: Vec<f64> = obj.extract().map_err(|_| {
        PyErr::from(Error::invalid(
            what,
            "expected a (lat, lon, alt) position: degrees, degrees, metres above the ellipsoid",
        ))
    })?;
    if v.len() != 3 {
        return Err(shape_err(
            what,
            "(lat, lon, alt)",
            format!("{} values", v.len()),
        ));
    }
    Ok(Geodetic::try_new(v[0], v[1], v[2])?)
}

/// `"first"`, `"mean"` or a position.
pub(crate) fn origin_arg(obj: &Bound<'_, PyAny>) -> PyResult<Origin> {
    if let Ok(s) = obj.extract::<String>() {
        return Ok(Origin::parse(&s)?);
    }
    Ok(Origin::Given(position(obj, "origin")?))
}

fn zone_arg(
    zone: Option<u8>,
    hemisphere: Option<&str>,
    lat: Option<f64>,
) -> PyResult<Option<UtmZone>> {
    match (zone, hemisphere) {
        (None, None) => Ok(None),
        (None, Some(_)) => Err(Error::invalid("hemisphere", "given without a zone").into()),
        (Some(z), h) => {
            let h = match h {
                Some(h) => Hemisphere::parse(h)?,
                None if lat.is_some_and(|l| l < 0.0) => Hemisphere::South,
                None => Hemisphere::North,
            };
            Ok(Some(UtmZone::try_new(z, h)?))
        }
    }
}

fn status_name(s: FixStatus) -> &'static str {
    match s {
        FixStatus::NoFix => "no_fix",
        FixStatus::Single => "single",
        FixStatus::Differential => "differential",
        FixStatus::RtkFixed => "rtk_fixed",
        FixStatus::RtkFloat => "rtk_float",
        FixStatus::Estimated => "estimated",
        FixStatus::Other => "other",
    }
}

fn status_from_name(s: &str) -> PyResult<FixStatus> {
    Ok(match s {
        "no_fix" => FixStatus::NoFix,
        "single" => FixStatus::Single,
        "differential" => FixStatus::Differential,
        "rtk_fixed" => FixStatus::RtkFixed,
        "rtk_float" => FixStatus::RtkFloat,
        "estimated" => FixStatus::Estimated,
        "other" => FixStatus::Other,
        _ => {
            return Err(Error::invalid(
                "status",
                format!(
                    "{s:?}: expected one of no_fix, single, differential, rtk_fixed, rtk_float, estimated, other"
                ),
            )
            .into())
        }
    })
}

/// GNSS fixes: times (s), lat/lon (degrees), alt (m above WGS84), ENU
/// covariance (m²) where known, status; "no fix" entries dropped and counted.
#[pyclass(name = "GnssFixes", module = "slam2world._slam2world", frozen)]
pub struct PyGnssFixes {
    pub inner: GnssFixes,
}

#[pymethods]
impl PyGnssFixes {
    #[new]
    #[pyo3(signature = (times, lat, lon, alt, covariance=None, status=None))]
    fn new(
        times: &Bound<'_, PyAny>,
        lat: &Bound<'_, PyAny>,
        lon: &Bound<'_, PyAny>,
        alt: &Bound<'_, PyAny>,
        covariance: Option<&Bound<'_, PyAny>>,
        status: Option<Vec<String>>,
    ) -> PyResult<Self> {
        let times = column(times, "times", None)?;
        let n = times.len();
        let lat = column(lat, "lat", Some(n))?;
        let lon = column(lon, "lon", Some(n))?;
        let alt = column(alt, "alt", Some(n))?;
        let covariance = match covariance {
            Some(c) => {
                let a: PyArrayLike3<'_, f64, AllowTypeChange> = c.extract().map_err(|_| {
                    shape_err("covariance", "a float array (N, 3, 3)", "not one".into())
                })?;
                let shape = a.shape().to_vec();
                if shape != [n, 3, 3] {
                    return Err(shape_err(
                        "covariance",
                        &format!("({n}, 3, 3)"),
                        format!("{shape:?}"),
                    ));
                }
                let v: Vec<f64> = a.as_array().iter().copied().collect();
                // A row of NaN means "unknown" for that fix.
                Some(
                    v.chunks_exact(9)
                        .map(|m| {
                            (!m.iter().all(|x| x.is_nan())).then(|| Matrix3::from_row_slice(m))
                        })
                        .collect(),
                )
            }
            None => None,
        };
        let status = match status {
            Some(s) => {
                if s.len() != n {
                    return Err(shape_err(
                        "status",
                        &format!("({n},)"),
                        format!("({},)", s.len()),
                    ));
                }
                Some(
                    s.iter()
                        .map(|x| status_from_name(x))
                        .collect::<PyResult<Vec<_>>>()?,
                )
            }
            None => None,
        };
        Ok(PyGnssFixes {
            inner: GnssFixes::try_new(times, lat, lon, alt, covariance, status)?,
        })
    }

    /// (N,) seconds.
    #[getter]
    fn times<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.times.clone().into_pyarray(py)
    }
    /// (N,) degrees north.
    #[getter]
    fn lat<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.lat.clone().into_pyarray(py)
    }
    /// (N,) degrees east.
    #[getter]
    fn lon<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.lon.clone().into_pyarray(py)
    }
    /// (N,) metres above the WGS84 ellipsoid.
    #[getter]
    fn alt<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.alt.clone().into_pyarray(py)
    }
    /// (N, 3, 3) ENU covariance in m² (NaN where a fix has none), or None when no fix has one.
    #[getter]
    fn covariance<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArray3<f64>>>> {
        if self.inner.covariance.iter().all(Option::is_none) {
            return Ok(None);
        }
        let mut v = Vec::with_capacity(9 * self.inner.len());
        for c in &self.inner.covariance {
            match c {
                Some(m) => {
                    for r in 0..3 {
                        for k in 0..3 {
                            v.push(m[(r, k)]);
                        }
                    }
                }
                None => v.extend([f64::NAN; 9]),
            }
        }
        let a = numpy::ndarray::Array3::from_shape_vec((self.inner.len(), 3, 3), v)
            .map_err(|e| PyErr::from(Error::invalid("covariance", e.to_string())))?;
        Ok(Some(a.into_pyarray(py)))
    }
    /// Status per fix: "single", "differential", "rtk_fixed", "rtk_float", "estimated", "other".
    #[getter]
    fn status(&self) -> Vec<&'static str> {
        self.inner.status.iter().map(|s| status_name(*s)).collect()
    }
    /// How many "no fix" entries the source had (dropped).
    #[getter]
    fn dropped_no_fix(&self) -> usize {
        self.inner.dropped_no_fix
    }
    /// "source" (Unix / the source's stamps) or "time_of_day" (NMEA without a date).
    #[getter]
    fn time_base(&self) -> &'static str {
        match self.inner.time_base {
            TimeBase::Source => "source",
            TimeBase::TimeOfDay => "time_of_day",
        }
    }
    fn __len__(&self) -> usize {
        self.inner.len()
    }
    /// (N,) `1 / (trace(cov)/3)` (1/m²), or None unless every fix has a covariance.
    fn weights<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.inner.weights().map(|w| w.into_pyarray(py))
    }
    /// The track in ENU at `origin` ("first", "mean" or `(lat, lon, alt)`):
    /// `(Trajectory (ENU metres, no orientations), weights or None, origin (lat, lon, alt))`.
    #[pyo3(signature = (origin=None))]
    #[allow(clippy::type_complexity)]
    fn to_enu<'py>(
        &self,
        py: Python<'py>,
        origin: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<(
        PyTrajectory,
        Option<Bound<'py, PyArray1<f64>>>,
        (f64, f64, f64),
    )> {
        let origin = match origin {
            Some(o) => origin_arg(o)?,
            None => Origin::First,
        };
        let t = py.detach(|| self.inner.to_enu(&origin))?;
        let o = t.frame.origin();
        Ok((
            PyTrajectory {
                inner: t.trajectory.into(),
            },
            t.weights.map(|w| w.into_pyarray(py)),
            (o.lat, o.lon, o.alt),
        ))
    }
    fn __repr__(&self) -> String {
        format!(
            "GnssFixes({} fixes, {} without a fix dropped)",
            self.inner.len(),
            self.inner.dropped_no_fix
        )
    }
}

/// Reads GNSS fixes: NMEA, CSV/TXT or MCAP (`format=None`: detected).
#[pyfunction(name = "read_gnss")]
#[pyo3(signature = (path, *, format=None, geoid_offset=0.0))]
fn read_gnss_py(
    py: Python<'_>,
    path: PathBuf,
    format: Option<&str>,
    geoid_offset: f64,
) -> PyResult<PyGnssFixes> {
    let format = format.map(GnssFormat::parse).transpose()?;
    let inner = py.detach(|| read_gnss(&path, format, geoid_offset))?;
    Ok(PyGnssFixes { inner })
}

/// Geodetic (N,) columns to ENU (N, 3) metres at `origin` ("first", "mean" of these, or a position).
#[pyfunction(name = "geodetic_to_enu")]
fn geodetic_to_enu_py<'py>(
    py: Python<'py>,
    lat: &Bound<'py, PyAny>,
    lon: &Bound<'py, PyAny>,
    alt: &Bound<'py, PyAny>,
    origin: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let g = geodetic_columns(lat, lon, alt)?;
    let origin = origin_arg(origin)?;
    let out = py.detach(|| -> crate::Result<Vec<Vector3<f64>>> {
        let frame = EnuFrame::new(origin.resolve(&g)?)?;
        Ok(g.par_iter().map(|p| frame.geodetic_to_enu(p)).collect())
    })?;
    rows_out(py, &out)
}

/// ENU (N, 3) metres at `origin` (a position) to `(lat, lon, alt)` columns.
#[pyfunction(name = "enu_to_geodetic")]
fn enu_to_geodetic_py<'py>(
    py: Python<'py>,
    enu: &Bound<'py, PyAny>,
    origin: &Bound<'py, PyAny>,
) -> PyResult<Columns<'py>> {
    let p = vectors(enu, "enu")?;
    let frame = EnuFrame::new(position(origin, "origin")?)?;
    let g = py.detach(|| {
        p.par_iter()
            .map(|v| frame.enu_to_geodetic(v))
            .collect::<crate::Result<Vec<_>>>()
    })?;
    Ok(columns_out(py, &g))
}

/// Geodetic (N,) columns to ECEF (N, 3) metres.
#[pyfunction(name = "geodetic_to_ecef")]
fn geodetic_to_ecef_py<'py>(
    py: Python<'py>,
    lat: &Bound<'py, PyAny>,
    lon: &Bound<'py, PyAny>,
    alt: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let g = geodetic_columns(lat, lon, alt)?;
    let out: Vec<Vector3<f64>> = py.detach(|| g.par_iter().map(geo::geodetic_to_ecef).collect());
    rows_out(py, &out)
}

/// ECEF (N, 3) metres to `(lat, lon, alt)` columns.
#[pyfunction(name = "ecef_to_geodetic")]
fn ecef_to_geodetic_py<'py>(py: Python<'py>, ecef: &Bound<'py, PyAny>) -> PyResult<Columns<'py>> {
    let p = vectors(ecef, "ecef")?;
    let g = py.detach(|| {
        p.par_iter()
            .map(geo::ecef_to_geodetic)
            .collect::<crate::Result<Vec<_>>>()
    })?;
    Ok(columns_out(py, &g))
}

/// Geodetic columns to UTM `(xyz (N, 3), zone, hemisphere, epsg)`; the zone
/// is the one holding the first point unless given.
#[pyfunction(name = "geodetic_to_utm")]
#[pyo3(signature = (lat, lon, alt, zone=None, *, hemisphere=None))]
fn geodetic_to_utm_py<'py>(
    py: Python<'py>,
    lat: &Bound<'py, PyAny>,
    lon: &Bound<'py, PyAny>,
    alt: &Bound<'py, PyAny>,
    #[pyo3(from_py_with = super::arrays::uint::opt_zone)] zone: Option<u8>,
    hemisphere: Option<&str>,
) -> PyResult<(Bound<'py, PyArray2<f64>>, u8, &'static str, u16)> {
    let g = geodetic_columns(lat, lon, alt)?;
    let zone = zone_arg(zone, hemisphere, g.first().map(|p| p.lat))?;
    let (xyz, zone) = py.detach(|| geo::geodetic_to_utm(&g, zone))?;
    Ok((
        rows_out(py, &xyz)?,
        zone.number,
        zone.hemisphere.name(),
        zone.epsg(),
    ))
}

/// UTM (N, 3) `(easting, northing, height)` of `zone` / `hemisphere` to `(lat, lon, alt)` columns.
#[pyfunction(name = "utm_to_geodetic")]
#[pyo3(signature = (xyz, zone, hemisphere="north"))]
fn utm_to_geodetic_py<'py>(
    py: Python<'py>,
    xyz: &Bound<'py, PyAny>,
    #[pyo3(from_py_with = super::arrays::uint::zone)] zone: u8,
    hemisphere: &str,
) -> PyResult<Columns<'py>> {
    let p = vectors(xyz, "xyz")?;
    let zone = UtmZone::try_new(zone, Hemisphere::parse(hemisphere)?)?;
    let g = py.detach(|| geo::utm_to_geodetic(&p, zone))?;
    Ok(columns_out(py, &g))
}

#[allow(clippy::too_many_arguments)]
/// `PointCloud.write_las`: the cloud (ENU metres at `origin`) as LAS 1.4 / LAZ
/// in `crs` ("utm" or "ecef"); returns the EPSG code written.
pub fn write_las(
    py: Python<'_>,
    points: PyReadonlyArray2<'_, f32>,
    colors: Option<PyReadonlyArray2<'_, u8>>,
    path: PathBuf,
    origin: &Bound<'_, PyAny>,
    crs: &str,
    zone: Option<u8>,
    hemisphere: Option<&str>,
) -> PyResult<u16> {
    let origin = position(origin, "origin")?;
    let crs = GeoCrs::parse(crs, zone_arg(zone, hemisphere, Some(origin.lat))?)?;
    let pts = points.as_slice()?;
    let cols = colors.as_ref().map(|c| c.as_slice()).transpose()?;
    let info = py.detach(|| crate::io::las::write_las_parts(&path, pts, cols, &origin, crs))?;
    Ok(info.epsg)
}

/// `PointCloud.write_pcd`: binary PCD (x y z [rgb]).
pub fn write_pcd(
    py: Python<'_>,
    points: PyReadonlyArray2<'_, f32>,
    colors: Option<PyReadonlyArray2<'_, u8>>,
    path: PathBuf,
) -> PyResult<()> {
    let pts = points.as_slice()?;
    let cols = colors.as_ref().map(|c| c.as_slice()).transpose()?;
    py.detach(|| crate::io::pcd::write_pcd_parts(&path, pts, cols))?;
    Ok(())
}

/// Adds the geodesy functions and `GnssFixes` to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyGnssFixes>()?;
    m.add_function(wrap_pyfunction!(read_gnss_py, m)?)?;
    m.add_function(wrap_pyfunction!(geodetic_to_enu_py, m)?)?;
    m.add_function(wrap_pyfunction!(enu_to_geodetic_py, m)?)?;
    m.add_function(wrap_pyfunction!(geodetic_to_ecef_py, m)?)?;
    m.add_function(wrap_pyfunction!(ecef_to_geodetic_py, m)?)?;
    m.add_function(wrap_pyfunction!(geodetic_to_utm_py, m)?)?;
    m.add_function(wrap_pyfunction!(utm_to_geodetic_py, m)?)?;
    Ok(())
}
