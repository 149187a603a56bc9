//! Arguments shared by the commands: value parsers, and the association and
//! fit options of `align`, `convert` and `transform-cloud` (one flag, one
//! default, one help text for all three).

use clap::Args;
use nalgebra::Matrix4;

use crate::align::checks::FitChecks;
use crate::align::dof::{Anchor, Dof};
use crate::align::robust::{RobustLoss, RobustOptions};
use crate::align::time_offset::TimeOffsetOptions;
use crate::align::trajectories::{SkipInit, TrajectoryAlignOptions};
use crate::align::AlignMethod;
use crate::defaults;
use crate::error::{cut, Error, Result};
use crate::geometry::Sim3;
use crate::trajectory::Association;

/// clap parser of a time unit (`s`, `ms`, `us`, `ns`).
pub(crate) fn time_unit(s: &str) -> std::result::Result<crate::io::text::TimeUnit, String> {
    crate::io::text::TimeUnit::parse(s).map_err(|e| e.to_string())
}

/// clap parser: a finite number.
pub(crate) fn finite(s: &str) -> std::result::Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!("expected a finite number, got {}", cut(s))),
    }
}

/// clap parser: a finite number `>= 0`.
pub(crate) fn non_negative(s: &str) -> std::result::Result<f64, String> {
    match finite(s) {
        Ok(v) if v >= 0.0 => Ok(v),
        _ => Err(format!("expected a finite number >= 0, got {}", cut(s))),
    }
}

/// clap parser: a finite number `> 0`.
pub(crate) fn positive(s: &str) -> std::result::Result<f64, String> {
    match finite(s) {
        Ok(v) if v > 0.0 => Ok(v),
        _ => Err(format!("expected a finite number > 0, got {}", cut(s))),
    }
}

/// clap parser: a confidence level in (0, 1).
pub(crate) fn level(s: &str) -> std::result::Result<f64, String> {
    match finite(s) {
        Ok(v) if v > 0.0 && v < 1.0 => Ok(v),
        _ => Err(format!("expected a level in (0, 1), got {}", cut(s))),
    }
}

/// Parses a rigid transform: 16 numbers (a row-major 4×4 matrix) or 7
/// (`tx ty tz qx qy qz qw`), separated by commas, semicolons or spaces; metres.
pub fn parse_transform(what: &str, s: &str) -> Result<Sim3> {
    let v: std::result::Result<Vec<f64>, _> = s
        .split(|c: char| c == ',' || c == ';' || c.is_whitespace())
        .filter(|t| !t.is_empty())
        .map(str::parse::<f64>)
        .collect();
    let v = v.map_err(|e| Error::invalid(what, format!("{e} in {}", cut(s))))?;
    match v.len() {
        16 => Sim3::from_matrix(&Matrix4::from_row_slice(&v)),
        7 => Sim3::from_quaternion_xyzw(
            [v[3], v[4], v[5], v[6]],
            nalgebra::Vector3::new(v[0], v[1], v[2]),
            1.0,
        ),
        n => Err(Error::invalid(
            what,
            format!("expected 16 numbers (row-major 4x4) or 7 (tx ty tz qx qy qz qw), got {n}"),
        )),
    }
}

fn body_from_cam(s: &str) -> std::result::Result<Sim3, String> {
    parse_transform("--body-from-cam", s).map_err(|e| e.to_string())
}

fn skip_init(s: &str) -> std::result::Result<SkipInit, String> {
    s.parse().map_err(|e: Error| e.to_string())
}

fn loss(s: &str) -> std::result::Result<RobustLoss, String> {
    s.parse().map_err(|e: Error| e.to_string())
}

fn method(s: &str) -> std::result::Result<AlignMethod, String> {
    s.parse().map_err(|e: Error| e.to_string())
}

fn dof(s: &str) -> std::result::Result<Dof, String> {
    s.parse().map_err(|e: Error| e.to_string())
}

