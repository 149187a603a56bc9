//! Drift-aware alignment: one Sim(3) per matched pose, each fitted over a
//! window of its neighbours along the path (tricube weights, so that the
//! transforms change smoothly from pose to pose), and a blend of them
//! (lerp of the translation, slerp of the rotation, geometric mean of the
//! scale) at any time: `T_world_slam(t)`.
//!
//! A window the positions cannot determine (too few or collinear pairs) is
//! widened (doubled) until they can, up to the whole run.
//!
//! Every window is fitted with the degrees of freedom of the single fit
//! ([`super::dof::fit_window`]): with `4dof` each local transform is a yaw
//! and a translation, with `se3` / `4dof` every local scale is 1.

use nalgebra::Vector3;

use super::dof::{align_dof, fit_window, Anchor, Dof, DofOptions};
use super::{align, AlignMethod, AlignOptions, Alignment};
use crate::defaults;
use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::trajectory::{matched_pairs_with, Association, Trajectory};

/// The width of the window of each local fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Window {
    /// This many matched poses (the centre one included).
    Poses(usize),
    /// This length of reference path, metres (centred on the pose).
    Distance(f64),
}

impl Window {
    /// Checks the window: at least 3 poses, or a finite distance `> 0` metres.
    pub fn check(&self) -> Result<()> {
        match *self {
            Window::Poses(k) if k < 3 => Err(Error::invalid(
                "window",
                format!("need at least 3 poses, got {k}"),
            )),
            Window::Distance(d) if !(d.is_finite() && d > 0.0) => Err(Error::invalid(
                "window",
                format!("a distance must be finite and > 0 metres, got {d}"),
            )),
            _ => Ok(()),
        }
    }
}

impl Default for Window {
    fn default() -> Self {
        Window::Poses(15)
    }
}

/// Options of [`align_windowed`].
#[derive(Clone, Debug, PartialEq)]
pub struct WindowedOptions {
    /// Width of each local fit.
    pub window: Window,
    /// Largest time difference of a matched pair, seconds.
    pub max_diff: f64,
    /// Seconds added to the SLAM stamps before matching.
    pub offset: f64,
    /// Fit the scale (`false` turns `sim3` into `se3`).
    pub scale: bool,
    /// The transforms each fit chooses from (the single and the local ones).
    pub dof: Dof,
    /// Largest tilt of the estimate's gravity a yaw-only single fit accepts,
    /// degrees (the local fits are not checked again); `None`: no check.
    pub max_tilt_deg: Option<f64>,
    /// How SLAM stamps are paired with reference stamps.
    pub association: Association,
}

impl Default for WindowedOptions {
    fn default() -> Self {
        WindowedOptions {
            window: Window::default(),
            max_diff: defaults::MAX_DIFF,
            offset: defaults::OFFSET,
            scale: true,
            dof: Dof::Sim3,
            max_tilt_deg: Some(defaults::MAX_TILT_DEG),
            association: Association::Evo,
        }
    }
}

/// The result of [`align_windowed`].
#[derive(Clone, Debug)]
pub struct WindowedAlignment {
    /// SLAM stamps of the matched poses (seconds, offset applied), increasing.
    pub times: Vec<f64>,
    /// `T_world_slam` at each of `times`.
    pub transforms: Vec<Sim3>,
    /// Per pose `‖p_ref − T(t)·p_slam‖`, metres.
    pub residuals: Vec<f64>,
    /// rms of `residuals`, metres.
    pub rmse: f64,
    /// The single Sim(3) over every pair, for comparison.
    pub global: Alignment,
    /// Matched pairs `(slam index, reference index)`.
    pub pairs: Vec<(usize, usize)>,
}

