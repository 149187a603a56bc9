//! UTM zone coordinates on WGS84 (EPSG:326xx north, 327xx south).
//!
//! The projection is `proj4rs`'s transverse Mercator by Poder/Engsager, the
//! algorithm PROJ (and so pyproj) uses for `+proj=utm`; the zone's definition
//! (proj string, WKT) comes from `crs-definitions`' EPSG table, so the CRS a
//! file names and the numbers in it come from one source.
//!
//! Coordinates: `(easting, northing, height)` in metres; the height is the
//! height above the WGS84 ellipsoid, passed through unchanged (a UTM CRS is
//! horizontal only).

use nalgebra::Vector3;
use proj4rs::proj::Proj;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::geodesy::{check_geodetic, Geodetic};
use crate::error::{Error, Result};

/// Above this many points a conversion runs in parallel.
const PARALLEL_MIN: usize = 4096;

/// North or south of the equator: the false northing (0 or 10 000 km) and the
/// EPSG series (326xx or 327xx).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Hemisphere {
    /// False northing 0, EPSG:326xx.
    North,
    /// False northing 10 000 000 m, EPSG:327xx.
    South,
}

impl Hemisphere {
    /// `"north"` / `"south"` (also `"n"` / `"s"`, any case).
    pub fn parse(name: &str) -> Result<Self> {
        match name.to_ascii_lowercase().as_str() {
            "north" | "n" => Ok(Hemisphere::North),
            "south" | "s" => Ok(Hemisphere::South),
            _ => Err(Error::invalid(
                "hemisphere",
                format!("{name:?}: expected \"north\" or \"south\""),
            )),
        }
    }

    /// `"north"` / `"south"`.
    pub fn name(self) -> &'static str {
        match self {
            Hemisphere::North => "north",
            Hemisphere::South => "south",
        }
    }
}

/// A UTM zone: number 1–60 (6° wide, zone 1 from 180°W) and hemisphere.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct UtmZone {
    /// 1–60.
    pub number: u8,
    /// North or south.
    pub hemisphere: Hemisphere,
}

impl UtmZone {
    /// Checks the zone number (1–60).
    pub fn try_new(number: u8, hemisphere: Hemisphere) -> Result<Self> {
        if !(1..=60).contains(&number) {
            return Err(Error::invalid(
                "UTM zone",
                format!("{number}: expected a zone number 1 to 60"),
            ));
        }
        Ok(UtmZone { number, hemisphere })
    }

    /// The zone of the standard UTM grid that holds a position (degrees), with
    /// the Norway (32V) and Svalbard (31X–37X) exceptions, and the hemisphere
    /// of its latitude (0° is north). UTM covers 80°S to 84°N: beyond, the
    /// position is refused (UPS is not implemented; use ECEF or ENU there).
    pub fn containing(lat: f64, lon: f64) -> Result<Self> {
        check_geodetic("position", 0, lat, lon, 0.0)?;
        if !(-80.0..=84.0).contains(&lat) {
            return Err(Error::InvalidFix {
                what: "position for a UTM zone".into(),
                index: 0,
                field: "latitude".into(),
                value: lat,
                expected: "degrees within [-80, 84], where UTM is defined".into(),
            });
        }
        let lon = normalize_lon(lon);
        let mut number = ((lon + 180.0) / 6.0).floor() as i32 + 1;
        if (56.0..64.0).contains(&lat) && (3.0..12.0).contains(&lon) {
            number = 32;
        }
        if (72.0..=84.0).contains(&lat) && (0.0..42.0).contains(&lon) {
            number = match lon {
                l if l < 9.0 => 31,
                l if l < 21.0 => 33,
                l if l < 33.0 => 35,
                _ => 37,
            };
        }
        let hemisphere = if lat >= 0.0 {
            Hemisphere::North
        } else {
            Hemisphere::South
        };
        UtmZone::try_new(number.clamp(1, 60) as u8, hemisphere)
    }

