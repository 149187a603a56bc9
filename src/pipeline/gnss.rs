//! The GNSS-reference path of `convert`: fixes (from a log's `NavSatFix` /
//! `LocationFix` topic, or a CSV / NMEA file given beside the input) become
//! the reference trajectory in a local ENU frame, so that the fitted
//! `T_world_slam` **is** `T_enu_slam`: the world frame is ENU at the origin
//! the report carries (x east, y north, z up along the ellipsoid normal,
//! metres).
//!
//! - Origin: the first fix, the ECEF mean of the fixes, or a given
//!   `(lat, lon, alt)` ([`Origin`]).
//! - Pairing: the fixes are interpolated linearly (in ENU) at the SLAM stamps
//!   (plus the offset) where two fixes at most `max_gap` seconds apart bracket
//!   the stamp (by default five of the fixes' median intervals: a 1 Hz
//!   receiver pairs as a 10 Hz one does, across a dropout of up to four
//!   fixes), so every keyframe is paired without the error of a nearest-stamp
//!   match; with `estimate_offset` the fixes are used as they
//!   are (the offset search needs the reference's own stamps).
//! - Weights: with a covariance on every fix, each pair weighs
//!   `1 / σ̄²`, σ̄² the mean per-axis variance interpolated like the positions
//!   ([`GnssFixes::weights`]); without, all pairs weigh the same.
//! - Lever arm: the antenna in the body frame (`T_body_antenna`'s
//!   translation, metres; the body is the SLAM camera unless a
//!   `body_from_cam` is given), applied with the SLAM orientations through
//!   the known-extrinsic fit.
//! - Refused before the fit: a track that never moves more than its noise
//!   ([`GnssFixes::to_enu`]); fixes without a fix are dropped and counted.

use std::path::PathBuf;
use std::sync::Arc;

use nalgebra::{UnitQuaternion, Vector3};

use super::report::GnssReport;
use super::source::{Recording, Source};
use super::startup::{cut_of_pairs, LiveCut};
use crate::align::trajectories::TrajectoryAlignOptions;
use crate::error::{Error, Result};
use crate::geo::{EnuFrame, GeoCrs, GnssFixes, Origin, UtmZone};
use crate::geometry::Sim3;
use crate::io::gnss::{read_gnss, GnssFormat};
use crate::trajectory::Trajectory;

/// How GNSS fixes become the reference.
#[derive(Clone, Debug, PartialEq)]
pub struct GnssOptions {
    /// Where the ENU origin is put.
    pub origin: Origin,
    /// The antenna in the body frame, metres (`None`: at the body origin).
    pub lever_arm: Option<Vector3<f64>>,
    /// Weigh the pairs by the fixes' covariances (when every fix has one).
    pub weights: bool,
    /// Largest time between two fixes that an interpolated reference
    /// position bridges, seconds; `None`: [`crate::defaults::GAP_STEPS`]
    /// times the fixes' median interval ([`GnssOptions::max_gap_for`]).
    pub max_gap: Option<f64>,
}

impl Default for GnssOptions {
    fn default() -> Self {
        GnssOptions {
            origin: Origin::First,
            lever_arm: None,
            weights: true,
            max_gap: None,
        }
    }
}

impl GnssOptions {
    /// The gap bridged between fixes stamped `times` (sorted): the given
    /// one, else [`crate::defaults::GAP_STEPS`] times their median
    /// interval (the given default's rule needs two fixes; with fewer any gap
    /// is as good as none).
    pub fn max_gap_for(&self, times: &[f64]) -> f64 {
        if let Some(g) = self.max_gap {
            return g;
        }
        crate::trajectory::gap_of(times)
    }

    /// Checks the lever arm (finite) and `max_gap` (finite, `> 0`).
    pub fn check(&self) -> Result<()> {
        if let Some(l) = &self.lever_arm {
            if l.iter().any(|v| !v.is_finite()) {
                return Err(Error::invalid(
                    "lever_arm",
                    format!("must be three finite metres, got {:?}", l.as_slice()),
                ));
            }
        }
        if let Some(g) = self.max_gap {
            if !(g.is_finite() && g > 0.0) {
                return Err(Error::invalid(
                    "gnss_max_gap",
                    format!(
                        "must be a finite number of seconds > 0, got {}",
                        crate::error::num(g)
                    ),
                ));
            }
        }
        if let Origin::Given(g) = &self.origin {
            crate::geo::Geodetic::try_new(g.lat, g.lon, g.alt)?;
        }
        Ok(())
    }
}

