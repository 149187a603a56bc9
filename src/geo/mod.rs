//! Geodesy and GNSS fixes.
//!
//! - [`geodesy`]: WGS84 geodetic (degrees, metres above the ellipsoid) ↔ ECEF
//!   (metres) ↔ local ENU at an origin (x east, y north, z up, metres);
//! - [`utm`]: UTM zone coordinates (EPSG:326xx / 327xx) and the CRS texts;
//! - [`crs`]: ENU points carried exactly into a UTM zone or ECEF;
//! - [`fixes`]: [`GnssFixes`], the checked track every GNSS reader fills, and
//!   its ENU reference trajectory with weights.

pub mod crs;
pub mod fixes;
pub mod geodesy;
pub mod utm;

pub use crs::{enu_to_crs, CrsPoints, GeoCrs};
pub use fixes::{EnuTrack, FixStatus, GnssFix, GnssFixes, TimeBase};
pub use geodesy::{ecef_to_geodetic, geodetic_to_ecef, EnuFrame, Geodetic, Origin};
pub use utm::{geodetic_to_utm, utm_to_geodetic, Hemisphere, UtmProjection, UtmZone};
