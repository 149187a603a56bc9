//! WGS84 geodetic coordinates, Earth-centred Earth-fixed (ECEF) and local
//! east-north-up (ENU) frames.
//!
//! - Geodetic: latitude and longitude in **degrees**, height in metres above
//!   the WGS84 ellipsoid (not above the geoid / mean sea level).
//! - ECEF (EPSG:4978): metres, x through (0°N, 0°E), z through the north pole.
//! - ENU at an origin: metres, x east, y north, z up along the ellipsoid normal
//!   of the origin (the local tangent plane).
//!
//! Geodetic ↔ ECEF is `map_3d` (a port of pymap3d: the closed form forward,
//! You (2000) with one correction step for the inverse); the ENU rotation is
//! built once per origin here.

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// A WGS84 geodetic position: `lat`, `lon` in degrees, `alt` in metres above
/// the ellipsoid.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Geodetic {
    /// Latitude, degrees north, in [-90, 90].
    pub lat: f64,
    /// Longitude, degrees east (any finite value; 190 is -170).
    pub lon: f64,
    /// Height above the WGS84 ellipsoid, metres.
    pub alt: f64,
}

impl Geodetic {
    /// Checks that all three are finite and the latitude is within ±90°.
    pub fn try_new(lat: f64, lon: f64, alt: f64) -> Result<Self> {
        check_geodetic("position", 0, lat, lon, alt)?;
        Ok(Geodetic { lat, lon, alt })
    }

    /// ECEF position, metres.
    pub fn to_ecef(&self) -> Vector3<f64> {
        geodetic_to_ecef(self)
    }
}

/// The domain check of a geodetic triple, naming the argument and index.
pub(crate) fn check_geodetic(what: &str, index: usize, lat: f64, lon: f64, alt: f64) -> Result<()> {
    let bad = |field: &str, value: f64, expected: &str| Error::InvalidFix {
        what: what.into(),
        index,
        field: field.into(),
        value,
        expected: expected.into(),
    };
    if !lat.is_finite() {
        return Err(bad("latitude", lat, "a finite number of degrees"));
    }
    if !(-90.0..=90.0).contains(&lat) {
        return Err(bad("latitude", lat, "degrees within [-90, 90]"));
    }
    if !lon.is_finite() {
        return Err(bad("longitude", lon, "a finite number of degrees"));
    }
    if !alt.is_finite() {
        return Err(bad("altitude", alt, "a finite number of metres"));
    }
    Ok(())
}

/// Geodetic (degrees, metres above the ellipsoid) to ECEF (metres).
pub fn geodetic_to_ecef(g: &Geodetic) -> Vector3<f64> {
    let (x, y, z) = map_3d::geodetic2ecef(
        g.lat.to_radians(),
        g.lon.to_radians(),
        g.alt,
        map_3d::Ellipsoid::WGS84,
    );
    Vector3::new(x, y, z)
}

/// ECEF (metres) to geodetic (degrees in [-90, 90] × (-180, 180], metres
/// above the ellipsoid). The centre of the Earth (where the latitude is
/// undefined) and non-finite input are errors.
pub fn ecef_to_geodetic(p: &Vector3<f64>) -> Result<Geodetic> {
    if p.iter().any(|v| !v.is_finite()) {
        return Err(Error::NonFinite {
            what: "ECEF position".into(),
            index: 0,
        });
    }
    let (lat, lon, alt) = map_3d::ecef2geodetic(p.x, p.y, p.z, map_3d::Ellipsoid::WGS84);
    if !(lat.is_finite() && lon.is_finite() && alt.is_finite()) {
        return Err(Error::Degenerate {
            reason: "ECEF position at the centre of the Earth has no geodetic latitude".into(),
            value: p.norm(),
        });
    }
    Ok(Geodetic {
        lat: lat.to_degrees(),
        lon: lon.to_degrees(),
        alt,
    })
}

/// `R_enu_ecef` at a latitude and longitude (degrees): rows are the east,
/// north and up unit vectors in ECEF.
pub fn rotation_enu_ecef(lat: f64, lon: f64) -> Matrix3<f64> {
    let (sp, cp) = lat.to_radians().sin_cos();
    let (sl, cl) = lon.to_radians().sin_cos();
    Matrix3::new(-sl, cl, 0.0, -sp * cl, -sp * sl, cp, cp * cl, cp * sl, sp)
}

/// A local east-north-up frame at a geodetic origin: x east, y north, z up
/// (the ellipsoid normal at the origin), metres; the origin is (0, 0, 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnuFrame {
    origin: Geodetic,
    origin_ecef: Vector3<f64>,
    /// `R_enu_ecef`.
    rotation: Matrix3<f64>,
}

impl EnuFrame {
    /// The frame at `origin` (checked like [`Geodetic::try_new`]).
    pub fn new(origin: Geodetic) -> Result<Self> {
        check_geodetic("origin", 0, origin.lat, origin.lon, origin.alt)?;
        Ok(EnuFrame {
            origin,
            origin_ecef: geodetic_to_ecef(&origin),
            rotation: rotation_enu_ecef(origin.lat, origin.lon),
        })
    }