/// An ENU origin as the CLI and Python spell it: `first`, `mean`, or
/// `LAT,LON,ALT` (degrees, metres above the ellipsoid; commas or spaces).
pub fn parse_origin(s: &str) -> Result<Origin> {
    let t = s.trim();
    if t.eq_ignore_ascii_case("first") || t.eq_ignore_ascii_case("mean") {
        return Origin::parse(&t.to_ascii_lowercase());
    }
    let v: std::result::Result<Vec<f64>, _> = t
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|x| !x.is_empty())
        .map(str::parse::<f64>)
        .collect();
    match v {
        Ok(v) if v.len() == 3 => Ok(Origin::Given(crate::geo::Geodetic::try_new(
            v[0], v[1], v[2],
        )?)),
        _ => Err(Error::invalid(
            "origin",
            format!(
                "{}: expected \"first\", \"mean\" or LAT,LON,ALT",
                crate::error::cut(s)
            ),
        )),
    }
}

/// The georeferenced clouds a conversion writes beside the others.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GeoOutputs {
    /// `cloud.las` (LAS 1.4 with the CRS record): `None` writes it when the
    /// reference is GNSS (the only case where the world is on the Earth);
    /// `Some(true)` asks for it (refused without a GNSS reference),
    /// `Some(false)` turns it off.
    pub las: Option<bool>,
    /// Write the LAS file compressed, as `cloud.laz` (asks for it when `las`
    /// is `None`).
    pub laz: bool,
    /// `cloud.pcd` (binary PCD, the world frame's `f32` metres: ENU with a
    /// GNSS reference).
    pub pcd: bool,
    /// The CRS of the LAS file ([`crate::defaults::CRS`]: the UTM zone of the
    /// ENU origin; or ECEF).
    pub crs: GeoCrs,
}

impl Default for GeoOutputs {
    fn default() -> Self {
        GeoOutputs {
            las: None,
            laz: false,
            pcd: false,
            crs: GeoCrs::Utm(None),
        }
    }
}

impl GeoOutputs {
    /// True when the LAS / LAZ file is written for a conversion that does
    /// (`georeferenced`) or does not have a GNSS reference; an error when it
    /// is asked for without one.
    pub fn las_for(&self, georeferenced: bool) -> Result<bool> {
        // `laz` alone asks for the (compressed) file.
        let asked = self.las.or(self.laz.then_some(true));
        match (asked, georeferenced) {
            (Some(true), false) => Err(Error::invalid(
                "las",
                "a LAS file carries a CRS: it needs a GNSS reference (a gnss topic or file)",
            )),
            (Some(false), _) => Ok(false),
            (_, g) => Ok(g),
        }
    }
}

/// A GNSS file given beside the input: CSV / TXT `time, lat, lon, alt[, cov]`
/// (degrees, metres above the WGS84 ellipsoid) or NMEA (`GGA`, `GST`).
#[derive(Clone, Debug, PartialEq)]
pub struct GnssFile {
    /// The file.
    pub path: PathBuf,
    /// Its format (`None`: detected from its first lines).
    pub format: Option<GnssFormat>,
    /// Metres added to every height (the geoid separation of a file whose
    /// heights are above mean sea level).
    pub geoid_offset: f64,
}

/// Reads `file` into the recording as its reference. Refused when the
/// recording already has a reference file (one reference per conversion).
pub fn attach_gnss(rec: &mut Recording, file: &GnssFile) -> Result<()> {
    if let Some(r) = &rec.source.reference_file {
        return Err(Error::invalid(
            "gnss",
            format!(
                "a conversion has one reference: {} and {} both given",
                r.path.display(),
                file.path.display()
            ),
        ));
    }
    rec.gnss = Some(read_gnss(&file.path, file.format, file.geoid_offset)?);
    rec.source.gnss_path = Some(file.path.clone());
    rec.source.gnss_topic = None;
    Ok(())
}

/// A source with a GNSS file attached ([`attach_gnss`]).
pub struct WithGnss {
    /// The input.
    pub inner: Box<dyn Source>,
    /// The GNSS file.
    pub file: GnssFile,
}