    /// EPSG code: 32600 + zone (north) or 32700 + zone (south).
    pub fn epsg(&self) -> u16 {
        match self.hemisphere {
            Hemisphere::North => 32600 + self.number as u16,
            Hemisphere::South => 32700 + self.number as u16,
        }
    }

    /// Longitude of the zone's central meridian, degrees.
    pub fn central_meridian(&self) -> f64 {
        self.number as f64 * 6.0 - 183.0
    }

    fn definition(&self) -> Result<crs_definitions::Def> {
        crs_definitions::from_code(self.epsg()).ok_or_else(|| {
            Error::invalid(
                "UTM zone",
                format!("EPSG:{} is missing from the EPSG table", self.epsg()),
            )
        })
    }

    /// The zone's CRS as OGC WKT 1 (EPSG's own text, `AUTHORITY["EPSG","326xx"]`).
    pub fn wkt(&self) -> Result<&'static str> {
        Ok(self.definition()?.wkt)
    }
}

/// Longitude into [-180, 180).
pub(crate) fn normalize_lon(lon: f64) -> f64 {
    (lon + 180.0).rem_euclid(360.0) - 180.0
}

/// OGC WKT 1 of WGS84 ECEF (EPSG:4978), for files in geocentric coordinates.
pub fn ecef_wkt() -> &'static str {
    crs_definitions::EPSG_4978.wkt
}

/// The forward and inverse UTM projection of one zone.
pub struct UtmProjection {
    zone: UtmZone,
    geographic: Proj,
    projected: Proj,
}

fn proj_err(what: &str, e: proj4rs::errors::Error) -> Error {
    Error::invalid(what, e.to_string())
}

impl UtmProjection {
    /// The projection of `zone` (from the EPSG definition of its code).
    pub fn new(zone: UtmZone) -> Result<Self> {
        let def = zone.definition()?;
        let projected = Proj::from_proj_string(def.proj4).map_err(|e| proj_err("UTM zone", e))?;
        let geographic = Proj::from_proj_string(crs_definitions::EPSG_4326.proj4)
            .map_err(|e| proj_err("WGS84", e))?;
        Ok(UtmProjection {
            zone,
            geographic,
            projected,
        })
    }

    /// The zone.
    pub fn zone(&self) -> UtmZone {
        self.zone
    }

    /// Geodetic (degrees, metres) to `(easting, northing, height)` metres;
    /// `index` names the point in errors.
    pub fn forward(&self, g: &Geodetic, index: usize) -> Result<Vector3<f64>> {
        check_geodetic("position", index, g.lat, g.lon, g.alt)?;
        let lon = normalize_lon(g.lon);
        let mut p = (lon.to_radians(), g.lat.to_radians(), g.alt);
        proj4rs::transform::transform(&self.geographic, &self.projected, &mut p)
            .map_err(|e| self.out_of_zone(index, format!("({}, {}): {e}", g.lat, g.lon)))?;
        let v = Vector3::new(p.0, p.1, p.2);
        if v.iter().any(|c| !c.is_finite()) {
            return Err(self.out_of_zone(index, format!("({}, {})", g.lat, g.lon)));
        }
        Ok(v)
    }

    /// `(easting, northing, height)` metres to geodetic (degrees, metres above
    /// the ellipsoid).
    pub fn inverse(&self, p: &Vector3<f64>, index: usize) -> Result<Geodetic> {
        if p.iter().any(|c| !c.is_finite()) {
            return Err(Error::NonFinite {
                what: "UTM coordinates".into(),
                index,
            });
        }
        let mut q = (p.x, p.y, p.z);
        proj4rs::transform::transform(&self.projected, &self.geographic, &mut q)
            .map_err(|e| self.out_of_zone(index, format!("({}, {}): {e}", p.x, p.y)))?;
        let g = Geodetic {
            lat: q.1.to_degrees(),
            lon: q.0.to_degrees(),
            alt: q.2,
        };
        if !(g.lat.is_finite() && g.lon.is_finite()) {
            return Err(self.out_of_zone(index, format!("({}, {})", p.x, p.y)));
        }
        Ok(g)
    }

