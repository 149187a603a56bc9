//! Metric scale and gravity with no second sensor: the ground plane of a
//! reconstruction and the cameras' known height above it.
//!
//! - [`fit_ground_plane`]: the floor in a cloud (map points, keyframe
//!   backprojections, COLMAP points) by RANSAC, refined by least squares on
//!   its inliers. The cameras say where "up" is roughly: most captures keep
//!   the image's y axis near the gravity direction (a robot's, a car's or a
//!   walker's camera; a drone's looking ahead), so planes whose normal lies
//!   more than [`GroundOptions::max_up_angle_deg`] from the cameras' mean
//!   "image up" are no floor candidates (walls). Of the candidates that have
//!   the cameras above them, the lowest large one (at least
//!   [`GroundOptions::large_share`] of the largest one's support) is the
//!   ground: a floor beside a table top or rows of edges along boxes. Many
//!   points under it (the floor not seen, or too little of it to count, and
//!   a table taken for it) are refused with the reason, as is a cloud with
//!   no plane.
//! - [`metric_from_height`]: with the plane's normal as "up", the cameras'
//!   distances to it in SLAM units and their heights in metres give the
//!   scale (one height for all, the first pose's, or one per pose); the world
//!   frame has z up, its origin on the ground under the first camera and x
//!   along the first camera's heading (yaw and the horizontal origin are not
//!   observable, as with `--anchor first`).
//! - [`height_profile`]: both per window of keyframes, a scale profile
//!   along a run whose scale wanders.
//!
//! The thresholds follow the data: the search counts points within 1 % of
//! the median distance from the points to the cameras; a plane found is a
//! surface only when the points within five such thresholds gather near it
//! (a slice through wall points fills that band evenly), its inliers are
//! those within three robust standard deviations of it, and the final plane
//! is fitted to those within one (the band's tails are skewed by what
//! stands on the floor).

use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::defaults;
use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::trajectory::Trajectory;

/// Most planes [`fit_ground_plane`] weighs (the floor and what stands on it:
/// table tops, shelves, the rows of edges along boxes).
const MAX_CANDIDATES: usize = 5;

/// Options of [`fit_ground_plane`].
#[derive(Clone, Debug, PartialEq)]
pub struct GroundOptions {
    /// Largest angle between a candidate's normal and the cameras' mean
    /// "image up" (−y), degrees; `None`: no such prior (every plane with the
    /// cameras on one side is a candidate).
    pub max_up_angle_deg: Option<f64>,
    /// Fewest inliers a plane needs.
    pub min_inliers: usize,
    /// A plane is large with at least this share of the largest one's
    /// support; the ground is the lowest large plane.
    pub large_share: f64,
    /// Largest share of the points that may lie under the chosen plane (by
    /// more than three of its standard deviations).
    pub max_below: f64,
    /// Seed of the RANSAC draws (the fit is deterministic).
    pub seed: u64,
}

impl Default for GroundOptions {
    fn default() -> Self {
        GroundOptions {
            max_up_angle_deg: Some(defaults::GROUND_MAX_UP_ANGLE_DEG),
            min_inliers: defaults::GROUND_MIN_INLIERS,
            large_share: defaults::GROUND_LARGE_SHARE,
            max_below: defaults::GROUND_MAX_BELOW,
            seed: 0x6a0d,
        }
    }
}

/// The ground plane of a cloud: the points `x` with `normal · x + offset = 0`,
/// `normal` pointing to the cameras' side.
#[derive(Clone, Debug, PartialEq)]
pub struct GroundPlane {
    /// Unit normal, towards the cameras ("up").
    pub normal: Vector3<f64>,
    /// Signed distance of the origin: `normal · x + offset` is the height of `x`.
    pub offset: f64,
    /// Points within [`GroundPlane::threshold`] of the plane.
    pub inliers: usize,
    /// Points fitted.
    pub n_points: usize,
    /// Robust standard deviation of the inliers' distances (SLAM units).
    pub spread: f64,
    /// Inlier threshold used (three spreads, SLAM units).
    pub threshold: f64,
    /// Share of the points lower than three spreads under the plane.
    pub below: f64,
    /// Share of the cameras above the plane.
    pub cameras_above: f64,
    /// Angle between the normal and the cameras' mean "image up", degrees
    /// (`None` without orientations).
    pub tilt_from_cameras_deg: Option<f64>,
    /// The strongest other candidate: its inliers and its height over this
    /// plane (SLAM units), if any.
    pub runner_up: Option<(usize, f64)>,
    /// How well the points fix the plane ([`PlaneUncertainty`]).
    pub uncertainty: PlaneUncertainty,
}

impl GroundPlane {
    /// Height of `x` above the plane (SLAM units).
    pub fn height(&self, x: &Vector3<f64>) -> f64 {
        self.normal.dot(x) + self.offset
    }