impl Source for WithGnss {
    fn read(&self) -> Result<Recording> {
        let mut rec = self.inner.read()?;
        attach_gnss(&mut rec, &self.file)?;
        Ok(rec)
    }

    fn read_bounded(&self) -> Result<Recording> {
        let mut rec = self.inner.read_bounded()?;
        attach_gnss(&mut rec, &self.file)?;
        Ok(rec)
    }
}

/// The reference a GNSS track gives the fit.
#[derive(Clone, Debug)]
pub struct GnssReference {
    /// The ENU frame (the world frame of the conversion).
    pub frame: EnuFrame,
    /// Reference positions in ENU (metres), at the SLAM stamps where
    /// interpolated, else at the fixes' stamps; shared with the conversion.
    pub trajectory: Arc<Trajectory>,
    /// Weight per reference position (1/m²), when the fixes have covariances
    /// and weights are asked for.
    pub weights: Option<Vec<f64>>,
    /// `T_antenna_cam` for the known-extrinsic fit, when there is a lever arm
    /// or a `body_from_cam`.
    pub antenna_from_cam: Option<Sim3>,
    /// The fixes' position noise, metres (3-D rms: the root of the mean
    /// `trace(Σ)`, or of `3·σ²` of [`crate::geo::FixStatus::nominal_sigma`]
    /// without a covariance): the fit checks' reference noise unless one is stated.
    pub noise: f64,
    /// What the report says of it (the fit's figures filled in later).
    pub report: GnssReport,
}

impl GnssReference {
    /// `align` fitted against this reference: the antenna as the known
    /// extrinsic, the fixes' noise as the reference noise unless one is
    /// stated; with the pairs' weights (none for a robust fit, whose IRLS
    /// weighs the pairs itself).
    pub fn fit_options(
        &self,
        align: &TrajectoryAlignOptions,
    ) -> (TrajectoryAlignOptions, Option<&[f64]>) {
        let mut o = align.clone();
        o.body_from_cam = self.antenna_from_cam;
        if o.checks.reference_noise.is_none() {
            o.checks.reference_noise = Some(self.noise);
        }
        let weights = self.weights.as_deref().filter(|_| align.robust.is_none());
        (o, weights)
    }
}

