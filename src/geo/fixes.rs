//! GNSS fixes: the model every GNSS reader fills (NMEA, CSV, `NavSatFix`,
//! `LocationFix`), checked once, and its conversion into an ENU reference
//! trajectory with weights from the fixes' covariances.

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use super::geodesy::{check_geodetic, EnuFrame, Geodetic, Origin};
use crate::error::{Error, Result};
use crate::trajectory::Trajectory;

/// The quality a receiver reports for a fix (NMEA GGA quality, ROS
/// `NavSatStatus`). Only [`FixStatus::NoFix`] is dropped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FixStatus {
    /// No position (GGA quality 0, `NavSatStatus.STATUS_NO_FIX`).
    NoFix,
    /// Stand-alone GNSS (GGA 1, `STATUS_FIX`); also a fix whose source says
    /// nothing of its quality (CSV, `foxglove.LocationFix`).
    Single,
    /// Differential: DGPS, SBAS, GBAS (GGA 2 and 3, `STATUS_SBAS_FIX`, `STATUS_GBAS_FIX`).
    Differential,
    /// RTK with fixed integers (GGA 4), centimetres.
    RtkFixed,
    /// RTK float (GGA 5), decimetres.
    RtkFloat,
    /// Dead reckoning (GGA 6).
    Estimated,
    /// Manual input, simulation or a code slam2world does not know (GGA 7, 8, …).
    Other,
}

impl FixStatus {
    /// From the GGA fix quality field.
    pub fn from_gga_quality(q: u8) -> Self {
        match q {
            0 => FixStatus::NoFix,
            1 => FixStatus::Single,
            2 | 3 => FixStatus::Differential,
            4 => FixStatus::RtkFixed,
            5 => FixStatus::RtkFloat,
            6 => FixStatus::Estimated,
            _ => FixStatus::Other,
        }
    }

    /// From `sensor_msgs/NavSatStatus.status` (-1 no fix, 0 fix, 1 SBAS, 2 GBAS).
    pub fn from_navsat_status(s: i8) -> Self {
        match s {
            s if s < 0 => FixStatus::NoFix,
            0 => FixStatus::Single,
            1 | 2 => FixStatus::Differential,
            _ => FixStatus::Other,
        }
    }

    /// True for every status but [`FixStatus::NoFix`].
    pub fn is_fix(self) -> bool {
        self != FixStatus::NoFix
    }

    /// A typical one-sigma position noise (m) for this quality, used only when
    /// a track has no covariance at all, to tell a track that never moves from
    /// one that does (see [`GnssFixes::to_enu`]): RTK fixed 0.05, RTK float
    /// 0.5, differential 1, single 3, anything else 5.
    pub fn nominal_sigma(self) -> f64 {
        match self {
            FixStatus::RtkFixed => 0.05,
            FixStatus::RtkFloat => 0.5,
            FixStatus::Differential => 1.0,
            FixStatus::Single => 3.0,
            _ => 5.0,
        }
    }
}

/// What the fix times count.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, Default, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum TimeBase {
    /// Seconds as the source stamps them: Unix time (UTC, no leap seconds)
    /// for NMEA with a date (RMC/ZDA) and for ROS/Foxglove stamps; whatever
    /// the file's first column counts for CSV.
    #[default]
    Source,
    /// Seconds since 00:00 UTC of the day of the first fix: NMEA without any
    /// RMC or ZDA sentence (GGA has only the time of day); passing midnight
    /// adds 86 400 s.
    TimeOfDay,
}

/// One fix as a reader produces it, before the checks of [`GnssFixes`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GnssFix {
    /// Seconds (see [`TimeBase`]).
    pub time: f64,
    /// Latitude, degrees.
    pub lat: f64,
    /// Longitude, degrees.
    pub lon: f64,
    /// Height above the WGS84 ellipsoid, metres.
    pub alt: f64,
    /// Position covariance in ENU at the fix (row-major x east, y north, z up), m², when known.
    pub covariance: Option<Matrix3<f64>>,
    /// Quality.
    pub status: FixStatus,
}

