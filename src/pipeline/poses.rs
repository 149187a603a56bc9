//! The pose-reference path of `convert`: `T_world_slam` fitted to a metric
//! reference trajectory (and, when asked, a windowed fit beside it).

use crate::align::trajectories::{
    align_trajectories_weighted, SkipInit, TrajectoryAlignOptions, TrajectoryAlignment,
};
use crate::align::windowed::{align_windowed, WindowedAlignment, WindowedOptions};
use crate::error::{Error, Result};
use crate::trajectory::Trajectory;

use super::options::ConvertOptions;
use super::report::WindowedReport;
use super::source::Recording;
use super::startup::{live_cut, pairs_before, LiveCut};

/// `T_world_slam` from reference poses.
#[derive(Clone, Debug)]
pub struct PoseFit {
    /// The fit with its pairs, APE, start-up cut, inliers, offset, covariance.
    pub alignment: TrajectoryAlignment,
    /// The windowed fit, with `compare_windowed`.
    pub windowed: Option<WindowedAlignment>,
    /// The start-up cut found in the live frames, with `skip_init auto` on a
    /// log that has them ([`super::startup`]); the fit then drops the
    /// keyframe pairs stamped before the stable stage.
    pub startup: Option<LiveCut>,
}

/// Fits the recording's SLAM poses (`slam`, sorted by time) to `reference`
/// (each pose weighing its `weights` entry, when given: a GNSS reference).
/// With live frames (`frames`, the recording's) and `skip_init auto`, the
/// start-up cut is `live` when given (a GNSS reference pairs the live frames
/// itself), else found from the live frames matched with `reference`.
/// A match failure names the file and the topics (for a reconstruction it
/// stays [`Error::Unmatched`], its time spans followed by the files).
pub fn fit(
    rec: &Recording,
    slam: &Trajectory,
    reference: &Trajectory,
    weights: Option<&[f64]>,
    (frames, live): (Option<&Trajectory>, Option<LiveCut>),
    opts: &ConvertOptions,
) -> Result<PoseFit> {
    // With live frames, `auto` cuts where their scale factors settle.
    let (align, startup) = match (frames, opts.align.skip_init) {
        (Some(frames), SkipInit::Auto) => {
            let cut = match live {
                Some(cut) => cut,
                None => live_cut(frames, reference, &opts.align)?,
            };
            let k = pairs_before(slam, reference, &opts.align, cut.stable_time)?;
            let align = TrajectoryAlignOptions {
                skip_init: SkipInit::First(k),
                ..opts.align.clone()
            };
            (align, Some(cut))
        }
        _ => (opts.align.clone(), None),
    };
    let mut alignment =
        align_trajectories_weighted(slam, reference, weights, &align).map_err(|e| match e {
            // A reconstruction keeps the variant, its spans naming the files.
            Error::Unmatched {
                matched,
                need,
                slam_span,
                reference_span,
                max_diff,
                offset,
                cause,
            } if rec.source.reconstruction.is_some() => Error::Unmatched {
                matched,
                need,
                slam_span: format!("{slam_span} ({})", rec.source.path.display()),
                reference_span: match &rec.source.reference_path {
                    Some(p) => format!("{reference_span} ({})", p.display()),
                    None => reference_span,
                },
                max_diff,
                offset,
                cause,
            },
            Error::Unmatched { .. } => Error::Mcap {
                path: rec.source.path.clone(),
                reason: format!(
                    "keyframes{} against reference{}: {e}",
                    rec.source
                        .keyframe_topic
                        .as_ref()
                        .map_or(String::new(), |t| format!(" of topic {t}")),
                    rec.source
                        .reference_topic
                        .as_ref()
                        .map(|t| format!(" topic {t}"))
                        .or_else(|| {
                            rec.source
                                .reference_path
                                .as_ref()
                                .map(|p| format!(" {}", p.display()))
                        })
                        .unwrap_or_default()
                ),
            },
            e => e,
        })?;
    if let Some(cut) = &startup {
        alignment.skip_reason = format!(
            "the first {} matched pairs (stamped before {:.3} s) dropped: {}",
            alignment.fit_start,
            cut.stable_time,
            cut.describe()
        );
    }
    let windowed = match opts.compare_windowed {
        Some(window) => Some(align_windowed(
            slam,
            reference,
            &WindowedOptions {
                window,
                max_diff: opts.align.max_diff,
                offset: alignment.offset,
                scale: opts.align.scale,
                dof: opts.align.dof,
                max_tilt_deg: opts.align.max_tilt_deg,
                association: opts.align.association,
            },
        )?),
        None => None,
    };
    Ok(PoseFit {
        alignment,
        windowed,
        startup,
    })
}

impl PoseFit {
    /// The report's comparison of the windowed fit with the single one.
    pub fn windowed_report(&self, opts: &ConvertOptions) -> Option<WindowedReport> {
        let w = self.windowed.as_ref()?;
        let (lo, hi) = w
            .transforms
            .iter()
            .map(|t| t.scale)
            .fold((f64::INFINITY, 0.0f64), |(a, b), s| (a.min(s), b.max(s)));
        Some(WindowedReport {
            cloud: if opts.windowed_cloud {
                "windowed"
            } else {
                "single"
            }
            .into(),
            window: format!("{:?}", opts.compare_windowed?),
            windowed_rmse: w.rmse,
            single_rmse: w.global.rmse,
            scale_min: lo,
            scale_max: hi,
        })
    }
}