fn anchor(s: &str) -> std::result::Result<Anchor, String> {
    s.parse().map_err(|e: Error| e.to_string())
}

fn association(s: &str) -> std::result::Result<Association, String> {
    s.parse().map_err(|e: Error| e.to_string())
}

/// The gravity-tilt limit of a yaw-only fit, degrees; `None`: no check.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TiltLimit(pub Option<f64>);

impl std::fmt::Display for TiltLimit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.0 {
            Some(t) => write!(f, "{t}"),
            None => f.write_str("none"),
        }
    }
}

fn tilt_limit(s: &str) -> std::result::Result<TiltLimit, String> {
    if s.trim().eq_ignore_ascii_case("none") {
        return Ok(TiltLimit(None));
    }
    non_negative(s)
        .map(|v| TiltLimit(Some(v)))
        .map_err(|_| format!("expected degrees >= 0 or none, got {}", cut(s)))
}

/// Association and fit options of `align`, `convert` and `transform-cloud`.
#[derive(Args, Debug, Clone)]
pub struct FitArgs {
    /// Largest time difference of a matched pair, seconds.
    #[arg(long, default_value_t = defaults::MAX_DIFF, value_name = "S", value_parser = non_negative)]
    pub max_diff: f64,
    /// Seconds added to the SLAM (EST) stamps before matching.
    #[arg(long, default_value_t = defaults::OFFSET, value_name = "S", allow_negative_numbers = true, value_parser = finite)]
    pub offset: f64,
    /// Fit SE(3) (scale fixed to 1) instead of Sim(3).
    #[arg(long)]
    pub no_scale: bool,
    /// Degrees of freedom: sim3 (rotation, translation, scale), se3 (no
    /// scale), 4dof (translation + yaw about gravity: a metric estimate whose
    /// z is already along gravity, e.g. VIO), scale+4dof (translation, yaw and
    /// scale: monocular SLAM whose gravity is known).
    #[arg(long, value_name = "sim3|se3|4dof|scale+4dof", default_value = defaults::DOF, value_parser = dof)]
    pub dof: Dof,
    /// `first`: map the first fitted pose exactly onto its reference (the
    /// rest fits rotation and scale about it as the dof allows).
    #[arg(long, value_name = "none|first", default_value = "none", value_parser = anchor)]
    pub anchor: Anchor,
    /// Pairing of stamps: evo (each pose of the shorter trajectory takes the
    /// nearest stamp of the other) or one_to_one (each pose at most once,
    /// closest pairs first: the TUM benchmark's and rpg's rule).
    #[arg(long, value_name = "evo|one_to_one", default_value = defaults::ASSOCIATION, value_parser = association)]
    pub association: Association,
    /// Largest tilt of the estimate's gravity (degrees, by the Sim(3) fit)
    /// that a 4dof / scale+4dof fit accepts; `none`: no check.
    #[arg(long, value_name = "DEG|none", default_value_t = TiltLimit(Some(defaults::MAX_TILT_DEG)), value_parser = tilt_limit)]
    pub max_tilt: TiltLimit,
    /// Noise of the reference positions, metres (3-D rms of one position's
    /// error), for the fit-quality refusals (default: estimated from the
    /// reference's second differences).
    #[arg(long, value_name = "M", value_parser = non_negative)]
    pub reference_noise: Option<f64>,
    /// Accept fits the quality checks refuse (a static reference, a fit that
    /// explains none of the reference's spread, a scale left at 1).
    #[arg(long)]
    pub no_fit_checks: bool,
    /// Fit only the first N matched pairs after the start-up cut (the error
    /// is still over all pairs).
    #[arg(long, value_name = "N")]
    pub n_to_align: Option<usize>,
    /// Rotation solver: horn (quaternion) or umeyama (SVD).
    #[arg(long, value_name = "horn|umeyama", default_value = defaults::METHOD, value_parser = method)]
    pub method: AlignMethod,
    /// Drop the start of the run from the fit: `auto` (start-up stages found in
    /// the frame-to-frame scale factors) or a number of matched pairs.
    #[arg(long, value_name = "auto|N", value_parser = skip_init)]
    pub skip_init: Option<SkipInit>,
    /// Robust fit (RANSAC over minimal fits, IRLS, inlier mask).
    #[arg(long)]
    pub robust: bool,
    /// Largest residual of an inlier, metres (default: from the data).
    #[arg(long, value_name = "M", requires = "robust", value_parser = positive)]
    pub inlier_threshold: Option<f64>,
    /// IRLS loss of the robust fit.
    #[arg(long, value_name = "huber|cauchy", default_value = defaults::LOSS, value_parser = loss)]
    pub loss: RobustLoss,
    /// Use the orientations as well as the positions (near-straight paths).
    #[arg(long)]
    pub use_orientations: bool,
    /// Estimate the time offset between the SLAM poses and the reference and apply it.
    #[arg(long)]
    pub estimate_offset: bool,
    /// Largest offset searched by --estimate-offset, seconds.
    #[arg(long, value_name = "S", default_value_t = defaults::MAX_OFFSET, value_parser = positive)]
    pub max_offset: f64,
    /// Known camera–body extrinsic T_body_cam: 16 numbers (row-major 4x4) or 7
    /// (tx ty tz qx qy qz qw), separated by commas or spaces; metres.
    #[arg(long, value_name = "NUMBERS", value_parser = body_from_cam, allow_hyphen_values = true)]
    pub body_from_cam: Option<Sim3>,
    /// Confidence level of the reported intervals.
    #[arg(long, value_name = "P", default_value_t = defaults::CONFIDENCE, value_parser = level)]
    pub confidence: f64,
}

