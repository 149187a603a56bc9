//! `T_world_slam` with no second sensor (`convert --camera-height`,
//! `--known-distance`, `--planar-motion`): what the user knows of the
//! scene ends in the level frame of [`crate::align::priors::level_frame`]
//! (z up, the first camera over the origin, x along its heading).
//!
//! - "Up" is the normal of the ground plane of the recording's SLAM-frame
//!   cloud ([`crate::align::ground::fit_ground_plane`]), or with
//!   `planar_motion` the normal of the plane the cameras ride in
//!   ([`crate::align::priors::planar_motion`]; no cloud needed).
//! - The scale is that of a known distance between two poses or map points
//!   ([`crate::align::priors::scale_between`]; poses named by index, image
//!   name or stamp, points by their SLAM coordinates) when given, else the cameras' known height over
//!   the ground plane ([`crate::align::ground::metric_from_height`]).
//! - The first camera's height is its height over the ground plane when
//!   there is one, else the height given, else 0.
//!
//! The cloud is the keyframes' backprojections (read back a batch at a time
//! when the pixels are on disk) or the reconstruction's points, at most
//! [`MAX_POINTS`] of them (every k-th). A reference sensor, when the
//! recording has one, still sets the frame; the prior is then fitted beside
//! it and the report says how far its scale and "up" lie from the sensor's.

use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::align::ground::{
    fit_ground_plane, height_profile, metric_from_height, CameraHeight, GroundOptions, GroundPlane,
    HeightScale, ProfileWindow,
};
use crate::align::priors::{
    level_frame, planar_motion, scale_between, KnownDistance, PlanarMotion,
};
use crate::cloud::{backproject_batch_counted, PointFilter};
use crate::defaults;
use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::keyframe::Keyframe;
use crate::trajectory::Trajectory;

use super::report::{
    DistanceReport, HeightGiven, PlanarReport, PlaneReport, PriorReport, ProfileReport,
};
use super::source::Recording;

/// Most points the plane is fitted to (every k-th of the cloud beyond it).
pub const MAX_POINTS: usize = 1_000_000;

/// The cameras' height above the ground, as the user gives it.
#[derive(Clone, Debug, PartialEq)]
pub enum HeightSpec {
    /// Metres at every pose (the median distance is scaled to it).
    Constant(f64),
    /// Metres at the first pose (a drone on the floor or a stand).
    First(f64),
    /// A file of `stamp height` lines (seconds, metres), interpolated at
    /// the poses' stamps.
    File(PathBuf),
}

impl std::str::FromStr for HeightSpec {
    type Err = Error;

    /// `1.2` (every pose), `first:0.95` (the first pose), else a file path.
    fn from_str(s: &str) -> Result<Self> {
        let metres = |v: &str| -> Result<f64> {
            match v.trim().parse::<f64>() {
                Ok(m) if m.is_finite() && m > 0.0 => Ok(m),
                _ => Err(Error::invalid(
                    "camera_height",
                    format!("must be a positive number of metres, got {v:?}"),
                )),
            }
        };
        if let Some(v) = s.strip_prefix("first:") {
            return metres(v).map(HeightSpec::First);
        }
        if s.trim().parse::<f64>().is_ok() {
            return metres(s).map(HeightSpec::Constant);
        }
        Ok(HeightSpec::File(PathBuf::from(s)))
    }
}

/// One end of a known distance: a pose (its index, its image name, or its
/// stamp; its camera centre) or a map point (SLAM coordinates, as the
/// input's cloud has them: picked in COLMAP's GUI, or in CloudCompare on
/// the input's own cloud).
#[derive(Clone, Debug, PartialEq)]
pub enum DistanceEnd {
    /// Index among the SLAM poses (keyframes, or frames), from 0.
    Index(usize),
    /// Stamp, seconds (the nearest pose within `max_diff`).
    Stamp(f64),
    /// Image name (a reconstruction's frame).
    Name(String),
    /// A point of the map, SLAM frame.
    Point(Vector3<f64>),
}