    /// Standard deviation of [`GroundPlane::height`] at `x` from the
    /// plane's own uncertainty (SLAM units).
    pub fn height_sigma(&self, x: &Vector3<f64>) -> f64 {
        let u = &self.uncertainty;
        let d = x - u.centroid;
        let g = Vector3::new(d.dot(&u.axes[0]), d.dot(&u.axes[1]), 1.0);
        let shift = (u.band.0.dot(x) + u.band.1) - (u.core.0.dot(x) + u.core.1);
        ((g.transpose() * u.covariance * g)[(0, 0)].max(0.0) + shift * shift).sqrt()
    }

    /// Standard deviation of the normal's direction, degrees (the
    /// jackknife's, and the angle between the core's and the band's planes).
    pub fn tilt_sigma_deg(&self) -> f64 {
        let u = &self.uncertainty;
        let c = &u.covariance;
        let shift = u.band.0.cross(&u.core.0).norm().asin();
        (c[(0, 0)] + c[(1, 1)] + shift * shift)
            .max(0.0)
            .sqrt()
            .to_degrees()
    }
}

/// The plane's uncertainty by a block jackknife: its core points (those it
/// is fitted to) cut into [`JACKKNIFE_CELLS`]² cells of equal count along
/// the plane's two axes, the plane fitted again without each cell. The
/// cells, not the points, are the samples: the depth errors of the points
/// one keyframe sees together are alike, and neighbouring points share
/// keyframes, so that the spread of the points alone would promise a plane
/// far surer than it is. A plane moved by `(a, b, c)` changes the height of
/// `x` by `a·(x − centroid)·axes[0] + b·(x − centroid)·axes[1] + c`.
#[derive(Clone, Debug, PartialEq)]
pub struct PlaneUncertainty {
    /// Centroid of the core points.
    pub centroid: Vector3<f64>,
    /// Two orthonormal axes in the plane.
    pub axes: [Vector3<f64>; 2],
    /// Covariance of `(a, b, c)`: the slopes along the axes (radians) and
    /// the offset at the centroid (SLAM units).
    pub covariance: Matrix3<f64>,
    /// Cells the jackknife left out (those that left a plane to fit).
    pub cells: usize,
    /// The plane of all the inliers (three robust sigmas), `(normal, offset)`.
    pub band: (Vector3<f64>, f64),
    /// The plane of the core.
    pub core: (Vector3<f64>, f64),
}

/// Cells along each axis of the plane's jackknife ([`PlaneUncertainty`]).
pub const JACKKNIFE_CELLS: usize = 4;

/// The [`PlaneUncertainty`] of the plane `(n, d)` fitted to `core`.
fn plane_uncertainty(
    core: &[Vector3<f64>],
    n: &Vector3<f64>,
    d: f64,
    band: (Vector3<f64>, f64),
) -> PlaneUncertainty {
    let centroid = core.iter().sum::<Vector3<f64>>() / core.len().max(1) as f64;
    let e0 = n
        .cross(&if n.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        })
        .normalize();
    let e1 = n.cross(&e0);
    // Cells of equal count: quantiles along e0, then along e1 within each.
    let k = JACKKNIFE_CELLS;
    let mut order: Vec<usize> = (0..core.len()).collect();
    order.sort_by(|&i, &j| core[i].dot(&e0).total_cmp(&core[j].dot(&e0)));
    let mut cell = vec![0usize; core.len()];
    for (a, strip) in order.chunks(core.len().div_ceil(k).max(1)).enumerate() {
        let mut s = strip.to_vec();
        s.sort_by(|&i, &j| core[i].dot(&e1).total_cmp(&core[j].dot(&e1)));
        for (b, part) in s.chunks(s.len().div_ceil(k).max(1)).enumerate() {
            for &i in part {
                cell[i] = a * k + b;
            }
        }
    }
    let base = n.dot(&centroid) + d;
    let thetas: Vec<Vector3<f64>> = (0..k * k)
        .filter_map(|c| {
            let kept: Vec<Vector3<f64>> = core
                .iter()
                .zip(&cell)
                .filter(|(_, &o)| o != c)
                .map(|(p, _)| *p)
                .collect();
            if kept.len() == core.len() {
                return None;
            }
            let (mut m, mut e) = least_squares_plane(&kept)?;
            if m.dot(n) < 0.0 {
                (m, e) = (-m, -e);
            }
            // The change of height at centroid + u e0 + v e1, linear in u, v.
            let dm = m - n;
            Some(Vector3::new(
                dm.dot(&e0),
                dm.dot(&e1),
                m.dot(&centroid) + e - base,
            ))
        })
        .collect();
    let b = thetas.len();
    let covariance = if b >= 2 {
        let mean = thetas.iter().sum::<Vector3<f64>>() / b as f64;
        thetas
            .iter()
            .map(|t| (t - mean) * (t - mean).transpose())
            .sum::<Matrix3<f64>>()
            * ((b - 1) as f64 / b as f64)
    } else {
        Matrix3::from_diagonal_element(f64::INFINITY)
    };
    PlaneUncertainty {
        centroid,
        axes: [e0, e1],
        covariance,
        cells: b,
        band,
        core: (*n, d),
    }
}