impl FitArgs {
    /// The core options these flags ask for.
    pub fn options(&self) -> TrajectoryAlignOptions {
        TrajectoryAlignOptions {
            max_diff: self.max_diff,
            offset: self.offset,
            scale: !self.no_scale,
            dof: self.dof,
            anchor: self.anchor,
            max_tilt_deg: self.max_tilt.0,
            association: self.association,
            checks: FitChecks {
                enabled: !self.no_fit_checks,
                reference_noise: self.reference_noise,
                ..FitChecks::default()
            },
            n_to_align: self.n_to_align,
            method: self.method,
            skip_init: self.skip_init.unwrap_or_default(),
            robust: self.robust.then(|| RobustOptions {
                inlier_threshold: self.inlier_threshold,
                loss: self.loss,
                ..Default::default()
            }),
            use_orientations: self.use_orientations,
            estimate_offset: self.estimate_offset.then(|| TimeOffsetOptions {
                max_offset: self.max_offset,
                ..Default::default()
            }),
            body_from_cam: self.body_from_cam,
        }
    }
}

/// The text lines of what the fit's options did (empty parts left out):
/// start-up cut, time offset, inliers, intervals.
pub fn fit_text(r: &crate::pipeline::report::FitReport) -> String {
    let mut s = String::new();
    if !matches!(r.dof, Dof::Sim3 | Dof::Se3)
        || r.anchor != Anchor::None
        || r.association != Association::Evo
    {
        s += &format!(
            "fit: dof {}, anchor {}, association {}\n",
            r.dof, r.anchor, r.association
        );
    }
    if let Some(d) = &r.dof_diagnostics {
        let tilt = d
            .gravity_tilt_deg
            .map_or("not observable".to_string(), |t| format!("{t:.3} deg"));
        s += &format!(
            "gravity tilt of the Sim(3) fit: {tilt}; yaw determinacy {:.6}\n",
            d.yaw_determinacy
        );
    }
    if r.fit_start > 0 || r.stages.is_some() {
        s += &format!("start-up cut: {}\n", r.skip_reason);
    }
    if let Some(o) = &r.offset_estimate {
        s += &format!(
            "time offset: {:+.6} s added to EST (estimated {:+.6} s; fit rmse {:.6} m, {:.6} m without)\n",
            r.offset, o.estimated, o.rmse, o.rmse_at_zero
        );
    }
    if let (Some(k), Some(out)) = (r.n_inliers, r.n_outliers) {
        s += &format!("robust fit: {k} inliers, {out} outliers\n");
    }
    if let Some(i) = &r.intervals {
        let t = &i.translation;
        let rot = &i.rotation_half_width_deg;
        s += &format!(
            "{:.0} % intervals: scale [{:.9}, {:.9}]; translation x [{:.6}, {:.6}] y [{:.6}, {:.6}] z [{:.6}, {:.6}]; rotation ±[{:.4}, {:.4}, {:.4}] deg\n",
            i.level * 100.0, i.scale[0], i.scale[1], t[0][0], t[0][1], t[1][0], t[1][1], t[2][0], t[2][1],
            rot[0], rot[1], rot[2]
        );
    }
    s
}