    /// The origin (degrees, metres above the ellipsoid).
    pub fn origin(&self) -> Geodetic {
        self.origin
    }

    /// The origin in ECEF, metres.
    pub fn origin_ecef(&self) -> Vector3<f64> {
        self.origin_ecef
    }

    /// `R_enu_ecef`: rotates ECEF vectors into ENU.
    pub fn rotation_enu_ecef(&self) -> Matrix3<f64> {
        self.rotation
    }

    /// ECEF position (metres) to ENU (metres).
    pub fn ecef_to_enu(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * (p - self.origin_ecef)
    }

    /// ENU position (metres) to ECEF (metres).
    pub fn enu_to_ecef(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation.tr_mul(p) + self.origin_ecef
    }

    /// Geodetic position to ENU (metres).
    pub fn geodetic_to_enu(&self, g: &Geodetic) -> Vector3<f64> {
        self.ecef_to_enu(&geodetic_to_ecef(g))
    }

    /// ENU position (metres) to geodetic; errors as [`ecef_to_geodetic`].
    pub fn enu_to_geodetic(&self, p: &Vector3<f64>) -> Result<Geodetic> {
        ecef_to_geodetic(&self.enu_to_ecef(p))
    }
}

/// Where the ENU origin of a set of fixes is put.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum Origin {
    /// The first fix.
    #[default]
    First,
    /// The centroid of the fixes in ECEF, taken back to geodetic (this is
    /// right across the antimeridian, where a mean of longitudes is not; its
    /// height lies slightly below the mean height for a track kilometres wide).
    Mean,
    /// A given position.
    Given(Geodetic),
}

impl Origin {
    /// `"first"`, `"mean"` (the CLI and Python spelling); a given origin has no name.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "first" => Ok(Origin::First),
            "mean" => Ok(Origin::Mean),
            other => Err(Error::invalid(
                "origin",
                format!("{other:?}: expected \"first\", \"mean\" or a (lat, lon, alt) position"),
            )),
        }
    }

    /// The origin for positions `points` (already checked); `None` for an
    /// empty set when the origin is not given.
    pub fn resolve(&self, points: &[Geodetic]) -> Result<Geodetic> {
        match self {
            Origin::Given(g) => {
                check_geodetic("origin", 0, g.lat, g.lon, g.alt)?;
                Ok(*g)
            }
            Origin::First => points.first().copied().ok_or_else(|| Error::TooFew {
                what: "fixes for the ENU origin".into(),
                need: 1,
                got: 0,
            }),
            Origin::Mean => {
                if points.is_empty() {
                    return Err(Error::TooFew {
                        what: "fixes for the ENU origin".into(),
                        need: 1,
                        got: 0,
                    });
                }
                let sum: Vector3<f64> = points.iter().map(geodetic_to_ecef).sum();
                ecef_to_geodetic(&(sum / points.len() as f64))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_matches_map_3d() {
        let o = Geodetic::try_new(48.19, 11.62, 540.0).unwrap();
        let f = EnuFrame::new(o).unwrap();
        let g = Geodetic::try_new(48.2, 11.6, 600.0).unwrap();
        let ours = f.geodetic_to_enu(&g);
        let (e, n, u) = map_3d::geodetic2enu(
            g.lat.to_radians(),
            g.lon.to_radians(),
            g.alt,
            o.lat.to_radians(),
            o.lon.to_radians(),
            o.alt,
            map_3d::Ellipsoid::WGS84,
        );
        assert!(
            (ours - Vector3::new(e, n, u)).norm() < 1e-6,
            "{ours} vs {e} {n} {u}"
        );
        // Up really is up: a point 100 m above the origin.
        let above = Geodetic {
            alt: o.alt + 100.0,
            ..o
        };
        assert!((f.geodetic_to_enu(&above) - Vector3::new(0.0, 0.0, 100.0)).norm() < 1e-6);
    }

    #[test]
    fn round_trip_through_ecef() {
        for &(lat, lon, alt) in &[
            (0.0, 0.0, 0.0),
            (89.9999, 10.0, 3000.0),
            (-90.0, 0.0, -50.0),
            (45.0, 179.9999, 8848.0),
            (-33.9, -70.6, 12_000.0),
        ] {
            let g = Geodetic::try_new(lat, lon, alt).unwrap();
            let back = ecef_to_geodetic(&g.to_ecef()).unwrap();
            let d = (back.to_ecef() - g.to_ecef()).norm();
            assert!(d < 1e-6, "{g:?} -> {back:?}: {d} m");
        }
        assert!(ecef_to_geodetic(&Vector3::zeros()).is_err());
    }

    #[test]
    fn bad_coordinates_are_typed_errors() {
        assert!(matches!(
            Geodetic::try_new(90.5, 0.0, 0.0),
            Err(Error::InvalidFix { ref field, .. }) if field == "latitude"
        ));
        assert!(Geodetic::try_new(f64::NAN, 0.0, 0.0).is_err());
        assert!(Geodetic::try_new(0.0, f64::INFINITY, 0.0).is_err());
        assert!(Origin::parse("middle").is_err());
    }
}