/// A plane through the centroid of `pts` along its least spread (the normal
/// not yet oriented), or `None` when the points do not span a plane.
fn least_squares_plane(pts: &[Vector3<f64>]) -> Option<(Vector3<f64>, f64)> {
    if pts.len() < 3 {
        return None;
    }
    let n = pts.len() as f64;
    let c = pts.iter().sum::<Vector3<f64>>() / n;
    let mut cov = Matrix3::zeros();
    for p in pts {
        let d = p - c;
        cov += d * d.transpose();
    }
    let e = SymmetricEigen::new(cov / n);
    let (i, _) = e
        .eigenvalues
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))?;
    let normal = e.eigenvectors.column(i).into_owned();
    let normal = normal.try_normalize(1e-300)?;
    Some((normal, -normal.dot(&c)))
}

/// The median of `v` (reordered), `NaN` for none.
fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let m = v.len() / 2;
    let (_, x, _) = v.select_nth_unstable_by(m, f64::total_cmp);
    *x
}

/// A plane found by [`fit_ground_plane`]'s search.
struct Candidate {
    normal: Vector3<f64>,
    offset: f64,
    inliers: Vec<usize>,
    /// Share of the cameras above it.
    above: f64,
    /// Its inlier threshold (three robust sigmas).
    tau: f64,
}

/// The cameras' mean "image up" (−y of each `R_world_cam`), when it is
/// consistent (its mean has at least half a unit's length).
fn camera_up(cameras: &Trajectory) -> Option<Vector3<f64>> {
    let o = cameras.orientations.as_ref()?;
    let sum: Vector3<f64> = o.iter().map(|q| -(q * Vector3::y())).sum();
    let mean = sum / o.len().max(1) as f64;
    (mean.norm() >= 0.5).then(|| mean.normalize())
}

/// One RANSAC candidate: the plane of most inliers (within `tau`) among the
/// `active` points whose normal points to the cameras' side and lies within
/// the tilt cone.
fn ransac(
    pts: &[Vector3<f64>],
    active: &[usize],
    centroid: &Vector3<f64>,
    up: Option<(Vector3<f64>, f64)>,
    tau: f64,
    rng: &mut ChaCha8Rng,
) -> Option<(Vector3<f64>, f64, usize)> {
    if active.len() < 3 {
        return None;
    }
    let mut best: Option<(Vector3<f64>, f64, usize)> = None;
    let mut iters = 2000usize;
    let mut k = 0;
    while k < iters {
        k += 1;
        let pick = |rng: &mut ChaCha8Rng| pts[active[rng.random_range(0..active.len())]];
        let (a, b, c) = (pick(rng), pick(rng), pick(rng));
        let Some(mut n) = (b - a).cross(&(c - a)).try_normalize(1e-12) else {
            continue;
        };
        if n.dot(&(centroid - a)) < 0.0 {
            n = -n;
        }
        if let Some((u, cos_max)) = up {
            if n.dot(&u) < cos_max {
                continue;
            }
        }
        let d = -n.dot(&a);
        let count = active
            .iter()
            .filter(|&&i| (n.dot(&pts[i]) + d).abs() < tau)
            .count();
        if best.as_ref().is_none_or(|b| count > b.2) {
            best = Some((n, d, count));
            // Enough draws to hit three inliers with 99.9 % probability.
            let w = count as f64 / active.len() as f64;
            let need = ((1.0 - 0.999f64).ln() / (1.0 - w.powi(3)).ln()).ceil();
            if need.is_finite() {
                iters = iters.min((need as usize).max(50));
            }
        }
    }
    best
}

/// Least-squares refinement of a plane on the points within `tau` of it
/// (twice), oriented to the cameras' side; with its inliers.
fn refine(
    pts: &[Vector3<f64>],
    idx: &[usize],
    plane: (Vector3<f64>, f64),
    towards: &Vector3<f64>,
    tau: f64,
) -> Option<(Vector3<f64>, f64, Vec<usize>)> {
    let (mut n, mut d) = plane;
    let mut inliers: Vec<usize> = Vec::new();
    for _ in 0..2 {
        inliers = idx
            .iter()
            .copied()
            .filter(|&i| (n.dot(&pts[i]) + d).abs() < tau)
            .collect();
        let chosen: Vec<Vector3<f64>> = inliers.iter().map(|&i| pts[i]).collect();
        let (mut m, mut e) = least_squares_plane(&chosen)?;
        if m.dot(towards) + e < 0.0 {
            (m, e) = (-m, -e);
        }
        (n, d) = (m, e);
    }
    Some((n, d, inliers))
}