impl WindowedAlignment {
    /// `T_world_slam` at SLAM time `t` (seconds, before the offset): the blend
    /// of the two neighbouring local transforms, the end ones outside.
    pub fn transform_at(&self, t: f64) -> Sim3 {
        let ts = &self.times;
        let n = ts.len();
        if n == 0 || !t.is_finite() {
            return self.global.transform;
        }
        let k = ts.partition_point(|&x| x <= t);
        if k == 0 {
            return self.transforms[0];
        }
        if k == n {
            return self.transforms[n - 1];
        }
        let (i, j) = (k - 1, k);
        let span = ts[j] - ts[i];
        let a = if span > 0.0 { (t - ts[i]) / span } else { 0.0 };
        blend(&self.transforms[i], &self.transforms[j], a)
    }
}

/// `(1 − a)·A + a·B` on the Sim(3) parameters (slerp, lerp, log-lerp).
pub fn blend(x: &Sim3, y: &Sim3, a: f64) -> Sim3 {
    let rotation = x
        .rotation
        .try_slerp(&y.rotation, a, 1e-12)
        .unwrap_or_else(|| x.rotation.nlerp(&y.rotation, a));
    let translation = x.translation.lerp(&y.translation, a);
    let scale = (x.scale.ln() * (1.0 - a) + y.scale.ln() * a).exp();
    Sim3 {
        rotation,
        translation,
        scale,
    }
}

/// Tricube weight of a distance `d` from the centre of a window of half-width `h`.
fn tricube(d: f64, h: f64) -> f64 {
    let u = (d / h).abs();
    if u >= 1.0 {
        0.0
    } else {
        let v = 1.0 - u * u * u;
        v * v * v
    }
}

/// Local fits of `dst ≈ T·src` around each pair; `coord[i]` is the position
/// of pair `i` along the path (index or metres), non-decreasing; `half` the
/// half-width in the same unit.
pub fn windowed_fits(
    src: &[Vector3<f64>],
    dst: &[Vector3<f64>],
    coord: &[f64],
    half: f64,
    opts: &AlignOptions,
    global: &Sim3,
) -> Vec<Sim3> {
    windowed_fits_with(src, dst, coord, half, global, |a, b, w| {
        let o = AlignOptions {
            weights: Some(w),
            ..opts.clone()
        };
        align(a, b, &o).map(|fit| fit.transform)
    })
}

/// [`windowed_fits`] with another fit per window: `fit(source, target,
/// weights)` over the window's pairs and tricube weights (e.g.
/// [`super::dof::fit_window`] for other degrees of freedom).
pub fn windowed_fits_with<F>(
    src: &[Vector3<f64>],
    dst: &[Vector3<f64>],
    coord: &[f64],
    half: f64,
    global: &Sim3,
    fit: F,
) -> Vec<Sim3>
where
    F: Fn(&[Vector3<f64>], &[Vector3<f64>], Vec<f64>) -> Result<Sim3>,
{
    let n = src.len();
    let total = coord.last().copied().unwrap_or(0.0) - coord.first().copied().unwrap_or(0.0);
    (0..n)
        .map(|i| {
            let mut h = half;
            loop {
                let lo = coord.partition_point(|&c| c < coord[i] - h);
                let hi = coord.partition_point(|&c| c <= coord[i] + h);
                let w: Vec<f64> = coord[lo..hi]
                    .iter()
                    .map(|&c| tricube(c - coord[i], h * (1.0 + 1e-9)))
                    .collect();
                if let Ok(t) = fit(&src[lo..hi], &dst[lo..hi], w) {
                    return t;
                }
                if h > total {
                    return *global;
                }
                h *= 2.0;
            }
        })
        .collect()
}