/// Writes `text` to stdout (a closed pipe is an error like any other write).
pub(crate) fn print(text: &str) -> Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|_| out.flush())
        .map_err(|e| Error::io("<stdout>", e))
}

/// Prints `value` as one line of compact JSON.
pub(crate) fn print_json<T: serde::Serialize>(value: &T) -> Result<()> {
    let mut text =
        serde_json::to_string(value).map_err(|e| Error::invalid("report", e.to_string()))?;
    text.push('\n');
    print(&text)
}

/// How GNSS fixes become the reference of a fit (`convert`, `align`).
#[derive(Args, Debug, Clone)]
pub struct GnssFitArgs {
    /// ENU origin of a GNSS reference: `first` (fix), `mean` (ECEF centroid)
    /// or `LAT,LON,ALT` (degrees, metres above the ellipsoid).
    #[arg(long, value_name = "first|mean|LAT,LON,ALT", default_value = defaults::ORIGIN, allow_hyphen_values = true, value_parser = origin)]
    pub origin: crate::geo::Origin,
    /// The GNSS antenna in the body frame (`T_body_antenna`, metres; the body
    /// is the SLAM camera unless `--body-from-cam` is given).
    #[arg(long, num_args = 3, value_names = ["X", "Y", "Z"], allow_hyphen_values = true, value_parser = finite)]
    pub lever_arm: Option<Vec<f64>>,
    /// Fit every GNSS pair with the same weight (default: 1/σ² from each
    /// fix's covariance, when every fix has one).
    #[arg(long)]
    pub no_gnss_weights: bool,
    /// Largest time between two fixes that a reference position interpolated
    /// at a SLAM stamp bridges, seconds (default: five of the fixes' median
    /// intervals, a dropout of up to four fixes).
    #[arg(long, value_name = "S", value_parser = positive)]
    pub gnss_max_gap: Option<f64>,
}

impl GnssFitArgs {
    /// The GNSS options.
    pub fn options(&self) -> crate::pipeline::gnss::GnssOptions {
        crate::pipeline::gnss::GnssOptions {
            origin: self.origin,
            lever_arm: self
                .lever_arm
                .as_ref()
                .map(|v| nalgebra::Vector3::new(v[0], v[1], v[2])),
            weights: !self.no_gnss_weights,
            max_gap: self.gnss_max_gap,
        }
    }
}

/// The line `convert` and `align` print of a GNSS reference.
pub fn gnss_text(g: &crate::pipeline::report::GnssReport) -> String {
    format!(
        "GNSS {}: {} fixes ({} without a fix dropped), world = ENU at lat {:.7} lon {:.7} alt {:.3} m ({}), {}{}\n",
        g.topic
            .clone()
            .or_else(|| g.file.as_ref().map(|p| p.display().to_string()))
            .unwrap_or_default(),
        g.fixes,
        g.dropped_no_fix,
        g.origin[0],
        g.origin[1],
        g.origin[2],
        g.origin_rule,
        g.utm_zone
            .as_ref()
            .map_or(String::new(), |z| format!("UTM zone {z}")),
        if g.weighted { ", weighted by covariance" } else { "" }
    )
}