impl std::str::FromStr for DistanceEnd {
    type Err = Error;

    /// `12` (an index), `1403715278.762` (a stamp: a number with a point or
    /// an exponent), `0.41,-1.2,3.05` (a map point: three numbers with
    /// commas), else an image name.
    fn from_str(s: &str) -> Result<Self> {
        let t = s.trim();
        if let Ok(i) = t.parse::<usize>() {
            return Ok(DistanceEnd::Index(i));
        }
        let parts: Vec<&str> = t.split(',').map(str::trim).collect();
        if parts.len() == 3 {
            if let Ok(v) = parts
                .iter()
                .map(|p| p.parse::<f64>())
                .collect::<std::result::Result<Vec<f64>, _>>()
            {
                if !v.iter().all(|x| x.is_finite()) {
                    return Err(Error::invalid(
                        "known_distance",
                        format!("a map point's coordinates must be finite, got {t:?}"),
                    ));
                }
                return Ok(DistanceEnd::Point(Vector3::new(v[0], v[1], v[2])));
            }
        }
        match t.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(DistanceEnd::Stamp(v)),
            Ok(v) => Err(Error::invalid(
                "known_distance",
                format!("a pose's stamp must be finite, got {v}"),
            )),
            Err(_) if t.is_empty() => Err(Error::invalid(
                "known_distance",
                "an end is a pose's index, stamp or image name, or a map point x,y,z; got an \
                 empty string",
            )),
            Err(_) => Ok(DistanceEnd::Name(t.to_string())),
        }
    }
}

impl std::fmt::Display for DistanceEnd {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DistanceEnd::Index(i) => write!(f, "pose {i}"),
            DistanceEnd::Stamp(t) => write!(f, "the pose at {t} s"),
            DistanceEnd::Name(n) => write!(f, "image {n:?}"),
            DistanceEnd::Point(p) => write!(f, "the map point ({}, {}, {})", p.x, p.y, p.z),
        }
    }
}

/// Two poses or map points a known distance apart.
#[derive(Clone, Debug, PartialEq)]
pub struct DistanceSpec {
    /// The first end.
    pub a: DistanceEnd,
    /// The second end.
    pub b: DistanceEnd,
    /// Their distance, metres.
    pub metres: f64,
}

/// The prior a conversion is told (`ConvertOptions::prior`): a scale
/// (`known_distance`, else `camera_height`) and an "up" (the ground plane,
/// or `planar_motion`).
#[derive(Clone, Debug, PartialEq)]
pub struct PriorOptions {
    /// The cameras' height above the ground.
    pub camera_height: Option<HeightSpec>,
    /// The height's standard deviation, metres (how well it is known; the
    /// scale's uncertainty in the report counts it).
    pub camera_height_sigma: Option<f64>,
    /// Two poses a known distance apart (the scale, before a height).
    pub known_distance: Option<DistanceSpec>,
    /// "Up" from the plane the cameras ride in instead of the ground plane.
    pub planar_motion: bool,
    /// How the ground plane is found.
    pub ground: GroundOptions,
}

impl PriorOptions {
    /// A height with the default ground search.
    pub fn height(camera_height: HeightSpec) -> Self {
        PriorOptions {
            camera_height: Some(camera_height),
            camera_height_sigma: None,
            known_distance: None,
            planar_motion: false,
            ground: GroundOptions::default(),
        }
    }

    /// The prior of a conversion's `camera_height` (with its sigma),
    /// `known_distance` and `planar_motion` (the CLI's flags, Python's
    /// arguments): `None` when none is given; planar motion alone is refused
    /// (it gives no scale), as is a sigma without a height.
    pub fn from_parts(
        camera_height: Option<HeightSpec>,
        camera_height_sigma: Option<f64>,
        known_distance: Option<DistanceSpec>,
        planar_motion: bool,
    ) -> Result<Option<Self>> {
        if camera_height.is_none() && camera_height_sigma.is_some() {
            return Err(Error::invalid(
                "camera_height_sigma",
                "is the uncertainty of camera_height: give the height too",
            ));
        }
        if camera_height.is_none() && known_distance.is_none() {
            if planar_motion {
                return Err(Error::invalid(
                    "planar_motion",
                    "gives \"up\" only: give the scale too (camera_height or known_distance)",
                ));
            }
            return Ok(None);
        }
        let opts = PriorOptions {
            camera_height,
            camera_height_sigma,
            known_distance,
            planar_motion,
            ground: GroundOptions::default(),
        };
        opts.check()?;
        Ok(Some(opts))
    }