/// Associates `slam` with `reference` by time (as
/// [`super::trajectories::align_trajectories`]), fits the single transform,
/// then one per pair over its window, each with the dof of `opts`. Errors:
/// those of the single fit ([`super::dof::align_dof`]'s), and
/// [`Error::InvalidArgument`] for a window below 3 poses or not positive, or
/// `scale: false` with `scale+4dof`.
pub fn align_windowed(
    slam: &Trajectory,
    reference: &Trajectory,
    opts: &WindowedOptions,
) -> Result<WindowedAlignment> {
    slam.check_lengths()?;
    reference.check_lengths()?;
    opts.window.check()?;
    let dof = opts.dof.with_scale_flag(opts.scale)?;
    let pairs = matched_pairs_with(
        slam,
        reference,
        opts.max_diff,
        opts.offset,
        3,
        opts.association,
    )?;
    let src: Vec<Vector3<f64>> = pairs.iter().map(|&(s, _)| slam.positions[s]).collect();
    let dst: Vec<Vector3<f64>> = pairs.iter().map(|&(_, r)| reference.positions[r]).collect();
    let dopts = DofOptions {
        dof,
        anchor: Anchor::None,
        weights: None,
        method: AlignMethod::Horn,
        max_tilt_deg: opts.max_tilt_deg,
    };
    let global = align_dof(&src, &dst, &dopts)?;
    let (coord, half): (Vec<f64>, f64) = match opts.window {
        Window::Poses(k) => (
            (0..pairs.len()).map(|i| i as f64).collect(),
            // k poses: the centre and (k − 1)/2 on each side with positive weight.
            (k as f64 + 1.0) / 2.0,
        ),
        Window::Distance(d) => {
            let mut c = Vec::with_capacity(dst.len());
            let mut acc = 0.0;
            for (i, p) in dst.iter().enumerate() {
                if i > 0 {
                    acc += (p - dst[i - 1]).norm();
                }
                c.push(acc);
            }
            (c, d / 2.0)
        }
    };
    let transforms = windowed_fits_with(&src, &dst, &coord, half, &global.transform, |a, b, w| {
        fit_window(a, b, w, dof, AlignMethod::Horn)
    });
    let times: Vec<f64> = pairs.iter().map(|&(s, _)| slam.timestamps[s]).collect();
    let residuals: Vec<f64> = transforms
        .iter()
        .zip(src.iter().zip(&dst))
        .map(|(t, (a, b))| (b - t.transform_point(a)).norm())
        .collect();
    let rmse =
        (residuals.iter().map(|e| e * e).sum::<f64>() / residuals.len().max(1) as f64).sqrt();
    Ok(WindowedAlignment {
        times,
        transforms,
        residuals,
        rmse,
        global,
        pairs,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn follows_a_drifting_scale() {
        // The SLAM scale drifts by 30 % over the run: one Sim(3) cannot follow it.
        let n = 200;
        let times: Vec<f64> = (0..n).map(|i| i as f64 * 0.1).collect();
        let world: Vec<Vector3<f64>> = times
            .iter()
            .map(|&t| Vector3::new(t, (0.7 * t).sin() * 3.0, (0.3 * t).cos()))
            .collect();
        let mut slam = vec![Vector3::zeros()];
        for i in 1..n {
            let lam = 1.0 + 0.3 * i as f64 / n as f64;
            let step = (world[i] - world[i - 1]) / 5.0 * lam;
            slam.push(slam[i - 1] + step);
        }
        let s = Trajectory::try_new(times.clone(), slam, None).unwrap();
        let r = Trajectory::try_new(times.clone(), world, None).unwrap();
        let w = align_windowed(&s, &r, &WindowedOptions::default()).unwrap();
        assert!(
            w.rmse < 0.1 * w.global.rmse,
            "{} vs {}",
            w.rmse,
            w.global.rmse
        );
        // The local scale falls as the SLAM steps grow.
        assert!(w.transforms[10].scale > 1.2 * w.transforms[190].scale);
        let mid = w.transform_at(5.05);
        assert!(mid.scale < w.transforms[50].scale && mid.scale > w.transforms[51].scale);
        assert!(matches!(
            align_windowed(
                &s,
                &r,
                &WindowedOptions {
                    window: Window::Poses(2),
                    ..Default::default()
                }
            ),
            Err(Error::InvalidArgument { .. })
        ));
    }
}