/// A checked GNSS track: times (s), WGS84 latitude and longitude (degrees),
/// height above the ellipsoid (m), per-fix ENU position covariance (m²) when
/// known, quality per fix. Fixes whose status is "no fix" are dropped on
/// construction and counted in [`GnssFixes::dropped_no_fix`].
#[derive(Clone, Debug, PartialEq)]
pub struct GnssFixes {
    /// Seconds, non-decreasing.
    pub times: Vec<f64>,
    /// Degrees north, in [-90, 90].
    pub lat: Vec<f64>,
    /// Degrees east.
    pub lon: Vec<f64>,
    /// Metres above the WGS84 ellipsoid.
    pub alt: Vec<f64>,
    /// ENU position covariance per fix (m²), `None` where the source did not give one.
    pub covariance: Vec<Option<Matrix3<f64>>>,
    /// Quality per fix (never [`FixStatus::NoFix`]).
    pub status: Vec<FixStatus>,
    /// How many fixes the source had with status "no fix" (dropped).
    pub dropped_no_fix: usize,
    /// What the times count.
    pub time_base: TimeBase,
}

/// The fixes as a reference trajectory in a local ENU frame.
#[derive(Clone, Debug)]
pub struct EnuTrack {
    /// The ENU frame (its origin goes into the report).
    pub frame: EnuFrame,
    /// Positions in ENU (x east, y north, z up, metres), no orientations;
    /// times as in the fixes.
    pub trajectory: Trajectory,
    /// Alignment weight per fix, `1 / (trace(Σ)/3)` (1/m²: the inverse of the
    /// mean per-axis variance), when every fix has a covariance.
    pub weights: Option<Vec<f64>>,
}

fn check_covariance(index: usize, c: &Matrix3<f64>) -> Result<()> {
    let bad = |value: f64, expected: &str| Error::InvalidFix {
        what: "fix".into(),
        index,
        field: "covariance".into(),
        value,
        expected: expected.into(),
    };
    if let Some(v) = c.iter().find(|v| !v.is_finite()) {
        return Err(bad(*v, "finite m² values"));
    }
    for k in 0..3 {
        if c[(k, k)] <= 0.0 {
            return Err(bad(c[(k, k)], "positive variances on the diagonal"));
        }
    }
    let asym = (c - c.transpose()).abs().max();
    if asym > 1e-9 * c.diagonal().max() {
        return Err(bad(asym, "a symmetric matrix"));
    }
    Ok(())
}

impl GnssFixes {
    /// Checks and keeps the fixes: times finite and non-decreasing, latitude
    /// and longitude finite with the latitude within ±90°, heights finite,
    /// covariances finite, symmetric, with positive variances — each refused
    /// with [`Error::InvalidFix`] naming the fix index in `fixes`. Fixes with
    /// [`FixStatus::NoFix`] are dropped (before the checks: a receiver writes
    /// empty or zero positions there) and counted.
    pub fn from_fixes(
        fixes: impl IntoIterator<Item = GnssFix>,
        time_base: TimeBase,
    ) -> Result<Self> {
        let mut out = GnssFixes {
            times: Vec::new(),
            lat: Vec::new(),
            lon: Vec::new(),
            alt: Vec::new(),
            covariance: Vec::new(),
            status: Vec::new(),
            dropped_no_fix: 0,
            time_base,
        };
        let mut last_time = f64::NEG_INFINITY;
        for (i, f) in fixes.into_iter().enumerate() {
            if !f.status.is_fix() {
                out.dropped_no_fix += 1;
                continue;
            }
            if !f.time.is_finite() || f.time < last_time {
                return Err(Error::InvalidFix {
                    what: "fix".into(),
                    index: i,
                    field: "time".into(),
                    value: f.time,
                    expected: if f.time.is_finite() {
                        format!("seconds not before the previous fix ({last_time})")
                    } else {
                        "a finite number of seconds".into()
                    },
                });
            }
            last_time = f.time;
            check_geodetic("fix", i, f.lat, f.lon, f.alt)?;
            if let Some(c) = &f.covariance {
                check_covariance(i, c)?;
            }
            out.times.push(f.time);
            out.lat.push(f.lat);
            out.lon.push(f.lon);
            out.alt.push(f.alt);
            out.covariance.push(f.covariance);
            out.status.push(f.status);
        }
        Ok(out)
    }