/// The plane candidates of [`fit_ground_plane`]: surfaces found one after
/// the other by RANSAC within `cone`, each with its inliers and the share
/// of the cameras above it.
fn search(
    pts: &[Vector3<f64>],
    cameras: &Trajectory,
    cam_centroid: &Vector3<f64>,
    cone: Option<(Vector3<f64>, f64)>,
    tau0: f64,
    opts: &GroundOptions,
) -> Vec<Candidate> {
    // The RANSAC draws run over at most 4 000 points (every k-th).
    let stride = pts.len().div_ceil(4_000).max(1);
    let mut active: Vec<usize> = (0..pts.len()).step_by(stride).collect();
    let all: Vec<usize> = (0..pts.len()).collect();
    let band = 5.0 * tau0;
    let mut rng = ChaCha8Rng::seed_from_u64(opts.seed);
    // Up to MAX_CANDIDATES candidates, each found in what the ones before left. A
    // candidate is a surface when the points within five search thresholds
    // of it gather near it (their robust sigma at most 0.4 of that band's
    // half-width); a slice through a volume or across walls fills the band
    // evenly (sigma ~0.74 of it). Its own threshold is three of its sigmas.
    let mut candidates: Vec<Candidate> = Vec::new();
    for _ in 0..8 {
        if candidates.len() == MAX_CANDIDATES {
            break;
        }
        let Some((n, d, count)) = ransac(pts, &active, cam_centroid, cone, tau0, &mut rng) else {
            break;
        };
        if count * stride < opts.min_inliers {
            break;
        }
        let mut r: Vec<f64> = all
            .iter()
            .map(|&i| (n.dot(&pts[i]) + d).abs())
            .filter(|&x| x < band)
            .collect();
        let sigma = 1.4826 * median(&mut r);
        active.retain(|&i| (n.dot(&pts[i]) + d).abs() >= band);
        if sigma.is_nan() || sigma > 0.4 * band {
            continue;
        }
        let tau = (3.0 * sigma).max(1e-12 * tau0);
        let Some((n, d, inliers)) = refine(pts, &all, (n, d), cam_centroid, tau) else {
            continue;
        };
        let above = cameras
            .positions
            .iter()
            .filter(|c| n.dot(c) + d > 0.0)
            .count() as f64
            / cameras.len() as f64;
        if inliers.len() >= opts.min_inliers {
            candidates.push(Candidate {
                normal: n,
                offset: d,
                inliers,
                above,
                tau,
            });
        }
    }
    candidates
}