/// The GNSS reference and the georeferenced outputs of `convert`.
#[derive(Args, Debug, Clone)]
pub struct GnssArgs {
    /// GNSS fixes as the reference, from a file: CSV / TXT `time, lat, lon,
    /// alt[, covariance]` (degrees; metres above the WGS84 ellipsoid) or NMEA
    /// (GGA, with GST accuracy); the world frame is then ENU at `--origin`.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["gnss_topic", "reference"])]
    pub gnss: Option<std::path::PathBuf>,
    /// Format of the `--gnss` file (default: detected from its first lines).
    #[arg(long, value_name = "csv|nmea", requires = "gnss", value_parser = gnss_format)]
    pub gnss_format: Option<crate::io::gnss::GnssFormat>,
    /// Metres added to every height of the `--gnss` file (the geoid
    /// separation, for heights above mean sea level).
    #[arg(long, value_name = "M", requires = "gnss", default_value_t = 0.0, allow_hyphen_values = true, value_parser = finite)]
    pub geoid_offset: f64,
    /// GNSS fixes as the reference, from a log topic (`sensor_msgs/NavSatFix`
    /// ros1 / cdr, `foxglove.LocationFix`); found by type when the log has no
    /// pose topic.
    #[arg(long, value_name = "TOPIC", conflicts_with = "pose_topic")]
    pub gnss_topic: Option<String>,
    /// Origin, lever arm, weights and interpolation of the fixes.
    #[command(flatten)]
    pub fit: GnssFitArgs,
    /// Write `cloud.las` (the default with a GNSS reference; refused without one).
    #[arg(long, conflicts_with = "no_las")]
    pub las: bool,
    /// Write no LAS file.
    #[arg(long)]
    pub no_las: bool,
    /// Write the LAS file compressed, as `cloud.laz`.
    #[arg(long, conflicts_with = "no_las")]
    pub laz: bool,
    /// Also write `cloud.pcd` (binary PCD, world-frame metres: ENU with GNSS).
    #[arg(long)]
    pub pcd: bool,
    /// CRS of the LAS file: `utm` (the zone of the ENU origin) or `ecef`.
    #[arg(long, value_name = "utm|ecef", default_value = defaults::CRS, value_parser = crs)]
    pub crs: crate::geo::GeoCrs,
}

pub(crate) fn gnss_format(s: &str) -> std::result::Result<crate::io::gnss::GnssFormat, String> {
    crate::io::gnss::GnssFormat::parse(s).map_err(|e| e.to_string())
}

fn origin(s: &str) -> std::result::Result<crate::geo::Origin, String> {
    crate::pipeline::gnss::parse_origin(s).map_err(|e| e.to_string())
}

fn crs(s: &str) -> std::result::Result<crate::geo::GeoCrs, String> {
    crate::geo::GeoCrs::parse(s, None).map_err(|e| e.to_string())
}

impl GnssArgs {
    /// The GNSS options.
    pub fn options(&self) -> crate::pipeline::gnss::GnssOptions {
        self.fit.options()
    }

    /// The georeferenced outputs.
    pub fn outputs(&self) -> crate::pipeline::gnss::GeoOutputs {
        crate::pipeline::gnss::GeoOutputs {
            las: if self.no_las {
                Some(false)
            } else {
                self.las.then_some(true)
            },
            laz: self.laz,
            pcd: self.pcd,
            crs: self.crs,
        }
    }

    /// The `--gnss` file.
    pub fn file(&self) -> Option<crate::pipeline::gnss::GnssFile> {
        self.gnss.as_ref().map(|p| crate::pipeline::gnss::GnssFile {
            path: p.clone(),
            format: self.gnss_format,
            geoid_offset: self.geoid_offset,
        })
    }
}
