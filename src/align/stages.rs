//! The start-up stages of a monocular SLAM run, found in the frame-to-frame
//! scale factors `p_k` (≈ s² once the scale has settled; see
//! [`crate::trajectory::scale_factors`]).
//!
//! The paper sees three stages in `p_k`: an unsynchronised start (occasional
//! large deviations), a converging stretch (the level moves towards its final
//! value), then a stable level. Nothing here is in seconds or in a fixed
//! number of factors: every size follows from the data.
//!
//! * `x_k = ln p_k` is cut into at most [`MAX_BLOCKS`] blocks of equal length
//!   (at least [`MIN_BLOCK`] factors) and each block is its median `y_j`, so
//!   that single wild factors (tracking bursts, start-up jumps) weigh nothing.
//!   The blocks' noise `σ_b` is the scaled MAD of consecutive differences
//!   over the later half (robust to the level's own moves).
//! * A model of the blocks is fitted by least squares for every pair of
//!   boundaries `c ≤ e`: before `c` the start stage, about the step's start
//!   level but anything at all beyond it (each block costs its squared
//!   residual up to a penalty of `ln(m)·σ_b²`, the price of a free
//!   parameter, plus one `σ_b²`, so that a block either stage explains alike
//!   is taken as stable); over
//!   `c..e` a smooth step (a raised cosine, which meets both levels
//!   tangentially) from a start level `a` to the stable level `L`; from `e` on
//!   the stable level with a slope `β` (a scale that drifts once stable). A
//!   start-up (`e > 0`) must pay for its two extra parameters too, and the
//!   drift its size: a ridge makes a change of [`STABLE_DRIFT`] in `ln p`
//!   over the stable stage cost one parameter (a scale drifting by more than
//!   that is not stable). The
//!   step's shape matters: the last part of any smooth approach lies under
//!   the noise, so a rule that waits for the level to be "near" the end cuts
//!   early; the shape puts the end where the approach reaches the level. A
//!   straight ramp has kinks, which the smooth step rounds: its stable start
//!   lands up to a fifth of the converging span after the kink, never before
//!   it (a ramp fitted as such chose ramps for smooth approaches too, and cut
//!   those early, which costs the fit more than a late cut).
//! * The boundaries' ranges are the boundaries whose best cost lies within
//!   [`RANGE_COST`]`·σ_b²` of the optimum (a likelihood-ratio interval).
//! * The run is taken as whole: the stable stage keeps two blocks at least.
//!   (The online session has a rule of its own for when the stable stage has
//!   begun; once the log is in, it ends on this cut.)

use nalgebra::{Matrix3, Vector3};

use crate::error::{Error, Result};

/// Fewest factors for a detection.
pub const MIN_FACTORS: usize = 21;

/// Most blocks the factors are cut into (the resolution of a boundary is the
/// run's length over this).
pub const MAX_BLOCKS: usize = 200;

/// Fewest factors in a block (its median must outvote a wild factor or two).
pub const MIN_BLOCK: usize = 3;

/// Cost above the optimum, in units of `σ_b²`, within which a boundary is
/// still in its stated range (≈ 2 standard errors).
pub const RANGE_COST: f64 = 4.0;

/// The change of `ln p` over the stable stage that a slow drift of the
/// scale may make at the price of one parameter (0.2: the scale drifting by
/// 10 %); a larger change is a stage of its own, not a drift.
pub const STABLE_DRIFT: f64 = 0.2;

/// Consistency factor of the MAD for Gaussian samples.
const MAD_TO_SIGMA: f64 = 1.4826;

/// The stage boundaries, indices into `p_k`.
#[derive(Clone, Debug, PartialEq)]
pub struct Stages {
    /// First factor of the converging stretch (0 when there is no start stage).
    pub converging_start: usize,
    /// First factor of the stable stage: fit from here.
    pub stable_start: usize,
    /// The range of `converging_start` the data supports (first, last).
    pub converging_range: (usize, usize),
    /// The range of `stable_start` the data supports (first, last).
    pub stable_range: (usize, usize),
    /// Number of factors.
    pub n: usize,
    /// The stable level of `p_k` at the stable start (≈ s²): `exp(L)`.
    pub stable_level: f64,
    /// Per-sample standard deviation of `ln p_k` in the stable stage (robust).
    pub noise: f64,
    /// Factors per block.
    pub window: usize,
    /// Whether a start-up was seen (a start stage or a converging stretch).
    pub startup_seen: bool,
}