/// The fixes as the reference of `slam` (sorted SLAM poses): ENU at the
/// origin, interpolated at the SLAM stamps (`offset` added) unless
/// `interpolate` is false, weights and lever arm as `opts` ask;
/// `body_from_cam` is the conversion's `T_body_cam`.
pub fn reference(
    fixes: &GnssFixes,
    slam: &Trajectory,
    opts: &GnssOptions,
    offset: f64,
    interpolate: bool,
    body_from_cam: Option<&Sim3>,
) -> Result<GnssReference> {
    opts.check()?;
    let max_gap = opts.max_gap_for(&fixes.times);
    let track = fixes.to_enu(&opts.origin)?;
    let weights = if opts.weights { track.weights } else { None };
    let (trajectory, weights, interpolated) = if interpolate {
        let times: Vec<f64> = slam.timestamps.iter().map(|t| t + offset).collect();
        let at = track
            .trajectory
            .interpolate_where_covered(&times, max_gap)?;
        let w = match &weights {
            Some(w) => {
                // The mean variance interpolated like the positions.
                let var = Trajectory::try_new(
                    track.trajectory.timestamps.clone(),
                    w.iter().map(|w| Vector3::new(1.0 / w, 0.0, 0.0)).collect(),
                    None,
                )?;
                let v = var.interpolate(&at.trajectory.timestamps, max_gap)?;
                Some(v.positions.iter().map(|p| 1.0 / p.x).collect())
            }
            None => None,
        };
        if at.trajectory.len() < 3 {
            return Err(Error::Unmatched {
                matched: at.trajectory.len(),
                need: 3,
                slam_span: span(&times),
                reference_span: span(&track.trajectory.timestamps),
                max_diff: max_gap,
                offset,
                cause: format!(
                    "GNSS fixes interpolated at the SLAM stamps: only {} of {} stamps lie between two fixes at most {} s apart",
                    at.trajectory.len(),
                    times.len(),
                    max_gap
                ),
            });
        }
        (at.trajectory, w, true)
    } else {
        (track.trajectory, weights, false)
    };
    let origin = track.frame.origin();
    let zone = UtmZone::containing(origin.lat, origin.lon).ok();
    let antenna_body = opts.lever_arm.map(|l| Sim3 {
        rotation: UnitQuaternion::identity(),
        translation: -l,
        scale: 1.0,
    });
    let antenna_from_cam = match (antenna_body, body_from_cam) {
        (Some(a), Some(b)) => Some(a * *b),
        (Some(a), None) => Some(a),
        (None, Some(b)) => Some(*b),
        (None, None) => None,
    };
    let report = GnssReport {
        fixes: fixes.len(),
        dropped_no_fix: fixes.dropped_no_fix,
        time_base: fixes.time_base,
        origin_rule: match opts.origin {
            Origin::First => "first",
            Origin::Mean => "mean",
            Origin::Given(_) => "given",
        }
        .into(),
        origin: [origin.lat, origin.lon, origin.alt],
        origin_ecef: track.frame.origin_ecef().into(),
        world_frame: "ENU at the origin: x east, y north, z up (the ellipsoid normal), metres; \
                      t_world_slam is T_enu_slam"
            .into(),
        utm_zone: zone.map(|z| {
            let h = match z.hemisphere {
                crate::geo::Hemisphere::North => 'N',
                crate::geo::Hemisphere::South => 'S',
            };
            format!("{}{h}", z.number)
        }),
        utm_epsg: zone.map(|z| z.epsg()),
        lever_arm: opts.lever_arm.map(Into::into),
        weighted: weights.is_some(),
        weight_range: weights.as_ref().map(|w| {
            w.iter().fold([f64::INFINITY, 0.0f64], |[lo, hi], &v| {
                [lo.min(v), hi.max(v)]
            })
        }),
        interpolated,
        max_gap,
        topic: None,
        file: None,
        outputs: Vec::new(),
        reference_positions: trajectory.len(),
        unpaired_stamps: if interpolated {
            slam.len() - trajectory.len()
        } else {
            0
        },
    };
    let noise = ((0..fixes.len())
        .map(|i| match &fixes.covariance[i] {
            Some(c) => c.trace(),
            None => 3.0 * fixes.status[i].nominal_sigma().powi(2),
        })
        .sum::<f64>()
        / fixes.len() as f64)
        .sqrt();
    Ok(GnssReference {
        frame: track.frame,
        trajectory: Arc::new(trajectory),
        weights,
        antenna_from_cam,
        noise,
        report,
    })
}

/// The start-up cut of the live frames (`live`, sorted) paired with the
/// fixes the way the online session pairs them: the fixes in ENU
/// interpolated at each live stamp plus `offset`, where two fixes at most
/// `max_gap` apart bracket it ([`super::startup::cut_of_pairs`] on those pairs).
pub fn live_cut(
    fixes: &GnssFixes,
    live: &Trajectory,
    opts: &GnssOptions,
    offset: f64,
) -> Result<LiveCut> {
    let track = fixes.to_enu(&opts.origin)?;
    let times: Vec<f64> = live.timestamps.iter().map(|t| t + offset).collect();
    let at = track
        .trajectory
        .interpolate_where_covered(&times, opts.max_gap_for(&fixes.times))?;
    let stamps: Vec<f64> = at.kept.iter().map(|&j| live.timestamps[j]).collect();
    let slam: Vec<Vector3<f64>> = at.kept.iter().map(|&j| live.positions[j]).collect();
    cut_of_pairs(&stamps, &slam, &at.trajectory.positions)
}