/// The ground plane of `points` under `cameras` (positions; orientations,
/// when given, bound the candidates' tilt). Errors: too few finite points,
/// no plane of [`GroundOptions::min_inliers`] under the cameras, a rival of
/// similar support, or too many points under the plane (each says so).
pub fn fit_ground_plane(
    points: &[Vector3<f64>],
    cameras: &Trajectory,
    opts: &GroundOptions,
) -> Result<GroundPlane> {
    let pts: Vec<Vector3<f64>> = points
        .iter()
        .copied()
        .filter(|p| p.iter().all(|v| v.is_finite()))
        .collect();
    if pts.len() < opts.min_inliers.max(3) {
        return Err(Error::TooFew {
            what: "finite points for a ground plane".into(),
            need: opts.min_inliers.max(3),
            got: pts.len(),
        });
    }
    if cameras.is_empty() {
        return Err(Error::TooFew {
            what: "camera poses above the ground".into(),
            need: 1,
            got: 0,
        });
    }
    let cam_centroid =
        cameras.positions.iter().sum::<Vector3<f64>>() / cameras.positions.len() as f64;
    let up = camera_up(cameras);
    let cone = match (up, opts.max_up_angle_deg) {
        (Some(u), Some(deg)) => Some((u, deg.to_radians().cos())),
        _ => None,
    };
    // The search threshold: 1 % of the points' median distance to the cameras.
    let mut dist: Vec<f64> = pts.iter().map(|p| (p - cam_centroid).norm()).collect();
    let tau0 = 0.01 * median(&mut dist);
    if tau0.is_nan() || tau0 <= 0.0 {
        return Err(Error::Degenerate {
            reason: "the points lie on the cameras: no scene to find a ground in".into(),
            value: tau0,
        });
    }
    let band = 5.0 * tau0;
    let candidates = search(&pts, cameras, &cam_centroid, cone, tau0, opts);
    let all: Vec<usize> = (0..pts.len()).collect();
    let under: Vec<&Candidate> = candidates.iter().filter(|c| c.above >= 0.9).collect();
    let most = under.iter().map(|c| c.inliers.len()).max().unwrap_or(0);
    // The ground: the lowest large plane (support at least `large_share` of
    // the largest), lowest meaning farthest under the cameras.
    let Some(best) = under
        .iter()
        .filter(|c| c.inliers.len() as f64 >= opts.large_share * most as f64)
        .max_by(|a, b| {
            let h = |c: &Candidate| c.normal.dot(&cam_centroid) + c.offset;
            h(a).total_cmp(&h(b))
        })
    else {
        return Err(no_ground(&candidates, pts.len(), cone.is_some(), opts));
    };
    let (above, tau) = (best.above, best.tau);
    // The plane itself from its core (within one robust sigma): what stands
    // on the floor (the foot of a box, its lowest edges) and depth errors
    // skew the band's upper tail, the core hardly.
    let (n, d, core) = match refine(
        &pts,
        &all,
        (best.normal, best.offset),
        &cam_centroid,
        tau / 3.0,
    ) {
        Some((n, d, core)) if core.len() >= opts.min_inliers => (n, d, core),
        _ => (best.normal, best.offset, best.inliers.clone()),
    };
    let core: Vec<Vector3<f64>> = core.iter().map(|&i| pts[i]).collect();
    let inliers: Vec<usize> = all
        .iter()
        .copied()
        .filter(|&i| (n.dot(&pts[i]) + d).abs() < tau)
        .collect();
    let uncertainty = plane_uncertainty(&core, &n, d, band_plane(&pts, &inliers, &n, d));
    let inliers = &inliers;
    // The largest other surface at another height (more than the search band
    // away; a candidate within it is a piece of the same noisy floor).
    let runner_up = under
        .iter()
        .filter(|c| !std::ptr::eq(**c, *best))
        .map(|c| {
            let h =
                c.inliers.iter().map(|&i| n.dot(&pts[i]) + d).sum::<f64>() / c.inliers.len() as f64;
            (c.inliers.len(), h)
        })
        .filter(|(_, h)| h.abs() > band)
        .max_by_key(|c| c.0);
    let mut r: Vec<f64> = inliers
        .iter()
        .map(|&i| (n.dot(&pts[i]) + d).abs())
        .collect();
    let spread = 1.4826 * median(&mut r);
    let below = pts.iter().filter(|p| n.dot(p) + d < -tau).count() as f64 / pts.len() as f64;
    if below > opts.max_below {
        return Err(Error::Degenerate {
            reason: format!(
                "{:.1} % of the points lie under the plane found (more than {:.1} %): it is not \
                 the ground (a table top or a platform, the floor not seen)",
                100.0 * below,
                100.0 * opts.max_below
            ),
            value: below,
        });
    }
    Ok(GroundPlane {
        normal: n,
        offset: d,
        inliers: inliers.len(),
        n_points: pts.len(),
        spread,
        threshold: tau,
        below,
        cameras_above: above,
        tilt_from_cameras_deg: up.map(|u| u.dot(&n).clamp(-1.0, 1.0).acos().to_degrees()),
        runner_up,
        uncertainty,
    })
}

/// The refusal when no candidate is the ground: how many points a plane
/// needed, among how many, and how large the planes found (not under the
/// cameras) were.
fn no_ground(candidates: &[Candidate], n_points: usize, cone: bool, opts: &GroundOptions) -> Error {
    let largest = candidates
        .iter()
        .map(|c| c.inliers.len())
        .max()
        .unwrap_or(0);
    Error::Degenerate {
        reason: format!(
            "no plane of {} points at least{} under the cameras among the cloud's {n_points}{}: \
             the ground is not in the cloud, or too little of it was seen",
            opts.min_inliers,
            if cone {
                " within the cameras' tilt"
            } else {
                ""
            },
            if largest > 0 {
                format!(" (the planes found, of up to {largest} points, are not under the cameras)")
            } else {
                String::new()
            }
        ),
        value: largest as f64,
    }
}

/// The least-squares plane of all the `inliers` of `pts` (the three-sigma
/// band), oriented as `(n, d)`; `(n, d)` itself when they span no plane.
fn band_plane(
    pts: &[Vector3<f64>],
    inliers: &[usize],
    n: &Vector3<f64>,
    d: f64,
) -> (Vector3<f64>, f64) {
    let band: Vec<Vector3<f64>> = inliers.iter().map(|&i| pts[i]).collect();
    least_squares_plane(&band)
        .map(|(m, e)| if m.dot(n) < 0.0 { (-m, -e) } else { (m, e) })
        .unwrap_or((*n, d))
}

