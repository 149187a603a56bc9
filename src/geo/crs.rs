//! Local ENU points carried into a global CRS (UTM zone or ECEF) for
//! georeferenced outputs.
//!
//! Far from the origin the ENU → UTM mapping is not a translation (the
//! tangent plane leaves the ellipsoid, grid north turns away from true north
//! by the meridian convergence, the UTM scale factor varies), so every point
//! goes the exact way: ENU → ECEF → geodetic → UTM, in parallel.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::geodesy::{ecef_to_geodetic, EnuFrame};
use super::utm::{ecef_wkt, UtmProjection, UtmZone};
use crate::error::{Error, Result};

/// The CRS of a georeferenced output.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GeoCrs {
    /// UTM easting, northing (m) and height above the WGS84 ellipsoid (m), in
    /// the given zone or, when `None`, the zone that holds the ENU origin.
    Utm(Option<UtmZone>),
    /// WGS84 ECEF (EPSG:4978), metres.
    Ecef,
}

impl GeoCrs {
    /// `"utm"` (with an optional zone) or `"ecef"`.
    pub fn parse(name: &str, zone: Option<UtmZone>) -> Result<Self> {
        match name.to_ascii_lowercase().as_str() {
            "utm" => Ok(GeoCrs::Utm(zone)),
            "ecef" if zone.is_none() => Ok(GeoCrs::Ecef),
            "ecef" => Err(Error::invalid(
                "zone",
                "a UTM zone makes no sense with crs=\"ecef\"",
            )),
            _ => Err(Error::invalid(
                "crs",
                format!("{name:?}: expected \"utm\" or \"ecef\""),
            )),
        }
    }
}

/// Points in a global CRS.
#[derive(Clone, Debug, PartialEq)]
pub struct CrsPoints {
    /// `(N, 3)` row-major, metres: UTM `(easting, northing, height)` or ECEF `(x, y, z)`.
    pub xyz: Vec<f64>,
    /// EPSG code of the CRS (326xx, 327xx or 4978).
    pub epsg: u16,
    /// The UTM zone, for a UTM CRS.
    pub zone: Option<UtmZone>,
    /// OGC WKT 1 of the CRS.
    pub wkt: &'static str,
}

/// ENU points (`(N, 3)` row-major `f32`, metres) of `frame` in `crs`.
/// Errors name the point that cannot be projected (a UTM zone holds points
/// within a few thousand km of its central meridian).
pub fn enu_to_crs(points: &[f32], frame: &EnuFrame, crs: GeoCrs) -> Result<CrsPoints> {
    if points.len() % 3 != 0 {
        return Err(Error::ShapeMismatch {
            what: "points".into(),
            expected: "(N, 3)".into(),
            got: format!("{} values", points.len()),
        });
    }
    if let Some(i) = points.iter().position(|v| !v.is_finite()) {
        return Err(Error::NonFinite {
            what: "points".into(),
            index: i / 3,
        });
    }
    let n = points.len() / 3;
    let ecef = |p: &[f32]| frame.enu_to_ecef(&Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64));
    let mut xyz = vec![0.0f64; 3 * n];
    match crs {
        GeoCrs::Ecef => {
            xyz.par_chunks_exact_mut(3)
                .zip(points.par_chunks_exact(3))
                .for_each(|(out, p)| out.copy_from_slice(ecef(p).as_slice()));
            Ok(CrsPoints {
                xyz,
                epsg: 4978,
                zone: None,
                wkt: ecef_wkt(),
            })
        }
        GeoCrs::Utm(zone) => {
            let o = frame.origin();
            let zone = match zone {
                Some(z) => z,
                None => UtmZone::containing(o.lat, o.lon)?,
            };
            let proj = UtmProjection::new(zone)?;
            xyz.par_chunks_exact_mut(3)
                .zip(points.par_chunks_exact(3))
                .enumerate()
                .try_for_each(|(i, (out, p))| -> Result<()> {
                    let g = ecef_to_geodetic(&ecef(p))?;
                    out.copy_from_slice(proj.forward(&g, i)?.as_slice());
                    Ok(())
                })?;
            Ok(CrsPoints {
                xyz,
                epsg: zone.epsg(),
                zone: Some(zone),
                wkt: zone.wkt()?,
            })
        }
    }
}
