//! The start-up stages of a monocular SLAM run, found in the frame-to-frame
//! scale factors `p_k` (≈ s² once the scale has settled; see
//! [`crate::trajectory::scale_factors`]).
//!
//! The paper sees three stages in `p_k`: an unsynchronised start (occasional
//! large deviations), a converging stretch (the level moves towards its final
//! value), then a stable level. Everything here is robust statistics of
//! `x_k = ln p_k`, with the window a fixed fraction of the run:
//!
//! * the stable level `L` and the per-sample noise `σ` are the median and the
//!   scaled MAD of the last third of `x`;
//! * a rolling median `m_k` (odd window `w`) follows the level; it is "at the
//!   stable level" where `|m_k − L| ≤ 4·max(1.2533·σ/√w, ω)`: four standard
//!   errors of a median of `w` samples, or four times the robust spread `ω` of
//!   `m_k` about `L` over the last third (a level that wanders once stable);
//! * `stable_start` is the first index after the last stretch of at least `w`
//!   consecutive factors not at the level (shorter excursions are kept);
//! * before it, `converging_start` is the change point of a level-then-ramp
//!   model of the rolling median (a constant start level, then a straight
//!   ramp to `L`), fitted by least squares.

use crate::error::{Error, Result};

/// Fewest factors for a detection (three windows of the smallest size).
pub const MIN_FACTORS: usize = 21;

/// Standard error of a median relative to `σ/√w`, for Gaussian samples.
const MEDIAN_EFFICIENCY: f64 = 1.2533;

/// Standard errors of the rolling median that still count as "at the level".
const LEVEL_TOLERANCE: f64 = 4.0;

/// Consistency factor of the MAD for Gaussian samples.
const MAD_TO_SIGMA: f64 = 1.4826;

/// The stage boundaries, indices into `p_k`.
#[derive(Clone, Debug, PartialEq)]
pub struct Stages {
    /// First factor of the converging stretch (0 when there is no start stage).
    pub converging_start: usize,
    /// First factor of the stable stage: fit from here.
    pub stable_start: usize,
    /// Number of factors.
    pub n: usize,
    /// The stable level of `p_k` (≈ s²): `exp(L)`.
    pub stable_level: f64,
    /// Per-sample standard deviation of `ln p_k` at the stable level (robust).
    pub noise: f64,
    /// Rolling window, factors.
    pub window: usize,
    /// Tolerance on the rolling median of `ln p_k`.
    pub tolerance: f64,
}

impl Stages {
    /// One line saying what is dropped and why.
    pub fn describe(&self) -> String {
        format!(
            "start stage: factors 0..{}, converging: {}..{}, stable from {} of {} \
             (level p = {:.6} ≈ s² → s ≈ {:.6}; rolling median of ln p over {} factors \
             within {:.3} of the level from there on)",
            self.converging_start,
            self.converging_start,
            self.stable_start,
            self.stable_start,
            self.n,
            self.stable_level,
            self.stable_level.sqrt(),
            self.window,
            self.tolerance
        )
    }
}

fn median_in_place(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    }
}

/// The median of each window `x[k - w/2 ..= k + w/2]` (cut at the ends), in
/// O(n·w) moves of a sorted window instead of a sort per window; the same
/// values as [`median_in_place`] of each window (the same multiset in the
/// same total order).
fn rolling_median(x: &[f64], w: usize) -> Vec<f64> {
    let h = w / 2;
    let n = x.len();
    let mut win: Vec<f64> = Vec::with_capacity(w + 1);
    let (mut lo, mut hi) = (0usize, 0usize);
    (0..n)
        .map(|k| {
            let (a, b) = (k.saturating_sub(h), (k + h + 1).min(n));
            while hi < b {
                let v = x[hi];
                let at = win.partition_point(|u| u.total_cmp(&v).is_lt());
                win.insert(at, v);
                hi += 1;
            }
            while lo < a {
                let v = x[lo];
                let at = win.partition_point(|u| u.total_cmp(&v).is_lt());
                win.remove(at);
                lo += 1;
            }
            let m = win.len() / 2;
            if win.len() % 2 == 1 {
                win[m]
            } else {
                0.5 * (win[m - 1] + win[m])
            }
        })
        .collect()
}

/// The change point `j` of a level-then-ramp model of the rolling median
/// `m[0..end]`: constant (its mean) before `j`, a straight ramp from that
/// constant to `level` over `j..end`; least squares, candidates every
/// quarter window.
fn ramp_start(m: &[f64], end: usize, level: f64, w: usize) -> usize {
    if end < 2 {
        return 0;
    }
    let step = (w / 4).max(1);
    let mut best = (0usize, f64::INFINITY);
    let mut j = 0;
    while j < end {
        let c = if j == 0 {
            m[0]
        } else {
            m[..j].iter().sum::<f64>() / j as f64
        };
        let mut cost: f64 = m[..j].iter().map(|v| (v - c) * (v - c)).sum();
        let len = (end - j) as f64;
        for (i, v) in m[j..end].iter().enumerate() {
            let r = c + (level - c) * (i as f64 + 0.5) / len;
            cost += (v - r) * (v - r);
        }
        if cost < best.1 {
            best = (j, cost);
        }
        j += step;
    }
    best.0
}