    /// [`GnssFixes::from_fixes`] from columns; `covariance` and `status` may
    /// be omitted (no covariance; every fix [`FixStatus::Single`]).
    pub fn try_new(
        times: Vec<f64>,
        lat: Vec<f64>,
        lon: Vec<f64>,
        alt: Vec<f64>,
        covariance: Option<Vec<Option<Matrix3<f64>>>>,
        status: Option<Vec<FixStatus>>,
    ) -> Result<Self> {
        let n = times.len();
        let check = |what: &str, len: usize| {
            if len != n {
                Err(Error::ShapeMismatch {
                    what: what.into(),
                    expected: format!("({n},), one per time"),
                    got: format!("({len},)"),
                })
            } else {
                Ok(())
            }
        };
        check("lat", lat.len())?;
        check("lon", lon.len())?;
        check("alt", alt.len())?;
        if let Some(c) = &covariance {
            check("covariance", c.len())?;
        }
        if let Some(s) = &status {
            check("status", s.len())?;
        }
        let fixes = (0..n).map(|i| GnssFix {
            time: times[i],
            lat: lat[i],
            lon: lon[i],
            alt: alt[i],
            covariance: covariance.as_ref().and_then(|c| c[i]),
            status: status.as_ref().map_or(FixStatus::Single, |s| s[i]),
        });
        GnssFixes::from_fixes(fixes, TimeBase::Source)
    }

    /// Number of fixes kept.
    pub fn len(&self) -> usize {
        self.times.len()
    }