    fn out_of_zone(&self, index: usize, what: String) -> Error {
        Error::OutOfRange {
            what: format!("point {index} in UTM zone {}", self.zone.epsg()),
            reason: format!("{what} cannot be projected in this zone"),
        }
    }
}

fn run<T: Send, U: Send + Sync>(
    items: &[U],
    f: impl Fn(usize, &U) -> Result<T> + Sync + Send,
) -> Result<Vec<T>> {
    if items.len() >= PARALLEL_MIN {
        items.par_iter().enumerate().map(|(i, x)| f(i, x)).collect()
    } else {
        items.iter().enumerate().map(|(i, x)| f(i, x)).collect()
    }
}

/// Geodetic positions to UTM `(easting, northing, height)`, all in one zone:
/// `zone`, or when `None` the zone that holds the first position
/// ([`UtmZone::containing`]). Parallel for large inputs.
pub fn geodetic_to_utm(
    points: &[Geodetic],
    zone: Option<UtmZone>,
) -> Result<(Vec<Vector3<f64>>, UtmZone)> {
    let zone = match zone {
        Some(z) => z,
        None => {
            let first = points.first().ok_or_else(|| Error::TooFew {
                what: "positions to choose a UTM zone from".into(),
                need: 1,
                got: 0,
            })?;
            UtmZone::containing(first.lat, first.lon)?
        }
    };
    let proj = UtmProjection::new(zone)?;
    let out = run(points, |i, g| proj.forward(g, i))?;
    Ok((out, zone))
}

/// UTM `(easting, northing, height)` of `zone` to geodetic positions.
pub fn utm_to_geodetic(points: &[Vector3<f64>], zone: UtmZone) -> Result<Vec<Geodetic>> {
    let proj = UtmProjection::new(zone)?;
    run(points, |i, p| proj.inverse(p, i))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zones_of_the_grid() {
        let z = |lat, lon| UtmZone::containing(lat, lon).unwrap();
        assert_eq!(z(49.0, 8.4).epsg(), 32632);
        assert_eq!(z(-33.9, 18.4).epsg(), 32734);
        assert_eq!(z(0.0, -180.0).number, 1);
        assert_eq!(z(0.0, 179.999).number, 60);
        assert_eq!(z(0.0, 180.0).number, 1);
        assert_eq!(z(60.0, 5.0).number, 32); // Norway
        assert_eq!(z(78.0, 15.0).number, 33); // Svalbard
        assert_eq!(z(78.0, 8.9).number, 31);
        assert!(UtmZone::containing(85.0, 0.0).is_err());
        assert!(UtmZone::try_new(61, Hemisphere::North).is_err());
        assert!(UtmZone::try_new(32, Hemisphere::North)
            .unwrap()
            .wkt()
            .unwrap()
            .contains("AUTHORITY[\"EPSG\",\"32632\"]"));
    }

    #[test]
    fn central_meridian_maps_to_false_easting() {
        let zone = UtmZone::try_new(32, Hemisphere::North).unwrap();
        let p = UtmProjection::new(zone).unwrap();
        let g = Geodetic {
            lat: 0.0,
            lon: 9.0,
            alt: 12.5,
        };
        let v = p.forward(&g, 0).unwrap();
        assert!(
            (v - Vector3::new(500_000.0, 0.0, 12.5)).norm() < 1e-6,
            "{v}"
        );
        let back = p.inverse(&v, 0).unwrap();
        assert!((back.lat - g.lat).abs() < 1e-12 && (back.lon - g.lon).abs() < 1e-12);
        let south = UtmProjection::new(UtmZone::try_new(32, Hemisphere::South).unwrap()).unwrap();
        assert!((south.forward(&g, 0).unwrap().y - 10_000_000.0).abs() < 1e-6);
    }
}