/// The cameras' known height above the ground, metres.
#[derive(Clone, Debug, PartialEq)]
pub enum CameraHeight {
    /// The same height at every pose (a robot, a car; the median is fitted).
    Constant(f64),
    /// The height at the first pose (the drone on the floor or a stand).
    First(f64),
    /// One height per pose (from a file, a barometer, a ground truth).
    PerPose(Vec<f64>),
}

/// The metric frame from a ground plane and the cameras' heights.
#[derive(Clone, Debug, PartialEq)]
pub struct HeightScale {
    /// `T_world_slam`: z up (the plane's normal), the origin on the ground
    /// under the first camera, x along its heading.
    pub t_world_slam: Sim3,
    /// Metres per SLAM unit.
    pub scale: f64,
    /// The cameras' heights above the plane, SLAM units.
    pub heights: Vec<f64>,
    /// Rms of the given heights less the fitted ones (metres; 0 for one).
    pub height_rms: f64,
    /// Relative standard deviation of the scale from the plane's
    /// uncertainty ([`GroundPlane::height_sigma`] where the heights are
    /// read) and the scatter of the cameras' heights about the fit (the
    /// median's error for one height, the least-squares fit's for a height
    /// per pose; none for the first pose alone). The given heights' own
    /// uncertainty adds to it ([`HeightScale::scale_sigma_with`]).
    pub scale_sigma: f64,
}

impl HeightScale {
    /// Relative standard deviation of the scale when the given heights
    /// themselves are uncertain by `relative` (their sigma over their
    /// value; the same for every pose, as a height misjudged is).
    pub fn scale_sigma_with(&self, relative: f64) -> f64 {
        self.scale_sigma.hypot(relative)
    }
}

/// Scale and gravity from `plane` and the cameras' `height`: see the module
/// doc. Errors: a camera on or under the plane among those used, a height
/// that is not a positive number, a per-pose list of another length.
pub fn metric_from_height(
    plane: &GroundPlane,
    cameras: &Trajectory,
    height: &CameraHeight,
) -> Result<HeightScale> {
    if cameras.is_empty() {
        return Err(Error::TooFew {
            what: "camera poses".into(),
            need: 1,
            got: 0,
        });
    }
    let h: Vec<f64> = cameras.positions.iter().map(|c| plane.height(c)).collect();
    let positive = |v: f64, what: &str| -> Result<f64> {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(Error::invalid(
                what,
                format!("must be a positive number of metres, got {v}"),
            ))
        }
    };
    let n = h.len() as f64;
    let centre = cameras.positions.iter().sum::<Vector3<f64>>() / n;
    // (scale, (SLAM height, metres) pairs, relative sigma of the SLAM
    // height the scale divides by).
    let (scale, given, sigma): (f64, Vec<(f64, f64)>, f64) = match height {
        CameraHeight::Constant(m) => {
            let m = positive(*m, "camera_height")?;
            let mut v = h.clone();
            let med = median(&mut v);
            let mut dev: Vec<f64> = h.iter().map(|x| (x - med).abs()).collect();
            // The median's standard error: 1.2533 robust sigmas over √n.
            let scatter = 1.2533 * 1.4826 * median(&mut dev) / n.sqrt();
            (
                m / med,
                h.iter().map(|&x| (x, m)).collect(),
                plane.height_sigma(&centre).hypot(scatter) / med,
            )
        }
        CameraHeight::First(m) => {
            let m = positive(*m, "camera_height")?;
            (
                m / h[0],
                vec![(h[0], m)],
                plane.height_sigma(&cameras.positions[0]) / h[0],
            )
        }
        CameraHeight::PerPose(v) => {
            if v.len() != h.len() {
                return Err(Error::ShapeMismatch {
                    what: "camera heights".into(),
                    expected: format!("({},), one per pose", h.len()),
                    got: format!("({},)", v.len()),
                });
            }
            for &m in v {
                positive(m, "camera heights")?;
            }
            let (num, den) = h
                .iter()
                .zip(v)
                .fold((0.0, 0.0), |(a, b), (x, m)| (a + x * m, b + x * x));
            let s = num / den;
            // The least-squares scale's error from the residuals (SLAM units).
            let rms = (h
                .iter()
                .zip(v)
                .map(|(x, m)| (m / s - x).powi(2))
                .sum::<f64>()
                / n)
                .sqrt();
            (
                s,
                h.iter().copied().zip(v.iter().copied()).collect(),
                (plane.height_sigma(&centre) / (den / n).sqrt()).hypot(rms / den.sqrt()),
            )
        }
    };
    if !(scale.is_finite() && scale > 0.0) {
        let first = h.first().copied().unwrap_or(f64::NAN);
        return Err(Error::Degenerate {
            reason: format!(
                "the cameras are not above the ground plane (first camera at {first:+.4} units)"
            ),
            value: first,
        });
    }
    let height_rms = (given
        .iter()
        .map(|(x, m)| (scale * x - m).powi(2))
        .sum::<f64>()
        / given.len() as f64)
        .sqrt();
    // z up, the first camera over the origin at its height in metres.
    let t_world_slam = super::priors::level_frame(&plane.normal, cameras, scale, scale * h[0]);
    Ok(HeightScale {
        t_world_slam,
        scale,
        heights: h,
        height_rms,
        scale_sigma: sigma,
    })
}