impl Stages {
    /// One line saying what is dropped and why.
    pub fn describe(&self) -> String {
        format!(
            "start stage: factors 0..{}, converging: {}..{} (its start within {}..={}), \
             stable from {} (within {}..={}) of {} (level p = {:.6} ≈ s² → s ≈ {:.6}; \
             a smooth step fitted to medians of ln p over blocks of {} factors)",
            self.converging_start,
            self.converging_start,
            self.stable_start,
            self.converging_range.0,
            self.converging_range.1,
            self.stable_start,
            self.stable_range.0,
            self.stable_range.1,
            self.n,
            self.stable_level,
            self.stable_level.sqrt(),
            self.window,
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

/// The robust standard deviation of `v` about its median (scaled MAD).
fn mad_sigma(v: &[f64]) -> f64 {
    let mut b = v.to_vec();
    let c = median_in_place(&mut b);
    for u in b.iter_mut() {
        *u = (*u - c).abs();
    }
    MAD_TO_SIGMA * median_in_place(&mut b)
}

/// The noise of a series from its consecutive differences (robust to slow
/// moves of its level): the scaled MAD of the differences over √2.
pub(crate) fn diff_sigma(v: &[f64]) -> f64 {
    if v.len() < 3 {
        return 0.0;
    }
    let d: Vec<f64> = v.windows(2).map(|w| w[1] - w[0]).collect();
    mad_sigma(&d) / std::f64::consts::SQRT_2
}

/// Sums of the smooth step `g_i = cos²(π/2 · (i + ½)/d)`, `i < d`: `(Σg, Σg²)`.
fn step_sums(d: usize) -> (f64, f64) {
    (0..d)
        .map(step_weight(d))
        .fold((0.0, 0.0), |(a, b), g| (a + g, b + g * g))
}

fn step_weight(d: usize) -> impl Fn(usize) -> f64 {
    move |i| {
        let u = (i as f64 + 0.5) / d as f64;
        0.5 * (1.0 + (std::f64::consts::PI * u).cos())
    }
}

/// The blocks' model fit (see the module doc) for every `c ≤ e ≤ e_max`.
struct Fit {
    /// Blocks.
    y: Vec<f64>,
    // Prefix sums of y, y², j·y.
    s1: Vec<f64>,
    s2: Vec<f64>,
    sj: Vec<f64>,
    // Σg, Σg² of a step of each length.
    g: Vec<(f64, f64)>,
    penalty: f64,
    /// `σ_b²`.
    unit: f64,
}

impl Fit {
    fn new(y: Vec<f64>, sigma: f64) -> Fit {
        let unit = sigma * sigma;
        let penalty = unit * (y.len() as f64).ln().max(1.0);
        let m = y.len();
        let (mut s1, mut s2, mut sj) = (vec![0.0; m + 1], vec![0.0; m + 1], vec![0.0; m + 1]);
        for (j, v) in y.iter().enumerate() {
            s1[j + 1] = s1[j] + v;
            s2[j + 1] = s2[j] + v * v;
            sj[j + 1] = sj[j] + j as f64 * v;
        }
        let g = (0..=m).map(step_sums).collect();
        Fit {
            y,
            s1,
            s2,
            sj,
            g,
            penalty,
            unit,
        }
    }

    /// Cost and the fitted `(L, a − L, β)` of boundaries `c ≤ e`.
    fn cost(&self, c: usize, e: usize) -> (f64, Vector3<f64>) {
        let m = self.y.len();
        let d = e - c;
        let ns = (m - e) as f64;
        // Stable part: h = j − e over e..m.
        let sh = ns * (ns - 1.0) / 2.0;
        let shh = (ns - 1.0) * ns * (2.0 * ns - 1.0) / 6.0;
        let sy_s = self.s1[m] - self.s1[e];
        let syh = (self.sj[m] - self.sj[e]) - e as f64 * sy_s;
        // Step part: g over c..e.
        let (sg, sgg) = self.g[d];
        let w = step_weight(d);
        let syg: f64 = self.y[c..e].iter().enumerate().map(|(i, v)| v * w(i)).sum();
        let n = (m - c) as f64;
        let sy = self.s1[m] - self.s1[c];
        let syy = self.s2[m] - self.s2[c];
        // Columns: 1 (L), g (a − L), h (β); Σ g·h = 0.
        let use_g = d > 0;
        let use_h = m - e >= 3;
        // The drift over the stable stage, β·(m − e), weighs as a parameter
        // at STABLE_DRIFT (a ridge on β).
        let ridge = self.penalty * (ns / STABLE_DRIFT).powi(2);
        let mut a = Matrix3::new(n, sg, sh, sg, sgg, 0.0, sh, 0.0, shh + ridge);
        let mut b = Vector3::new(sy, syg, syh);
        for (k, used) in [(1usize, use_g), (2, use_h)] {
            if !used {
                for i in 0..3 {
                    a[(k, i)] = 0.0;
                    a[(i, k)] = 0.0;
                }
                a[(k, k)] = 1.0;
                b[k] = 0.0;
            }
        }
        let theta = a.try_inverse().map_or_else(Vector3::zeros, |inv| inv * b);
        // Each block of the step and the stable stage costs its squared
        // residual up to the penalty (a block far off the model is an outlier
        // here as in the start stage, so that heavy tails do not make the
        // start stage the cheaper explanation), and the drift its ridge.
        let _ = syy;
        let rss = self.y[c..]
            .iter()
            .enumerate()
            .map(|(i, v)| {
                let j = c + i;
                let model = if j < e {
                    theta[0] + theta[1] * w(i)
                } else {
                    theta[0] + theta[2] * (j - e) as f64
                };
                ((v - model) * (v - model)).min(self.penalty)
            })
            .sum::<f64>()
            + ridge * theta[2] * theta[2];
        // The start stage: its blocks about the step's start level, each
        // costing at most the penalty (a wild start is anything), and one
        // unit of noise more than a stable block would (where the two
        // explain the data alike, a block is taken as stable).
        let start = if use_g { theta[0] + theta[1] } else { theta[0] };
        let pre: f64 = self.y[..c]
            .iter()
            .map(|v| ((v - start) * (v - start)).min(self.penalty) + self.unit)
            .sum();
        let params = if e > 0 { 2.0 } else { 0.0 };
        (rss + pre + self.penalty * params, theta)
    }
}

/// The scale factors of pairs `baseline` apart, `p_k` from pair `k` to pair
/// `k + baseline` (`n − baseline` factors), a zero SLAM step carrying the
/// previous factor.
pub(crate) fn factors_over(
    src: &[Vector3<f64>],
    dst: &[Vector3<f64>],
    baseline: usize,
) -> Vec<f64> {
    let b = baseline.max(1);
    let mut out = Vec::with_capacity(src.len().saturating_sub(b));
    let mut last = f64::NAN;
    for k in 0..src.len().saturating_sub(b) {
        let ds = (src[k + b] - src[k]).norm_squared();
        let dr = (dst[k + b] - dst[k]).norm_squared();
        let p = dr / ds;
        if p.is_finite() && p > 0.0 {
            last = p;
        }
        out.push(last);
    }
    // Leading gaps take the first valid factor.
    if let Some(first) = out.iter().copied().find(|v| v.is_finite()) {
        for v in out.iter_mut() {
            if !v.is_finite() {
                *v = first;
            } else {
                break;
            }
        }
    }
    out
}

/// Share of the median step (SLAM and reference alike) below which a scale
/// factor is left out of the stages: over a step that short (a standstill,
/// a slow turn in place) the positions' noise is most of the step and drives
/// `p_k` towards the ratio of the two noises, a level the run never has.
pub const SHORT_STEP: f64 = 0.25;

/// The factors (`p_k` from pair `k` to `k + baseline` of `src`, `dst`) whose
/// steps are at least [`SHORT_STEP`] of their median on both sides; every
/// factor when fewer than [`MIN_FACTORS`] would be left.
pub fn moving_factors(src: &[Vector3<f64>], dst: &[Vector3<f64>], baseline: usize) -> Vec<usize> {
    let b = baseline.max(1);
    let n = src.len().min(dst.len()).saturating_sub(b);
    let steps =
        |v: &[Vector3<f64>]| -> Vec<f64> { (0..n).map(|k| (v[k + b] - v[k]).norm()).collect() };
    let (s, d) = (steps(src), steps(dst));
    let floor = |v: &[f64]| SHORT_STEP * median_in_place(&mut v.to_vec());
    if n == 0 {
        return Vec::new();
    }
    let (fs, fd) = (floor(&s), floor(&d));
    let keep: Vec<usize> = (0..n).filter(|&k| s[k] >= fs && d[k] >= fd).collect();
    if keep.len() < MIN_FACTORS {
        (0..n).collect()
    } else {
        keep
    }
}

/// [`detect_stages`] on the factors `p[keep[i]]` only (`keep` ascending, as
/// [`moving_factors`] gives it), with every index of the result an index
/// into `p` again (`n` is `p.len()`).
pub fn detect_stages_of(p: &[f64], keep: &[usize]) -> Result<Stages> {
    let kept: Vec<f64> = keep.iter().map(|&k| p[k]).collect();
    let mut st = detect_stages(&kept)?;
    let at = |i: usize| keep[i.min(keep.len() - 1)];
    st.converging_start = at(st.converging_start);
    st.stable_start = at(st.stable_start);
    st.converging_range = (at(st.converging_range.0), at(st.converging_range.1));
    st.stable_range = (at(st.stable_range.0), at(st.stable_range.1));
    st.n = p.len();
    Ok(st)
}

/// Per-factor noise of `ln p_k` that the stage factors are brought under by
/// a longer baseline ([`stage_factors`]): noisy steps bias `ln p_k` by about
/// half its variance, more where the motion is slow, and a bias that follows
/// the speed would pass for a move of the level.
pub const FACTOR_NOISE: f64 = 0.1;

/// Fewest factors per pair of baseline (the baseline is at most `n / 100`).
const PAIRS_PER_BASELINE: usize = 100;

/// The scale factors the stages are found in, from matched pairs of SLAM
/// (`src`) and reference (`dst`) positions: those of consecutive pairs where
/// their `ln` has a noise under [`FACTOR_NOISE`], else of pairs `K` apart,
/// `K` the smallest that brings the noise under it (noise falls as `1/K`
/// while the steps' own noise dominates; `K ≤ n / 100`). Returns the factors
/// (`p_k` from pair `k` to `k + K`) and `K`.
pub fn stage_factors(src: &[Vector3<f64>], dst: &[Vector3<f64>]) -> (Vec<f64>, usize) {
    let p = factors_over(src, dst, 1);
    let x: Vec<f64> = p.iter().map(|v| v.ln()).filter(|v| v.is_finite()).collect();
    let noise = diff_sigma(&x[x.len() / 2..]);
    let most = (src.len() / PAIRS_PER_BASELINE).max(1);
    let k = ((noise / FACTOR_NOISE).ceil() as usize).clamp(1, most);
    if k == 1 {
        (p, 1)
    } else {
        (factors_over(src, dst, k), k)
    }
}

/// The stages of matched pairs of SLAM (`src`) and reference (`dst`)
/// positions in time order, taken as a whole run: [`detect_stages`] on the
/// [`stage_factors`] whose steps are long enough to measure the scale
/// ([`moving_factors`]); indices are factor indices, factor `k` running from
/// pair `k` to pair `k + K`. Returns the stages and `K`.
pub fn stages_of_pairs(src: &[Vector3<f64>], dst: &[Vector3<f64>]) -> Result<(Stages, usize)> {
    let (p, baseline) = stage_factors(src, dst);
    let keep = moving_factors(src, dst, baseline);
    Ok((detect_stages_of(&p, &keep)?, baseline))
}

/// Finds the stages in the scale factors `p` of a whole run (see the module
/// doc). Errors: [`Error::TooFew`] (fewer than [`MIN_FACTORS`]),
/// [`Error::InvalidArgument`] (a factor that is not finite and positive).
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
    // The whole grid at the coarsest blocks, then each boundary refined on
    // blocks a quarter as long, near where the coarser level put it.
    let block = n.div_ceil(MAX_BLOCKS).max(MIN_BLOCK);
    let coarse = Level::new(&x, block);
    let m = coarse.m;
    let all = Window {
        c: 0..m + 1,
        e: 0..m + 1,
    };
    let found = coarse.search(&all);
    let (c_lo, c_hi) = found.c_range;
    let (e_lo, e_hi) = found.e_range;
    let (mut c, mut e, mut theta) = (coarse.at(found.c), coarse.at(found.e), found.theta);
    let mut b = block;
    while b > MIN_BLOCK {
        b = (b / REFINE).max(MIN_BLOCK);
        let level = Level::new(&x, b);
        let (jc, je) = (level.index(c), level.index(e));
        let near = |j: usize| j.saturating_sub(2 * REFINE)..(j + 2 * REFINE + 1).min(level.m + 1);
        let r = level.search(&Window {
            c: near(jc),
            e: near(je),
        });
        (c, e, theta) = (level.at(r.c), level.at(r.e), r.theta);
    }
    let (c_lo, c_hi) = (coarse.at(c_lo).min(c), coarse.at(c_hi).max(c));
    let (e_lo, e_hi) = (coarse.at(e_lo).min(e), coarse.at(e_hi).max(e));
    let stable_start = e.min(n - 1);
    let noise = if n - stable_start >= 3 {
        diff_sigma(&x[stable_start..])
    } else {
        f64::NAN
    };
    Ok(Stages {
        converging_start: c.min(stable_start),
        stable_start,
        converging_range: (c_lo.min(n - 1), c_hi.min(n - 1)),
        stable_range: (e_lo.min(n - 1), e_hi.min(n - 1)),
        n,
        stable_level: theta[0].exp(),
        noise,
        window: block,
        startup_seen: e_lo > 0,
    })
}

/// How much shorter the blocks of each refinement are.
const REFINE: usize = 4;

/// The candidate boundaries of a search, block indices.
struct Window {
    c: std::ops::Range<usize>,
    e: std::ops::Range<usize>,
}

/// What a search found: the best boundaries, their ranges (block indices)
/// and the fitted `(L, a − L, β)`.
struct Found {
    c: usize,
    e: usize,
    c_range: (usize, usize),
    e_range: (usize, usize),
    theta: Vector3<f64>,
}

/// The factors cut into blocks of one length, and the model's fit on them.
struct Level {
    n: usize,
    m: usize,
    fit: Fit,
}

impl Level {
    fn new(x: &[f64], block: usize) -> Level {
        let n = x.len();
        let m = (n / block).max(1);
        let y: Vec<f64> = (0..m)
            .map(|j| median_in_place(&mut x[j * n / m..(j + 1) * n / m].to_vec()))
            .collect();
        let sigma = diff_sigma(&y[m / 2..]).max(1e-12);
        Level {
            n,
            m,
            fit: Fit::new(y, sigma),
        }
    }

    /// First factor of block `j` (`n` past the last block).
    fn at(&self, j: usize) -> usize {
        j.min(self.m) * self.n / self.m
    }

    /// The block a factor index lies in (`m` for `n`).
    fn index(&self, f: usize) -> usize {
        if f >= self.n {
            self.m
        } else {
            (f * self.m / self.n).min(self.m - 1)
        }
    }

    /// The best boundaries in `w` (the stable stage keeps two blocks at
    /// least), with the ranges of those within [`RANGE_COST`].
    fn search(&self, w: &Window) -> Found {
        let m = self.m;
        let e_max = m.saturating_sub(2);
        let mut by_e = vec![f64::INFINITY; m + 1];
        let mut by_c = vec![f64::INFINITY; m + 1];
        let mut best = (0usize, 0usize, f64::INFINITY, Vector3::zeros());
        for e in w.e.clone().filter(|&e| e <= e_max) {
            for c in w.c.clone().filter(|&c| c <= e) {
                let (cost, theta) = self.fit.cost(c, e);
                by_e[e] = by_e[e].min(cost);
                by_c[c] = by_c[c].min(cost);
                if cost < best.2 {
                    best = (c, e, cost, theta);
                }
            }
        }
        let (c, e, opt, theta) = best;
        let limit = opt + RANGE_COST * self.fit.unit;
        let within = |v: &[f64], at: usize| {
            let first = v.iter().position(|&u| u <= limit).unwrap_or(at);
            let last = v.iter().rposition(|&u| u <= limit).unwrap_or(at);
            (first, last)
        };
        Found {
            c,
            e,
            c_range: within(&by_c, c),
            e_range: within(&by_e, e),
            theta,
        }
    }
}

#[cfg(test)]
mod tests {
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
        // A straight ramp has kinks at both ends, which the smooth step rounds
        // off: the stable start lands after the kink (never before it), within
        // a quarter of the converging span; the converging start as much before.
        assert!(s.stable_start >= 500 && s.stable_start <= 575, "{s:?}");
        assert!(
            s.stable_range.0 <= s.stable_start && s.stable_start <= s.stable_range.1,
            "{s:?}"
        );
        assert!(
            s.converging_start >= 125 && s.converging_start < 300,
            "{s:?}"
        );
        assert!(s.startup_seen);
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

    /// A level with white noise and heavy tails (one block in twenty far
    /// off, as small steps give a real run): nothing is a start-up.
    #[test]
    fn heavy_tails_without_a_start_up_keep_everything() {
        use rand::{Rng, SeedableRng};
        use rand_distr::StandardNormal;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(38);
        let p: Vec<f64> = (0..2000)
            .map(|_| {
                let z: f64 = rng.sample(StandardNormal);
                let wild = if rng.random::<f64>() < 0.05 {
                    if rng.random::<bool>() {
                        2.0
                    } else {
                        -2.0
                    }
                } else {
                    0.0
                };
                (1.2 + 0.05 * z + wild).exp()
            })
            .collect();
        let s = detect_stages(&p).unwrap();
        assert!(s.stable_start <= 20, "{}", s.describe());
    }

    /// A run that ends standing still: the steps under a quarter of the
    /// median are left out, and the stages are not found in them.
    #[test]
    fn a_standstill_at_the_end_is_no_stage() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let noise = Normal::new(0.0, 2e-4).unwrap();
        let mut n3 = || {
            Vector3::new(
                noise.sample(&mut rng),
                noise.sample(&mut rng),
                noise.sample(&mut rng),
            )
        };
        // 1000 pairs moving 1 cm a step, then 200 still; the SLAM at half scale.
        let truth: Vec<Vector3<f64>> = (0..1200)
            .map(|k| Vector3::new(0.01 * k.min(1000) as f64, 0.0, 0.0))
            .collect();
        let dst: Vec<Vector3<f64>> = truth.iter().map(|p| p + n3()).collect();
        let src: Vec<Vector3<f64>> = truth.iter().map(|p| p * 0.5 + n3()).collect();
        let keep = moving_factors(&src, &dst, 1);
        assert!(
            keep.iter().all(|&k| k < 1000),
            "{:?}",
            &keep[keep.len() - 3..]
        );
        let (st, _) = stages_of_pairs(&src, &dst).unwrap();
        assert!(st.stable_start <= 50, "{}", st.describe());
        // Without the filter, the standstill's factors (noise over noise) are a level of their own.
        let (p, _) = stage_factors(&src, &dst);
        let all: Vec<usize> = (0..p.len()).collect();
        let unfiltered = detect_stages_of(&p, &all).unwrap();
        assert!(unfiltered.stable_start > 900, "{}", unfiltered.describe());
    }
}