fn span(t: &[f64]) -> String {
    match (t.first(), t.last()) {
        (Some(a), Some(b)) => format!("{a} .. {b} s ({} stamps)", t.len()),
        _ => "empty".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::{FixStatus, GnssFix, TimeBase};
    use nalgebra::Matrix3;

    fn fixes(n: usize) -> GnssFixes {
        GnssFixes::from_fixes(
            (0..n).map(|i| GnssFix {
                time: i as f64 * 0.2,
                lat: 48.0 + i as f64 * 1e-4,
                lon: 11.0,
                alt: 500.0,
                covariance: Some(Matrix3::from_diagonal(&Vector3::new(
                    1.0 + i as f64,
                    1.0 + i as f64,
                    1.0 + i as f64,
                ))),
                status: FixStatus::Single,
            }),
            TimeBase::Source,
        )
        .unwrap()
    }

    #[test]
    fn fixes_are_interpolated_at_the_slam_stamps_with_their_weights() {
        let f = fixes(30);
        let times: Vec<f64> = (0..20).map(|i| 0.1 + i as f64 * 0.3).collect();
        let slam = Trajectory::try_new(times.clone(), vec![Vector3::zeros(); 20], None).unwrap();
        let r = reference(&f, &slam, &GnssOptions::default(), 0.0, true, None).unwrap();
        assert_eq!(r.trajectory.timestamps, times);
        // Halfway between fixes 0 and 1: half the northing step, weight 1 / 1.5.
        let step = r.frame.geodetic_to_enu(&f.positions()[1]).y;
        assert!((r.trajectory.positions[0].y - step / 2.0).abs() < 1e-9);
        let w = r.weights.unwrap();
        assert!((w[0] - 1.0 / 1.5).abs() < 1e-12, "{}", w[0]);
        assert_eq!(r.report.utm_zone.as_deref(), Some("32N"));
        assert_eq!(r.report.utm_epsg, Some(32632));
        assert!(r.antenna_from_cam.is_none());
        // Past the last fix (5.8 s): unpaired.
        let late: Vec<f64> = (0..20).map(|i| 5.0 + i as f64).collect();
        let slam = Trajectory::try_new(late, vec![Vector3::zeros(); 20], None).unwrap();
        assert!(matches!(
            reference(&f, &slam, &GnssOptions::default(), 0.0, true, None),
            Err(Error::Unmatched { .. })
        ));
    }

    #[test]
    fn the_gap_bridged_is_given_or_five_median_fix_intervals() {
        let auto = GnssOptions::default();
        // 1 Hz with one dropout of 3 s: the median interval is 1 s.
        let times = [0.0, 1.0, 2.0, 5.0, 6.0, 7.0];
        assert_eq!(auto.max_gap_for(&times), 5.0);
        assert_eq!(auto.max_gap_for(&[0.0, 0.1, 0.2]), 5.0 * 0.1);
        assert_eq!(auto.max_gap_for(&[3.0]), f64::INFINITY);
        let given = GnssOptions {
            max_gap: Some(0.5),
            ..GnssOptions::default()
        };
        assert_eq!(given.max_gap_for(&times), 0.5);
        let bad = GnssOptions {
            max_gap: Some(0.0),
            ..GnssOptions::default()
        };
        assert!(bad.check().is_err());
        // A 1 Hz receiver pairs every stamp between its fixes by default, none with 0.5 s.
        let f = GnssFixes::from_fixes(
            (0..30).map(|i| GnssFix {
                time: i as f64,
                lat: 48.0 + i as f64 * 1e-4,
                lon: 11.0,
                alt: 500.0,
                covariance: None,
                status: FixStatus::Single,
            }),
            TimeBase::Source,
        )
        .unwrap();
        let times: Vec<f64> = (0..50).map(|i| 0.25 + i as f64 * 0.5).collect();
        let slam = Trajectory::try_new(times, vec![Vector3::zeros(); 50], None).unwrap();
        let r = reference(&f, &slam, &auto, 0.0, true, None).unwrap();
        assert_eq!(r.trajectory.len(), 50);
        assert_eq!(r.report.max_gap, 5.0);
        assert!(matches!(
            reference(&f, &slam, &given, 0.0, true, None),
            Err(Error::Unmatched { .. })
        ));
    }

    #[test]
    fn the_lever_arm_is_the_antenna_in_the_body_frame() {
        let f = fixes(30);
        let slam =
            Trajectory::try_new(vec![0.0, 1.0, 2.0], vec![Vector3::zeros(); 3], None).unwrap();
        let opts = GnssOptions {
            lever_arm: Some(Vector3::new(0.1, 0.0, 0.2)),
            ..GnssOptions::default()
        };
        let r = reference(&f, &slam, &opts, 0.0, true, None).unwrap();
        let x = r.antenna_from_cam.unwrap();
        // The antenna (0.1, 0, 0.2) in the body frame is the antenna frame's origin.
        assert!(x.transform_point(&Vector3::new(0.1, 0.0, 0.2)).norm() < 1e-15);
        let bad = GnssOptions {
            lever_arm: Some(Vector3::new(f64::NAN, 0.0, 0.0)),
            ..GnssOptions::default()
        };
        assert!(matches!(
            reference(&f, &slam, &bad, 0.0, true, None),
            Err(Error::InvalidArgument { .. })
        ));
    }
}