    /// True when no fix was kept.
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }

    /// The fixes as geodetic positions.
    pub fn positions(&self) -> Vec<Geodetic> {
        (0..self.len())
            .map(|i| Geodetic {
                lat: self.lat[i],
                lon: self.lon[i],
                alt: self.alt[i],
            })
            .collect()
    }

    /// The per-fix alignment weights `1 / (trace(Σ)/3)` (1/m²), when every
    /// fix has a covariance. The inverse mean variance is the weight of an
    /// isotropic point-to-point fit (Horn / Umeyama weights are one scalar per
    /// point), the usual reduction of a 3×3 covariance to it.
    pub fn weights(&self) -> Option<Vec<f64>> {
        self.covariance
            .iter()
            .map(|c| c.map(|c| 3.0 / c.trace()))
            .collect()
    }

    /// The track in a local ENU frame at `origin` (first fix, ECEF centroid,
    /// or given), with the weights of [`GnssFixes::weights`].
    ///
    /// Refused: fewer than 2 fixes ([`Error::TooFew`]); a track that never
    /// moves more than its noise ([`Error::Degenerate`]): the RMS distance of
    /// the fixes from their centroid is at most 3 σ, with σ² the mean per-axis
    /// variance over the fixes (from the covariances where given, else
    /// [`FixStatus::nominal_sigma`]). A receiver at rest scatters with an RMS
    /// distance of √3 σ ≈ 1.7 σ, so it is refused; a track of a few σ and more
    /// passes.
    pub fn to_enu(&self, origin: &Origin) -> Result<EnuTrack> {
        if self.len() < 2 {
            return Err(Error::TooFew {
                what: "GNSS fixes for a reference trajectory".into(),
                need: 2,
                got: self.len(),
            });
        }
        let geo = self.positions();
        let frame = EnuFrame::new(origin.resolve(&geo)?)?;
        let positions: Vec<Vector3<f64>> = geo.iter().map(|g| frame.geodetic_to_enu(g)).collect();
        let n = positions.len() as f64;
        let centroid: Vector3<f64> = positions.iter().sum::<Vector3<f64>>() / n;
        let rms = (positions
            .iter()
            .map(|p| (p - centroid).norm_squared())
            .sum::<f64>()
            / n)
            .sqrt();
        let mean_var = (0..self.len())
            .map(|i| match &self.covariance[i] {
                Some(c) => c.trace() / 3.0,
                None => self.status[i].nominal_sigma().powi(2),
            })
            .sum::<f64>()
            / n;
        let sigma = mean_var.sqrt();
        if rms <= 3.0 * sigma {
            return Err(Error::Degenerate {
                reason: format!(
                    "the GNSS track never moves more than its noise: RMS distance from its centroid \
                     {rms:.3} m is within 3 sigma = {:.3} m (sigma {sigma:.3} m over {} fixes)",
                    3.0 * sigma,
                    self.len()
                ),
                value: rms,
            });
        }
        let trajectory = Trajectory::try_new(self.times.clone(), positions, None)?;
        Ok(EnuTrack {
            frame,
            trajectory,
            weights: self.weights(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fix(time: f64, lat: f64, status: FixStatus) -> GnssFix {
        GnssFix {
            time,
            lat,
            lon: 11.6,
            alt: 500.0,
            covariance: Some(Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 4.0))),
            status,
        }
    }

    #[test]
    fn no_fix_is_dropped_and_counted() {
        let f = GnssFixes::from_fixes(
            [
                fix(0.0, 48.0, FixStatus::Single),
                GnssFix {
                    lat: f64::NAN,
                    ..fix(1.0, 0.0, FixStatus::NoFix)
                },
                fix(2.0, 48.001, FixStatus::RtkFixed),
            ],
            TimeBase::Source,
        )
        .unwrap();
        assert_eq!(f.len(), 2);
        assert_eq!(f.dropped_no_fix, 1);
        assert_eq!(f.weights().unwrap(), vec![0.5, 0.5]);
    }

    #[test]
    fn bad_fixes_name_their_index() {
        let cases = [
            (fix(f64::NAN, 48.0, FixStatus::Single), "time"),
            (fix(1.0, f64::NAN, FixStatus::Single), "latitude"),
            (fix(1.0, 91.0, FixStatus::Single), "latitude"),
            (
                GnssFix {
                    lon: f64::NAN,
                    ..fix(1.0, 48.0, FixStatus::Single)
                },
                "longitude",
            ),
            (
                GnssFix {
                    covariance: Some(Matrix3::zeros()),
                    ..fix(1.0, 48.0, FixStatus::Single)
                },
                "covariance",
            ),
            (fix(-1.0, 48.0, FixStatus::Single), "time"),
        ];
        for (bad, want) in cases {
            let e =
                GnssFixes::from_fixes([fix(0.0, 48.0, FixStatus::Single), bad], TimeBase::Source)
                    .unwrap_err();
            match e {
                Error::InvalidFix { index, field, .. } => {
                    assert_eq!((index, field.as_str()), (1, want))
                }
                other => panic!("{other}"),
            }
        }
    }

    #[test]
    fn a_track_at_rest_is_refused_and_a_moving_one_is_not() {
        // 20 fixes within 1 m of each other, sigma 1 m: at rest.
        let still: Vec<GnssFix> = (0..20)
            .map(|i| fix(i as f64, 48.0 + (i % 3) as f64 * 3e-6, FixStatus::Single))
            .collect();
        let s = GnssFixes::from_fixes(still, TimeBase::Source).unwrap();
        assert!(matches!(
            s.to_enu(&Origin::First),
            Err(Error::Degenerate { .. })
        ));
        // 100 m north.
        let moving: Vec<GnssFix> = (0..20)
            .map(|i| fix(i as f64, 48.0 + i as f64 * 5e-5, FixStatus::Single))
            .collect();
        let m = GnssFixes::from_fixes(moving, TimeBase::Source).unwrap();
        let t = m.to_enu(&Origin::First).unwrap();
        assert_eq!(t.trajectory.positions[0], Vector3::zeros());
        let last = t.trajectory.positions[19];
        assert!(
            last.y > 100.0 && last.y < 110.0 && last.x.abs() < 1e-6,
            "{last}"
        );
        assert!(t.trajectory.orientations.is_none());
    }
}
