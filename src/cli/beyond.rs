//! Command-line options beyond one closed-form fit (shared by `align` and
//! `convert`): start-up cut, robust fit, orientations, time offset, extrinsic,
//! and the report of what they did (with confidence intervals).

use clap::Args;
use nalgebra::Matrix4;

use crate::align::extended::{ExtendedAlignment, ExtendedOptions, SkipInit};
use crate::align::robust::{RobustLoss, RobustOptions};
use crate::align::time_offset::TimeOffsetOptions;
use crate::error::{Error, Result};
use crate::geometry::Sim3;

/// Alignment options beyond the closed form.
#[derive(Args, Debug, Default)]
pub struct BeyondArgs {
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
    #[arg(long, value_name = "huber|cauchy", default_value = "huber", value_parser = loss)]
    pub loss: RobustLoss,
    /// Use the orientations as well as the positions (near-straight paths).
    #[arg(long)]
    pub use_orientations: bool,
    /// Estimate the time offset between EST and REF and apply it.
    #[arg(long)]
    pub estimate_offset: bool,
    /// Largest offset searched by --estimate-offset, seconds.
    #[arg(long, value_name = "S", default_value_t = 0.5, value_parser = positive)]
    pub max_offset: f64,
    /// Known camera–body extrinsic T_body_cam: 16 numbers (row-major 4x4) or 7
    /// (tx ty tz qx qy qz qw), separated by commas or spaces; metres.
    #[arg(long, value_name = "NUMBERS", value_parser = body_from_cam, allow_hyphen_values = true)]
    pub body_from_cam: Option<Sim3>,
    /// Confidence level of the reported intervals.
    #[arg(long, value_name = "P", default_value_t = 0.95, value_parser = level)]
    pub confidence: f64,
}

fn skip_init(s: &str) -> std::result::Result<SkipInit, String> {
    s.parse().map_err(|e: Error| e.to_string())
}

fn loss(s: &str) -> std::result::Result<RobustLoss, String> {
    s.parse().map_err(|e: Error| e.to_string())
}

fn positive(s: &str) -> std::result::Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("expected a finite number > 0, got {s:?}")),
    }
}

fn level(s: &str) -> std::result::Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v > 0.0 && v < 1.0 => Ok(v),
        _ => Err(format!("expected a level in (0, 1), got {s:?}")),
    }
}

/// Parses 16 numbers (row-major 4×4) or 7 (`tx ty tz qx qy qz qw`).
pub fn parse_transform(s: &str) -> Result<Sim3> {
    let v: std::result::Result<Vec<f64>, _> = s
        .split(|c: char| c == ',' || c == ';' || c.is_whitespace())
        .filter(|t| !t.is_empty())
        .map(str::parse::<f64>)
        .collect();
    let v = v.map_err(|e| Error::invalid("body_from_cam", format!("{e} in {s:?}")))?;
    match v.len() {
        16 => Sim3::from_matrix(&Matrix4::from_row_slice(&v)),
        7 => Sim3::from_quaternion_xyzw(
            [v[3], v[4], v[5], v[6]],
            nalgebra::Vector3::new(v[0], v[1], v[2]),
            1.0,
        ),
        n => Err(Error::invalid(
            "body_from_cam",
            format!("expected 16 or 7 numbers, got {n}"),
        )),
    }
}

fn body_from_cam(s: &str) -> std::result::Result<Sim3, String> {
    parse_transform(s).map_err(|e| e.to_string())
}

impl BeyondArgs {
    /// The core options these flags ask for.
    pub fn options(&self) -> ExtendedOptions {
        ExtendedOptions {
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

/// The JSON report of the extras: start-up cut, offset, inliers, intervals.
pub fn report_json(r: &ExtendedAlignment, level: f64) -> serde_json::Value {
    r.report_json(level)
}

/// The text lines of the extras (empty parts left out).
pub fn report_text(r: &ExtendedAlignment, level: f64) -> String {
    let mut s = String::new();
    if r.fit_start > 0 || r.stages.is_some() {
        s += &format!("start-up cut: {}\n", r.skip_reason);
    }
    if let Some(o) = &r.offset_estimate {
        s += &format!(
            "time offset: {:+.6} s added to EST (estimated {:+.6} s; fit rmse {:.6} m, {:.6} m without)\n",
            r.offset, o.offset, o.rmse, o.rmse_at_zero
        );
    }
    if let Some(m) = &r.inliers {
        let k = m.iter().filter(|&&b| b).count();
        s += &format!("robust fit: {k} inliers, {} outliers\n", m.len() - k);
    }
    if let Some(c) = &r.covariance {
        if let (Ok(sc), Ok(t), Ok(rot)) = (
            c.scale_interval(level),
            c.translation_intervals(level),
            c.rotation_half_widths(level),
        ) {
            s += &format!(
                "{:.0} % intervals: scale [{:.9}, {:.9}]; translation x [{:.6}, {:.6}] y [{:.6}, {:.6}] z [{:.6}, {:.6}]; rotation ±[{:.4}, {:.4}, {:.4}] deg\n",
                level * 100.0, sc.0, sc.1, t[0].0, t[0].1, t[1].0, t[1].1, t[2].0, t[2].1,
                rot[0].to_degrees(), rot[1].to_degrees(), rot[2].to_degrees()
            );
        }
    }
    s
}