/// The scale of one window of keyframes ([`height_profile`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ProfileWindow {
    /// First camera of the window (index).
    pub first: usize,
    /// Last camera of the window (index, inclusive).
    pub last: usize,
    /// Mean stamp of its cameras.
    pub time: f64,
    /// Metres per SLAM unit there; `None` where no ground was found.
    pub scale: Option<f64>,
    /// The window's floor points (0 without a plane).
    pub inliers: usize,
    /// Why the window has no scale (the ground plane's refusal).
    pub reason: Option<String>,
}

/// The scale along a run whose scale wanders: the ground plane and the
/// cameras' `height` (metres, the same at every pose) per window of
/// `window` consecutive cameras, the windows overlapping by half. Point `i`
/// of `points` was seen from camera `owner[i]` (an index of `cameras`);
/// each window fits the points of its own cameras, so that the floor under
/// one stretch of the run scales that stretch. A window where the floor is
/// not seen gets the reason instead of a scale. The window is a trade: its
/// keyframes must see enough floor, and the scale must change little over
/// it (a drifting scale puts the floor seen from each keyframe at its own
/// distance, and the floors of a long window make a band, not a plane).
/// Errors: `owner` of another length or naming no camera, a window of
/// fewer than 2 cameras, a height that is not a positive number.
pub fn height_profile(
    points: &[Vector3<f64>],
    owner: &[usize],
    cameras: &Trajectory,
    height: f64,
    window: usize,
    opts: &GroundOptions,
) -> Result<Vec<ProfileWindow>> {
    use rayon::prelude::*;
    if owner.len() != points.len() {
        return Err(Error::ShapeMismatch {
            what: "point owners".into(),
            expected: format!("({},), one camera per point", points.len()),
            got: format!("({},)", owner.len()),
        });
    }
    let n = cameras.len();
    if let Some(&bad) = owner.iter().find(|&&o| o >= n) {
        return Err(Error::invalid(
            "owner",
            format!("names camera {bad}, and there are {n}"),
        ));
    }
    if window < 2 {
        return Err(Error::invalid(
            "window",
            format!("must hold at least 2 cameras, got {window}"),
        ));
    }
    if !(height.is_finite() && height > 0.0) {
        return Err(Error::invalid(
            "camera_height",
            format!("must be a positive number of metres, got {height}"),
        ));
    }
    let mut by_camera: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (i, &o) in owner.iter().enumerate() {
        by_camera[o].push(i);
    }
    let window = window.min(n.max(1));
    let step = (window / 2).max(1);
    let mut starts: Vec<usize> = (0..n.saturating_sub(window) + 1).step_by(step).collect();
    if let Some(&l) = starts.last() {
        // The last window ends at the last camera.
        if l + window < n {
            starts.push(n - window);
        }
    }
    starts
        .par_iter()
        .map(|&a| {
            let b = (a + window).min(n);
            let pts: Vec<Vector3<f64>> = by_camera[a..b]
                .iter()
                .flatten()
                .map(|&i| points[i])
                .collect();
            let cams = Trajectory::try_new(
                cameras.timestamps[a..b].to_vec(),
                cameras.positions[a..b].to_vec(),
                cameras.orientations.as_ref().map(|o| o[a..b].to_vec()),
            )?;
            let time = cams.timestamps.iter().sum::<f64>() / (b - a) as f64;
            let fitted = fit_ground_plane(&pts, &cams, opts).and_then(|plane| {
                metric_from_height(&plane, &cams, &CameraHeight::Constant(height))
                    .map(|m| (plane.inliers, m.scale))
            });
            let (scale, inliers, reason) = match fitted {
                Ok((inliers, scale)) => (Some(scale), inliers, None),
                Err(e) => (None, 0, Some(e.to_string())),
            };
            Ok(ProfileWindow {
                first: a,
                last: b - 1,
                time,
                scale,
                inliers,
                reason,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, UnitQuaternion};

    /// A room in SLAM units (scale `1 / s` of metres): a floor at z = 0
    /// (metric), two walls, cameras at 1.2 m looking ahead with a little
    /// roll and pitch; the SLAM frame turned and shifted.
    fn room(table: bool, floor: bool) -> (Vec<Vector3<f64>>, Trajectory, Sim3) {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut noise = |s: f64| (rng.random::<f64>() - 0.5) * 2.0 * s;
        let mut world = Vec::new();
        for _ in 0..3000 {
            let (x, y) = (noise(5.0), noise(5.0));
            if floor {
                world.push(Vector3::new(x, y, noise(0.01)));
            }
            world.push(Vector3::new(5.0 + noise(0.01), y, 1.5 + noise(1.5)));
            world.push(Vector3::new(x, 5.0 + noise(0.01), 1.5 + noise(1.5)));
            if table && x.abs() < 4.2 && y.abs() < 4.2 {
                world.push(Vector3::new(x, y, 0.75 + noise(0.01)));
            }
        }
        let mut stamps = Vec::new();
        let mut pos = Vec::new();
        let mut rot = Vec::new();
        for k in 0..40 {
            let a = k as f64 * 0.15;
            stamps.push(k as f64);
            pos.push(Vector3::new(2.0 * a.cos(), 2.0 * a.sin(), 1.2));
            // Camera: z ahead (tangent), y down, with a few degrees of roll and pitch.
            let ahead = Vector3::new(-a.sin(), a.cos(), 0.0);
            let down = -Vector3::z();
            let right = down.cross(&ahead);
            let r = Matrix3::from_columns(&[right, down, ahead]);
            let wobble = UnitQuaternion::from_euler_angles(noise(0.05), noise(0.05), 0.0);
            rot.push(
                UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r)) * wobble,
            );
        }
        // The SLAM frame: metres × 1/2.5, turned and shifted.
        let t_slam_world = Sim3 {
            rotation: UnitQuaternion::from_euler_angles(0.4, -1.0, 2.0),
            translation: Vector3::new(3.0, -1.0, 0.5),
            scale: 0.4,
        };
        let pts = world
            .iter()
            .map(|p| t_slam_world.transform_point(p))
            .collect();
        let cams = Trajectory::try_new(
            stamps,
            pos.iter()
                .map(|p| t_slam_world.transform_point(p))
                .collect(),
            Some(rot.iter().map(|q| t_slam_world.rotation * q).collect()),
        )
        .unwrap();
        (pts, cams, t_slam_world)
    }

    #[test]
    fn the_floor_and_a_known_height_give_scale_and_gravity() {
        let (pts, cams, t_slam_world) = room(false, true);
        let plane = fit_ground_plane(&pts, &cams, &GroundOptions::default()).unwrap();
        assert!(plane.inliers >= 2900, "{plane:?}");
        let up = t_slam_world.rotation * Vector3::z();
        assert!(plane.normal.angle(&up).to_degrees() < 0.2, "{plane:?}");
        let m = metric_from_height(&plane, &cams, &CameraHeight::Constant(1.2)).unwrap();
        assert!((m.scale - 2.5).abs() < 0.01 * 2.5, "{}", m.scale);
        // In the world frame the cameras ride at 1.2 m and the first one is over the origin.
        let c0 = m.t_world_slam.transform_point(&cams.positions[0]);
        assert!(
            c0.x.abs() < 1e-9 && c0.y.abs() < 1e-9 && (c0.z - 1.2).abs() < 0.02,
            "{c0:?}"
        );
        let first = metric_from_height(&plane, &cams, &CameraHeight::First(1.2)).unwrap();
        assert!((first.scale - 2.5).abs() < 0.02 * 2.5, "{}", first.scale);
        let per = metric_from_height(&plane, &cams, &CameraHeight::PerPose(vec![1.2; 40])).unwrap();
        assert!((per.scale - 2.5).abs() < 0.01 * 2.5, "{}", per.scale);
        assert!(metric_from_height(&plane, &cams, &CameraHeight::PerPose(vec![1.2; 3])).is_err());
        assert!(metric_from_height(&plane, &cams, &CameraHeight::Constant(-1.0)).is_err());
    }

    #[test]
    fn a_table_beside_the_floor_is_passed_over_and_no_floor_is_refused() {
        let (pts, cams, t_slam_world) = room(true, true);
        let plane = fit_ground_plane(&pts, &cams, &GroundOptions::default()).unwrap();
        let up = t_slam_world.rotation * Vector3::z();
        assert!(plane.normal.angle(&up).to_degrees() < 0.2, "{plane:?}");
        // The floor, with the table top 0.75 m (0.3 units) over it as the runner-up.
        let floor = plane.height(&t_slam_world.transform_point(&Vector3::zeros()));
        assert!(floor.abs() < 0.005, "{plane:?}");
        let (_, h) = plane.runner_up.unwrap();
        assert!((h - 0.3).abs() < 0.01, "{plane:?}");
        let (pts, cams, _) = room(false, false);
        let e = fit_ground_plane(&pts, &cams, &GroundOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("no plane"), "{e}");
        let (pts, cams, _) = room(true, false);
        let e = fit_ground_plane(&pts, &cams, &GroundOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("under the plane"), "{e}");
    }
}