/// Finds the stages in the scale factors `p` (see the module doc). Errors:
/// [`Error::TooFew`] (fewer than [`MIN_FACTORS`]), [`Error::InvalidArgument`]
/// (a factor that is not finite and positive).
pub fn detect_stages(p: &[f64]) -> Result<Stages> {
    let n = p.len();
    if n < MIN_FACTORS {
        return Err(Error::TooFew {
            what: "scale factors for stage detection".into(),
            need: MIN_FACTORS,
            got: n,
        });
    }
    if let Some(i) = p.iter().position(|v| !(v.is_finite() && *v > 0.0)) {
        return Err(Error::invalid(
            "scale factors",
            format!("must be finite and > 0, factor {i} is {}", p[i]),
        ));
    }
    let x: Vec<f64> = p.iter().map(|v| v.ln()).collect();
    let w = ((n / 40) | 1).clamp(7, 101);
    let tail = &x[n - n / 3..];
    let mut buf = tail.to_vec();
    let level = median_in_place(&mut buf);
    for v in buf.iter_mut() {
        *v = (*v - level).abs();
    }
    let noise = MAD_TO_SIGMA * median_in_place(&mut buf);
    let med = rolling_median(&x, w);
    // The level may wander slowly once stable (scale drift): the spread of the
    // rolling median over the tail widens the tolerance accordingly.
    let mut tail_med: Vec<f64> = med[n - n / 3..].iter().map(|m| (m - level).abs()).collect();
    let wander = MAD_TO_SIGMA * median_in_place(&mut tail_med);
    let tolerance =
        (LEVEL_TOLERANCE * (MEDIAN_EFFICIENCY * noise / (w as f64).sqrt()).max(wander)).max(1e-9);
    let off = |k: usize| (med[k] - level).abs() > tolerance;
    // The last stretch of at least `w` consecutive factors off the level ends
    // the start-up; shorter excursions of a stable run are kept.
    let mut stable_start = 0;
    let (mut run, mut run_end) = (0usize, 0usize);
    for k in (0..n).rev() {
        if off(k) {
            if run == 0 {
                run_end = k;
            }
            run += 1;
            if run >= w {
                stable_start = (run_end + 1).min(n - 1);
                break;
            }
        } else {
            run = 0;
        }
    }
    let converging_start = ramp_start(&med, stable_start, level, w);
    Ok(Stages {
        converging_start,
        stable_start,
        n,
        stable_level: level.exp(),
        noise,
        window: w,
        tolerance,
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_sliding_median_is_the_median_of_each_window() {
        // Ties, both ends, windows longer than the data.
        let x: Vec<f64> = (0..500)
            .map(|i| ((i * 7919) % 37) as f64 * 0.5 - 3.0)
            .collect();
        for w in [1, 7, 8, 101, 1001] {
            let h = w / 2;
            let naive: Vec<f64> = (0..x.len())
                .map(|k| {
                    let mut b = x[k.saturating_sub(h)..(k + h + 1).min(x.len())].to_vec();
                    median_in_place(&mut b)
                })
                .collect();
            assert_eq!(rolling_median(&x, w), naive, "w {w}");
        }
    }

    use super::*;

    #[test]
    fn three_synthetic_stages() {
        // Start: jumpy around 3; converging linearly in ln to 9 over 200..500; stable 9.
        let mut p = Vec::new();
        for k in 0..900 {
            let wiggle = 1.0 + 0.05 * ((k as f64) * 1.7).sin();
            let v = if k < 200 {
                3.0 * if k % 7 == 0 { 2.5 } else { 1.0 }
            } else if k < 500 {
                (3f64.ln() + (9f64.ln() - 3f64.ln()) * (k - 200) as f64 / 300.0).exp()
            } else {
                9.0
            };
            p.push(v * wiggle);
        }
        let s = detect_stages(&p).unwrap();
        assert!(s.stable_start > 400 && s.stable_start <= 520, "{s:?}");
        assert!(
            s.converging_start >= 150 && s.converging_start < 300,
            "{s:?}"
        );
        assert!((s.stable_level - 9.0).abs() < 0.2);
        assert!(detect_stages(&p[..10]).is_err());
        let mut bad = p.clone();
        bad[3] = -1.0;
        assert!(detect_stages(&bad).is_err());
    }

    #[test]
    fn a_stable_run_keeps_everything() {
        let p: Vec<f64> = (0..300)
            .map(|k| 4.0 * (1.0 + 0.1 * ((k as f64) * 2.3).sin()))
            .collect();
        let s = detect_stages(&p).unwrap();
        assert_eq!(s.stable_start, 0);
    }
}