    /// Checks that a scale is given.
    pub fn check(&self) -> Result<()> {
        if self.camera_height.is_none() && self.known_distance.is_none() {
            return Err(Error::invalid(
                "prior",
                "the scale needs the cameras' height over the ground (camera_height) or a known \
                 distance between two poses (known_distance)",
            ));
        }
        if let Some(s) = self.camera_height_sigma {
            if !(s.is_finite() && s >= 0.0) {
                return Err(Error::invalid(
                    "camera_height_sigma",
                    format!("must be a number of metres, 0 or more, got {s}"),
                ));
            }
        }
        if let Some(d) = &self.known_distance {
            if !(d.metres.is_finite() && d.metres > 0.0) {
                return Err(Error::invalid(
                    "known_distance",
                    format!(
                        "the distance must be a positive number of metres, got {}",
                        d.metres
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// Where the prior's "up" came from.
#[derive(Clone, Debug, PartialEq)]
pub enum Up {
    /// The ground plane's normal.
    Ground,
    /// The normal of the plane the cameras ride in.
    Planar(PlanarMotion),
}

/// One end of a known distance as found among the poses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FoundEnd {
    /// The pose's index among the SLAM poses (`None`: a map point).
    pub pose: Option<usize>,
    /// Where it is, SLAM frame.
    pub at: Vector3<f64>,
}

/// The prior's fit.
#[derive(Clone, Debug, PartialEq)]
pub struct PriorFit {
    /// `T_world_slam`.
    pub transform: Sim3,
    /// The ground plane (SLAM frame), when one was fitted.
    pub plane: Option<GroundPlane>,
    /// Scale from the plane and the heights, when heights were given.
    pub height: Option<HeightScale>,
    /// The known distance's two ends and its scale, when given (it sets
    /// the scale).
    pub distance: Option<([FoundEnd; 2], KnownDistance)>,
    /// Where "up" came from.
    pub up: Up,
    /// Stamps of the SLAM poses.
    pub stamps: Vec<f64>,
    /// The scale per window of keyframes ([`height_profile`]; one height at
    /// every pose, keyframes with depth and a run of two windows or more).
    pub profile: Vec<ProfileWindow>,
}

impl PriorFit {
    /// `T_world_slam` of the prior.
    pub fn transform(&self) -> Sim3 {
        self.transform
    }

    /// The report of the fit, `opts` as given; `sensor` is `T_world_slam`
    /// of a reference sensor that set the frame instead.
    pub fn report(&self, opts: &PriorOptions, sensor: Option<&Sim3>) -> PriorReport {
        let scale = self.transform.scale;
        // "Up" in the SLAM frame: the world's z carried back.
        let up = self.transform.rotation.inverse() * Vector3::z();
        PriorReport {
            used_for_transform: sensor.is_none(),
            scale,
            scale_from: if self.distance.is_some() {
                "known_distance"
            } else {
                "camera_height"
            }
            .into(),
            up_from: match self.up {
                Up::Ground => "ground_plane",
                Up::Planar(_) => "planar_motion",
            }
            .into(),
            up: [up.x, up.y, up.z],
            camera_height: opts.camera_height.as_ref().map(|spec| match spec {
                HeightSpec::Constant(v) => HeightGiven::Constant { metres: *v },
                HeightSpec::First(v) => HeightGiven::First { metres: *v },
                HeightSpec::File(f) => HeightGiven::File { path: f.clone() },
            }),
            height_scale: self.height.as_ref().map(|m| m.scale),
            camera_height_sigma: opts.camera_height_sigma,
            scale_sigma_ground: self.height.as_ref().map(|m| m.scale_sigma),
            scale_sigma: self.height.as_ref().map(|m| {
                let stated = opts.camera_height_sigma.unwrap_or(0.0);
                // The given height the stated sigma is relative to.
                let metres = match &opts.camera_height {
                    Some(HeightSpec::Constant(v) | HeightSpec::First(v)) => *v,
                    _ => {
                        let mut h = m.heights.clone();
                        h.sort_by(f64::total_cmp);
                        m.scale * h[h.len() / 2]
                    }
                };
                m.scale_sigma_with(stated / metres)
            }),
            height_rms: self.height.as_ref().map(|m| m.height_rms),
            known_distance: self.distance.map(|([a, b], k)| DistanceReport {
                poses: [a.pose, b.pose],
                ends: [a.at.into(), b.at.into()],
                metres: k.metres,
                slam_distance: k.slam_distance,
                scale: k.scale,
            }),
            plane: self.plane.as_ref().map(|p| PlaneReport {
                normal: [p.normal.x, p.normal.y, p.normal.z],
                offset: p.offset,
                inliers: p.inliers,
                n_points: p.n_points,
                spread: p.spread,
                below: p.below,
                cameras_above: p.cameras_above,
                tilt_from_cameras_deg: p.tilt_from_cameras_deg,
                tilt_sigma_deg: p.tilt_sigma_deg(),
                runner_up: p.runner_up,
            }),
            planar_motion: match &self.up {
                Up::Planar(m) => Some(PlanarReport {
                    normal: [m.normal.x, m.normal.y, m.normal.z],
                    rms: m.rms,
                    extent: m.extent,
                    tilt_bound_deg: m.tilt_bound_deg,
                    sigma_deg: m.sigma_deg,
                }),
                Up::Ground => None,
            },
            heights: match (&self.plane, &self.height) {
                (Some(_), Some(m)) => self
                    .stamps
                    .iter()
                    .zip(&m.heights)
                    .map(|(&t, &h)| [t, scale * h])
                    .collect(),
                _ => Vec::new(),
            },
            profile: self
                .profile
                .iter()
                .map(|w| ProfileReport {
                    first: w.first,
                    last: w.last,
                    time: w.time,
                    scale: w.scale,
                    inliers: w.inliers,
                    reason: w.reason.clone(),
                })
                .collect(),
            scale_vs_sensor: sensor.map(|s| scale / s.scale - 1.0),
            up_vs_sensor_deg: sensor
                .map(|s| (s.rotation * up).z.clamp(-1.0, 1.0).acos().to_degrees()),
        }
    }
}

/// Fits the prior to the recording's cloud and its SLAM poses `slam`
/// (`rows[s]`: the keyframe of pose `s`, as [`Recording::slam_trajectory`]
/// gives them; `names[s]`: the image name of pose `s`, where it has one;
/// `max_diff`:
/// how far a stamp may lie from the pose it names). Errors: no scale given,
/// no cloud where the ground plane is needed, the ground plane's and planar
/// motion's refusals, the heights' (a file that does not cover the poses,
/// a height that is not a positive number), a pose not found.
pub fn fit(
    rec: &Recording,
    slam: &Trajectory,
    rows: &[Option<usize>],
    names: &[Option<String>],
    opts: &PriorOptions,
    filter: &PointFilter,
    max_diff: f64,
) -> Result<PriorFit> {
    opts.check()?;
    // The ground plane: for "up", or for the heights.
    let mut profile = Vec::new();
    let plane = if !opts.planar_motion || opts.camera_height.is_some() {
        let (points, owner) = slam_points(rec, filter)?;
        if points.is_empty() {
            return Err(Error::invalid(
                if opts.camera_height.is_some() {
                    "camera_height"
                } else {
                    "prior"
                },
                format!(
                    "{} has no points in its cloud: the ground plane needs the map (or give \
                     planar_motion for \"up\" and known_distance for the scale)",
                    rec.source.path.display()
                ),
            ));
        }
        let plane = fit_ground_plane(&points, slam, &opts.ground)?;
        // The scale along the run, for one height at every pose and points
        // that know their keyframe.
        if let (Some(HeightSpec::Constant(h)), Some(owner), Some(w)) =
            (&opts.camera_height, owner, profile_window(slam.len()))
        {
            // Keyframe index -> SLAM row.
            let mut row_of = vec![usize::MAX; rec.keyframes.len()];
            for (s, r) in rows.iter().enumerate() {
                if let Some(k) = r {
                    row_of[*k] = s;
                }
            }
            let (pts, own): (Vec<Vector3<f64>>, Vec<usize>) = points
                .iter()
                .zip(&owner)
                .filter_map(|(p, &k)| {
                    let s = *row_of.get(k)?;
                    (s != usize::MAX).then_some((*p, s))
                })
                .unzip();
            profile = height_profile(&pts, &own, slam, *h, w, &opts.ground)?;
        }
        Some(plane)
    } else {
        None
    };
    let height = match (&plane, &opts.camera_height) {
        (Some(p), Some(spec)) => {
            let given = match spec {
                HeightSpec::Constant(v) => CameraHeight::Constant(*v),
                HeightSpec::First(v) => CameraHeight::First(*v),
                HeightSpec::File(f) => CameraHeight::PerPose(heights_at(f, &slam.timestamps)?),
            };
            Some(metric_from_height(p, slam, &given)?)
        }
        _ => None,
    };
    let distance = match &opts.known_distance {
        Some(d) => {
            let ends = [
                find_end(&d.a, slam, names, max_diff)?,
                find_end(&d.b, slam, names, max_diff)?,
            ];
            let what = format!("{} and {}", d.a, d.b);
            let k = scale_between(&ends[0].at, &ends[1].at, d.metres, slam, &what)?;
            Some((ends, k))
        }
        None => None,
    };
    let up = if opts.planar_motion {
        Up::Planar(planar_motion(slam, defaults::PLANAR_MAX_TILT_BOUND_DEG)?)
    } else {
        Up::Ground
    };
    // The ground plane is fitted unless planar motion gives "up", and a
    // height or a distance is there (checked): both always match.
    let normal = match (&up, &plane) {
        (Up::Planar(m), _) => m.normal,
        (Up::Ground, Some(p)) => p.normal,
        (Up::Ground, None) => return Err(Error::invalid("prior", "no \"up\": no ground plane")),
    };
    let scale = match (&distance, &height) {
        (Some((_, k)), _) => k.scale,
        (None, Some(m)) => m.scale,
        (None, None) => {
            return Err(Error::invalid(
                "prior",
                "no scale: no height and no distance",
            ))
        }
    };
    // The first camera's height in metres: over the ground plane when there
    // is one, else as given, else 0.
    let first = match (&plane, &opts.camera_height) {
        (Some(p), _) => scale * p.height(&slam.positions[0]),
        (None, Some(HeightSpec::Constant(v) | HeightSpec::First(v))) => *v,
        (None, _) => 0.0,
    };
    Ok(PriorFit {
        transform: level_frame(&normal, slam, scale, first),
        plane,
        height,
        distance,
        up,
        stamps: slam.timestamps.clone(),
        profile,
    })
}

/// The end `r` names: a map point as given, a pose by its index among
/// `slam` and its camera centre.
fn find_end(
    r: &DistanceEnd,
    slam: &Trajectory,
    names: &[Option<String>],
    max_diff: f64,
) -> Result<FoundEnd> {
    let n = slam.len();
    let found = match r {
        DistanceEnd::Point(p) => return Ok(FoundEnd { pose: None, at: *p }),
        DistanceEnd::Index(i) => (*i < n).then_some(*i),
        DistanceEnd::Name(name) => names.iter().position(|m| m.as_deref() == Some(name)),
        DistanceEnd::Stamp(t) => {
            let k = slam.timestamps.partition_point(|s| s < t);
            [k.checked_sub(1), (k < n).then_some(k)]
                .into_iter()
                .flatten()
                .min_by(|&i, &j| {
                    (slam.timestamps[i] - t)
                        .abs()
                        .total_cmp(&(slam.timestamps[j] - t).abs())
                })
                .filter(|&i| (slam.timestamps[i] - t).abs() <= max_diff)
        }
    };
    let i = found.ok_or_else(|| {
        Error::invalid(
            "known_distance",
            format!(
                "{r} is not among the {n} SLAM poses{}",
                match r {
                    DistanceEnd::Index(_) => format!(" (0 .. {})", n.max(1) - 1),
                    DistanceEnd::Stamp(_) => format!(" (none within {max_diff} s)"),
                    DistanceEnd::Name(_) | DistanceEnd::Point(_) => String::new(),
                }
            ),
        )
    })?;
    Ok(FoundEnd {
        pose: Some(i),
        at: slam.positions[i],
    })
}

/// Points of the SLAM cloud, and the keyframe (index) of each when known.
type SlamPoints = (Vec<Vector3<f64>>, Option<Vec<usize>>);

/// The recording's cloud in the SLAM frame, at most [`MAX_POINTS`] (every
/// k-th): its keyframes backprojected (their pixels read back a batch at a
/// time when on disk), each point with the index in `rec.keyframes` of the
/// keyframe it came from; else its own cloud (no owners).
fn slam_points(rec: &Recording, filter: &PointFilter) -> Result<SlamPoints> {
    let kfs = &rec.keyframes;
    if kfs.is_empty() {
        let Some(c) = &rec.cloud else {
            return Ok((Vec::new(), None));
        };
        let points = c
            .points_every(c.len().div_ceil(MAX_POINTS))
            .filter(|p| p.iter().all(|v| v.is_finite()))
            .collect();
        return Ok((points, None));
    }
    let index: std::collections::HashMap<i32, usize> =
        kfs.iter().enumerate().map(|(k, kf)| (kf.id, k)).collect();
    // The pixels with depth are a share of the images: the stride bounds
    // the points kept by the pixels there are.
    let pixels: usize = kfs
        .iter()
        .map(|k| k.camera.width as usize * k.camera.height as usize)
        .sum();
    let stride = pixels.div_ceil(MAX_POINTS).max(1);
    let mut out = Vec::new();
    let mut owner = Vec::new();
    let batch = super::batch_len();
    let order: Vec<usize> = (0..kfs.len()).collect();
    for (b, idx) in order.chunks(batch).enumerate() {
        crate::interrupt::check()?;
        let loaded;
        let keyframes: &[Keyframe] = match &rec.pixels {
            Some(px) => {
                loaded = idx
                    .par_iter()
                    .map(|&i| super::load_keyframe(kfs, px, i))
                    .collect::<Result<Vec<_>>>()?;
                &loaded
            }
            None => &kfs[b * batch..b * batch + idx.len()],
        };
        let (c, _) =
            backproject_batch_counted(keyframes, b * batch, filter, |_| Sim3::identity(), false)?;
        out.extend(c.points_every(stride));
        owner.extend(
            c.keyframe_ids
                .iter()
                .step_by(stride)
                .map(|id| index.get(id).copied().unwrap_or(usize::MAX)),
        );
    }
    Ok((out, Some(owner)))
}

/// Keyframes per window of the scale profile of a run of `n` keyframes:
/// a tenth of the run (about twenty windows, half overlapping), at least
/// [`defaults::PROFILE_MIN_WINDOW`]; `None` when the run holds fewer than
/// two such windows.
pub fn profile_window(n: usize) -> Option<usize> {
    let w = n.div_ceil(10).max(defaults::PROFILE_MIN_WINDOW);
    (n >= 2 * w).then_some(w)
}

/// The heights of the `stamp height` file at `path` at each of `stamps`
/// (linear between its lines). Errors: a line that is not two numbers,
/// stamps not increasing, a pose outside the file's span.
fn heights_at(path: &Path, stamps: &[f64]) -> Result<Vec<f64>> {
    let mut rows: Vec<(f64, f64)> = Vec::new();
    crate::io::lines::for_each_line(path, "camera height file", |line, text| {
        let t = text.trim();
        if t.is_empty() || t.starts_with('#') || t.starts_with("//") {
            return Ok(());
        }
        let fields: Vec<&str> = t
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|f| !f.is_empty())
            .collect();
        if fields.len() != 2 {
            return Err(Error::parse(
                path,
                line,
                format!("expected `stamp height`, got {} fields", fields.len()),
            ));
        }
        let v = crate::io::lines::parse_fields(path, line, &fields)?;
        if let Some(&(prev, _)) = rows.last() {
            if v[0] <= prev {
                return Err(Error::parse(
                    path,
                    line,
                    format!("stamps must increase: {} after {prev}", v[0]),
                ));
            }
        }
        rows.push((v[0], v[1]));
        Ok(())
    })?;
    let (Some(&(t0, _)), Some(&(t1, _))) = (rows.first(), rows.last()) else {
        return Err(Error::parse(path, 1, "no `stamp height` line"));
    };
    stamps
        .iter()
        .map(|&t| {
            if t < t0 || t > t1 {
                return Err(Error::invalid(
                    "camera_height",
                    format!(
                        "{}: a pose at {t} s lies outside the heights' span {t0} .. {t1} s",
                        path.display()
                    ),
                ));
            }
            // The first line at or after t (there is one: t <= t1).
            let k = rows.partition_point(|&(s, _)| s < t);
            let (sb, hb) = rows[k];
            Ok(match k.checked_sub(1).map(|j| rows[j]) {
                Some((sa, ha)) if sb > t => ha + (hb - ha) * (t - sa) / (sb - sa),
                _ => hb,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_distance_end_is_an_index_a_stamp_a_point_or_a_name() {
        let end = |s: &str| s.parse::<DistanceEnd>();
        assert_eq!(end(" 12 ").unwrap(), DistanceEnd::Index(12));
        assert_eq!(
            end("1403715278.762").unwrap(),
            DistanceEnd::Stamp(1403715278.762)
        );
        assert_eq!(
            end("0.41, -1.2,3.05").unwrap(),
            DistanceEnd::Point(Vector3::new(0.41, -1.2, 3.05))
        );
        assert_eq!(
            end("frame,0001.png").unwrap(),
            DistanceEnd::Name("frame,0001.png".into())
        );
        assert!(end("1,nan,2").unwrap_err().to_string().contains("finite"));
        assert!(end(" ").is_err());
    }

    #[test]
    fn the_profile_window_is_a_tenth_of_the_run_from_its_least() {
        let least = defaults::PROFILE_MIN_WINDOW;
        assert_eq!(profile_window(2 * least - 1), None);
        assert_eq!(profile_window(2 * least), Some(least));
        assert_eq!(profile_window(300), Some(30));
    }

    #[test]
    fn a_height_sigma_needs_a_height_and_planar_motion_a_scale() {
        let d = DistanceSpec {
            a: DistanceEnd::Index(0),
            b: DistanceEnd::Index(1),
            metres: 1.0,
        };
        assert!(PriorOptions::from_parts(None, Some(0.1), Some(d), false).is_err());
        assert!(PriorOptions::from_parts(None, None, None, true).is_err());
        assert_eq!(
            PriorOptions::from_parts(None, None, None, false).unwrap(),
            None
        );
        let h = Some(HeightSpec::Constant(1.2));
        assert!(PriorOptions::from_parts(h.clone(), Some(-0.1), None, false).is_err());
        let p = PriorOptions::from_parts(h, Some(0.05), None, false).unwrap();
        assert_eq!(p.unwrap().camera_height_sigma, Some(0.05));
    }
}
